"""docs/editor.png: the editor on the default exemplar with a calm and a rough
stroke of painted randomness (Paint canvas tool), 1280 x 800, under Xvfb:

    xvfb-run -a -s "-screen 0 1280x800x24" python scripts/figure_editor.py [OUT.png]
"""
import os
import sys
import tempfile

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, ROOT)
os.environ.setdefault("INFINITEX_STATE", tempfile.mkdtemp(prefix="infinitex-figure-"))

from imgui_bundle.immapp import testing  # noqa: E402

from infinitex.app.ui.editor import Editor  # noqa: E402


def main(out: str) -> int:
    ed = Editor(recover=False, window_size=(1280, 800))

    def settle(ctx):
        for _ in range(3000):
            ctx.yield_()
            if ed.session is not None and ed.session.ready and ed.doc is not None and ed.refined \
                    and ed.session.job is None:
                return

    def stroke(ctx, r, x0, y0, dx, dy, value):
        ed.tool.brush.value, ed.tool.brush.radius = value, 40.0
        ctx.mouse_move_to_pos((r.min.x + x0, r.min.y + y0))
        ctx.mouse_down(0)
        for i in range(1, 9):
            ctx.mouse_move_to_pos((r.min.x + x0 + dx * i, r.min.y + y0 + dy * i))
        ctx.mouse_up(0)
        settle(ctx)

    def test(ctx):
        settle(ctx)
        ctx.set_ref("//Infinitex")
        ctx.item_click("**/Paint canvas (B)##tool-paint-canvas")
        ctx.yield_(3)
        r = ctx.item_info("**/canvas").rect_full
        stroke(ctx, r, 120, 200, 30, 25, 0.0)    # calm
        stroke(ctx, r, 560, 420, 30, -20, 2.0)   # rough
        ctx.mouse_move_to_pos((r.min.x + 450, r.min.y + 640))
        settle(ctx)
        testing.capture(ctx, out)

    testing.run(test_function=test, runner_params=ed.runner_params(), run_speed=testing.TestRunSpeed.fast)
    return 0


if __name__ == "__main__":
    sys.exit(main(os.path.abspath(sys.argv[1] if len(sys.argv) > 1 else os.path.join(ROOT, "docs", "editor.png"))))
