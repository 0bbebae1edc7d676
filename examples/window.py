"""A window of the infinite texture, anywhere on the canvas.

    python examples/window.py [OUT_DIR]

Two windows of the bundled gravel: one at the origin, one two billion pixels
away; any window of the same canvas agrees with any other where they overlap.
"""
import os
import sys

import numpy as np

import infinitex as itx

out = sys.argv[1] if len(sys.argv) > 1 else "."
gravel = os.path.join(itx.ASSETS, "gravel.png")

near = itx.synthesize(gravel, size=(512, 256), origin=(0, 0), seed=1)
far = itx.synthesize(gravel, size=(512, 256), origin=(-2**30, 2**30 - 256), seed=1)
part = itx.synthesize(gravel, size=(128, 128), origin=(100, 50), seed=1)
assert np.array_equal(part, near[50:178, 100:228])  # spatial determinism

for name, img in (("window_near.png", near), ("window_far.png", far)):
    itx.write_png(os.path.join(out, name), img)
    print(f"wrote {name} {img.shape[1]}x{img.shape[0]}")
