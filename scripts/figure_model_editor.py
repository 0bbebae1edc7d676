"""Make docs/model-editor.png: the editor with a model open.

    xvfb-run -a -s "-screen 0 1280x800x24" .venv/bin/python scripts/figure_model_editor.py [OUT.png]

The bundled brick on a vase (generated, CC0, unwrapped by xatlas) at the
default Structure, its texture done; the Model panel open, the seams shown, a
comb stroke down its right side (the bricks turn along it) and a feature
placed on its left (its circles shown by the Features tool).
"""
import os
import sys
import tempfile

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, ROOT)
sys.path.insert(0, os.path.join(ROOT, "tests", "app"))

import trimesh  # noqa: E402
from gui_harness import Harness  # noqa: E402
from imgui_bundle.immapp import testing  # noqa: E402

from infinitex import ASSETS  # noqa: E402
from infinitex.engine.surface.shapes import vase  # noqa: E402


def main(out: str) -> int:
    tmp = tempfile.mkdtemp(prefix="infinitex-figure-")
    os.environ.setdefault("INFINITEX_STATE", os.path.join(tmp, "state"))
    m = vase()
    path = os.path.join(tmp, "vase.glb")
    trimesh.Trimesh(m.positions, m.faces, visual=trimesh.visual.TextureVisuals(uv=m.uvs), process=False).export(path)
    h = Harness(tmp, os.path.join(ASSETS, "brick.png"), window_size=(1280, 800))
    ed = h.ed

    def test(ctx) -> None:
        h.settle(ctx)
        ctx.set_ref("//Infinitex")
        ctx.menu_click("File/Open model...")
        ctx.yield_(2)
        ctx.item_input_value("//**/##path", path)
        ctx.yield_(3)
        ed.model.set_surface("Model texture scale", repeats=5.0)
        ed.model.show_seams = True
        ed.model.camera = ed.model.camera.orbit(-25.0, -5.0)
        h.settle(ctx, 900)
        # A comb stroke down the vase's right side (the bricks turn to run along it) and a feature.
        r = ctx.item_info("//**/canvas").rect_full
        cx, cy = (r.min.x + r.max.x) / 2, (r.min.y + r.max.y) / 2
        ctx.item_click("//**/Direction (D)##tool-direction")
        ed.tool.mode, ed.tool.brush.radius, ed.tool.brush.strength = "comb", 45.0, 1.0
        ctx.mouse_move_to_pos((cx + 70, cy - 150))
        ctx.mouse_down(0)
        for i in range(1, 16):
            ctx.mouse_move_to_pos((cx + 70 + 2 * i, cy - 150 + 20 * i))
        ctx.mouse_up(0)
        ctx.item_click("//**/Features (F)##tool-feature")
        ed.tool.inner, ed.tool.outer, ed.tool.exact = 28, 40, True
        ctx.mouse_move_to_pos((cx - 80, cy + 20))
        ctx.mouse_click(0)
        ctx.mouse_move_to_pos((r.max.x - 20, r.min.y + 20))
        h.settle(ctx, 900)
        ctx.yield_(5)
        testing.capture(ctx, out)
        h.check("captured", os.path.exists(out))
    return h.run(test)


if __name__ == "__main__":
    sys.exit(main(sys.argv[1] if len(sys.argv) > 1 else os.path.join(ROOT, "docs", "model-editor.png")))
