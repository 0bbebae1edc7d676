"""Drive the real editor with the imgui test engine (run under Xvfb by test_editor.py).

    xvfb-run -a python tests/app/gui_driver.py OUT_DIR

Each check writes a line "ok NAME" or "FAIL NAME: why" to OUT_DIR/report.txt;
the canvas is read back exactly (RGB) by the editor itself on request.
"""
from __future__ import annotations

import os
import sys

import numpy as np

HERE = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
sys.path.insert(0, HERE)

from imgui_bundle import imgui
from imgui_bundle.immapp import testing

from gui_harness import Harness

from infinitex.engine.params import DEFAULT_STRUCTURE


def main(out: str) -> int:
    h = Harness(out, window_size=(1000, 700))
    ed, check, settle, canvas, wait = h.ed, h.check, h.settle, h.canvas, h.wait

    def test(ctx) -> None:
        settle(ctx)
        a = canvas(ctx)
        check("canvas shows texture", a.std() > 5, f"std {a.std():.2f}")

        # A randomness slider changes the canvas; undo restores it exactly.
        L = ed.session.L
        ctx.item_input_value(f"//**/16 px##jit{L - 4}", 0.1)
        b = canvas(ctx)
        check("slider edits the document", abs(ed.doc.jitter_for(L)[L - 4] - 0.1) < 1e-6,
              str(ed.doc.jitter_for(L)))
        check("slider changes the canvas", not np.array_equal(a, b), "identical canvas")
        ctx.key_press(imgui.Key.mod_ctrl | imgui.Key.z)
        c = canvas(ctx)
        check("undo restores the canvas exactly", np.array_equal(a, c), "canvas differs after undo")
        ctx.key_press(imgui.Key.mod_ctrl | imgui.Key.mod_shift | imgui.Key.z)
        d = canvas(ctx)
        check("redo brings the edit back", np.array_equal(b, d), "canvas differs after redo")

        # Pan by dragging with the right button, zoom with the wheel.
        v0 = ed.view
        r = ctx.item_info("//**/canvas").rect_full
        cx, cy = (r.min.x + r.max.x) / 2, (r.min.y + r.max.y) / 2
        ctx.mouse_move_to_pos((cx, cy))
        ctx.mouse_down(1)
        ctx.mouse_move_to_pos((cx + 120, cy + 80))
        ctx.mouse_up(1)
        check("right-drag pans", (ed.view.x, ed.view.y) != (v0.x, v0.y), f"{v0} -> {ed.view}")
        e = canvas(ctx)
        check("panned canvas differs", not np.array_equal(d, e), "same canvas after pan")
        ctx.mouse_move_to_pos((cx, cy))
        ctx.mouse_wheel_y(-4)
        settle(ctx)
        check("wheel zooms out", ed.view.zoom < 1.0, f"zoom {ed.view.zoom}")
        ctx.mouse_wheel_y(4)
        settle(ctx)
        check("wheel zooms back", abs(ed.view.zoom - 1.0) < 1e-9, f"zoom {ed.view.zoom}")

        # The Structure slider: Variety (the per-pixel synthesis alone) is another
        # texture, one undo step. The painting below runs at Variety, whose reach
        # is small (the fidelity stage carries a change much further).
        before_structure, steps = canvas(ctx), len(ed.history.undo_stack)
        check("documents start at the default Structure", ed.doc.structure == DEFAULT_STRUCTURE, str(ed.doc.structure))
        ctx.item_input_value("//**/Structure", 0)
        settle(ctx)
        check("the Structure slider edits the document", ed.doc.structure == 0, str(ed.doc.structure))
        check("Structure is one undo step", len(ed.history.undo_stack) == steps + 1,
              f"{len(ed.history.undo_stack) - steps} steps")
        check("Structure changes the canvas", not np.array_equal(before_structure, canvas(ctx)), "same canvas")

        # Paint randomness on the canvas: one stroke changes the canvas near the
        # stroke only, is one undo step, and undo restores the canvas exactly.
        before_paint = canvas(ctx)
        steps_before = len(ed.history.undo_stack)
        ctx.set_ref("//Infinitex")
        ctx.item_click("//**/Paint canvas (B)##tool-paint-canvas")
        tool = ed.tool
        tool.brush.value, tool.brush.radius, tool.brush.strength = 2.0, 30.0, 1.0
        r = ctx.item_info("//**/canvas").rect_full
        cx, cy = (r.min.x + r.max.x) / 2, (r.min.y + r.max.y) / 2
        ctx.mouse_move_to_pos((cx - 60, cy))
        ctx.mouse_down(0)
        for i in range(1, 7):
            ctx.mouse_move_to_pos((cx - 60 + 20 * i, cy + 5 * i))
        ctx.mouse_up(0)
        painted = canvas(ctx)
        check("paint tool is active", ed.tool.name == "paint-canvas", ed.tool.name)
        check("a stroke is one undo step", len(ed.history.undo_stack) == steps_before + 1,
              f"{len(ed.history.undo_stack) - steps_before} steps")
        diff = np.any(painted != before_paint, axis=-1)
        ys, xs = np.nonzero(diff)
        check("a stroke changes the canvas", diff.sum() > 100, f"{diff.sum()} pixels")
        # Canvas-local stroke box (the canvas image starts at the item's top-left).
        sx0, sx1 = cx - 60 - r.min.x - 30, cx + 60 - r.min.x + 30
        sy0, sy1 = cy - r.min.y - 30, cy + 30 - r.min.y + 30
        far = 200  # the reach of correction through the coarse levels stays well inside this
        check("only near the stroke", len(xs) > 0 and xs.min() > sx0 - far and xs.max() < sx1 + far
              and ys.min() > sy0 - far and ys.max() < sy1 + far,
              f"changed x {xs.min() if len(xs) else None}..{xs.max() if len(xs) else None}, stroke {sx0:.0f}..{sx1:.0f}")
        check("the canvas field holds the paint", ed.doc.randomness_canvas is not None, "no field")
        testing.capture(ctx, os.path.join(out, "painted.png"))
        ctx.key_press(imgui.Key.mod_ctrl | imgui.Key.z)
        check("undo removes the stroke exactly", np.array_equal(canvas(ctx), before_paint), "canvas differs")
        ctx.key_press(imgui.Key.mod_ctrl | imgui.Key.mod_shift | imgui.Key.z)
        check("redo repaints it exactly", np.array_equal(canvas(ctx), painted), "canvas differs")
        # Paint on the exemplar, in its window: the exemplar field changes, one undo step.
        ctx.item_click("//**/Paint exemplar (E)##tool-paint-exemplar")
        ctx.yield_(3)
        ed.tool.brush.value, ed.tool.brush.radius = 0.0, 10.0
        steps_before = len(ed.history.undo_stack)
        ctx.set_ref("//Paint exemplar")
        er = ctx.item_info("//**/exemplar-paint").rect_full
        ctx.mouse_move_to_pos((er.min.x + 20, er.min.y + 20))
        ctx.mouse_down(0)
        ctx.mouse_move_to_pos((er.min.x + 80, er.min.y + 60))
        ctx.mouse_up(0)
        ctx.yield_(2)
        f = ed.doc.randomness_exemplar
        check("exemplar stroke paints the exemplar field", f is not None and int(f.values.min()) < 32768,
              "no exemplar field")
        check("exemplar stroke is one undo step", len(ed.history.undo_stack) == steps_before + 1,
              f"{len(ed.history.undo_stack) - steps_before} steps")
        ctx.key_press(imgui.Key.mod_ctrl | imgui.Key.z)
        ctx.yield_(2)
        check("undo removes the exemplar stroke", ed.doc.randomness_exemplar is None, "still painted")
        # Avoid mode: a stroke marks exemplar regions the synthesis no longer copies; one undo step.
        ctx.set_ref("//Infinitex")
        ctx.item_click("//**/Avoid##paint-mode")
        ctx.yield_(2)
        ed.tool.brush.radius, ed.tool.brush.eraser = 12.0, False
        steps_before = len(ed.history.undo_stack)
        before_avoid = canvas(ctx)
        ctx.set_ref("//Paint exemplar")
        er = ctx.item_info("//**/exemplar-paint").rect_full
        zoom = ed.tool.zoom
        ctx.mouse_move_to_pos((er.min.x + 58 * zoom, er.min.y + 12 * zoom))  # over gravel's crevice
        ctx.mouse_down(0)
        ctx.mouse_move_to_pos((er.min.x + 74 * zoom, er.min.y + 30 * zoom))
        ctx.mouse_up(0)
        settle(ctx)
        mask = ed.doc.avoid_exemplar
        check("an avoid stroke marks the exemplar", mask is not None and 0.02 < mask.fraction < 0.5,
              "no mask" if mask is None else f"{mask.fraction}")
        check("the avoid stroke is one undo step", len(ed.history.undo_stack) == steps_before + 1,
              f"{len(ed.history.undo_stack) - steps_before} steps")
        testing.capture(ctx, os.path.join(out, "avoid.png"))
        check("the canvas follows the avoided regions", ed.session.controls.avoid == mask
              and not np.array_equal(canvas(ctx), before_avoid), "canvas unchanged")
        ctx.key_press(imgui.Key.mod_ctrl | imgui.Key.z)
        settle(ctx)
        check("undo removes the avoided regions exactly", ed.doc.avoid_exemplar is None
              and ed.session.controls.avoid is None and np.array_equal(canvas(ctx), before_avoid), "differs")
        ctx.set_ref("//Infinitex")
        ctx.item_click("//**/Randomness##paint-mode")
        ctx.set_ref("//Infinitex")
        ctx.item_click("//**/Navigate (N)##tool-navigate")

        # Drag a feature from the exemplar panel onto the canvas: placed where it
        # was dropped, the canvas shows it, undo removes it exactly.
        before_feature = canvas(ctx)
        n_before = len(ed.doc.features)
        ctx.set_ref("//Infinitex")
        ctx.item_drag_and_drop("//**/exemplar-thumb", "//**/canvas")
        after_feature = canvas(ctx)
        feats = ed.doc.features
        r = ctx.item_info("//**/canvas").rect_full
        check("a dropped feature is placed", len(feats) == n_before + 1, f"{len(feats)} features")
        if len(feats) == n_before + 1:
            f = feats[-1]
            cx, cy = (r.min.x + r.max.x) / 2 - r.min.x, (r.min.y + r.max.y) / 2 - r.min.y
            x0, y0 = ed.view.top_left(*ed.canvas_size)
            want = (x0 + cx / ed.view.zoom, y0 + cy / ed.view.zoom)
            check("at the drop point", abs(f.canvas[0] - want[0]) <= 2 and abs(f.canvas[1] - want[1]) <= 2,
                  f"{f.canvas} vs {want}")
            m = ed.session.analysis.size
            check("of the exemplar point under the mouse", abs(f.exemplar[0] - m // 2) <= 2
                  and abs(f.exemplar[1] - m // 2) <= 2, f"{f.exemplar}")
            diff = np.any(after_feature != before_feature, axis=-1)
            ys, xs = np.nonzero(diff)
            check("the canvas shows the feature there", diff.sum() > 200 and abs(np.median(xs) - cx) < 60
                  and abs(np.median(ys) - cy) < 60, f"{diff.sum()} px changed")
        ctx.key_press(imgui.Key.mod_ctrl | imgui.Key.z)
        check("undo removes the feature exactly", len(ed.doc.features) == n_before
              and np.array_equal(canvas(ctx), before_feature), "canvas differs")
        ctx.item_click("//**/Navigate (N)##tool-navigate")

        # Save, change things, reopen: the canvas is identical to the saved one.
        saved_view = ed.view
        f = canvas(ctx)
        path = os.path.join(out, "project.itex")
        ctx.set_ref("//Infinitex")
        ctx.menu_click("File/Save As...")
        ctx.yield_(2)
        ctx.item_input_value("//**/##path", path)  # typed, then Enter: the prompt closes
        ctx.yield_(2)
        check("save writes the project", os.path.isfile(path), "no file")
        check("save clears the dirty flag", not ed.history.dirty, "still dirty")
        ctx.item_click("//**/New seed")
        g = canvas(ctx)
        check("new seed changes the canvas", not np.array_equal(f, g), "same canvas")
        ed.history.mark_saved()  # so reopening does not ask to discard
        ctx.set_ref("//Infinitex")
        ctx.menu_click("File/Open...")
        ctx.yield_(2)
        ctx.item_input_value("//**/##path", path)  # typed, then Enter: the prompt closes
        ctx.yield_(2)
        h = canvas(ctx)
        check("reopened view", ed.view == saved_view, f"{ed.view} vs {saved_view}")
        check("reopened canvas is identical", np.array_equal(f, h), "canvas differs after reopening")

        # Export a toroidal tile through the Export panel, with its coordinate map.
        ed.exports.settings.tile_size = 64
        ed.exports.settings.write_coords = True
        ctx.set_ref("//Infinitex")
        ctx.menu_click("File/Export toroidal tile...")
        ctx.yield_(2)
        # Its size first (the tile size set above), then the file.
        check("the tile's size is asked first", ctx.window_info("//Export toroidal tile###tileprompt").window
              is not None and ed.dialogs.path_request is None, "no size window")
        ctx.item_click("//Export toroidal tile###tileprompt/Choose file...")
        ctx.yield_(2)
        tile_path = os.path.join(out, "tile.png")
        ctx.item_input_value("//**/##path", tile_path)
        wait(ctx, lambda: ed.exports.job is None, 180)  # an export in a process of its own
        ctx.yield_(3)
        ok = os.path.isfile(tile_path) and os.path.isfile(os.path.join(out, "tile_coords.png"))
        check("toroidal tile exported", ok, "missing files")
        if ok:
            from PIL import Image

            from infinitex.export import decode_coords
            coords = decode_coords(np.asarray(Image.open(os.path.join(out, "tile_coords.png"))))
            check("tile coordinates are exemplar positions", coords.shape == (64, 64, 2)
                  and coords.min() >= 0 and coords.max() < ed.session.analysis.size, str(coords.shape))
        check("export window closed", not ed.panels._export_popup, "still open")

        # A broken file gives a message and changes nothing.
        bad = os.path.join(out, "broken.itex")
        with open(bad, "w") as fh:
            fh.write("{ not json")
        before = ed.doc
        ed.files.open_path(bad)
        ctx.yield_(3)
        check("broken project leaves the document", ed.doc is before, "document changed")
        check("broken project shows a message", any("not an Infinitex project" in m.body
                                                    for m in ed.dialogs.modals), "no message")
        ctx.item_click("//**/OK")

        # A project whose exemplar file is outside its folder: asked first.
        import json

        from infinitex.project import Document, ExemplarSource, Project, project_to_json
        gravel = os.path.join(HERE, "infinitex", "assets", "gravel.png")
        os.makedirs(os.path.join(out, "sub"), exist_ok=True)
        outside = os.path.join(out, "sub", "outside.itex")
        d = project_to_json(Project(Document(ExemplarSource.from_file(gravel), seed=77)), embed=False)
        with open(outside, "w") as fh:
            json.dump(d, fh)
        before = ed.doc
        ed.files.open_path(outside)
        ctx.yield_(3)
        check("outside exemplar asks first", any("outside the project's folder" in m.body
                                                 for m in ed.dialogs.modals), "no question")
        ctx.item_click("//**/Cancel")
        ctx.yield_(3)
        check("cancel leaves the document", ed.doc is before and not ed.dialogs.modals, "document changed")
        ed.files.open_path(outside)
        ctx.yield_(3)
        ctx.item_click("//**/Read it")
        settle(ctx)
        check("read it opens the project", ed.doc.seed == 77 and ed.files.project_path == outside,
              f"seed {ed.doc.seed}, path {ed.files.project_path}")

        # Quitting with unsaved edits asks; Cancel keeps the editor running.
        ctx.item_click("//**/New seed")
        ctx.yield_(2)
        ctx.key_press(imgui.Key.mod_ctrl | imgui.Key.q)
        ctx.yield_(3)
        check("quit with unsaved edits asks", any("unsaved" in m.body for m in ed.dialogs.modals), "no question")
        ctx.item_click("//**/Cancel")
        ctx.yield_(3)
        check("cancel keeps the editor", not ed.files.quit_requested and not ed.dialogs.modals, "quitting")
        check("no test-engine errors", not ctx.is_error(), "an interaction failed (see the log)")
        testing.capture(ctx, os.path.join(out, "final.png"))

    return h.run(test)


if __name__ == "__main__":
    sys.exit(main(sys.argv[1]))
