"""A corner Wang tile set for a game engine, from the bundled gravel.

    python examples/tile_set.py [OUT_FOLDER]

16 tiles of 128 px with 2 corner colours: any two tiles whose shared corners
have the same colours meet without a seam. Writes the atlas, its description
(each tile's corner colours and place), a random 8 x 8 arrangement, and the
engines' terrains: Tiled's gravel-set.tsx and example map gravel-set.tmx,
Godot 4's gravel-set.tres. The command line does the same with ``infinitex
export gravel.png -o gravel-set.png --wang 2 --tile 128``.
"""
import os
import sys

import infinitex as itx

out = sys.argv[1] if len(sys.argv) > 1 else "."
os.makedirs(out, exist_ok=True)
atlas, desc = itx.tile_set(os.path.join(itx.ASSETS, "gravel.png"), colors=2, n=128, seed=3)
files = itx.save_tile_set(atlas, desc, os.path.join(out, "gravel-set.png"), seed=1)
first = desc["tiles"][0]
print(f"{desc['count']} tiles of {desc['tile']} px; the first has corners "
      f"{first['nw']}{first['ne']}/{first['sw']}{first['se']} at ({first['x']}, {first['y']})")
print(f"wrote gravel-set.png {atlas.shape[1]}x{atlas.shape[0]}")
print("wrote gravel-set_preview.png 1024x1024")
print("and", ", ".join(os.path.basename(f) for f in files if not f.endswith(".png")))
