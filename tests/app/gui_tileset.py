"""Drive the real editor through a tile-set export (run under Xvfb by
test_editor.py):

    xvfb-run -a python tests/app/gui_tileset.py OUT_DIR

File > Export tile set: the settings, a preview made while the editor keeps
drawing frames, Shuffle, Tiled's files without Godot's, then Export... to a typed path; the files written
and the notice saying where. test_editor.py compares the atlas with the same
set made by the command line. Writes "ok NAME" / "FAIL NAME: why" lines to
OUT_DIR/report.txt.
"""
from __future__ import annotations

import json
import os
import signal
import sys
import time

HERE = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
sys.path.insert(0, HERE)

from imgui_bundle.immapp import testing  # noqa: E402

from gui_harness import Harness  # noqa: E402

DIALOG = "//Export tile set###tileset"


def main(out: str) -> int:
    h = Harness(out)
    ed, check, settle = h.ed, h.check, h.settle

    wait = h.wait

    held = []  # the large export's process, held still for a moment (see below)

    def test(ctx) -> None:
        try:
            steps(ctx)
        finally:
            for pid in held:  # never left stopped, whatever failed
                try:
                    os.kill(pid, signal.SIGCONT)
                except ProcessLookupError:  # (it has ended since)
                    pass

    def steps(ctx) -> None:
        settle(ctx)
        # A PNG export first (in a process of its own, held still below): the tile set will wait behind it.
        ctx.set_ref("//Infinitex")
        for header in ("Randomness", "Exemplar", "Display"):
            ctx.item_close(f"**/{header}")
        ctx.item_open("**/Export")
        ctx.yield_(2)
        ed.exports.settings.rect = [0, 0, 512, 512]
        ctx.yield_(2)
        ctx.item_click("**/Export rectangle...")
        ctx.yield_(2)
        ctx.item_input_value("//**/##path", os.path.join(out, "big.png"))
        ctx.yield_(2)
        check("an export runs apart", type(ed.exports.job).__name__ == "BackgroundExport", repr(ed.exports.job))
        # Held still until the tile set is queued behind it (it must not end first on a quiet machine).
        pid = getattr(getattr(ed.exports.job, "proc", None), "pid", None)
        if pid:
            os.kill(pid, signal.SIGSTOP)
            held.append(pid)
        ctx.set_ref("//Infinitex")
        ctx.menu_click("File/Export tile set for game engines...")
        ctx.yield_(3)
        d = ed.panels.tileset
        check("the dialog opens", ctx.window_info(DIALOG).window is not None and d.state == 2, str(d.state))
        ctx.set_ref(DIALOG)
        ctx.combo_click("Tile size/64")
        ctx.yield_(2)
        check("the tile size is chosen", d.size == 64, str(d.size))
        ctx.item_click("Preview")
        frames0, t0 = ed.frame_count, time.monotonic()
        built = wait(ctx, lambda: d.job is not None and d.job.built, 120)
        elapsed = time.monotonic() - t0
        frames = ed.frame_count - frames0
        # Spread over frames (FRAME_BUDGET_S of it a frame): a build that held the
        # editor would take a frame or two. (Not a frame rate: on a busy machine,
        # the suite's own workers and this export's beside it, 3 a second was seen.)
        check("the preview is made while the editor keeps drawing", built and frames >= 10,
              f"built {built}, {frames} frames in {elapsed:.1f} s, {d.error}")
        ctx.yield_(3)
        check("the preview shows 8 x 8 tiles", d.tex is not None and d.tex.size == (512, 512),
              str(d.tex and d.tex.size))
        testing.capture(ctx, os.path.join(out, "tileset-dialog.png"))
        first = d.tex.glo if d.tex is not None else None
        ctx.item_click("Shuffle")
        ctx.yield_(3)
        check("Shuffle lays the tiles out anew", d.seed == 1 and d.tex_seed == 1 and d.tex is not None,
              f"{d.seed} {d.tex_seed} {first}")
        ctx.item_click("1:1")
        ctx.yield_(3)
        mip = d.tex is not None and d.tex.filter[0] == 0x2703  # GL_LINEAR_MIPMAP_LINEAR: fitted, filtered
        check("the preview zooms to 1:1 and its fitted view is filtered", d.zoom == 1.0 and mip
              and ctx.item_exists("tileset-preview"), f"{d.zoom} {d.tex and d.tex.filter}")
        testing.capture(ctx, os.path.join(out, "tileset-dialog-1to1.png"))
        ctx.item_click("Fit")
        ctx.yield_(2)
        ctx.item_click("Godot 4 terrain")  # Tiled's files only
        ctx.yield_(2)
        check("a ticked engine is chosen", d.tiled and not d.godot, f"{d.tiled} {d.godot}")
        ctx.item_click("Export...")
        ctx.yield_(2)
        target = os.path.join(out, "set.png")
        ctx.set_ref("//Infinitex")
        ctx.item_input_value("//**/##path", target)
        ctx.yield_(2)
        check("the tile set waits behind the running export", len(ed.exports.queue) == 1
              and type(ed.exports.job).__name__ == "BackgroundExport", f"{ed.exports.job} {ed.exports.queue}")
        for pid in held:
            os.kill(pid, signal.SIGCONT)
        done = wait(ctx, lambda: ed.exports.job is None and not ed.exports.queue, 540)  # (a loaded machine: minutes)
        ctx.yield_(2)
        files = ["big.png", "set.png", "set.json", "set_preview.png", "set.tsx", "set.tmx"]
        check("the set is written, with Tiled's files and not Godot's", done and not os.path.exists(
              os.path.join(out, "set.tres")) and all(os.path.isfile(os.path.join(out, f)) for f in files),
              str(os.listdir(out)))
        check("the notice says where", ed.notice is not None and os.path.abspath(target) in ed.notice[0]
              and "16 tiles of 64 px" in ed.notice[0], str(ed.notice))
        if os.path.isfile(os.path.join(out, "set.json")):
            desc = json.load(open(os.path.join(out, "set.json"), encoding="utf-8"))
            check("the description lists 16 tiles", desc["count"] == 16 and len(desc["tiles"]) == 16, str(desc)[:200])
        check("the dialog's set was handed over", d.job is None and d.state == 0, f"{d.job} {d.state}")

    return h.run(test, watchdog_s=900)


if __name__ == "__main__":
    sys.exit(main(sys.argv[1]))
