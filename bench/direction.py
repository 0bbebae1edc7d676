"""Direction fields: how closely the texture follows a painted field, and what
it costs.

    python -m bench.direction [--json OUT.json] [--size 384]

Exemplars: the bundled CC0 brick (upright bricks) and the shared wood photo
(horizontal grain) when present. Fields over the whole window: none (the
identity, each measure's baseline), a constant turn of 30, 60 and 90
degrees, circles about the window's centre and a wave.
At Variety and Balanced, one run each:

- anisometry error (LH06): per pixel, ``||grad S - J||`` (Frobenius; finite
  differences of the sub-pixel coordinate map, in exemplar pixels per canvas
  pixel), median; and the share of pixels whose coordinate continues both
  neighbors through J within 0.25 px (inside a patch: the rest are seams);
- orientation error: the dominant orientation of each 32 x 32 block (the
  structure tensor of the luminance blurred by 1.5 px; blocks whose
  orientation is weak, with a coherence under 0.2, are left out) against the exemplar's own dominant
  orientation turned by the field at the block's centre, modulo 180 degrees;
  median over blocks (target: under 10 degrees);
- with the circles field against without, alternating, medians of 3: the
  time of a window; panning: 8 steps of 32 px of the view;
- a comb dab's local update (radius 24 px, synthesized at once, headless),
  median of 8.

Prints a table, writes JSON.
"""
from __future__ import annotations

import argparse
import json
import os
import sys
import time

import numpy as np

HERE = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
if HERE not in sys.path:
    sys.path.insert(0, HERE)

ORIGIN = (3000, -7000)
BLOCK = 32


def fields(size: int):
    """name -> angle map (degrees, (size, size)) placed at ORIGIN."""
    ys, xs = np.mgrid[0:size, 0:size] + 0.5
    c = size / 2
    return {
        "none": np.zeros((size, size)),  # the identity: the baseline of each measure
        "turn 30": np.full((size, size), 30.0),
        "turn 60": np.full((size, size), 60.0),
        "turn 90": np.full((size, size), 90.0),
        "circles": np.degrees(np.arctan2(ys - c, xs - c)) + 90.0,
        "wave": np.degrees(np.arctan(0.8 * np.cos(xs / 50.0))),
    }


def structure_orientation(gray: np.ndarray) -> tuple[float, float]:
    """(orientation of the gradients in degrees mod 180, coherence in [0, 1]):
    the structure tensor of the luminance blurred by 1.5 px, central
    differences (forward differences of fine grain near 2 px are biased
    towards the axes: the exemplar turned by 30 degrees measured 18)."""
    from scipy import ndimage
    gy, gx = np.gradient(ndimage.gaussian_filter(gray.astype(np.float64), 1.5))
    jxx, jyy, jxy = (gx * gx).sum(), (gy * gy).sum(), (gx * gy).sum()
    coh = np.hypot(jxx - jyy, 2 * jxy) / max(jxx + jyy, 1e-12)
    return float(np.degrees(0.5 * np.arctan2(2 * jxy, jxx - jyy)) % 180.0), float(coh)


def orientation_errors(img: np.ndarray, angle: np.ndarray, ex_orient: float) -> list[float]:
    out = []
    H, W = img.shape[:2]
    for y in range(0, H - BLOCK + 1, BLOCK):
        for x in range(0, W - BLOCK + 1, BLOCK):
            o, coh = structure_orientation(img[y:y + BLOCK, x:x + BLOCK])
            if coh < 0.2:
                continue
            want = (ex_orient + angle[y + BLOCK // 2, x + BLOCK // 2]) % 180.0
            d = abs(o - want) % 180.0
            out.append(min(d, 180.0 - d))
    return out


def anisometry(c: np.ndarray, J: np.ndarray, m: int) -> tuple[float, float]:
    """(median ||grad S - J||_F, share of pixels continuing both neighbors within 0.25 px)."""
    F = c[..., :2].astype(np.int64) * 256 + c[..., 2:]
    period = 256 * m

    def wrapped(d):
        return ((d + period // 2) % period - period // 2) / 256.0
    dx = wrapped(F[:-1, 1:] - F[:-1, :-1])  # (h, w, 2): S(p + e_x) - S(p)
    dy = wrapped(F[1:, :-1] - F[:-1, :-1])
    j = J[:-1, :-1].astype(np.float64) / 4096.0
    ex = dx - np.stack([j[..., 0], j[..., 2]], axis=-1)
    ey = dy - np.stack([j[..., 1], j[..., 3]], axis=-1)
    err = np.sqrt((ex ** 2).sum(-1) + (ey ** 2).sum(-1))
    coherent = (np.abs(ex).max(-1) <= 0.25) & (np.abs(ey).max(-1) <= 0.25)
    return float(np.median(err)), float(coherent.mean())


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--json", default=None)
    ap.add_argument("--size", type=int, default=384)
    args = ap.parse_args()
    from infinitex import ASSETS
    from infinitex.engine.analysis import analyze
    from infinitex.engine.controls import Controls
    from infinitex.engine.controls.direction import DirectionField, comb, jacobian
    from infinitex.engine.exemplar import load_exemplar
    from infinitex.engine.gpu import Gpu
    from infinitex.engine.params import SynthParams, structure_params
    from infinitex.engine.pyramid import Rect
    from infinitex.engine.synth import Synthesizer

    exemplars = {"brick": os.path.join(ASSETS, "brick.png")}
    wood = os.path.join(HERE, "..", "shared", "exemplars", "wood.png")
    if os.path.exists(wood):
        exemplars["wood"] = wood
    n = args.size
    rect = Rect.of(ORIGIN[0], ORIGIN[1], n, n)
    gpu = Gpu()
    rows = []
    try:
        for name, path in exemplars.items():
            ex = load_exemplar(path)
            an = analyze(ex)
            gray = ex.pixels[..., :3].mean(axis=-1) if ex.pixels.shape[2] >= 3 else ex.pixels[..., 0]
            ex_orient, ex_coh = structure_orientation(gray)
            for structure in (0, 2):
                params = structure_params(SynthParams.default(an.L, seed=3), structure)
                for fname, angle in fields(n).items():
                    field = DirectionField.from_jacobians(jacobian(angle), *ORIGIN)
                    with Synthesizer(an, params, gpu=gpu, controls=Controls(direction=field)) as s:
                        c = s.window(rect, remainder=True)
                        img = s.colors(c)
                    lum = img[..., :3].mean(axis=-1) if img.shape[2] >= 3 else img[..., 0]
                    errs = orientation_errors(lum, angle, ex_orient)
                    med, coh = anisometry(c, field.dense(rect.x0, rect.y0, n, n), an.size)
                    rows.append(dict(exemplar=name, structure=structure, field=fname,
                                     orientation_median_deg=float(np.median(errs)) if errs else None,
                                     orientation_blocks=len(errs), anisometry_median=med, continued=coh,
                                     exemplar_orientation=ex_orient, exemplar_coherence=ex_coh))
                    r = rows[-1]
                    print(f"{name:6s} {('Variety', '', 'Balanced')[structure]:8s} {fname:8s} "
                          f"orientation {r['orientation_median_deg'] or float('nan'):5.1f} deg ({len(errs)} blocks)  "
                          f"||grad S - J|| {med:.3f}  continued {coh:.2f}", flush=True)
                # Times, with the circles field and without, alternating (medians of 3): a
                # window, a pan of 8 steps, and a comb dab's local update.
                field = DirectionField.from_jacobians(jacobian(fields(n)["circles"]), *ORIGIN)
                times: dict = {"plain": [], "field": []}
                pans: dict = {"plain": [], "field": []}
                for rep in range(3):
                    for label, ctl in (("plain", Controls()), ("field", Controls(direction=field))):
                        with Synthesizer(an, params, gpu=gpu, controls=ctl) as s:
                            if rep == 0:
                                s.window(rect)  # programs compiled
                            t = time.perf_counter()
                            s.window(rect)
                            times[label].append(time.perf_counter() - t)
                for rep in range(3):
                    for label, ctl in (("plain", Controls()), ("field", Controls(direction=field))):
                        vp = Synthesizer(an, params, gpu=gpu, controls=ctl).viewport()
                        try:
                            view = rect
                            vp.show(view)
                            t = time.perf_counter()
                            for _ in range(8):
                                view = Rect.of(view.x0 + 32, view.y0 + 16, n, n)
                                vp.show(view)
                            pans[label].append((time.perf_counter() - t) / 8)
                        finally:
                            vp.release()
                window = {k: float(np.median(v)) for k, v in times.items()}
                pan = {k: float(np.median(v)) for k, v in pans.items()}
                vp = Synthesizer(an, params, gpu=gpu, controls=Controls(direction=field)).viewport()
                try:
                    vp.show(rect)
                    dabs = []
                    cur = field
                    for i in range(9):
                        old = cur
                        cx, cy = rect.x0 + 60 + 30 * i, rect.y0 + 200
                        cur, _ = cur.edited(cx - 24, cy - 24, np.full((48, 48), 0.8), comb(20.0 * i))
                        t = time.perf_counter()
                        vp.pyramid.update_controls(Controls(direction=cur), [Rect(*r) for r in old.changed_rects(cur)])
                        dabs.append(time.perf_counter() - t)
                    dab_s = float(np.median(dabs[1:]))
                finally:
                    vp.release()
                rows.append(dict(exemplar=name, structure=structure, field="times",
                                 window_s=window["field"], plain_window_s=window["plain"],
                                 window_ratio=window["field"] / window["plain"],
                                 pan_step_s=pan["field"], plain_pan_step_s=pan["plain"],
                                 pan_ratio=pan["field"] / pan["plain"], dab_s=dab_s))
                print(f"{name:6s} {('Variety', '', 'Balanced')[structure]:8s} window {window['field']:.2f} s vs "
                      f"{window['plain']:.2f} s without ({window['field'] / window['plain']:.2f}x); pan step "
                      f"{pan['field'] * 1000:.0f} ms vs {pan['plain'] * 1000:.0f} ms ({pan['field'] / pan['plain']:.2f}x); "
                      f"comb dab {dab_s * 1000:.0f} ms", flush=True)
    finally:
        gpu.release()
    per = [r for r in rows if r.get("orientation_median_deg") is not None and r["field"] != "none"]
    for st in (0, 2):
        sel = [r["orientation_median_deg"] for r in per if r["structure"] == st]
        an_sel = [r["anisometry_median"] for r in per if r["structure"] == st]
        print(f"{('Variety', '', 'Balanced')[st]}: orientation error median over cases {np.median(sel):.1f} deg "
              f"(max {max(sel):.1f}); anisometry median {np.median(an_sel):.3f}")
    if args.json:
        os.makedirs(os.path.dirname(os.path.abspath(args.json)), exist_ok=True)
        with open(args.json, "w") as f:
            json.dump({"size": n, "rows": rows}, f, indent=1)
    return 0


if __name__ == "__main__":
    sys.exit(main())
