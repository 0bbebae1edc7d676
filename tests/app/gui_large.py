"""Drive the real editor through a large photo (run under Xvfb by test_editor.py):

    xvfb-run -a python tests/app/gui_large.py OUT_DIR

A 1300 x 1100 image opens at 512 px; the Exemplar panel's Import "Resize, up
to 2048 px" keeps 1024 px of it, analyzed in the background (the editor keeps
drawing frames) with the random-walk search, which the Advanced section says;
the canvas is the engine's output; Undo goes back to 512 px. Writes
"ok NAME" / "FAIL NAME: why" lines to OUT_DIR/report.txt.
"""
from __future__ import annotations

import os
import sys
import time

HERE = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
sys.path.insert(0, HERE)
sys.path.insert(0, os.path.join(HERE, "scripts"))

from gui_harness import Harness  # noqa: E402
from imgui_bundle import imgui  # noqa: E402
from imgui_bundle.immapp import testing  # noqa: E402
from make_material import cobbles  # noqa: E402

from infinitex.engine.imagefile import write_image  # noqa: E402


def main(out: str) -> int:
    photo = os.path.join(out, "photo.png")
    write_image(photo, cobbles(1300, seed=3, stones=90)["basecolor"][:1100], 8)
    h = Harness(out, photo)
    ed, check, settle, canvas = h.ed, h.check, h.settle, h.canvas

    def test(ctx) -> None:
        settle(ctx)
        check("a large photo opens at 512 px", ed.session.exemplar.size == 512 and ed.doc.fit == "resize"
              and ed.session.analysis.k == 2, str(ed.session.exemplar.size))
        ctx.set_ref(ctx.window_info("//Infinitex/Panels").window)
        ctx.combo_click("Import/Resize, up to 2048 px")
        frames, t0 = 0, time.perf_counter()
        while not (ed.session.ready and ed.session.exemplar is not None and ed.session.exemplar.size == 1024):
            ctx.yield_()
            frames += 1
            if time.perf_counter() - t0 > 300:
                break
        seconds = time.perf_counter() - t0
        settle(ctx)
        check("Import up to 2048 px keeps 1024 px of it", ed.doc.fit == "resize-2048"
              and ed.session.exemplar.size == 1024 and ed.session.L == 10, f"{ed.doc.fit} {ed.session.exemplar.size}")
        check("the editor keeps drawing while it is analyzed", frames >= 5 and frames / max(seconds, 1e-3) > 2,
              f"{frames} frames in {seconds:.1f} s")
        check("analyzed with the random-walk search", ed.session.analysis.k == 0
              and all(lv.simset is None for lv in ed.session.analysis.levels), str(ed.session.analysis.k))
        shown = canvas(ctx)
        check("the canvas shows texture", shown.std() > 8, f"std {shown.std():.1f}")
        ctx.set_ref("//Infinitex")
        for header in ("Randomness", "Exemplar", "Display"):
            ctx.item_close(f"**/{header}")
        ctx.item_open("**/Advanced")
        ctx.yield_(3)
        check("Advanced says how it is searched", ctx.item_exists("**/Similar spots"), "no k slider")
        testing.capture(ctx, os.path.join(out, "large.png"))
        ctx.item_close("**/Advanced")
        for header in ("Randomness", "Exemplar", "Display"):
            ctx.item_open(f"**/{header}")
        ctx.key_down(imgui.Key.left_ctrl)
        ctx.key_press(imgui.Key.z)
        ctx.key_up(imgui.Key.left_ctrl)
        settle(ctx)
        check("undo goes back to 512 px", ed.doc.fit == "resize" and ed.session.exemplar.size == 512
              and ed.session.analysis.k == 2, f"{ed.doc.fit} {ed.session.exemplar.size}")

    return h.run(test)


if __name__ == "__main__":
    sys.exit(main(sys.argv[1]))
