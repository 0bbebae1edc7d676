"""Randomness painted over the canvas: calm on the left, rough on the right.

    python examples/painted_randomness.py [OUT_DIR]

A CanvasField holds the painted values (uint16: 0 calm, 32768 neutral, 65535
rough) in sparse tiles; painted() adds a round dab. With the field calm the
exemplar is copied as it is; rough breaks it up more.
"""
import os
import sys

import infinitex as itx

out = sys.argv[1] if len(sys.argv) > 1 else "."
brick = os.path.join(itx.ASSETS, "brick.png")
field = itx.CanvasField()
for y in range(16, 256, 32):
    for x in range(16, 160, 32):
        field, _ = field.painted(x, y, 28.0, 0)                 # calm: value 0
        field, _ = field.painted(x + 352, y, 28.0, 65535)       # rough: value 65535
img = itx.synthesize(brick, size=(512, 256), seed=2, controls=itx.Controls(randomness_canvas=field))
itx.write_png(os.path.join(out, "painted.png"), img)
print(f"wrote painted.png {img.shape[1]}x{img.shape[0]}")
