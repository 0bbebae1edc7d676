"""A seamless (toroidal) tile, and a 2 x 2 repetition of it to check the seams.

    python examples/toroidal_tile.py [OUT_DIR]
"""
import os
import sys

import numpy as np

import infinitex as itx

out = sys.argv[1] if len(sys.argv) > 1 else "."
tile = itx.tile(os.path.join(itx.ASSETS, "gravel.png"), 256, seed=3)
itx.write_png(os.path.join(out, "tile.png"), tile)
itx.write_png(os.path.join(out, "tile_2x2.png"), np.tile(tile, (2, 2, 1)))
print("wrote tile.png 256x256")
print("wrote tile_2x2.png 512x512")
