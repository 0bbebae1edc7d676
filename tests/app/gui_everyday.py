"""Drive the real editor through what a user meets in the first minutes
(run under Xvfb by test_editor.py):

    xvfb-run -a python tests/app/gui_everyday.py OUT_DIR

Advanced collapsed on start and its controls explained on hover; the zoom
keys; the shortcuts window; Open Recent; opening an image makes a new
document; Make tileable offered for a photo that does not tile; the title names the document and its unsaved state; an export
says where it wrote; Save offered before unsaved edits are lost. Writes
"ok NAME" / "FAIL NAME: why" lines to OUT_DIR/report.txt.
"""
from __future__ import annotations

import os
import sys

HERE = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
sys.path.insert(0, HERE)

from imgui_bundle import imgui
from imgui_bundle.immapp import testing

from infinitex.app.ui import panels
from gui_harness import Harness

GRAVEL = os.path.join(HERE, "infinitex", "assets", "gravel.png")
BRICK = os.path.join(HERE, "infinitex", "assets", "brick.png")


def main(out: str) -> int:
    h = Harness(out)
    ed, check, settle, canvas, wait = h.ed, h.check, h.settle, h.canvas, h.wait

    def test(ctx) -> None:
        settle(ctx)
        ctx.set_ref("//Infinitex")
        check("advanced collapsed on start", not ctx.item_exists("**/Correction passes")
              and ctx.item_exists("**/All levels"), "synthesis internals shown")
        ctx.mouse_move("**/All levels")
        ctx.yield_(40)
        check("a tooltip explains the randomness", "every scale" in panels.LAST_TIP[0], panels.LAST_TIP[0])
        # Dragging the slider hides its tooltip (it would cover the canvas being tuned).
        from infinitex.app.ui.panels import widgets
        ctx.mouse_down(0)
        at = imgui.get_io().mouse_pos
        ctx.mouse_move_to_pos(imgui.ImVec2(at.x + 30, at.y))  # along the slider, still over it
        ctx.yield_(40)
        shown_while_dragging = widgets.TIP_FRAME[0] >= imgui.get_frame_count() - 2
        ctx.mouse_up(0)
        ed.files.undo()
        ctx.yield_(2)
        check("no tooltip while a slider is dragged", not shown_while_dragging, "the tooltip stayed")
        for header in ("Randomness", "Exemplar", "Display"):  # make room: Advanced is the last section
            ctx.item_close(f"**/{header}")
        ctx.item_open("**/Advanced")
        ctx.yield_(2)
        check("advanced opens", ctx.item_exists("**/Correction passes"), "no Correction passes")
        ctx.mouse_move("**/Coherence")
        ctx.yield_(40)
        check("advanced controls say what they do", "(coherence kappa, LH05)" in panels.LAST_TIP[0],
              panels.LAST_TIP[0])
        # Passes per scale: one slider per level; a drag is one undo step, the synthesis follows.
        ctx.item_open("**/Passes per scale")
        ctx.yield_(2)
        L = ed.session.L
        fine = f"**/1 px##pass{L}"
        check("passes per scale shown", ctx.item_exists(fine) and ed.doc.passes_for(L)[L] == 2,
              f"{ed.doc.passes_for(L)}")
        ctx.item_input_value(fine, 3)
        settle(ctx)
        testing.capture(ctx, os.path.join(out, "passes.png"))
        check("a scale's passes reach the synthesis", ed.doc.passes_for(L)[L] == 3
              and ed.session.params.passes_at(L) == 3 and ed.session.params.passes_at(L - 1) == 2,
              f"{ed.doc.level_passes} {ed.session.params}")
        ed.files.undo()
        settle(ctx)
        check("undo restores the passes", ed.doc.level_passes == () and ed.session.params.level_passes is None,
              f"{ed.doc.level_passes}")
        ctx.item_close("**/Passes per scale")
        ctx.item_close("**/Advanced")
        for header in ("Randomness", "Exemplar", "Display"):
            ctx.item_open(f"**/{header}")

        # Zoom keys (the mouse over the canvas, nothing being edited).
        ctx.mouse_move("**/canvas")
        z0 = ed.view.zoom
        ctx.key_press(imgui.Key.equal)
        ctx.yield_(2)
        z_in = ed.view.zoom
        ctx.key_press(imgui.Key.minus)
        ctx.key_press(imgui.Key.minus)
        ctx.yield_(2)
        z_out = ed.view.zoom
        ctx.key_press(imgui.Key._1)
        ctx.yield_(2)
        check("+ zooms in, - out, 1 is actual size", abs(z_in - 2 * z0) < 1e-9 and abs(z_out - z0 / 2) < 1e-9
              and ed.view.zoom == 1.0, f"{z0} {z_in} {z_out} {ed.view.zoom}")
        ctx.key_press(imgui.Key._0)
        ctx.yield_(2)
        w, h = ed.canvas_size
        check("0 fits one exemplar across the canvas", ed.session.analysis.size * ed.view.zoom <= min(w, h)
              < 2 * ed.session.analysis.size * ed.view.zoom, f"zoom {ed.view.zoom}")
        ctx.key_press(imgui.Key._1)
        ctx.key_press(imgui.Key.f1)
        ctx.yield_(2)
        check("F1 shows the shortcuts", ed.shortcuts.listed and ctx.window_info("//Shortcuts (F1)").window is not None,
              "no window")
        ctx.key_press(imgui.Key.f1)
        ctx.yield_(2)
        check("F1 hides them again", not ed.shortcuts.listed, "still shown")

        # Without a native chooser, File > Open is the in-window file browser (browser.py).
        ed.dialogs.prompt = False
        ctx.set_ref("//Infinitex")
        ctx.menu_click("File/Open...")
        ctx.yield_(3)
        check("the in-window file browser opens", ctx.window_info("//Open exemplar or project###infinitex-path")
              .window is not None and ed.dialogs.path_request is not None and ed.dialogs.path_request.browser,
              "no browser window")
        ctx.item_click("//Open exemplar or project###infinitex-path/Cancel")
        ctx.yield_(3)
        check("cancel closes it and changes nothing", ed.dialogs.path_request is None
              and ed.doc.exemplar.name == "gravel.png", "still open")
        ctx.menu_click("File/Save As...")
        ctx.yield_(3)
        req = ed.dialogs.path_request
        br = req.browser if req is not None else None
        check("Save As proposes a file name in the start folder", br is not None and br.name == "untitled.itex"
              and br.folder == ed.dialogs.start_dir(), f"{br and (br.name, br.folder)}")
        check("the chooser lists no size for folders", br is not None and all(
            e.size == 0 for e in br.listing() if e.is_dir), "a folder with a size")
        ctx.key_press(imgui.Key.escape)
        ctx.yield_(3)
        check("Escape cancels the chooser", ed.dialogs.path_request is None, "still open")
        ed.dialogs.prompt = True

        # Tile mode: the canvas shows the periodic texture of the tile size (T toggles it).
        import numpy as np
        ed.exports.settings.tile_size = 64
        ctx.mouse_move("**/canvas")
        ctx.key_press(imgui.Key.t)
        a = canvas(ctx)
        check("tile mode shows the periodic texture", ed.viewer.tile_mode and ed.session.params.period == 64
              and np.array_equal(a[:, :-64], a[:, 64:]) and np.array_equal(a[:-64], a[64:]), "not periodic")
        ctx.key_press(imgui.Key.t)
        b = canvas(ctx)
        check("T turns tile mode off", not ed.viewer.tile_mode and ed.session.params.period == 0
              and not np.array_equal(b[:, :-64], b[:, 64:]), "still periodic")

        # The title names the document and its unsaved state.
        check("title of a new document", ed.files.title == "untitled (gravel.png) - Infinitex", ed.files.title)
        ctx.set_ref("//Infinitex")
        ctx.item_click("**/New seed")
        ctx.yield_(2)
        check("title marks unsaved edits", ed.files.title.startswith("*untitled"), ed.files.title)

        # Opening an image with unsaved edits asks, offering Save; Discard opens it as a new document.
        ed.files.confirm_discard(lambda: ed.files.open_path(BRICK))
        ctx.yield_(3)
        modal = ed.dialogs.modals[0] if ed.dialogs.modals else None
        check("unsaved edits: Save offered", modal is not None and [b for b, _ in modal.buttons] ==
              ["Save", "Discard", "Cancel"], str(modal and modal.buttons))
        ctx.item_click("//**/Discard")
        settle(ctx)
        check("an image opens as a new document", ed.doc.exemplar.name == "brick.png" and ed.files.project_path is None
              and not ed.history.can_undo() and not ed.history.dirty, f"{ed.doc.exemplar.name} {ed.files.project_path}")
        check("open recent lists it", ed.prefs.settings.recent and ed.prefs.settings.recent[0] == os.path.abspath(BRICK),
              str(ed.prefs.settings.recent))
        # The brick photo does not tile: Make tileable is offered; it is one undo step.
        ctx.set_ref("//Infinitex")
        check("make tileable offered", ctx.item_exists("**/Make tileable") and not ed.session.exemplar.toroidal,
              f"toroidal {ed.session.exemplar.toroidal}")
        ctx.item_click("**/Make tileable")
        settle(ctx)
        check("make tileable reaches the synthesis", ed.doc.make_tileable and ed.session.exemplar.toroidal
              and ed.session.analysis.toroidal, f"{ed.doc.make_tileable} {ed.session.exemplar.toroidal}")
        ed.files.undo()
        settle(ctx)
        check("undo turns it off", not ed.doc.make_tileable and not ed.session.exemplar.toroidal,
              f"{ed.doc.make_tileable}")
        ed.files.open_path(GRAVEL)
        settle(ctx)
        ctx.set_ref("//Infinitex")
        ctx.menu_click("File/Open Recent/brick.png##recent1")
        settle(ctx)
        check("File > Open Recent reopens it", ed.doc.exemplar.name == "brick.png"
              and ed.prefs.settings.recent[:2] == (os.path.abspath(BRICK), os.path.abspath(GRAVEL)), str(ed.prefs.settings.recent))

        # Save as a project, then the title is its name; an export says where it went.
        proj = os.path.join(out, "bricks.itex")
        ctx.set_ref("//Infinitex")
        ctx.menu_click("File/Save As...")
        ctx.yield_(2)
        ctx.item_input_value("//**/##path", proj)
        ctx.yield_(2)
        check("saved title", ed.files.title == "bricks.itex - Infinitex", ed.files.title)
        check("a saved project is recent too", ed.prefs.settings.recent[0] == os.path.abspath(proj), str(ed.prefs.settings.recent))
        target = os.path.join(out, "view.png")
        ctx.set_ref("//Infinitex")
        ctx.menu_click("File/Export view as PNG...")
        ctx.yield_(2)
        ctx.item_input_value("//**/##path", target)
        wait(ctx, lambda: ed.exports.job is None, 180)  # an export in a process of its own
        ctx.yield_(2)
        check("an export says where it wrote", ed.notice is not None and os.path.abspath(target) in ed.notice[0]
              and os.path.isfile(target), str(ed.notice))
        testing.capture(ctx, os.path.join(out, "everyday.png"))

    return h.run(test)


if __name__ == "__main__":
    sys.exit(main(sys.argv[1]))
