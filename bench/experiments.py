"""What each synthesis setting does to quality and variety, on every bench exemplar.

    python -m bench.experiments [--size 256] [--variants base,walk6,...] [--json OUT.json]

For every exemplar of ``../shared/exemplars`` and ``bench/exemplars`` and every
variant below (a change from the defaults), a SIZE^2 window at (10007, -20011)
is measured (bench/measures.py): neighborhood energy, Portilla-Simoncelli
distance, repetition, the mean size of verbatim copies, the fraction of seams
sheared by one pixel (the zipper lines of 800% zoom) and the usage peak (the
most used 16 px block of the exemplar over the mean: what makes gravel's
zoomed-out streaks) - lower is better for all - and the warm window time. Prints the medians per variant, writes
them and every value to JSON (default bench/results/quality-experiments.json).
Quality for the G'MIC peer comes from ``bench/quality.py``.
"""
from __future__ import annotations

import argparse
import glob
import json
import os
import sys
import time
from dataclasses import replace

import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, ROOT)

from bench.measures import all_measures  # noqa: E402
from infinitex.engine.analysis import AnalysisSettings, analyze  # noqa: E402
from infinitex.engine.exemplar import load_exemplar  # noqa: E402
from infinitex.engine.params import SynthParams  # noqa: E402
from infinitex.engine.pyramid import Rect  # noqa: E402
from infinitex.engine.synth import Synthesizer  # noqa: E402

ORIGIN = (10007, -20011)
# name: (what it changes, SynthParams changes, analysis changes, fine-level jitter (value, levels) or None)
VARIANTS = {
    "base": ("defaults (appearance, k 2, 2 passes, kappa 0.5, jitter 0.6)", {}, {}, None),
    "walk6": ("TBN10 random walk, 6 steps, after the k-coherence candidates", {"walk": 6}, {}, None),
    "k0": ("no similarity sets (k 0): coherent candidates + random walk, 6 steps", {}, {"k": 0}, None),
    "fd0.5": ("LH06 feature-distance channel, weight 0.5", {}, {"feature_weight": 0.5}, None),
    "fd1": ("LH06 feature-distance channel, weight 1", {}, {"feature_weight": 1.0}, None),
    "fd2": ("LH06 feature-distance channel, weight 2", {}, {"feature_weight": 2.0}, None),
    "k0-walk10": ("no similarity sets (k 0): coherent candidates + random walk, 10 steps", {"walk": 10}, {"k": 0}, None),
    "passes3": ("3 correction passes", {"passes": 3}, {}, None),
    "passes4": ("4 correction passes", {"passes": 4}, {}, None),
    "kappa0": ("coherence kappa 0", {"kappa": 0.0}, {}, None),
    "kappa1.5": ("coherence kappa 1.5", {"kappa": 1.5}, {}, None),
    "k4": ("k = 4 similar spots", {}, {"k": 4}, None),
    "color": ("LH05 5x5 color neighborhoods", {}, {"model": "color"}, None),
    "color-passes3": ("color neighborhoods, 3 passes", {"passes": 3}, {"model": "color"}, None),
    "passes3-kappa0": ("3 correction passes, kappa 0", {"passes": 3, "kappa": 0.0}, {}, None),
    "passes3-kappa0.25": ("3 correction passes, kappa 0.25", {"passes": 3, "kappa": 0.25}, {}, None),
    "subgrid3": ("3 x 3 subpasses", {"subgrid": 3}, {}, None),
    "coarse3": ("3 passes on all but the 2 finest levels, 2 on those",
                {"level_passes": lambda L: tuple(3 if l < L - 1 else 2 for l in range(L + 1))}, {}, None),
    "coarse4": ("4 passes on all but the 2 finest levels, 2 on those",
                {"level_passes": lambda L: tuple(4 if l < L - 1 else 2 for l in range(L + 1))}, {}, None),
    "coarse6": ("6 passes on all but the 2 finest levels, 2 on those",
                {"level_passes": lambda L: tuple(6 if l < L - 1 else 2 for l in range(L + 1))}, {}, None),
    "coarse4-fine3": ("4 passes on all but the 2 finest levels, 3 on those",
                      {"level_passes": lambda L: tuple(4 if l < L - 1 else 3 for l in range(L + 1))}, {}, None),
    "fine3": ("2 passes, 3 on the 2 finest levels",
              {"level_passes": lambda L: tuple(2 if l < L - 1 else 3 for l in range(L + 1))}, {}, None),
    "fine0.2": ("jitter 0.2 on the 2 finest levels", {}, {}, (0.2, 2)),
    "fine0-5": ("no jitter on the 5 finest levels", {}, {}, (0.0, 5)),
}
MEASURES = ("energy", "ps", "repetition", "copied", "verbatim_mean_px", "sheared", "usage_peak", "seconds")


def exemplar_paths() -> list[str]:
    folders = [os.path.join(os.path.dirname(ROOT), "shared", "exemplars"), os.path.join(ROOT, "bench", "exemplars")]
    return [p for f in folders for p in sorted(glob.glob(os.path.join(f, "*.png")))]


def params_for(L: int, changes: dict, fine) -> SynthParams:
    """The variant's parameters for an exemplar with finest level L (a change may be a function of L)."""
    p = replace(SynthParams.default(L), **{k: v(L) if callable(v) else v for k, v in changes.items()})
    if fine is not None:
        value, levels = fine
        p = replace(p, jitter=tuple(value if l > L - levels else r for l, r in enumerate(p.jitter)))
    return p


def main(argv: list[str]) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--size", type=int, default=256)
    ap.add_argument("--variants", default=",".join(VARIANTS))
    ap.add_argument("--json", default=os.path.join(ROOT, "bench", "results", "quality-experiments.json"))
    a = ap.parse_args(argv)
    names = [v for v in a.variants.split(",") if v]
    unknown = [v for v in names if v not in VARIANTS]
    if unknown:
        sys.stderr.write(f"unknown variants {unknown}; choose among {', '.join(VARIANTS)}\n")
        return 2
    values = {v: {m: [] for m in MEASURES} for v in names}
    paths = exemplar_paths()
    for path in paths:
        ex = load_exemplar(path)
        analyses = {}
        line = f"{os.path.splitext(os.path.basename(path))[0]:<12}"
        for v in names:
            _, changes, settings, fine = VARIANTS[v]
            key = tuple(sorted(settings.items()))
            if key not in analyses:
                analyses[key] = analyze(ex, AnalysisSettings(**settings))
            an = analyses[key]
            with Synthesizer(an, params_for(an.L, changes, fine)) as s:
                s.window(Rect.of(0, 0, 32, 32))  # shaders compiled
                t0 = time.perf_counter()
                coords = s.window(Rect.of(ORIGIN[0], ORIGIN[1], a.size, a.size))
                dt = time.perf_counter() - t0
                out = s.colors(coords)
            row = dict(all_measures(ex.pixels, out, coords, an.size, an.toroidal, ps=True), seconds=dt)
            for m in MEASURES:
                values[v][m].append(float(row[m]))
            line += f"  {v} E {row['energy']:.5f} PS {row['ps']:.3f}"
        print(line, flush=True)
    medians = {v: {m: float(np.median(values[v][m])) for m in MEASURES} for v in names}
    print(f"\nmedians over {len(paths)} exemplars, {a.size}^2 windows (lower is better)")
    print(f"{'variant':<15}{'energy':>9}{'PS':>8}{'repeat':>8}{'copied':>8}{'verbatim':>10}{'sheared':>9}{'usage':>7}"
          f"{'ms':>7}")
    for v in names:
        d = medians[v]
        print(f"{v:<15}{d['energy']:9.5f}{d['ps']:8.3f}{d['repetition']:8.3f}{d['copied']:8.2f}{d['verbatim_mean_px']:10.1f}"
              f"{d['sheared']:9.3f}{d['usage_peak']:7.2f}{d['seconds'] * 1000:7.0f}")
    os.makedirs(os.path.dirname(a.json), exist_ok=True)
    with open(a.json, "w") as f:
        json.dump({"size": a.size, "origin": ORIGIN, "exemplars": [os.path.basename(p) for p in paths],
                   "variants": {v: VARIANTS[v][0] for v in names}, "medians": medians, "values": values}, f, indent=1)
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
