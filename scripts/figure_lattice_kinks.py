"""Make docs/lattice-kinks.png: lattice mode's finer scales at the document's
full randomness (before) and at half of it (after, the default), zoomed 3x.

    .venv/bin/python scripts/figure_lattice_kinks.py [OUT.png]

One row per exemplar (our weave from bench/exemplars, and a generated basket
weave and diagonal tiles from tests/lattice_scenes.py): a 96 px crop of the
input, then a 96 x 96 window of lattice mode (the lattice found, Balanced, in
the input's geometry) with LATTICE_FINE_JITTER at 1 and at its default.
"""
import os
import sys

import numpy as np
from PIL import Image, ImageDraw

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, ROOT)
sys.path.insert(0, os.path.join(ROOT, "tests"))

import lattice_scenes  # noqa: E402

import infinitex.engine.controls as controls_module  # noqa: E402
from infinitex.api import synthesize  # noqa: E402
from infinitex.engine.exemplar import load_full  # noqa: E402
from infinitex.engine.imagefile import to_rgb8, write_png  # noqa: E402


def _inputs():
    yield load_full(os.path.join(ROOT, "bench", "exemplars", "weave.png"))
    wanted = ["basket_weave", "diagonal_tiles"]
    for img, entry in lattice_scenes.scenes("held"):
        if entry["what"] in wanted:
            wanted.remove(entry["what"])
            yield img


def main(out: str) -> None:
    n, zoom, gap = 96, 3, 6
    default = controls_module.LATTICE_FINE_JITTER
    rows = []
    for img in _inputs():
        cells = [to_rgb8(img[:n, :n])]
        for f in (1.0, default):
            controls_module.LATTICE_FINE_JITTER = f
            cells.append(to_rgb8(synthesize(img, (n, n), (3001, -5003)) / 255.0))
        controls_module.LATTICE_FINE_JITTER = default
        big = [np.kron(c, np.ones((zoom, zoom, 1), np.uint8)) for c in cells]
        rows.append(np.concatenate([np.pad(b, ((0, gap), (0, gap), (0, 0)), constant_values=255) for b in big], axis=1))
    img = np.concatenate(rows, axis=0)
    head = Image.new("RGB", (img.shape[1], 22), "white")
    draw = ImageDraw.Draw(head)
    labels = ["input", "before: finer scales at full randomness", f"after: at {default:g} of it (default)"]
    for i, t in enumerate(labels):
        draw.text((i * (n * zoom + gap) + 4, 5), t, fill=(0, 0, 0))
    write_png(out, np.concatenate([np.asarray(head), img], axis=0))


if __name__ == "__main__":
    main(sys.argv[1] if len(sys.argv) > 1 else os.path.join(ROOT, "docs", "lattice-kinks.png"))
