"""A big export, streamed tile by tile in bounded memory and resumable:
a tiled BigTIFF, a UDIM tile set and a multiscale Zarr pyramid of the same
rectangle.

    python examples/huge_export.py [OUT_DIR]

(The command line does the same: infinitex export IMAGE -o OUT.tif --format tiff
--rect X Y W H --tile N [--workers N | --scheduler [ADDRESS]]; rectangles up to
2^20 px a side.)
"""
import os
import sys

import infinitex as itx

out = sys.argv[1] if len(sys.argv) > 1 else "."
an = itx.analyze(itx.load_exemplar(os.path.join(itx.ASSETS, "gravel.png")))
rect = itx.Rect.of(0, 0, 2048, 1536)
with itx.Synthesizer(an) as s:
    itx.TiledExport(s, rect, os.path.join(out, "huge.tif"), "tiff", tile=512).run(
        lambda done, total: print(f"\rtile {done}/{total}", end="", file=sys.stderr))
    itx.TiledExport(s, rect, os.path.join(out, "huge.png"), "tiles", tile=1024).run()
    itx.TiledExport(s, rect, os.path.join(out, "huge.zarr"), "zarr", tile=512).run()  # levels 0..2
import tifffile  # noqa: E402
from PIL import Image  # noqa: E402

img = tifffile.imread(os.path.join(out, "huge.tif"))
Image.fromarray(img[::4, ::4]).save(os.path.join(out, "huge_preview.png"))  # a quarter-size look at it
print(f"\nwrote huge_preview.png {img.shape[1] // 4}x{img.shape[0] // 4}")
print(f"tiles: {', '.join(sorted(n for n in os.listdir(out) if n.startswith('huge.1')))}")
import zarr  # noqa: E402

levels = zarr.open_group(os.path.join(out, "huge.zarr"), mode="r")
print("zarr levels:", ", ".join(f"{k} {levels[k].shape[1]}x{levels[k].shape[0]}" for k in sorted(levels.array_keys())))
