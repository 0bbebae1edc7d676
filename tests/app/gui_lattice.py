"""Drive the lattice tool of the real editor with the imgui test engine
(run under Xvfb by test_editor.py).

    xvfb-run -a python tests/app/gui_lattice.py OUT_DIR

Opens generated running-bond bricks (their quick preview first, then their
lattice, found behind it, adopted as one undo step), turns
it off in the Exemplar panel, auto-detects it again, drags a handle with the
mouse, undoes it; the Direction tool offers to turn the lattice off (one step); writes "ok NAME" / "FAIL NAME: why" lines
to OUT_DIR/report.txt and screenshots to OUT_DIR/found.png (the Exemplar
panel on opening) and OUT_DIR/lattice.png.
"""
from __future__ import annotations

import os
import sys

import numpy as np

HERE = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
sys.path.insert(0, HERE)
sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))  # tests/: lattice_gen

from gui_harness import Harness
from imgui_bundle import imgui
from imgui_bundle.immapp import testing
from lattice_gen import bricks

from infinitex.engine.imagefile import to_u8, write_png


def main(out: str) -> int:
    img, _, _ = bricks(np.random.default_rng(1), side=256, bw=40, bh=18)
    path = os.path.join(out, "bricks.png")
    write_png(path, to_u8(img))
    os.environ["INFINITEX_CACHE"] = os.path.join(out, "cache")  # not analyzed before: the quick preview shows first
    h = Harness(out, path)
    ed, check, settle, canvas = h.ed, h.check, h.settle, h.canvas

    def preview(ctx) -> bytes:
        ctx.yield_(2)  # the window re-rectifies during a frame (GL stays on the main thread)
        px = ed.tool.preview_pixels
        return b"" if px is None else px.tobytes()

    def test(ctx) -> None:
        settle(ctx)
        found = ed.doc.lattice
        check("opening the image finds its lattice", found is not None and abs(found.t1[0] - 40) < 0.5
              and abs(abs(found.t2[0]) - 20) < 0.5 and abs(found.t2[1] - 18) < 0.5, str(found))
        check("the Exemplar panel says it was found", ed.files.found_lattice is not None
              and ed.files.found_lattice.lattice == found, str(ed.files.found_lattice))
        # The image's quick preview showed first; the lattice, found behind it, is one undo step with a notice.
        check("the lattice found after the first texture is one undo step", ed.history.undo_label() == "Lattice found"
              and ed.notice is not None and "Found a lattice" in ed.notice[0], ed.history.undo_label())
        on_open = canvas(ctx)
        ctx.set_ref(ctx.window_info("//Infinitex/Panels").window)
        ctx.item_open("Exemplar")
        ctx.scroll_to_item_y("Turn off##lattice-off")
        ctx.yield_(2)
        testing.capture(ctx, os.path.join(out, "found.png"))  # docs/lattice-found.png
        ctx.item_click("Turn off##lattice-off")
        ctx.item_close("Exemplar")
        ctx.scroll_to_top(imgui.test_engine.TestRef(ctx.window_info("//Infinitex/Panels").window.id_))
        ctx.set_ref("//Infinitex")
        settle(ctx)
        check("Turn off synthesizes without it", ed.doc.lattice is None, str(ed.doc.lattice))
        plain = canvas(ctx)
        ctx.item_click("//**/Lattice (L)##tool-lattice")
        ctx.yield_(3)
        check("lattice tool selected", ed.tool.name == "lattice", ed.tool.name)
        ctx.item_click("//**/Auto-detect")
        settle(ctx)
        lat = ed.doc.lattice
        check("auto-detect finds the bricks", lat is not None and abs(lat.t1[0] - 40) < 0.5 and abs(lat.t1[1]) < 0.5
              and abs(abs(lat.t2[0]) - 20) < 0.5 and abs(lat.t2[1] - 18) < 0.5, str(lat))
        check("confidence shown", ed.tool.detection is not None and ed.tool.detection.confidence > 0.5,
              str(ed.tool.detection))
        on_lattice = canvas(ctx)
        check("the canvas changes to lattice synthesis", not np.array_equal(plain, on_lattice) and on_lattice.std() > 5,
              "same canvas")
        check("the same lattice gives the same texture as on opening", np.array_equal(on_open, on_lattice),
              "differs")
        before = preview(ctx)
        # The handles sit on the detected lattice: drag the end of t1 by the mouse.
        info = ctx.item_info("//Lattice/**/lattice-handles")
        r = info.rect_full
        z = ed.tool.zoom
        hx, hy = lat.origin[0] + lat.t1[0], lat.origin[1] + lat.t1[1]
        start = imgui.ImVec2(r.min.x + hx * z, r.min.y + hy * z)
        ctx.mouse_move_to_pos(start)
        ctx.mouse_down(0)
        ctx.mouse_move_to_pos(imgui.ImVec2(start.x - 2 * z, start.y + 1 * z))
        ctx.yield_(2)
        dragging = preview(ctx)
        check("the preview follows the handle while dragging", dragging and dragging != before, "preview unchanged")
        ctx.mouse_up(0)
        settle(ctx)
        moved = ed.doc.lattice
        check("the handle moved t1", moved is not None and abs(moved.t1[0] - (lat.t1[0] - 2)) < 1.0
              and abs(moved.t1[1] - (lat.t1[1] + 1)) < 1.0, str(moved))
        check("one undo step per drag", ed.history.undo_label() == "Move lattice vector t1", ed.history.undo_label())
        ctx.key_press(imgui.Key.mod_ctrl | imgui.Key.z)
        settle(ctx)
        check("undo restores the lattice", ed.doc.lattice == lat, str(ed.doc.lattice))
        check("undo restores the preview", preview(ctx) == before, "preview differs")
        check("undo restores the canvas", np.array_equal(canvas(ctx), on_lattice), "canvas differs")
        ctx.item_click("//**/Rectified")
        rect = canvas(ctx)
        check("rectified geometry differs from the original", not np.array_equal(rect, on_lattice), "same canvas")
        ctx.item_click("//**/Original geometry")
        check("original geometry comes back exactly", np.array_equal(canvas(ctx), on_lattice), "canvas differs")
        testing.capture(ctx, os.path.join(out, "lattice.png"))  # docs/lattice-editor.png

        # A handle dropped where the block no longer fits: the block shrinks, the origin stays.
        H, W = ed.tool.image().shape[:2]
        vp = imgui.get_main_viewport()
        check("the Lattice window leaves the canvas room", W * ed.tool.zoom <= 0.3 * vp.work_size.x,
              f"image {W} px at {ed.tool.zoom}x in a {vp.work_size.x:.0f} px window")
        r = ctx.item_info("//Lattice/**/lattice-handles").rect_full
        z = ed.tool.zoom
        ctx.mouse_move_to_pos(imgui.ImVec2(r.min.x + lat.origin[0] * z, r.min.y + lat.origin[1] * z))
        ctx.mouse_down(0)
        target = (round(W / 2), round(H - 1.3 * abs(lat.t2[1])))
        ctx.mouse_move_to_pos(imgui.ImVec2(r.min.x + target[0] * z, r.min.y + target[1] * z))
        ctx.yield_(2)
        ctx.mouse_up(0)
        settle(ctx)
        shrunk = ed.doc.lattice
        check("a block that does not fit shrinks instead of refusing", shrunk is not None
              and shrunk.nx * shrunk.ny < lat.nx * lat.ny and abs(shrunk.origin[0] - target[0]) < 1.5
              and abs(shrunk.origin[1] - target[1]) < 1.5 and "cells used" in ed.tool.message,
              f"{shrunk} / {ed.tool.message!r}")
        check("the shrunk block fits", shrunk is not None and shrunk.validate(W, H) is None, str(shrunk))
        check("one undo step for the move", ed.history.undo_label() == "Move lattice origin", ed.history.undo_label())

        def off_handles(points, lattice):
            """The first point farther than 30 screen px from every handle."""
            handles = ed.tool._handles(lattice)
            return next(p for p in points if min(abs(p[0] - hx) + abs(p[1] - hy) for hx, hy in handles) * z > 30)

        def mark(a, w, h):
            """Drag a rectangle w x h image px from a (one cell marked by hand)."""
            ctx.mouse_move_to_pos(imgui.ImVec2(r.min.x + a[0] * z, r.min.y + a[1] * z))
            ctx.mouse_down(0)
            ctx.mouse_move_to_pos(imgui.ImVec2(r.min.x + (a[0] + w) * z, r.min.y + (a[1] + h) * z))
            ctx.yield_(2)
            ctx.mouse_up(0)
            settle(ctx)

        # A rectangle dragged over one cell defines the lattice.
        a = off_handles([(W * f, H * g) for f in (0.1, 0.3, 0.6) for g in (0.1, 0.3)], shrunk)
        mark(a, 30, 24)
        cell = ed.doc.lattice
        check("a rectangle over one cell defines the lattice", cell is not None
              and abs(cell.t1[0] - 30) < 1.0 and cell.t1[1] == 0 and cell.t2[0] == 0 and abs(cell.t2[1] - 24) < 1.0
              and cell.nx * cell.ny >= 4 and ed.history.undo_label() == "Mark lattice cell",
              f"{cell} / {ed.history.undo_label()}")
        check("its cells keep the marked phase", cell is not None
              and abs(((cell.origin[0] - a[0]) / cell.t1[0]) - round((cell.origin[0] - a[0]) / cell.t1[0])) < 0.05
              and abs(((cell.origin[1] - a[1]) / cell.t2[1]) - round((cell.origin[1] - a[1]) / cell.t2[1])) < 0.05,
              str(cell))
        # One brick marked by hand: the rows are staggered (running bond), and the
        # panel offers their offset; one click gives the bricks' own lattice.
        corners = [(lat.origin[0] + i * lat.t1[0] + j * lat.t2[0], lat.origin[1] + j * lat.t2[1])
                   for j in (2, 3, 4) for i in (1, 2, 3)]
        mark(off_handles([p for p in corners if 0 <= p[0] and p[0] + 40 < W and p[1] + 18 < H], cell), 40, 18)
        offer = ed.tool.proposal
        check("a marked brick offers the rows' offset", offer is not None and abs(offer.t2[0] - 20) <= 1.5
              and abs(offer.t2[1] - 18) < 1.0 and "staggered" in ed.tool.message, f"{offer} / {ed.tool.message!r}")
        if offer is not None:
            ctx.item_click(f"//**/Offset the rows by {offer.t2[0]:.0f} px")
            settle(ctx)
        staggered = ed.doc.lattice
        check("one click gives staggered rows, one undo step", staggered is not None
              and abs(staggered.t2[0] - 20) <= 1.5 and ed.history.undo_label() == "Offset lattice rows",
              f"{staggered} / {ed.history.undo_label()}")

        # The Direction tool says before any stroke that it does not go with a lattice, and turns it off in one step.
        ctx.item_click("//**/Direction (D)##tool-direction")
        ctx.yield_(2)
        ctx.set_ref(ctx.window_info("//Infinitex/Panels").window)
        ctx.item_click("Turn the lattice off##direction-lattice-off")
        ctx.set_ref("//Infinitex")
        settle(ctx)
        check("the Direction tool turns the lattice off in one step", ed.tool.name == "direction"
              and ed.doc.lattice is None and ed.history.undo_label() == "Lattice off",
              f"{ed.tool.name} / {ed.doc.lattice} / {ed.history.undo_label()}")
        ctx.key_press(imgui.Key.mod_ctrl | imgui.Key.z)
        settle(ctx)
        check("undo brings the lattice back", ed.doc.lattice == staggered, str(ed.doc.lattice))

        # What the tool said of this document goes with it: another document opens clean.
        ed.tool.message = "a message about this document's lattice"
        ed.history.mark_saved()
        ed.files.open_path(os.path.join(HERE, "infinitex", "assets", "gravel.png"))
        settle(ctx)
        tool = next(t for t in ed.tools if t.name == "lattice")
        check("another document's panel starts without the last one's message",
              ed.doc.exemplar.name == "gravel.png" and tool.message == "" and tool.detection is None,
              f"{ed.doc.exemplar.name} / {tool.message!r}")
        check("no test-engine errors", not ctx.is_error(), "an interaction failed (see the log)")

    return h.run(test)


if __name__ == "__main__":
    sys.exit(main(sys.argv[1]))
