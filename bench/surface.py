"""Texture on a model (synthesis in its atlas, LH06 6): seams, anisometry,
speed and the 3D view's frame rate.

    python -m bench.surface [--json OUT.json] [--quick]

Models (generated, CC0: engine/surface/shapes.py): a cube whose six faces are
separate charts (turned and mirrored in UV), a capped cylinder (one seam where
u wraps), a vase unwrapped by xatlas (~12k triangles, 20+ charts). Exemplars:
the bundled gravel and brick and the bench's own cells and weave. Balanced,
seed 3, one run each:

- seam error (engine/surface/seams.py): the colour difference across every UV
  seam (the texels half a texel inside each side of points one texel apart on
  the surface) over the difference between adjacent texels inside charts;
  ours against a naive per-chart synthesis (the same passes without the
  indirection maps, ``--no-seams``), measured in the same run (target: at most 1.2);
- anisometry error ``||grad S - J||`` inside charts (median, exemplar px per
  texel), as bench/direction.py measures it;
- the time to synthesize a 2048^2 atlas of a 50k-triangle vase (the atlas
  build and the synthesis, Balanced and Variety);
- the model view's frame rate while orbiting: the 50k vase with the 2048^2
  texture drawn at 1280 x 800 (headless EGL, 60 frames, each finished).

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


def anisometry_inside(c: np.ndarray, J: np.ndarray, own: np.ndarray, m: int) -> float:
    """Median ||grad S - J|| over texels whose right and lower neighbors are in their chart."""
    F = c[..., :2].astype(np.int64) * 256 + c[..., 2:]
    period = 256 * m

    def wrapped(d):
        return ((d + period // 2) % period - period // 2) / 256.0
    dx = wrapped(F[:-1, 1:] - F[:-1, :-1])
    dy = wrapped(F[1:, :-1] - F[:-1, :-1])
    j = J[:-1, :-1].astype(np.float64) / 4096.0
    ex = dx - np.stack([j[..., 0], j[..., 2]], axis=-1)
    ey = dy - np.stack([j[..., 1], j[..., 3]], axis=-1)
    err = np.sqrt((ex ** 2).sum(-1) + (ey ** 2).sum(-1))
    inside = (own[:-1, :-1] >= 0) & (own[:-1, :-1] == own[:-1, 1:]) & (own[:-1, :-1] == own[1:, :-1])
    return float(np.median(err[inside]))


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--json", default=None)
    ap.add_argument("--quick", action="store_true", help="small atlases, two exemplars (a smoke run)")
    args = ap.parse_args()
    from infinitex import ASSETS
    from infinitex.app.render.model_view import ModelView, OrbitCamera
    from infinitex.engine.analysis import analyze
    from infinitex.engine.exemplar import load_exemplar
    from infinitex.engine.gpu import Gpu
    from infinitex.engine.imagefile import to_u8
    from infinitex.engine.params import SynthParams, structure_params
    from infinitex.engine.surface import AtlasDomain
    from infinitex.engine.surface.bake import atlas_coords, atlas_image
    from infinitex.engine.surface.seams import seam_error
    from infinitex.engine.surface.shapes import cube, cylinder, vase
    from infinitex.engine.synth import Synthesizer
    from infinitex.export.surface import plan

    exemplars = {"gravel": os.path.join(ASSETS, "gravel.png"), "brick": os.path.join(ASSETS, "brick.png"),
                 "cells": os.path.join(HERE, "bench", "exemplars", "cells.png"),
                 "weave": os.path.join(HERE, "bench", "exemplars", "weave.png")}
    if args.quick:
        exemplars = {k: exemplars[k] for k in ("gravel", "brick")}
    models = {"cube": (cube(), 512), "cylinder": (cylinder(), 512), "vase": (vase(), 1024)}
    if args.quick:
        models = {k: (m, 256) for k, (m, _) in models.items()}
    gpu = Gpu()
    rows = []
    try:
        for ename, path in exemplars.items():
            an = analyze(load_exemplar(path))
            params = structure_params(SynthParams.default(an.L, seed=3), 2)
            with Synthesizer(an, params, gpu=gpu) as synth:
                for mname, (model, size) in models.items():
                    pl = plan(model, size, an.size)  # about one exemplar px per texel
                    row = dict(exemplar=ename, model=mname, size=size, triangles=len(model.faces))
                    for seams in (True, False):
                        atlas = AtlasDomain(model, size, pl.sigma, seams=seams)
                        t = time.perf_counter()
                        c = atlas_coords(synth, atlas)
                        dt = time.perf_counter() - t
                        img = atlas_image(an.levels[an.L].stack, c, atlas, an.toroidal)
                        se = seam_error(img, atlas)
                        key = "ours" if seams else "naive"
                        row[f"{key}_seam"] = round(se.ratio, 3)
                        row[f"{key}_seconds"] = round(dt, 2)
                        if seams:
                            row["charts"] = atlas.charts
                            row["samples"] = se.samples
                            row["anisometry"] = round(anisometry_inside(
                                c, atlas.jacobians(0, 0, 0, size, size), atlas.owner(0), an.size), 3)
                    rows.append(row)
                    print(f"{ename:7s} {mname:8s} {size:5d}  seam ours {row['ours_seam']:.2f}  naive "
                          f"{row['naive_seam']:.2f}  anisometry {row['anisometry']:.3f}  "
                          f"{row['ours_seconds']:.1f} s", flush=True)

        # Speed: a 2048^2 atlas of a 50k-triangle vase.
        big = vase(segments=200, rings=125)
        n = 256 if args.quick else 2048
        an = analyze(load_exemplar(exemplars["brick"]))
        pl = plan(big, n, an.size)
        t = time.perf_counter()
        atlas = AtlasDomain(big, n, pl.sigma)
        for k in range(an.L + 1):
            atlas.links(k, 0, 0, 1, 1)
        build = time.perf_counter() - t
        speed = dict(triangles=len(big.faces), charts=atlas.charts, size=n, atlas_build_s=round(build, 2))
        for structure, label in ((0, "variety"), (2, "balanced")):
            params = structure_params(SynthParams.default(an.L, seed=3), structure)
            with Synthesizer(an, params, gpu=gpu) as synth:
                t = time.perf_counter()
                c = atlas_coords(synth, atlas)
                speed[f"{label}_s"] = round(time.perf_counter() - t, 2)
        img = to_u8(atlas_image(an.levels[an.L].stack, c, atlas, an.toroidal))
        print(f"vase {len(big.faces):,} triangles, {atlas.charts} charts, {n}^2: atlas {build:.1f} s, "
              f"Variety {speed['variety_s']:.1f} s, Balanced {speed['balanced_s']:.1f} s", flush=True)

        # The model view's frame rate while orbiting.
        gpu.activate()
        view = ModelView(gpu.ctx, big.positions, big.faces, big.uvs)
        view.set_texture(img)
        cam = OrbitCamera.framing(big.positions)
        w, h = 1280, 800
        fbo = gpu.ctx.framebuffer(color_attachments=[gpu.ctx.renderbuffer((w, h))],
                                  depth_attachment=gpu.ctx.depth_renderbuffer((w, h)))
        fbo.use()
        times = []
        for i in range(60):
            t = time.perf_counter()
            fbo.clear(0.1, 0.1, 0.1, 1.0, depth=1.0)
            view.draw(cam.orbit(6.0 * i, 0.0), (0, 0, w, h))
            gpu.ctx.finish()
            times.append(time.perf_counter() - t)
        fps = 1.0 / float(np.median(times[5:]))
        speed["view_fps_1280x800"] = round(fps, 1)
        print(f"model view: {fps:.1f} fps at 1280x800 ({gpu.renderer})")
        view.release()
        fbo.release()
    finally:
        gpu.release()
    ours = [r["ours_seam"] for r in rows]
    naive = [r["naive_seam"] for r in rows]
    print(f"\nseam error, median over {len(rows)} cases: ours {np.median(ours):.2f} (max {max(ours):.2f}), "
          f"naive per-chart {np.median(naive):.2f} (max {max(naive):.2f})")
    if args.json:
        with open(args.json, "w") as f:
            json.dump(dict(cases=rows, speed=speed), f, indent=1)
    return 0


if __name__ == "__main__":
    sys.exit(main())
