"""Gravel's zoomed-out streaks, with and without the crevice avoided (issue 14).

    python -m bench.avoid [--size 1024] [--json OUT.json] [--figure OUT.png]

The shared gravel exemplar has one dark diagonal crevice (32 x 32 px centered
on (66, 22)) that the synthesis places about once per exemplar area, always in
the same orientation: zoomed out, a pattern of diagonal streaks. For a
SIZE^2 window at (10007, -20011), plain and with the crevice painted as an
avoided region (controls.ExemplarMask), it reports the share of the output
copied from the crevice, the share of the darkest 2% (luminance blurred by
6 px, what reads as a streak at 25%) that comes from it, the busiest 16 px
exemplar block over the mean (usage peak), neighborhood energy, the
Portilla-Simoncelli distance and the window time; and writes a figure of both
at 25% (box-filtered), side by side.
"""
from __future__ import annotations

import argparse
import json
import os
import sys
import time

import numpy as np
from scipy import ndimage

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, ROOT)

from bench.measures import neighborhood_energy, ps_distance, usage_peak  # noqa: E402
from infinitex.engine.analysis import AnalysisSettings, analyze  # noqa: E402
from infinitex.engine.controls import Controls, ExemplarMask  # noqa: E402
from infinitex.engine.exemplar import load_exemplar  # noqa: E402
from infinitex.engine.imagefile import to_u8, write_png  # noqa: E402
from infinitex.engine.params import SynthParams  # noqa: E402
from infinitex.engine.pyramid import Rect  # noqa: E402
from infinitex.engine.synth import Synthesizer  # noqa: E402

GRAVEL = os.path.join(os.path.dirname(ROOT), "shared", "exemplars", "gravel.png")
CREVICE = (50, 6, 32, 32)  # x, y, w, h in exemplar pixels: centered on (66, 22)
ORIGIN = (10007, -20011)


def main(argv: list[str]) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--size", type=int, default=1024)
    ap.add_argument("--json", default=os.path.join(ROOT, "bench", "results", "avoid-gravel.json"))
    ap.add_argument("--figure", default=os.path.join(ROOT, "docs", "avoid-gravel.png"))
    a = ap.parse_args(argv)
    ex = load_exemplar(GRAVEL)
    an = analyze(ex, AnalysisSettings())
    m = an.size
    x, y, w, h = CREVICE
    v = np.zeros((m, m), np.uint8)
    v[y:y + h, x:x + w] = 1
    mask = ExemplarMask(v)
    rows, shots = {}, []
    for name, controls in (("plain", Controls()), ("crevice avoided", Controls(avoid=mask))):
        with Synthesizer(an, SynthParams.default(an.L), controls=controls) as s:
            s.window(Rect.of(0, 0, 32, 32))
            t0 = time.perf_counter()
            coords = s.window(Rect.of(ORIGIN[0], ORIGIN[1], a.size, a.size))
            dt = time.perf_counter() - t0
            out = s.colors(coords)
        from_crevice = v[coords[..., 1] % m, coords[..., 0] % m] != 0
        luma = ndimage.gaussian_filter(out[..., :3].mean(axis=-1), 6.0)
        dark = luma <= np.quantile(luma, 0.02)
        crop = out[:256, :256]
        rows[name] = {
            "copied_from_crevice": float(from_crevice.mean()),
            "darkest_2pct_from_crevice": float(from_crevice[dark].mean()),
            "usage_peak": usage_peak(coords, m),
            "energy": neighborhood_energy(ex.pixels, crop)[0],
            "ps": ps_distance(ex.pixels, crop),
            "seconds": dt,
        }
        k = 4  # 25%: the mean of each 4 x 4 block, as the canvas's zoomed-out levels show it
        small = out[..., :3].reshape(a.size // k, k, a.size // k, k, -1).mean(axis=(1, 3))
        shots.append(small)
    print(f"gravel, {a.size}^2 window at {ORIGIN}; crevice {w}x{h} at ({x}, {y})-({x + w}, {y + h})")
    print(f"{'':<17}{'from crevice':>13}{'darkest 2%':>12}{'usage peak':>12}{'energy':>9}{'PS':>7}{'s':>7}")
    for name, r in rows.items():
        print(f"{name:<17}{r['copied_from_crevice']:13.3f}{r['darkest_2pct_from_crevice']:12.2f}"
              f"{r['usage_peak']:12.2f}{r['energy']:9.5f}{r['ps']:7.3f}{r['seconds']:7.2f}")
    gap = np.full((shots[0].shape[0], 6, shots[0].shape[2]), 1.0, np.float32)
    os.makedirs(os.path.dirname(os.path.abspath(a.figure)), exist_ok=True)
    write_png(a.figure, to_u8(np.concatenate([shots[0], gap, shots[1]], axis=1)))
    print(f"figure (plain | crevice avoided, 25%): {a.figure}")
    os.makedirs(os.path.dirname(os.path.abspath(a.json)), exist_ok=True)
    with open(a.json, "w") as f:
        json.dump({"size": a.size, "origin": ORIGIN, "crevice": CREVICE, "rows": rows}, f, indent=1)
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
