"""Texture by numbers: how well the synthesis follows painted labels.

    python -m bench.labels [--json OUT.json]

Exemplars of our own making from the bundled CC0 textures: two textures side
by side (128 px, label 0 on the left half, label 1 on the right), and two
target label maps painted on the canvas (a winding 60 px path through the
other label, and blobs of both labels), 384 x 384 at canvas (1000, -2000).
Measured at Variety and Balanced, one run each:

- label fidelity: the share of pixels whose exemplar label L_src(S(p)) is the
  painted one, over the window and in the band within 8 px of a painted
  boundary;
- transitions: the mean distance of each output 5x5 neighborhood to its
  nearest exemplar neighborhood, in the boundary band over the interior (1 =
  transitions as clean as the rest);
- time of the window.

With ``--walk`` each case also runs with labeled pixels walking TBN10's random
walk after the k-coherence candidates (engine/controls/labels.py LABEL_WALK;
off by default: the per-label seed candidate is tried either way, without
which no pixel could enter a label far from its neighbors' sources): TBN10's
claim is that the walk finds better transitions.

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

PAIRS = (("gravel", "brick"), ("grass", "gravel"), ("brick", "grass"))
SIZE = 384
ORIGIN = (1000, -2000)
BAND = 8


def exemplar(a: str, b: str) -> np.ndarray:
    from infinitex import ASSETS
    from infinitex.engine.exemplar import load_exemplar
    pa = load_exemplar(os.path.join(ASSETS, f"{a}.png")).pixels
    pb = load_exemplar(os.path.join(ASSETS, f"{b}.png")).pixels
    return np.ascontiguousarray(np.concatenate([pa[:, 32:96], pb[:, 32:96]], axis=1))


def targets() -> dict[str, np.ndarray]:
    from scipy import ndimage
    ys, xs = np.mgrid[0:SIZE, 0:SIZE]
    path = (np.abs(ys - SIZE / 2 - 70 * np.sin(xs / 55.0)) < 30).astype(np.int64)
    rng = np.random.default_rng(4)
    noise = ndimage.gaussian_filter(rng.standard_normal((SIZE, SIZE)), 24, mode="wrap")
    blobs = (noise > 0).astype(np.int64)
    return {"path": path, "blobs": blobs}


def energy_map(ex: np.ndarray, out: np.ndarray) -> np.ndarray:
    """Per output pixel (5x5 neighborhoods, borders excluded): the squared
    distance per value to the nearest exemplar neighborhood (10 PCA dims searched)."""
    from scipy.spatial import cKDTree

    def patches(img):
        h, w, c = img.shape
        v = np.lib.stride_tricks.sliding_window_view(img, (5, 5), axis=(0, 1))
        return v.reshape(h - 4, w - 4, -1).astype(np.float64)
    e = patches(np.pad(ex, ((2, 2), (2, 2), (0, 0)), mode="wrap")).reshape(-1, 25 * ex.shape[2])
    o = patches(out)
    flat = o.reshape(-1, o.shape[-1])
    mean = e.mean(axis=0)
    _, _, vt = np.linalg.svd(e - mean, full_matrices=False)
    basis = vt[:10].T
    _, j = cKDTree((e - mean) @ basis).query((flat - mean) @ basis, workers=-1)
    d = ((flat - e[j]) ** 2).mean(axis=1)
    return d.reshape(o.shape[:2])


def run_case(pair, name, target, structure, gpu) -> dict:
    from scipy import ndimage

    from infinitex.engine.analysis import analyze
    from infinitex.engine.controls import CanvasLabels, Controls, ExemplarLabels
    from infinitex.engine.exemplar import from_array
    from infinitex.engine.params import SynthParams, structure_params
    from infinitex.engine.pyramid import Rect
    from infinitex.engine.synth import Synthesizer
    px = exemplar(*pair)
    ex = from_array(px, toroidal=False)
    an = analyze(ex)
    ids = np.zeros((128, 128), np.uint8)
    ids[:, 64:] = 1
    controls = Controls(labels_exemplar=ExemplarLabels(ids),
                        labels_canvas=CanvasLabels.from_image((target + 1).astype(np.uint8), *ORIGIN))
    params = structure_params(SynthParams.default(an.L, seed=1), structure)
    with Synthesizer(an, params, gpu=gpu, controls=controls) as s:
        t = time.perf_counter()
        S = s.window(Rect.of(ORIGIN[0], ORIGIN[1], SIZE, SIZE))
        dt = time.perf_counter() - t
        out = s.colors(S)
    got = ids[S[..., 1], S[..., 0]]
    edge = ndimage.binary_dilation(target != np.roll(target, 1, 0)) | ndimage.binary_dilation(
        target != np.roll(target, 1, 1))
    band = ndimage.binary_dilation(edge, iterations=BAND)
    e = energy_map(px, out)
    inner = ~band[2:-2, 2:-2]
    return {"exemplar": "|".join(pair), "target": name, "structure": structure,
            "fidelity": float((got == target).mean()), "band_fidelity": float((got == target)[band].mean()),
            "transition_energy": float(e[band[2:-2, 2:-2]].mean() / max(1e-12, e[inner].mean())),
            "seconds": dt}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--json", metavar="OUT.json")
    ap.add_argument("--walk", action="store_true",
                    help="also run every case with the labeled pixels' random walk on (k-coherence candidates only "
                         "by default)")
    args = ap.parse_args(argv)
    from infinitex.engine.gpu import Gpu
    gpu = Gpu()
    rows = []
    print(f"{'exemplar':<14} {'target':<6} {'structure':>9} {'fidelity':>8} {'band':>6} {'trans.':>6} {'time':>7}")
    from infinitex.engine.controls import labels as labels_module
    from infinitex.engine.params import DEFAULT_WALK
    walks = (("walk", DEFAULT_WALK),) if args.walk else ()
    walks = (("k-coherence", labels_module.LABEL_WALK),) + walks
    for pair in PAIRS:
        for name, target in targets().items():
            for structure in (0, 2):
                for search, steps in walks:
                    labels_module.LABEL_WALK = steps  # the labeled pixels' walk (a #define of the passes)
                    r = dict(run_case(pair, name, target, structure, gpu), search=search)
                    rows.append(r)
                    print(f"{r['exemplar']:<14} {name:<6} {['Variety', '', 'Balanced'][structure]:>9} "
                          f"{100 * r['fidelity']:7.1f}% {100 * r['band_fidelity']:5.1f}% "
                          f"{r['transition_energy']:6.2f} {r['seconds']:6.2f}s {search}", flush=True)
    labels_module.LABEL_WALK = walks[0][1]
    if args.walk:
        for structure in (0, 2):
            pairs = [(a, b) for a, b in zip(rows[0::2], rows[1::2]) if a["structure"] == structure]
            better = sum(b["transition_energy"] < a["transition_energy"] for a, b in pairs)
            print(f"{['Variety', '', 'Balanced'][structure]}: transitions with the walk / k-coherence only, median "
                  f"{float(np.median([b['transition_energy'] for _, b in pairs])):.2f} / "
                  f"{float(np.median([a['transition_energy'] for a, _ in pairs])):.2f}, band fidelity "
                  f"{100 * float(np.median([b['band_fidelity'] for _, b in pairs])):.1f}% / "
                  f"{100 * float(np.median([a['band_fidelity'] for a, _ in pairs])):.1f}%; "
                  f"the walk better in {better} of {len(pairs)} cases")
        rows_walk = [r for r in rows if r["search"] == "k-coherence"]
    else:
        rows_walk = rows
    for structure in (0, 2):
        sel = [r for r in rows_walk if r["structure"] == structure]
        print(f"median {['Variety', '', 'Balanced'][structure]}: fidelity "
              f"{100 * float(np.median([r['fidelity'] for r in sel])):.1f}%, band "
              f"{100 * float(np.median([r['band_fidelity'] for r in sel])):.1f}%, transitions "
              f"{float(np.median([r['transition_energy'] for r in sel])):.2f}")
    gpu.release()
    if args.json:
        from infinitex.engine.safeio import atomic_write
        atomic_write(args.json, json.dumps({"cases": rows}, indent=1).encode())
    return 0


if __name__ == "__main__":
    sys.exit(main())
