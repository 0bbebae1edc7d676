"""Make docs/structure-before-after.png: the Structure / Variety presets on
structured exemplars, zoomed 2x.

    .venv/bin/python scripts/figure_structure.py [OUT.png]

One row per exemplar (our weave, cells and text from bench/exemplars, and the
brick asset): a 112 px crop of the exemplar, then a 112 x 112 window at
(10007, -20011) with Structure Variety (the per-pixel synthesis alone, the
engine before the fidelity stage) and with the default preset.
"""
import os
import sys

import numpy as np
from PIL import Image, ImageDraw

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, ROOT)

from infinitex.engine.analysis import analyze  # noqa: E402
from infinitex.engine.exemplar import load_exemplar  # noqa: E402
from infinitex.engine.imagefile import to_rgb8, write_png  # noqa: E402
from infinitex.engine.params import DEFAULT_STRUCTURE, STRUCTURE_NAMES, SynthParams, structure_params  # noqa: E402
from infinitex.engine.pyramid import Rect  # noqa: E402
from infinitex.engine.synth import Synthesizer  # noqa: E402

EXEMPLARS = (("bench", "exemplars", "weave.png"), ("bench", "exemplars", "cells.png"),
             ("bench", "exemplars", "text.png"), ("infinitex", "assets", "brick.png"))


def main(out: str) -> None:
    n, zoom, gap = 112, 2, 6
    rows = []
    for parts in EXEMPLARS:
        ex = load_exemplar(os.path.join(ROOT, *parts))
        an = analyze(ex)
        cells = [ex.pixels[:n, :n]]
        for s in (0, DEFAULT_STRUCTURE):
            with Synthesizer(an, structure_params(SynthParams.default(an.L), s)) as synth:
                cells.append(synth.colors(synth.window(Rect.of(10007, -20011, n, n))))
        big = [np.kron(to_rgb8(c), np.ones((zoom, zoom, 1), np.uint8)) for c in cells]
        row = np.concatenate([np.pad(b, ((0, gap), (0, gap), (0, 0)), constant_values=255) for b in big], axis=1)
        rows.append(row)
    img = np.concatenate(rows, axis=0)
    head = Image.new("RGB", (img.shape[1], 22), "white")
    draw = ImageDraw.Draw(head)
    labels = ["exemplar", f"before ({STRUCTURE_NAMES[0]})", f"after ({STRUCTURE_NAMES[DEFAULT_STRUCTURE]}, default)"]
    for i, t in enumerate(labels):
        draw.text((i * (n * zoom + gap) + 4, 5), t, fill=(0, 0, 0))
    write_png(out, np.concatenate([np.asarray(head), img], axis=0))


if __name__ == "__main__":
    main(sys.argv[1] if len(sys.argv) > 1 else os.path.join(ROOT, "docs", "structure-before-after.png"))
