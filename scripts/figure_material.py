"""docs/material.png: the editor on the shipped cobblestone material
(infinitex/assets/cobbles), lit preview with the light low from the upper
left, the Material and Display panels open, 1280 x 800, under Xvfb:

    xvfb-run -a -s "-screen 0 1280x800x24" python scripts/figure_material.py [OUT.png]
"""
import os
import sys
import tempfile
import time

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, ROOT)
os.environ.setdefault("INFINITEX_STATE", tempfile.mkdtemp(prefix="infinitex-figure-"))
os.environ["INFINITEX_NO_NATIVE_DIALOGS"] = "1"
os.environ["INFINITEX_PATH_PROMPT"] = "1"

from imgui_bundle.immapp import testing  # noqa: E402

from infinitex.app.ui.editor import Editor  # noqa: E402

COBBLES = os.path.join(ROOT, "infinitex", "assets", "cobbles")


def main(out: str) -> int:
    ed = Editor(COBBLES, recover=False, window_size=(1280, 800))

    def frames_until(ctx, cond, seconds):
        t0 = time.monotonic()
        while not cond() and time.monotonic() - t0 < seconds:
            ctx.yield_()
            time.sleep(0.01)

    def ready():
        return ed.session is not None and ed.session.ready and ed.refined and ed.files.pending is None

    def test(ctx):
        frames_until(ctx, ready, 600)
        ctx.set_ref("//Infinitex")
        for header in ("Randomness", "Exemplar", "Export", "Advanced"):
            ctx.item_close(f"**/{header}")
        for header in ("Material", "Display"):
            ctx.item_open(f"**/{header}")
        ctx.item_click("**/Lit material")
        ctx.yield_(2)
        ctx.item_input_value("**/Light direction", 140.0)
        ctx.item_input_value("**/Light height", 30.0)
        frames_until(ctx, lambda: ed.refined, 120)
        ctx.mouse_move_to_pos((1200, 760))
        ctx.yield_(5)
        testing.capture(ctx, out)

    testing.run(test_function=test, runner_params=ed.runner_params(), run_speed=testing.TestRunSpeed.fast)
    return 0 if os.path.isfile(out) else 1


if __name__ == "__main__":
    sys.exit(main(sys.argv[1] if len(sys.argv) > 1 else os.path.join(ROOT, "docs", "material.png")))
