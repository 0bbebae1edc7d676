"""How far a stroke's edit reaches: which pixels of the view a 100 px stroke
changes, and how far from it, per level.

    python -m bench.reach [--json OUT.json]

The labelled pair of bench.labels (grass | gravel, label 0 on the left half
of the exemplar, 1 on the right); a 1024 x 768 view around the origin,
synthesized before and after a 100 px horizontal stroke (51 dabs, brush
radius 16 px) of label 1, of calm (0) and of rough (2) randomness, at Variety
and at Balanced. Per case: the share of the view's pixels whose coordinates
changed, the largest and the 99th-percentile distance of a changed pixel
from the stroke's edge, and per level the same in that level's pixels and in
finest pixels. What bounds the reach: a level is steered only where the
stroke covers its features (randomness: a level pixel's whole footprint,
reduce_toward_neutral; labels: half its footprint, and at levels of 4 px and
more its 3 x 3 neighbours' too), and from a steered level a change carries
at most that level's correction margin (Pyramid.margins; at Balanced the
fidelity stage's iterations make it 51 level pixels on the coarser levels)
on each level down. Prints a table, writes JSON.
"""
from __future__ import annotations

import argparse
import json
import os
import sys

import numpy as np

HERE = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
if HERE not in sys.path:
    sys.path.insert(0, HERE)

VIEW = (-512, -384, 1024, 768)
RADIUS = 16.0
STROKE = [(-50.0 + 2 * i, 0.0) for i in range(51)]


def stroke_controls(kind: str, ids: np.ndarray):
    from infinitex.engine.controls import CanvasField, CanvasLabels, Controls, ExemplarLabels
    lab, field = CanvasLabels(), CanvasField()
    for cx, cy in STROKE:
        if kind == "labels":
            lab, _ = lab.painted(cx, cy, RADIUS, 2)  # label 1
        else:
            field, _ = field.painted(cx, cy, RADIUS, 0 if kind == "calm" else 65535, 0.8, 0.5)
    return Controls(labels_exemplar=ExemplarLabels(ids), labels_canvas=lab,
                    randomness_canvas=None if kind == "labels" else field)


def run_case(kind: str, structure: int, an, ids, gpu) -> dict:
    from scipy import ndimage

    from infinitex.engine.controls import CanvasLabels, Controls, ExemplarLabels
    from infinitex.engine.params import SynthParams, structure_params
    from infinitex.engine.pyramid import Rect
    from infinitex.engine.synth import Synthesizer
    params = structure_params(SynthParams.default(an.L, seed=1), structure)
    base = Controls(labels_exemplar=ExemplarLabels(ids), labels_canvas=CanvasLabels())
    after = stroke_controls(kind, ids)
    W = Rect.of(*VIEW)
    levels = []
    for l in range(an.L + 1):
        k = an.L - l
        Wl = W.coarser(k)
        with Synthesizer(an, params, gpu=gpu, controls=base) as s:
            b = s.window(Wl, level=l)
        with Synthesizer(an, params, gpu=gpu, controls=after) as s:
            a = s.window(Wl, level=l)
        changed = np.any(a[..., :2] != b[..., :2], axis=-1)
        on = np.zeros(changed.shape, bool)
        for cx, cy in STROKE:
            on[(int(cy) >> k) - Wl.y0, (int(cx) >> k) - Wl.x0] = True
        d = ndimage.distance_transform_edt(~on) - RADIUS / (1 << k)
        reach = float(d[changed].max()) if changed.any() else 0.0
        levels.append({"level": l, "pixel_px": 1 << k, "changed": float(changed.mean()),
                       "reach_level_px": round(max(0.0, reach), 1), "reach_px": round(max(0.0, reach) * (1 << k)),
                       "p99_px": round(max(0.0, float(np.percentile(d[changed], 99))) * (1 << k)) if changed.any() else 0})
    fin = levels[-1]
    return {"kind": kind, "structure": structure, "changed": fin["changed"], "reach_px": fin["reach_px"],
            "p99_px": fin["p99_px"], "levels": levels}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--json", metavar="OUT.json")
    args = ap.parse_args(argv)
    from bench.labels import exemplar
    from infinitex.engine.analysis import analyze
    from infinitex.engine.exemplar import from_array
    from infinitex.engine.gpu import Gpu
    from infinitex.engine.params import DEFAULT_STRUCTURE
    gpu = Gpu()
    an = analyze(from_array(exemplar("grass", "gravel"), toroidal=False))
    ids = np.zeros((128, 128), np.uint8)
    ids[:, 64:] = 1
    rows = []
    print(f"{'stroke':8} {'structure':>9} {'changed':>8} {'reach':>7} {'p99':>6}   per level (finest px reach, coarse to fine)")
    for kind in ("labels", "calm", "rough"):
        for structure in (0, DEFAULT_STRUCTURE):
            r = run_case(kind, structure, an, ids, gpu)
            rows.append(r)
            per = " ".join(f"{lv['reach_px']}" if lv["changed"] else "-" for lv in r["levels"])
            print(f"{kind:8} {('Variety' if structure == 0 else 'Balanced'):>9} {100 * r['changed']:7.1f}% "
                  f"{r['reach_px']:6d}px {r['p99_px']:5d}px   {per}", flush=True)
    if args.json:
        with open(args.json, "w") as fh:
            json.dump({"view": VIEW, "radius": RADIUS, "stroke_px": 100, "cases": rows}, fh, indent=1)
    return 0


if __name__ == "__main__":
    sys.exit(main())
