"""Texture in motion: does it flow, stay coherent and sharp, loop, and how fast.

    python -m bench.flow [--json OUT.json] [--size 256] [--frames 48] [--strips DIR]

Exemplars: the shared pebbles, caustics and granite (and the bundled gravel
when those are missing). Fields, generated over the window (px per frame): a
vortex, a shear, a source-sink pair and a river along a curve (still around
it). Ours (engine/advect.py) against the baseline flow-map shaders use: two
phases of the static texture, each pushed along the local velocity for a
cycle of 2 periods and reset, crossfaded with triangle weights (the phases
half a cycle apart, the second one offset so that the two differ).

- moves with the flow: block matching (16 x 16 blocks, SSD, parabolic
  sub-pixel) between frames t and t + 3, against the field's own trajectory
  from the block's centre; median angle error (degrees) and median measured /
  expected speed, over blocks expected to move at least 1.5 px;
- coherent in time: the mean absolute difference between frame t + 1 and
  frame t moved along the field (bilinear), over the plain one between frames
  t and t + 10 (target <= 0.25); ``jump``: the largest frame step over the
  median step (target <= 2);
- sharp: neighborhood energy (bench.measures, every phase) of frames 0, 16,
  32 and the last over the static texture's (target <= 1.2); the standard
  deviation of frame 100 over frame 0's (target within 5%);
- loop: with --loop 32, frame 32 equals frame 0, and the step 31 -> 32 over the median step;
- speed (ours): 512 x 512 frames played in order (coordinates and 8-bit
  colors), frames per second over 48 frames, the static windows' syntheses
  included, at Variety and Balanced, corrected at the cuts (what exports
  write) and not (``--speed-only`` runs this part alone).

``--strips DIR`` writes, per exemplar and the vortex, every 4th frame of 32
as a strip for ours and for the baseline, under neutral names, with a key
file apart (for a blind judge). Prints a table, writes JSON.
"""
from __future__ import annotations

import argparse
import json
import os
import sys
import time

import numpy as np
from scipy import ndimage

HERE = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
if HERE not in sys.path:
    sys.path.insert(0, HERE)

ORIGIN = (4000, -3000)
SPEED = 1.5


def fields(size: int) -> dict[str, np.ndarray]:
    """name -> velocity (size, size, 2) float, px per frame, over the window."""
    ys, xs = np.mgrid[0:size, 0:size] + 0.5
    c = size / 2
    dx, dy = xs - c, ys - c
    r = np.hypot(dx, dy) + 1e-9
    out = {}
    s = SPEED * np.clip(r / (size / 4), 0, 1) * np.exp(-np.maximum(r - size / 4, 0) / size)
    out["vortex"] = np.stack([-dy / r * s, dx / r * s], -1)
    out["shear"] = np.stack([SPEED * np.clip(dy / c, -1, 1), np.zeros_like(dy)], -1)
    d = size / 4  # a source at (c - d, c), a sink at (c + d, c)
    v = np.zeros((size, size, 2))
    for sx, sign in ((c - d, 1.0), (c + d, -1.0)):
        ex, ey = xs - sx, ys - c
        r2 = ex * ex + ey * ey + 16.0
        v[..., 0] += sign * ex / r2
        v[..., 1] += sign * ey / r2
    v *= SPEED / np.percentile(np.hypot(v[..., 0], v[..., 1]), 95)
    norm = np.hypot(v[..., 0], v[..., 1])
    v *= (np.minimum(norm, SPEED) / np.maximum(norm, 1e-9))[..., None]
    out["source-sink"] = v
    curve = c + size / 6 * np.sin(xs / size * 2 * np.pi)  # a river along y = curve(x)
    slope = size / 6 * 2 * np.pi / size * np.cos(xs / size * 2 * np.pi)
    t = np.stack([np.ones_like(slope), slope], -1) / np.hypot(1, slope)[..., None]
    out["river"] = t * (SPEED * np.exp(-((ys - curve) / (size / 10)) ** 2))[..., None]
    return out


def velocity_map(v: np.ndarray):
    from infinitex.engine.controls.flow import Q, VelocityMap
    return VelocityMap(np.rint(v * Q).astype(np.int32), *ORIGIN)


def trajectory_end(v: np.ndarray, x: float, y: float, steps: int) -> tuple[float, float]:
    """Where content at (x, y) (window px) is ``steps`` frames later, following v forward."""
    for _ in range(steps):
        vx, vy = (ndimage.map_coordinates(v[..., i], [[y - 0.5], [x - 0.5]], order=1, mode="nearest")[0]
                  for i in (0, 1))
        x, y = x + vx, y + vy
    return x, y


def gray(img: np.ndarray) -> np.ndarray:
    return img.mean(-1) if img.ndim == 3 else img


def displacement(a: np.ndarray, b: np.ndarray, cx: int, cy: int, reach: int, half: int = 8):
    """The sub-pixel shift of a's block at (cx, cy) in b (SSD, parabolic), or None near the edges."""
    H, W = a.shape
    if cx - half - reach < 0 or cy - half - reach < 0 or cx + half + reach > W or cy + half + reach > H:
        return None
    blk = a[cy - half:cy + half, cx - half:cx + half]
    n = 2 * reach + 1
    ssd = np.empty((n, n))
    for j in range(n):
        for i in range(n):
            y0, x0 = cy - half + j - reach, cx - half + i - reach
            ssd[j, i] = ((b[y0:y0 + 2 * half, x0:x0 + 2 * half] - blk) ** 2).sum()
    j, i = np.unravel_index(np.argmin(ssd), ssd.shape)

    def refine(lo, mid, hi):
        d = lo - 2 * mid + hi
        return 0.0 if d <= 0 else 0.5 * (lo - hi) / d
    dx = i - reach + (refine(ssd[j, i - 1], ssd[j, i], ssd[j, i + 1]) if 0 < i < n - 1 else 0.0)
    dy = j - reach + (refine(ssd[j - 1, i], ssd[j, i], ssd[j + 1, i]) if 0 < j < n - 1 else 0.0)
    return dx, dy


def motion(frames: list[np.ndarray], v: np.ndarray, k: int = 3) -> tuple[float, float]:
    """(median angle error in degrees, median speed ratio) of blocks expected to move >= 1.5 px."""
    size = v.shape[0]
    angles, ratios = [], []
    for t in range(0, len(frames) - k, 6):
        a, b = gray(frames[t]), gray(frames[t + k])
        for cy in range(24, size - 24, 20):
            for cx in range(24, size - 24, 20):
                ex, ey = trajectory_end(v, cx, cy, k)
                ex, ey = ex - cx, ey - cy
                if np.hypot(ex, ey) < 1.5:
                    continue
                d = displacement(a, b, cx, cy, int(np.ceil(SPEED * k)) + 2)
                if d is None:
                    continue
                ang = np.degrees(np.arctan2(d[1], d[0]) - np.arctan2(ey, ex))
                angles.append(abs((ang + 180) % 360 - 180))
                ratios.append(np.hypot(*d) / np.hypot(ex, ey))
    return float(np.median(angles)), float(np.median(ratios))


def advected(img: np.ndarray, v: np.ndarray) -> np.ndarray:
    """img moved one frame along v (backward lookup, bilinear)."""
    ys, xs = np.mgrid[0:v.shape[0], 0:v.shape[1]].astype(np.float64)
    pos = [ys - v[..., 1], xs - v[..., 0]]
    ch = img if img.ndim == 3 else img[..., None]
    return np.stack([ndimage.map_coordinates(ch[..., c], pos, order=1, mode="nearest") for c in range(ch.shape[2])], -1)


def coherence(frames: list[np.ndarray], v: np.ndarray, border: int = 12) -> tuple[float, float, list[float]]:
    """(compensated step / plain 10-frame difference, largest step / median step, the steps)."""
    inner = (slice(border, -border), slice(border, -border))
    steps = [float(np.abs(frames[t + 1] - advected(frames[t], v))[inner].mean()) for t in range(len(frames) - 1)]
    plain = [float(np.abs(frames[t + 10] - frames[t])[inner].mean()) for t in range(0, len(frames) - 10, 4)]
    med = float(np.median(steps))
    return med / float(np.median(plain)), max(steps) / med, steps


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--json", default=None)
    ap.add_argument("--size", type=int, default=256)
    ap.add_argument("--frames", type=int, default=48)
    ap.add_argument("--strips", default=None, metavar="DIR")
    ap.add_argument("--no-speed", action="store_true")
    ap.add_argument("--speed-only", action="store_true", help="only the speed (adds its figures to --json's file)")
    ap.add_argument("--speed-size", nargs=2, type=int, default=[512, 512], metavar=("W", "H"),
                    help="the frames' size for the speed (default 512 512; a lent GPU: 1920 1080)")
    ap.add_argument("--period", type=int, default=0, help="the renewal period (default: what the field suggests, "
                    "Flow.suggested_period)")
    ap.add_argument("--no-correction", action="store_true", help="ours without the finest level's correction")
    ap.add_argument("--exemplars", default="pebbles,caustics,granite")
    args = ap.parse_args()
    from bench.measures import neighborhood_energy
    from infinitex import ASSETS
    from infinitex.engine.advect import FlowFrames, SynthSource
    from infinitex.engine.analysis import analyze
    from infinitex.engine.controls.flow import Flow
    from infinitex.engine.exemplar import load_exemplar
    from infinitex.engine.gpu import Gpu
    from infinitex.engine.imagefile import to_u8, write_png
    from infinitex.engine.params import STRUCTURE_NAMES, SynthParams, structure_params
    from infinitex.engine.pyramid import Rect
    from infinitex.engine.synth import Synthesizer

    shared = os.path.join(HERE, "..", "shared", "exemplars")
    names = [n for n in args.exemplars.split(",") if os.path.exists(os.path.join(shared, n + ".png"))]
    paths = {n: os.path.join(shared, n + ".png") for n in names} or {"gravel": os.path.join(ASSETS, "gravel.png")}
    size, F = args.size, args.frames
    rect = Rect.of(*ORIGIN, size, size)
    flows = fields(size)
    gpu = Gpu()
    period = args.period
    results: dict = {"size": size, "frames": F, "period": period or "suggested", "corrected": not args.no_correction, "speed_px_per_frame": SPEED, "runs": {},
                     "renderer": gpu.renderer}
    rng = np.random.default_rng(7)
    key = {}
    if args.speed_only:
        paths_q = {}
        if args.json and os.path.exists(args.json):
            with open(args.json) as f:
                results = json.load(f)
    else:
        paths_q = paths
    for ename, path in paths_q.items():
        ex = load_exemplar(path)
        an = analyze(ex)
        synth = Synthesizer(an, gpu=gpu)
        # The static texture around the window (for the baseline and the references).
        pad = int(SPEED * 2 * 32) + 4  # the longest suggested life: 2 periods of 32
        big = Rect(rect.x0 - pad, rect.y0 - pad, rect.x1 + pad, rect.y1 + pad)
        static_big = synth.colors(synth.window(big, remainder=True)).astype(np.float64)
        static = static_big[pad:-pad, pad:-pad]
        e_static = neighborhood_energy(ex.pixels, static)[0]
        for fname, v in flows.items():
            flow = Flow(map=velocity_map(v))
            flow = Flow(map=flow.map, period=period or flow.suggested_period())
            ff = FlowFrames(SynthSource(synth), flow, seed=1, correct=not args.no_correction)
            ours = [synth.colors(ff.frame(t, rect)).astype(np.float64) for t in range(F)]
            base = crossfade(static_big, pad, v, F, 2 * flow.period)
            row = {"period": flow.period}
            for who, frames in (("ours", ours), ("crossfade", base)):
                ang, ratio = motion(frames, v)
                coh, jump, _ = coherence(frames, v)
                energies = [neighborhood_energy(ex.pixels, frames[t])[0] for t in (0, 16, 32, F - 1) if t < F]
                row[who] = dict(angle_error_deg=ang, speed_ratio=ratio, coherence=coh, jump=jump,
                                energy_ratio=max(energies) / e_static,
                                contrast_ratio=float(frames[F // 2].std() / frames[0].std()))
            f100 = synth.colors(ff.frame(100, rect)).astype(np.float64)
            row["ours"]["std_100_over_0"] = float(f100.std() / ours[0].std())
            results["runs"][f"{ename}/{fname}"] = row
            print(f"{ename:9s} {fname:12s} " + "  ".join(
                f"{who}: angle {r['angle_error_deg']:5.1f} speed {r['speed_ratio']:4.2f} coh {r['coherence']:4.2f} "
                f"jump {r['jump']:4.2f} energy {r['energy_ratio']:4.2f}" for who, r in row.items() if who != "period")
                + f"  (period {flow.period})", flush=True)
            if args.strips and fname == "vortex":
                os.makedirs(args.strips, exist_ok=True)
                pair = [("ours", ours), ("crossfade", base)]
                order = rng.permutation(2)
                for label, i in zip("AB", order):
                    who, frames = pair[i]
                    strip = np.concatenate([frames[t][64:192, 64:192] for t in range(0, 32, 4)], 1)
                    write_png(os.path.join(args.strips, f"{ename}_{label}.png"), to_u8(strip.astype(np.float32)))
                    key[f"{ename}_{label}"] = who
        # The loop: frame 32 is frame 0; its last step against the median step.
        vortex = Flow(map=velocity_map(flows["vortex"]))
        lf = FlowFrames(SynthSource(synth), Flow(map=vortex.map, period=period or vortex.suggested_period(32), loop=32),
                        seed=1, correct=not args.no_correction)
        loop = [synth.colors(lf.frame(t, rect)).astype(np.float64) for t in range(33)]
        _, _, steps = coherence(loop, flows["vortex"])
        results["runs"][f"{ename}/loop"] = dict(exact=bool(np.array_equal(loop[32], loop[0])),
                                                last_step_over_median=steps[31] / float(np.median(steps)))
        print(f"{ename:9s} loop 32: exact {np.array_equal(loop[32], loop[0])}, "
              f"last step / median {steps[31] / np.median(steps):.2f}", flush=True)
        synth.release()
    if args.strips and key:
        with open(os.path.join(args.strips, "..", "flow_strips_key.json"), "w") as f:
            json.dump(key, f, indent=1)
    if not args.no_speed:
        results["speed"] = speed(gpu, paths, structure_params, SynthParams, STRUCTURE_NAMES, *args.speed_size)
    gpu.release()
    if args.json:
        with open(args.json, "w") as f:
            json.dump(results, f, indent=1)
    return 0


def crossfade(static_big: np.ndarray, pad: int, v: np.ndarray, frames: int, cycle: int) -> list[np.ndarray]:
    """The two-phase flow-map baseline over the window: layer i shows the static
    texture pushed back by v * phase_i * cycle, reset each cycle, half a cycle
    apart, the second offset by a quarter of the pad; triangle weights."""
    size = v.shape[0]
    ys, xs = np.mgrid[0:size, 0:size].astype(np.float64) + pad
    ch = static_big.shape[2]
    out = []
    for t in range(frames):
        ph0 = (t / cycle) % 1.0
        ph1 = (ph0 + 0.5) % 1.0
        w0 = 1.0 - abs(1.0 - 2.0 * ph0)
        layers = []
        for ph, off in ((ph0, 0.0), (ph1, pad / 4)):
            pos = [ys - v[..., 1] * ph * cycle + off, xs - v[..., 0] * ph * cycle + off]
            layers.append(np.stack([ndimage.map_coordinates(static_big[..., c], pos, order=1, mode="wrap")
                                    for c in range(ch)], -1))
        out.append(w0 * layers[0] + (1.0 - w0) * layers[1])
    return out


def speed(gpu, paths, structure_params, SynthParams, names, w: int = 512, h: int = 512) -> dict:
    from infinitex.engine.advect import FlowFrames, SynthSource
    from infinitex.engine.analysis import analyze
    from infinitex.engine.controls.flow import Flow, Q, VelocityMap
    from infinitex.engine.exemplar import load_exemplar
    from infinitex.engine.pyramid import Rect
    from infinitex.engine.synth import Synthesizer
    from infinitex.export.window import colors_u8
    path = next(iter(paths.values()))
    an = analyze(load_exemplar(path))
    v = fields(max(w, h))["vortex"][:h, :w]
    rect = Rect.of(*ORIGIN, w, h)
    out = {}
    for preset in (0, 2):
        params = structure_params(SynthParams.default(an.L), preset)
        synth = Synthesizer(an, params, gpu=gpu)
        flow = Flow(map=VelocityMap(np.rint(v * Q).astype(np.int32), *ORIGIN))
        flow = Flow(map=flow.map, period=flow.suggested_period())
        top = an.levels[an.L].stack
        u8 = np.rint(np.clip(top, 0, 1) * 255).astype(np.uint8)
        for mode, correct in (("corrected", True), ("uncorrected", False), ("draft", False)):
            ff = FlowFrames(SynthSource(synth), flow, seed=1, correct=correct)
            times = []
            for t in range(48):
                t0 = time.perf_counter()
                if mode == "draft":  # what the editor plays: uncorrected, colored in GL
                    ff.draft_rgb(t, rect, u8)
                else:
                    colors_u8([u8], ff.frame(t, rect), 0, an.toroidal)
                times.append(time.perf_counter() - t0)
            ff.release()
            key = f"{names[preset]} {mode}"
            out[key] = dict(fps=48 / sum(times), worst_ms=max(times) * 1000, median_ms=float(np.median(times)) * 1000)
            print(f"speed {key:22s} {w}x{h}: {out[key]['fps']:.1f} fps (median {out[key]['median_ms']:.0f} ms, "
                  f"worst {out[key]['worst_ms']:.0f} ms)", flush=True)
        synth.release()
    return out


if __name__ == "__main__":
    sys.exit(main())
