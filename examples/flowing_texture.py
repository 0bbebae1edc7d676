"""Texture in motion: a seamless, looping flipbook of gravel swirling in a
vortex (a velocity map made here), and a river of it sliding over still ground.

    python examples/flowing_texture.py [OUT_DIR]
"""
import os
import sys

import numpy as np

import infinitex as itx

out = sys.argv[1] if len(sys.argv) > 1 else "."
gravel = os.path.join(itx.ASSETS, "gravel.png")

# A vortex over a 128 x 128 tile, in px per frame (+x right, +y down): a tile that
# flows, loops after 32 frames and tiles in space.
n = 128
ys, xs = np.mgrid[0:n, 0:n] + 0.5
dx, dy = xs - n / 2, ys - n / 2
r = np.hypot(dx, dy) + 1e-9
speed = 1.2 * np.clip(r / 24, 0, 1) * np.clip((n / 2 - r) / 24, 0, 1)  # still at the tile's edges
vortex = np.stack([-dy / r * speed, dx / r * speed], -1)
frames = itx.animate(gravel, 32, velocity=(0.0, 0.0), velocity_map=vortex, toroidal=n, loop=True)
itx.write_animation(os.path.join(out, "vortex.png"), frames, fps=24, loop=True)  # and vortex.json
print("wrote vortex.png 1024x512")  # a flipbook atlas: 8 x 4 frames of 128 x 128

# A river 40 px wide along a sine, 2 px per frame, on a 256 x 192 window of the infinite canvas.
h, w = 192, 256
ys, xs = np.mgrid[0:h, 0:w] + 0.5
curve = h / 2 + 30 * np.sin(xs / w * 2 * np.pi)
slope = 30 * 2 * np.pi / w * np.cos(xs / w * 2 * np.pi)
along = np.stack([np.ones_like(slope), slope], -1) / np.hypot(1, slope)[..., None]
river = along * (2.0 * np.exp(-((ys - curve) / 20) ** 2))[..., None]
frames = itx.animate(gravel, 24, velocity=(0.0, 0.0), velocity_map=river, size=(w, h), origin=(0, 0))
itx.write_animation(os.path.join(out, "river.webp"), frames, fps=24)
print(f"wrote river.webp {w}x{h}")  # 24 frames, animated
