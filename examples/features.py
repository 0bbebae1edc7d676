"""Features: a chosen spot of the exemplar placed on the canvas.

    python examples/features.py [OUT_DIR]

A Feature copies the exemplar around ``exemplar`` (x, y) to ``canvas`` (x,
y), inside circles of radius going from ``outer`` (coarse levels) to
``inner`` (fine levels); the texture around it corrects itself to fit.
"""
import os
import sys

import infinitex as itx

out = sys.argv[1] if len(sys.argv) > 1 else "."
gravel = os.path.join(itx.ASSETS, "gravel.png")
features = tuple(itx.Feature(exemplar=(64, 64), canvas=(x, 128), inner=16, outer=40) for x in (96, 256, 416))
img = itx.synthesize(gravel, size=(512, 256), seed=4, controls=itx.Controls(features=features))
itx.write_png(os.path.join(out, "features.png"), img)
print(f"wrote features.png {img.shape[1]}x{img.shape[0]}")
