"""Texture a model: synthesis directly in its atlas, seamless across its UV seams.

    python examples/texture_model.py [OUT_DIR]

A vase (generated here, unwrapped by xatlas into about 20 charts) gets the
bundled brick, upright, five exemplar widths around its largest side. The
synthesis reads neighborhoods across the charts' seams, so the bricks run on
over them; ``seams=False`` synthesizes each chart on its own, for comparison.
Writes the atlas (PNG) and the model with it attached (GLB, opens in Blender).
On the command line: ``infinitex surface vase.glb brick.png -o vase.glb``.
"""
import os
import sys

import infinitex as itx
from infinitex.engine.surface.seams import seam_error
from infinitex.engine.surface.shapes import vase
from infinitex.export.surface import glb_bytes

out = sys.argv[1] if len(sys.argv) > 1 else "."
model = vase()
brick = os.path.join(itx.ASSETS, "brick.png")
img, coords, atlas = itx.texture_model(model, brick, 1024, repeats=5.0, seed=1)
itx.write_png(os.path.join(out, "vase_brick.png"), itx.to_u8(img))
with open(os.path.join(out, "vase_brick.glb"), "wb") as f:
    f.write(glb_bytes(model, {"image": img}))
naive, _, _ = itx.texture_model(model, brick, 1024, repeats=5.0, seed=1, seams=False)
print(f"{len(model.faces)} triangles, {atlas.charts} charts; seam error {seam_error(img, atlas).ratio:.2f} "
      f"(each chart on its own: {seam_error(naive, atlas).ratio:.2f}; 1.0 = as continuous as the texture)")
print(f"wrote vase_brick.png {img.shape[1]}x{img.shape[0]}")
print("and vase_brick.glb: the model with it attached")
