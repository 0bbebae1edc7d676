"""The engine on another machine's GL (a lent GPU): per-preset timings and cross-machine identity.

    python -m bench.device run OUT_DIR [--quick] [--presets 0 2 ...]
    python -m bench.device compare OUT_DIR/coords.npz

``run`` (on the machine to measure) writes ``OUT_DIR/device.json`` and
``OUT_DIR/coords.npz`` and prints a table. Per Structure preset, on gravel:

  full_ms            a full 512^2 window (warm: shaders compiled, analysis cached), median
  over_variety       full_ms / Variety's, in the same run
  pan_ms             mean per frame, 512^2 viewport panned 8 px/frame over 64 frames; pan_speedup = full / pan
  view_ms            a fresh 1024 x 768 view
  dab_ms             a paint dab (48 px brush, 32 dabs along a stroke) until that view is exact again:
                     recorded, its quick look made, settled, then the view shown (median, p90)
  dab_px             level pixels re-synthesized per dab (median)
  look_ms            from a dab to its quick look made (QuickLooks.look, what the editor shows at once),
                     median (look_max_ms: the largest); label_look_ms, comb_look_ms the same for those dabs;
                     the times until exact include it, as in the editor
  dab_exact          the painted view equals a fresh synthesis with the final controls
  jump_ms            that view moved 4,500 px (all of it new) until exact, median of 3
  release_ms         a randomness slider released (one level's jitter changed) until the view is exact, median of 3
  label_dab_ms       texture by numbers: a label dab (label 1 over canvas labels of 0, two labels proposed on the
                     exemplar) until the view is exact, median of 16; label_dab_exact as dab_exact
  comb_dab_ms        direction fields: a comb dab (48 px) on an identity field until exact, median of 16;
                     comb_dab_exact as dab_exact
  hd_view_ms         a 1920 x 1080 view of all-new canvas, kept on the GPU (as the editor shows it), median of 3;
                     hd_pan_ms: a pan frame of it (8 px, mean of 16); hd_window_ms: the same window read back
                     as coordinates (Synthesizer.window); uhd_*: the same at 3840 x 2160 (not with --quick)

``coords.npz`` holds exemplar coordinates of fixed windows (gravel and the weave,
every preset, near the origin and near (+2^30, -2^30), and a toroidal tile);
``compare`` synthesizes the same windows with this machine's GL and reports
which are bit-identical: determinism across GPUs, drivers and llvmpipe.
``--quick``: smaller windows and views, fewer runs, Maximum skipped (< 2 min on llvmpipe);
``run(..., sizes=SMOKE)``: every path at the smallest sizes (the test's, 20 s here).
"""
from __future__ import annotations

import argparse
import json
import os
import statistics
import sys
import time
from dataclasses import dataclass, replace

import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, ROOT)

from bench.speed import timed  # noqa: E402
from infinitex.engine.analysis import analyze  # noqa: E402
from infinitex.engine.controls import CanvasField, Controls  # noqa: E402
from infinitex.engine.controls.direction import DirectionField, comb, jacobian  # noqa: E402
from infinitex.engine.controls.labels import CanvasLabels, ExemplarLabels, propose_labels  # noqa: E402
from infinitex.engine.exemplar import load_exemplar  # noqa: E402
from infinitex.engine.gpu import Gpu  # noqa: E402
from infinitex.engine.params import STRUCTURE_LEVELS, STRUCTURE_NAMES, SynthParams, structure_params  # noqa: E402
from infinitex.engine.rect import Rect  # noqa: E402
from infinitex.engine.synth import Synthesizer  # noqa: E402

EXEMPLARS = {"gravel": os.path.join(ROOT, "infinitex", "assets", "gravel.png"),
             "weave": os.path.join(ROOT, "bench", "exemplars", "weave.png")}
ORIGINS = {"near0": (-40, -17), "far": (2 ** 30 - 70, -2 ** 30 + 33)}
SCREENS = {"hd": (1920, 1080), "uhd": (3840, 2160)}


@dataclass(frozen=True)
class Sizes:
    """How much a run measures: the full window's side and its runs, pan frames,
    the view, paint dabs and label / comb dabs, the screens (scaled by
    ``screen_scale``), the identity windows' side and toroidal tile."""

    window: int
    runs: int
    pans: int
    view: tuple[int, int]
    dabs: int
    brush_dabs: int
    screens: tuple[str, ...]
    screen_scale: float
    ident: int
    tile: int

    def screen(self, name: str) -> tuple[int, int]:
        """The measured size of screen ``name`` (of SCREENS)."""
        return tuple(round(v * self.screen_scale) for v in SCREENS[name])


FULL = Sizes(512, 7, 64, (1024, 768), 32, 16, ("hd", "uhd"), 1.0, 192, 128)
QUICK = Sizes(256, 3, 16, (512, 384), 8, 4, ("hd",), 1.0, 96, 64)
SMOKE = Sizes(128, 1, 4, (256, 192), 4, 2, ("hd",), 0.25, 64, 64)  # the test's: every path, small


def identity_windows(gpu: Gpu, presets, n: int, tile: int) -> dict[str, np.ndarray]:
    """Coordinates of the fixed windows, by name (exemplar_preset_origin, exemplar_preset_tor)."""
    out = {}
    for name, path in EXEMPLARS.items():
        an = analyze(load_exemplar(path))
        for s in presets:
            syn = Synthesizer(an, structure_params(SynthParams.default(an.L), s), gpu=gpu)
            try:
                for tag, (x, y) in ORIGINS.items():
                    out[f"{name}_{s}_{tag}"] = syn.window(Rect.of(x, y, n, n))
                out[f"{name}_{s}_tor"] = syn.toroidal(tile)
            finally:
                syn.release()
    return out


def preset_timings(gpu: Gpu, an, s: int, z: Sizes) -> dict:
    params = structure_params(SynthParams.default(an.L), s)
    ctx = gpu.ctx
    syn = Synthesizer(an, params, gpu=gpu)
    try:
        syn.window(Rect.of(0, 0, 64, 64))  # compile shaders
        n = z.window
        r = {"full_ms": timed(lambda i: _timed(lambda: syn.window(Rect.of(1000 * i + 7, -777 * i, n, n)), ctx),
                              z.runs)}
        vp = syn.viewport()
        _timed(lambda: vp.show(Rect.of(0, 0, n, n)), ctx)
        r["pan_ms"] = statistics.mean(_timed(lambda: vp.show(Rect.of(8 * f, 3 * f, n, n)), ctx)
                                      for f in range(1, z.pans + 1))
        vp.release()
        w, h = z.view
        view = Rect.of(-300, 200, w, h)
        vp = syn.viewport()
        r["view_ms"] = _timed(lambda: vp.show(view), ctx)
        # A stroke across the view, calm then rough every 8 dabs.
        def paint(f, k, c):
            new, box = f.painted(c[0], c[1], 24.0, 65535 if (k // 8) % 2 == 0 else 0)
            return new, [box]
        dabs, controls, px, looks = _stroke_dabs(vp, view, z.dabs, CanvasField(), paint,
                                          lambda f: Controls(randomness_canvas=f))
        r.update(dab_ms=statistics.median(dabs), dab_p90_ms=float(np.percentile(dabs, 90)),
                 look_ms=statistics.median(looks), look_max_ms=max(looks),
                 dab_px=int(statistics.median(px)), dab_exact=_exact(vp, gpu, an, params, controls, view))
        # The whole view replaced: a 4,500 px jump, then a randomness slider released.
        jumps, releases = [], []
        for k in range(3):
            view = Rect.of(view.x0 + 4500, view.y0, w, h)
            jumps.append(_timed(lambda: vp.show(view), ctx))
        for k in range(3):
            j = list(params.jitter)
            j[an.L - 2 - k] = 0.2 + 0.1 * k
            released = replace(params, jitter=tuple(j))
            releases.append(_timed(lambda: (vp.set_params(released), vp.show(view)), ctx))
        vp.release()
        r.update(jump_ms=statistics.median(jumps), release_ms=statistics.median(releases))
        r.update(_screen_views(syn, ctx, z))
        r.update(_label_dabs(gpu, an, params, view, z.brush_dabs))
        r.update(_comb_dabs(gpu, an, params, view, z.brush_dabs))
        return {k: round(v, 2) if isinstance(v, float) else v for k, v in r.items()}
    finally:
        syn.release()


def _screen_views(syn, ctx, z: Sizes) -> dict:
    """Screen-sized views (``z.screens`` of SCREENS, scaled by ``z.screen_scale``): a view of
    all-new canvas on the GPU (as the editor shows it: nothing read back), median
    of 3 far apart; a pan frame (8 px, mean of 16); the same window read back as
    coordinates (Synthesizer.window), one run."""
    r = {}
    for name in z.screens:
        w, h = z.screen(name)
        vp = syn.viewport()
        views = [_timed(lambda k=k: vp.show(Rect.of(50000 * k - 900, 7000 * k, w, h)), ctx) for k in range(4)][1:]
        x, y = 100000, 3000
        pans = [_timed(lambda f=f: vp.show(Rect.of(x + 8 * f, y + 3 * f, w, h)), ctx) for f in range(17)][1:]
        vp.release()
        r[f"{name}_view_ms"] = statistics.median(views)
        r[f"{name}_pan_ms"] = statistics.mean(pans)
        r[f"{name}_window_ms"] = _timed(lambda: syn.window(Rect.of(-20000, 900, w, h)), ctx)
    return r


def _timed(fn, ctx) -> float:
    t = time.perf_counter()
    fn()
    ctx.finish()
    return (time.perf_counter() - t) * 1000.0


def _exact(vp, gpu: Gpu, an, params, controls: Controls, view: Rect) -> bool:
    """The viewport's pixels (with sub-pixel remainders) equal a fresh synthesis with ``controls``."""
    got = vp.pyramid.read(an.L, view, remainder=True)
    fresh = Synthesizer(an, params, gpu=gpu, controls=controls)
    try:
        return bool(np.array_equal(got, fresh.window(view, remainder=True)))
    finally:
        fresh.release()


def _stroke(view: Rect, k: int) -> tuple[float, float]:
    return view.x0 + 100 + 14 * k, view.y0 + view.h / 2 + 40 * np.sin(k / 3)


def _stroke_dabs(vp, view: Rect, count: int, field, dab, controls_of):
    """``count`` dabs along a stroke, each a local update of ``vp`` until ``view`` is
    exact, as the editor does it: recorded, shown as a quick look, then settled:
    ``dab(field, k, centre) -> (new field, changed (x0, y0, x1, y1) boxes)``,
    ``controls_of(field)`` the controls. Returns (ms per dab until exact, the final
    controls, level pixels per dab, ms per dab until its quick look is made)."""
    times, px, looks = [], [], []
    pyr = vp.pyramid
    for k in range(count):
        new, boxes = dab(field, k, _stroke(view, k))
        t = time.perf_counter()
        pyr.update_controls(controls_of(new), [Rect(*b) for b in boxes], defer=True)
        pyr.looks.look(vp.synth.L, view)
        vp.synth.gpu.ctx.finish()
        looks.append((time.perf_counter() - t) * 1000.0)
        n0 = pyr.pixels_synthesized
        pyr.settle()
        px.append(pyr.pixels_synthesized - n0)
        vp.show(view)
        vp.synth.gpu.ctx.finish()
        times.append((time.perf_counter() - t) * 1000.0)
        field = new
    return times, controls_of(field), px, looks


def _label_dabs(gpu: Gpu, an, params, view: Rect, count: int) -> dict:
    """Texture by numbers: label 1 painted along a stroke over canvas labels of 0 (two labels proposed on
    the exemplar), each dab until the view is exact."""
    el = ExemplarLabels(propose_labels(an, 2).astype(np.uint8))
    cl = CanvasLabels.from_image(np.zeros((view.h, view.w), np.uint8), view.x0, view.y0)
    def controls_of(c):
        return Controls(labels_exemplar=el, labels_canvas=c)
    vp = Synthesizer(an, params, gpu=gpu, controls=controls_of(cl)).viewport()
    try:
        vp.show(view)
        def paint(f, k, c):
            new, _ = f.painted(c[0], c[1], 24.0, 1)
            return new, f.changed_rects(new)
        dabs, final, _, looks = _stroke_dabs(vp, view, count, cl, paint, controls_of)
        return dict(label_dab_ms=statistics.median(dabs), label_look_ms=statistics.median(looks),
                    label_dab_exact=_exact(vp, gpu, an, params, final, view))
    finally:
        vp.release()
        vp.synth.release()


def _comb_dabs(gpu: Gpu, an, params, view: Rect, count: int) -> dict:
    """Direction fields: the comb (48 px, turning towards a new angle each dab) over an identity field."""
    field = DirectionField.from_jacobians(np.broadcast_to(jacobian(0.0), (view.h, view.w, 4)).copy(),
                                          view.x0, view.y0)
    vp = Synthesizer(an, params, gpu=gpu, controls=Controls(direction=field)).viewport()
    try:
        vp.show(view)
        def brush(f, k, c):
            new, _ = f.edited(int(c[0]) - 24, int(c[1]) - 24, np.full((48, 48), 0.8), comb(20.0 * k))
            return new, f.changed_rects(new)
        dabs, final, _, looks = _stroke_dabs(vp, view, count, field, brush, lambda f: Controls(direction=f))
        return dict(comb_dab_ms=statistics.median(dabs), comb_look_ms=statistics.median(looks),
                    comb_dab_exact=_exact(vp, gpu, an, params, final, view))
    finally:
        vp.release()
        vp.synth.release()


def run(out_dir: str, quick: bool, presets, sizes: Sizes | None = None) -> dict:
    """Measure ``presets`` (FULL, or QUICK with ``quick``, or ``sizes``); write device.json and coords.npz."""
    os.makedirs(out_dir, exist_ok=True)
    z = sizes or (QUICK if quick else FULL)
    gpu = Gpu()
    res = {"renderer": gpu.renderer, "quick": quick, "presets": {}}
    coords = identity_windows(gpu, presets, z.ident, z.tile)
    np.savez_compressed(os.path.join(out_dir, "coords.npz"), **coords)
    an = analyze(load_exemplar(EXEMPLARS["gravel"]))
    for s in presets:
        res["presets"][STRUCTURE_NAMES[s]] = preset_timings(gpu, an, s, z)
    base = res["presets"].get(STRUCTURE_NAMES[0])
    for r in res["presets"].values():
        if base:
            r["over_variety"] = round(r["full_ms"] / base["full_ms"], 2)
        r["pan_speedup"] = round(r["full_ms"] / r["pan_ms"], 1)
    gpu.release()
    with open(os.path.join(out_dir, "device.json"), "w") as f:
        json.dump(res, f, indent=1)
    print(f"renderer  {res['renderer']}")
    print(f"{'preset':<10}{'full':>9}{'/Variety':>10}{'pan':>8}{'pan x':>7}{'view':>9}{'jump':>9}{'release':>9}"
          f"{'dab':>9}{'dab p90':>9}{'dab px':>9}{'label':>9}{'comb':>9}{'looks':>20}  exact")
    for k, r in res["presets"].items():
        exact = r["dab_exact"] and r["label_dab_exact"] and r["comb_dab_exact"]
        print(f"{k:<10}{r['full_ms']:>7.1f}ms{r.get('over_variety', float('nan')):>9.2f}x{r['pan_ms']:>6.1f}ms"
              f"{r['pan_speedup']:>6.1f}x{r['view_ms']:>7.1f}ms{r['jump_ms']:>7.1f}ms{r['release_ms']:>7.1f}ms"
              f"{r['dab_ms']:>7.1f}ms{r['dab_p90_ms']:>7.1f}ms{r['dab_px']:>9d}{r['label_dab_ms']:>7.1f}ms"
              f"{r['comb_dab_ms']:>7.1f}ms {r['look_ms']:5.1f}/{r['label_look_ms']:5.1f}/{r['comb_look_ms']:5.1f}ms  {exact}")
    for k, r in res["presets"].items():
        print(f"{k:<10}" + "  ".join(f"{name} {z.screen(name)[0]}x{z.screen(name)[1]}: view {r[name + '_view_ms']:.1f} ms, "
                                     f"pan {r[name + '_pan_ms']:.2f} ms, window read back {r[name + '_window_ms']:.1f} ms"
                                     for name in SCREENS if name + "_view_ms" in r))
    return res


def compare(path: str) -> tuple[int, int]:
    """(identical, different) windows between ``path`` and this machine's GL."""
    theirs = np.load(path)
    names = sorted(theirs.files)
    presets = sorted({int(k.split("_")[1]) for k in names})
    n = theirs[f"gravel_{presets[0]}_near0"].shape[0]
    tile = theirs[f"gravel_{presets[0]}_tor"].shape[0]
    gpu = Gpu()
    print(f"this machine: {gpu.renderer}")
    mine = identity_windows(gpu, presets, n, tile)
    gpu.release()
    same = 0
    for k in names:
        ok = k in mine and np.array_equal(mine[k], theirs[k])
        same += ok
        print(f"{k:<20} {'identical' if ok else 'DIFFERENT'}")
    print(f"{same} of {len(names)} windows bit-identical")
    return same, len(names) - same


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    sub = ap.add_subparsers(dest="cmd", required=True)
    r = sub.add_parser("run", help="measure this machine; write device.json and coords.npz")
    r.add_argument("out_dir")
    r.add_argument("--quick", action="store_true")
    r.add_argument("--presets", nargs="+", type=int, choices=range(STRUCTURE_LEVELS), default=None)
    c = sub.add_parser("compare", help="the windows of coords.npz on this machine's GL")
    c.add_argument("coords")
    args = ap.parse_args(argv)
    if args.cmd == "run":
        presets = args.presets or [s for s in range(STRUCTURE_LEVELS) if not (args.quick and s == STRUCTURE_LEVELS - 1)]
        run(args.out_dir, args.quick, sorted(set(presets)))
        return 0
    return 1 if compare(args.coords)[1] else 0


if __name__ == "__main__":
    sys.exit(main())
