"""Make docs/model-editor.png: the editor with a model open.

    xvfb-run -a -s "-screen 0 1280x800x24" .venv/bin/python scripts/figure_model_editor.py [OUT.png]

The bundled brick on a vase (generated, CC0, unwrapped by xatlas) at the
default Structure, its texture done; the Model panel open, the seams shown.
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
        ed.set_surface("Model texture scale", repeats=5.0)
        ed.show_seams = True
        ed.camera = ed.camera.orbit(-25.0, -5.0)
        h.settle(ctx, 900)
        ctx.yield_(5)
        testing.capture(ctx, out)
        h.check("captured", os.path.exists(out))
    return h.run(test)


if __name__ == "__main__":
    sys.exit(main(sys.argv[1] if len(sys.argv) > 1 else os.path.join(ROOT, "docs", "model-editor.png")))
