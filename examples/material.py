"""A whole material: one synthesis, every map looked up through it, each
written at its own precision (the shipped cobblestones: 8-bit base color and
roughness, 16-bit normal and height).

    python examples/material.py [OUT_DIR]
"""
import os
import sys

import infinitex as itx

out = sys.argv[1] if len(sys.argv) > 1 else "."
mat = itx.open_material(os.path.join(itx.ASSETS, "cobbles", "cobbles_basecolor.png"))  # + its siblings
with itx.Synthesizer(itx.analyze(mat.guide())) as s:  # the analysis sees base color + height
    coords = s.window(itx.Rect.of(5000, -2000, 384, 256))
    for role in mat.roles:
        depth = mat.maps[role].depth
        itx.write_image(os.path.join(out, f"cobbles_{role}.png"), mat.lookup(role, coords), depth)
        print(f"wrote cobbles_{role}.png 384x256")
