"""Direction fields: the texture turns and grows where you say.

    python examples/direction_field.py [OUT_DIR]

A direction field gives, over the canvas, the direction along which the
exemplar's +x axis runs (degrees, clockwise on screen), how much larger the
texture shows and how much it is stretched along that direction. Here the
brick courses go round in circles about the middle of the window, and the brick grows from
the left (scale 0.6) to the right (scale 1.6). Maps can also be read from flow
or angle images: ``direction_field("flow.png")``, or ``--direction-map`` on the
command line.
"""
import os
import sys

import numpy as np

import infinitex as itx

out = sys.argv[1] if len(sys.argv) > 1 else "."
brick = os.path.join(itx.ASSETS, "brick.png")

ys, xs = np.mgrid[0:320, 0:320] + 0.5
# The exemplar's +x points away from the middle, so its courses (which run
# along the exemplar's y: the bricks stand upright in it) go round in circles.
angle = np.degrees(np.arctan2(ys - 160, xs - 160))
field = itx.direction_field(angle)                                  # placed at canvas (0, 0)
img = itx.synthesize(brick, size=(320, 320), seed=1, controls=itx.Controls(direction=field))
itx.write_png(os.path.join(out, "direction_circle.png"), img)
print(f"wrote direction_circle.png {img.shape[1]}x{img.shape[0]}")

scale = np.linspace(0.6, 1.6, 512)[None, :].repeat(192, axis=0)    # grows from left to right
field = itx.DirectionField.from_jacobians(itx.jacobian(0.0, scale), 0, 0)
img = itx.synthesize(brick, size=(512, 192), seed=1, controls=itx.Controls(direction=field))
itx.write_png(os.path.join(out, "direction_scale.png"), img)
print(f"wrote direction_scale.png {img.shape[1]}x{img.shape[0]}")
