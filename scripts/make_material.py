"""Generate the shipped example material: cobblestones whose maps come from the
same shapes (a periodic Voronoi diagram), so they tile and stay aligned.

    python scripts/make_material.py [OUT_FOLDER] [--size 512] [--seed 7]

writes NAME_basecolor.png (8-bit RGB), NAME_height.png (16-bit), NAME_normal.png
(16-bit RGB, OpenGL convention) and NAME_roughness.png (8-bit). Our own work:
CC0, like the rest of infinitex/assets. The maps come from bench/cobbles.py (:func:`cobbles`, which the tests and benchmarks use too).
"""
from __future__ import annotations

import argparse
import os
import sys

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
if ROOT not in sys.path:
    sys.path.insert(0, ROOT)

from bench.cobbles import cobbles  # noqa: E402  (the tests import it from here too)


DEPTHS = {"basecolor": 8, "height": 16, "normal": 16, "roughness": 8}


def main(argv: list[str]) -> int:
    from infinitex.engine.imagefile import write_image
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("out", nargs="?", default=os.path.join("infinitex", "assets", "cobbles"))
    p.add_argument("--size", type=int, default=512)
    p.add_argument("--seed", type=int, default=7)
    p.add_argument("--name", default="cobbles")
    a = p.parse_args(argv)
    os.makedirs(a.out, exist_ok=True)
    for role, px in cobbles(a.size, a.seed).items():
        path = os.path.join(a.out, f"{a.name}_{role}.png")
        write_image(path, px, DEPTHS[role])
        print(f"wrote {path} ({px.shape[1]}x{px.shape[0]}, {DEPTHS[role]}-bit)")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
