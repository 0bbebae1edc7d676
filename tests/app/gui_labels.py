"""Drive the real editor through texture by numbers (run under Xvfb by
test_editor.py):

    xvfb-run -a python tests/app/gui_labels.py OUT_DIR

An exemplar of two textures (dark on the left, light on the right); the
Labels tool (G): Propose, then Import label map; a label stroke on the canvas
(one undo step, the canvas turns light along it only), a fill of the free
canvas around it, painting the exemplar's own labels in the Labels window;
undo restores the canvas exactly. Writes "ok NAME" / "FAIL NAME: why" lines to
OUT_DIR/report.txt and labels-editor.png.
"""
from __future__ import annotations

import os
import sys

HERE = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
sys.path.insert(0, HERE)

import numpy as np  # noqa: E402
from gui_harness import Harness  # noqa: E402
from imgui_bundle import imgui  # noqa: E402
from imgui_bundle.immapp import testing  # noqa: E402
from PIL import Image  # noqa: E402


def two_textures(out: str) -> tuple[str, str]:
    """The exemplar (dark gravel | light inverted gravel) and its label map (black | green)."""
    g = np.asarray(Image.open(os.path.join(HERE, "infinitex", "assets", "gravel.png")).convert("RGB"))
    img = g // 2
    img[:, 64:] = 150 + (255 - g[:, 64:]) // 3
    ex, lab = os.path.join(out, "two.png"), os.path.join(out, "two_labels.png")
    Image.fromarray(img).save(ex)
    m = np.zeros(g.shape, np.uint8)
    m[:, 64:] = (40, 200, 40)
    Image.fromarray(m).save(lab)
    return ex, lab


def main(out: str) -> int:
    ex, lab_path = two_textures(out)
    h = Harness(out, ex, window_size=(1000, 700))
    ed, check, settle, canvas = h.ed, h.check, h.settle, h.canvas

    def test(ctx) -> None:
        settle(ctx)
        ctx.set_ref("//Infinitex")
        ctx.item_input_value("//**/Structure", 0)  # Variety: a stroke's reach stays small
        settle(ctx)
        before = canvas(ctx)
        ctx.item_click("//**/Labels (G)##tool-labels")
        ctx.yield_(2)
        check("the Labels tool is active", ed.tool.name == "labels", ed.tool.name)
        ctx.item_click("//**/Propose")
        ctx.yield_(2)
        lab = ed.doc.labels
        check("Propose gives the exemplar labels", lab is not None and len(lab.colors) == 3
              and len(lab.exemplar.present) >= 2, str(None if lab is None else lab.exemplar.present))
        check("proposed labels alone change nothing", np.array_equal(canvas(ctx), before), "canvas changed")
        ctx.item_click("//**/Import label map...")
        ctx.yield_(2)
        ctx.item_input_value("//**/##path", lab_path)
        ctx.yield_(3)
        lab = ed.doc.labels
        check("a label map is imported by its colors", lab is not None and lab.colors == ((0, 0, 0), (40, 200, 40))
              and lab.exemplar.values[5, 5] == 0 and lab.exemplar.values[5, 100] == 1,
              str(None if lab is None else lab.colors))

        # A stroke of the light label across the middle: one undo step, the canvas
        # turns light along it, and stays as it was far from it.
        tool = ed.tool
        ctx.set_ref(ctx.window_info("//Infinitex/Panels").window)
        ctx.item_click("label-1/##active")
        ctx.set_ref("//Infinitex")
        check("a label is chosen in the list", tool.active == 1 and not tool.brush.eraser, str(tool.active))
        tool.brush.radius = 20.0
        steps = len(ed.history.undo_stack)
        r = ctx.item_info("//**/canvas").rect_full
        cx, cy = (r.min.x + r.max.x) / 2, (r.min.y + r.max.y) / 2
        sx0, sy = cx - 220, cy - 180  # a short stroke near the top left: room around it
        ctx.mouse_move_to_pos((sx0, sy))
        ctx.mouse_down(0)
        for i in range(1, 7):
            ctx.mouse_move_to_pos((sx0 + 15 * i, sy))
        ctx.mouse_up(0)
        painted = canvas(ctx)
        check("a label stroke is one undo step", len(ed.history.undo_stack) == steps + 1,
              f"{len(ed.history.undo_stack) - steps} steps")
        check("the stroke is in the document", not ed.doc.labels.canvas.empty, "no canvas labels")
        H, W = painted.shape[:2]
        bx0, bx1 = int(sx0 - r.min.x), int(sx0 + 90 - r.min.x)  # the stroke's centre line, canvas pixels
        by = int(sy - r.min.y)
        light_share = float((painted[by - 8:by + 8, bx0:bx1, 0] > 140).mean())
        check("the canvas follows the label along the stroke", light_share > 0.9, f"light {light_share:.2f}")
        changed = np.any(painted != before, axis=-1)
        ys, xs = np.nonzero(changed)
        far = 200  # the reach of correction through the coarse levels stays inside this (as gui_driver's paint)
        check("the canvas changes near the stroke only", len(xs) > 50 and xs.max() < bx1 + 20 + far
              and ys.max() < by + 20 + far, f"changed up to x {xs.max() if len(xs) else None}, "
              f"y {ys.max() if len(ys) else None}; stroke x {bx0}..{bx1}, y {by}")
        testing.capture(ctx, os.path.join(out, "labels-editor.png"))

        # Fill the free canvas around the stroke (within the view) with the dark label.
        ctx.set_ref(ctx.window_info("//Infinitex/Panels").window)
        ctx.item_click("label-0/##active")
        ctx.item_click("Fill##labels-mode")
        ctx.set_ref("//Infinitex")
        ctx.mouse_move_to_pos((cx, cy + 120))
        ctx.mouse_click(0)
        filled = canvas(ctx)
        dark = float((filled[H // 2:, :, 0] < 110).mean())
        check("a fill gives the free region its label", dark > 0.9 and ed.doc.labels.canvas.sample(
            np.array([int(ed.view.x)]), np.array([int(ed.view.y + 120)]))[0, 0] == 1, f"dark {dark:.2f}")
        check("the filled canvas keeps the stroke", float((filled[by - 8:by + 8, bx0:bx1, 0] > 140).mean()) > 0.9,
              "stroke lost")

        # A label image placed centered in the view: its transparent pixels leave the canvas as it is.
        img = np.zeros((40, 60, 4), np.uint8)
        img[10:30, 10:50] = (40, 200, 40, 255)
        Image.fromarray(img).save(os.path.join(out, "place.png"))
        ctx.set_ref(ctx.window_info("//Infinitex/Panels").window)
        ctx.item_click("Place label image...")
        ctx.set_ref("//Infinitex")
        ctx.yield_(2)
        ctx.item_input_value("//**/##path", os.path.join(out, "place.png"))
        ctx.yield_(3)
        vx, vy = int(ed.view.x), int(ed.view.y)
        got = ed.doc.labels.canvas.sample(np.array([vx, vx - 25]), np.array([vy, vy - 15]))
        check("a label image is placed in the view", got[0, 0] == 2 and got[1, 1] == 1, str(got.tolist()))

        # The exemplar's own labels, painted in the Labels window: the whole canvas may change.
        ctx.set_ref(ctx.window_info("//Infinitex/Panels").window)
        ctx.item_click("label-1/##active")
        ctx.item_click("Exemplar##labels-mode")
        ctx.set_ref("//Infinitex")
        ctx.yield_(2)
        er = ctx.item_info("//Labels/**/labels-paint").rect_full
        z = tool.zoom
        old = ed.doc.labels.exemplar
        ctx.mouse_move_to_pos((er.min.x + 20 * z, er.min.y + 20 * z))
        ctx.mouse_down(0)
        ctx.mouse_move_to_pos((er.min.x + 30 * z, er.min.y + 30 * z))
        ctx.mouse_up(0)
        new = ed.doc.labels.exemplar
        check("painting the exemplar's labels", new != old and new.values[25, 25] == 1
              and int((new.values != old.values).sum()) > 50, str(int((new.values != old.values).sum())))
        for _ in range(5):  # exemplar paint, placed image, fill, stroke, import (Propose stays)
            ctx.key_press(imgui.Key.mod_ctrl | imgui.Key.z)
        ctx.key_press(imgui.Key.mod_ctrl | imgui.Key.z)  # Propose
        check("undo restores the canvas exactly", np.array_equal(canvas(ctx), before), "canvas differs")
        check("undo removes the labels", ed.doc.labels is None, "labels left")

        # A palette: another exemplar added in the Exemplar panel becomes label 2; removing it, then undo.
        first = ed.doc
        ctx.set_ref(ctx.window_info("//Infinitex/Panels").window)
        ctx.item_click("Add to palette...")
        ctx.set_ref("//Infinitex")
        ctx.yield_(2)
        ctx.item_input_value("//**/##path", os.path.join(HERE, "infinitex", "assets", "gravel.png"))
        ctx.yield_(3)
        settle(ctx)
        doc = ed.doc
        check("Add to palette makes each exemplar a label", len(doc.entries()) == 2 and doc.labels is not None
              and doc.labels.names == ("two.png", "gravel.png") and ed.session.analysis.size == 256,
              f"{len(doc.entries())} {None if doc.labels is None else doc.labels.names}")
        ctx.set_ref(ctx.window_info("//Infinitex/Panels").window)
        ctx.item_click("**/x##palette-remove-1")
        ctx.set_ref("//Infinitex")
        settle(ctx)
        check("removing it leaves one exemplar", not ed.doc.palette and ed.doc.labels is None, str(ed.doc.palette))
        ctx.key_press(imgui.Key.mod_ctrl | imgui.Key.z)
        settle(ctx)
        check("undo brings the palette back", len(ed.doc.entries()) == 2, str(len(ed.doc.entries())))
        ctx.key_press(imgui.Key.mod_ctrl | imgui.Key.z)
        settle(ctx)
        check("undo once more: the document as it was", ed.doc == first and np.array_equal(canvas(ctx), before),
              "differs")

    return h.run(test)


if __name__ == "__main__":
    sys.exit(main(sys.argv[1]))
