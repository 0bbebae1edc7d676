"""docs/export-editor.png: the editor's Export panel set for a 64k BigTIFF
(size and time estimated before starting) with a streamed export running in
its progress window, 1280 x 800, under Xvfb:

    xvfb-run -a -s "-screen 0 1280x800x24" python scripts/figure_export.py [OUT.png]

The export goes to a temporary folder and is cancelled after the capture.
"""
import os
import shutil
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


def main(out: str) -> int:
    ed = Editor(recover=False, window_size=(1280, 800))
    folder = tempfile.mkdtemp(prefix="infinitex-figure-export-")

    def frames_until(ctx, cond, seconds):
        t0 = time.monotonic()
        while not cond() and time.monotonic() - t0 < seconds:
            ctx.yield_()
            time.sleep(0.01)

    def test(ctx):
        frames_until(ctx, lambda: ed.session is not None and ed.session.ready and ed.refined, 300)
        ctx.set_ref("//Infinitex")
        for header in ("Randomness", "Exemplar", "Display"):
            ctx.item_close(f"**/{header}")
        ctx.item_open("**/Export")
        ctx.yield_(2)
        ctx.item_click("**/64k##square")  # 65536 x 65536, BigTIFF
        ctx.yield_(2)
        frames_until(ctx, lambda: ed.exports.settings.estimate is not None and ed.exports.settings.estimate.poll(), 120)
        ctx.yield_(3)
        ctx.item_click("**/Export rectangle...")
        ctx.yield_(2)
        ctx.item_input_value("//**/##path", os.path.join(folder, "terrain.tif"))
        frames_until(ctx, lambda: ed.exports.job is None or ed.exports.job.rate() is not None, 120)
        frames_until(ctx, lambda: ed.exports.job is None or ed.exports.job.done_tiles >= 4, 60)
        ctx.mouse_move_to_pos((900, 600))
        ctx.yield_(3)
        testing.capture(ctx, out)
        if ed.exports.job is not None:
            ed.exports.job.cancel()
        frames_until(ctx, lambda: ed.exports.job is None, 120)

    try:
        testing.run(test_function=test, runner_params=ed.runner_params(), run_speed=testing.TestRunSpeed.fast)
    finally:
        shutil.rmtree(folder, ignore_errors=True)
    return 0


if __name__ == "__main__":
    sys.exit(main(os.path.abspath(sys.argv[1] if len(sys.argv) > 1 else os.path.join(ROOT, "docs",
                                                                                       "export-editor.png"))))
