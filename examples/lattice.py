"""A near-regular texture (bricks) keeps its rows: the lattice is detected.

    python examples/lattice.py [OUT_DIR]

The example draws a running-bond brick wall (bricks 40 x 18 px, each its own
shade), detects its lattice, and synthesizes with and without lattice mode.
"""
import os
import sys

import numpy as np

import infinitex as itx

out = sys.argv[1] if len(sys.argv) > 1 else "."
rng = np.random.default_rng(0)
ys, xs = np.mgrid[0:256, 0:256] + 0.5
row = np.floor(ys / 18)
u = xs + 20 * (row % 2)
col = np.floor(u / 40)
inside = np.minimum(np.minimum(u - 40 * col, 40 * (col + 1) - u), np.minimum(ys - 18 * row, 18 * (row + 1) - ys))
shade = rng.uniform(0.45, 0.75, (64, 64))[row.astype(int) % 64, col.astype(int) % 64]
wall = np.where(inside > 1.0, shade, 0.9)[:, :, None] * np.array([1.0, 0.55, 0.4])
wall = np.clip(wall + rng.normal(0, 0.02, wall.shape), 0, 1).astype(np.float32)

lattice = itx.detect_lattice(wall).lattice
print(f"lattice: {lattice.to_text()}")
plain = itx.synthesize(wall, size=(384, 256), seed=5)
kept = itx.synthesize(wall, size=(384, 256), seed=5, lattice=lattice)
for name, img in (("bricks_input.png", itx.to_u8(wall)), ("bricks_plain.png", plain), ("bricks_lattice.png", kept)):
    itx.write_png(os.path.join(out, name), img)
    print(f"wrote {name} {img.shape[1]}x{img.shape[0]}")
