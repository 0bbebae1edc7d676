"""Texture by numbers: say where each texture goes on the canvas.

    python examples/texture_by_numbers.py [OUT_DIR]

The exemplar holds two textures side by side (gravel on the left, brick on
the right), and its label map says which is which (label 0 and label 1). A
label map on the canvas asks for a winding gravel path through brick; pixels
outside the canvas map are free. Labels can also be images whose distinct
colors are the labels (``--labels-exemplar`` / ``--labels-canvas`` on the
command line). Then a palette: three separate exemplars (grass, gravel, brick),
each one label, packed into one exemplar by ``palette()``.
"""
import os
import sys

import numpy as np

import infinitex as itx

out = sys.argv[1] if len(sys.argv) > 1 else "."
gravel = itx.load_exemplar(os.path.join(itx.ASSETS, "gravel.png")).pixels
brick = itx.load_exemplar(os.path.join(itx.ASSETS, "brick.png")).pixels
both = np.concatenate([gravel[:, 32:96], brick[:, 32:96]], axis=1)     # 128 x 128, two textures
ids = np.zeros((128, 128), np.int64)
ids[:, 64:] = 1                                                         # 0: gravel, 1: brick
ys, xs = np.mgrid[0:256, 0:512]
path = np.abs(ys - 128 - 70 * np.sin(xs / 60.0)) < 24
canvas = np.where(path, 0, 1)                                           # gravel path through brick
img = itx.synthesize(both, size=(512, 256), seed=3, labels=(ids, canvas), label_strength=1.0)
itx.write_png(os.path.join(out, "by_numbers.png"), img)
print(f"wrote by_numbers.png {img.shape[1]}x{img.shape[0]}")

# A palette: three separate exemplars, one label each (label i = exemplar i),
# here a gravel path with grass on one side and brick on the other.
ex, layout = itx.palette([os.path.join(itx.ASSETS, f) for f in ("grass.png", "gravel.png", "brick.png")])
canvas = np.where(path, 1, np.where(ys < 128 + 70 * np.sin(xs / 60.0), 0, 2))
img = itx.synthesize(ex, size=(512, 256), seed=3, labels=(layout.labels(), canvas))
itx.write_png(os.path.join(out, "by_numbers_palette.png"), img)
print(f"wrote by_numbers_palette.png {img.shape[1]}x{img.shape[0]}")
print(f"  labels 0, 1, 2: {', '.join(layout.names)}")
