"""Drive the real editor through the Direction tool (run under Xvfb by
test_editor.py):

    xvfb-run -a python tests/app/gui_direction.py OUT_DIR

The bundled brick exemplar (its bricks stand upright): a comb stroke across
the canvas (one undo step; the field is painted along it; the canvas changes
near the stroke only and its bricks there lie along the stroke), a Grow
stroke, a guide (points clicked, Enter applies it), a placed flow map; the
overlay (H) draws; undo restores the canvas exactly. Writes "ok NAME" /
"FAIL NAME: why" lines to OUT_DIR/report.txt and direction-editor.png.
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

from infinitex.engine.controls.direction import MAX_STRETCH, decompose  # noqa: E402


def orientation(gray: np.ndarray) -> float:
    """The dominant orientation of the edges' normals... as the structure tensor's
    main direction of gradients, degrees in [0, 180): 0 = the intensity changes
    along x (vertical stripes)."""
    g = gray.astype(np.float64)
    gx = np.diff(g, axis=1)[:-1, :]
    gy = np.diff(g, axis=0)[:, :-1]
    jxx, jyy, jxy = (gx * gx).sum(), (gy * gy).sum(), (gx * gy).sum()
    return float(np.degrees(0.5 * np.arctan2(2 * jxy, jxx - jyy)) % 180.0)


def main(out: str) -> int:
    brick = os.path.join(HERE, "infinitex", "assets", "brick.png")
    h = Harness(out, brick, window_size=(1000, 700))
    ed, check, settle, canvas = h.ed, h.check, h.settle, h.canvas

    def test(ctx) -> None:
        settle(ctx)
        ctx.set_ref("//Infinitex")
        ctx.item_input_value("//**/Structure", 0)  # Variety: a stroke's reach stays small
        settle(ctx)
        before = canvas(ctx)
        ctx.item_click("//**/Direction (D)##tool-direction")
        ctx.yield_(2)
        check("the Direction tool is active", ed.tool.name == "direction", ed.tool.name)
        tool = ed.tool
        tool.brush.radius = 36.0
        tool.brush.strength = 1.0
        tool.brush.hardness = 0.8
        steps = len(ed.history.undo_stack)
        r = ctx.item_info("//**/canvas").rect_full
        cx, cy = (r.min.x + r.max.x) / 2, (r.min.y + r.max.y) / 2
        # A comb stroke going down the screen on the left: the exemplar's x runs down,
        # so its upright bricks lie across it (courses running down the screen... rotated 90 degrees).
        sx, sy0 = r.min.x + 170, r.min.y + 120
        ctx.mouse_move_to_pos((sx, sy0))
        ctx.mouse_down(0)
        for i in range(1, 13):
            ctx.mouse_move_to_pos((sx, sy0 + 20 * i))
        ctx.mouse_up(0)
        settle(ctx)
        combed = canvas(ctx)
        check("a comb stroke is one undo step", len(ed.history.undo_stack) == steps + 1,
              f"{len(ed.history.undo_stack) - steps} steps")
        f = ed.doc.direction
        check("the stroke is in the document", f is not None and not f.identity, "no field")
        px = int(ed.view.top_left(*ed.canvas_size)[0] + (sx - r.min.x) / ed.view.zoom)
        py = int(ed.view.top_left(*ed.canvas_size)[1] + (sy0 + 120 - r.min.y) / ed.view.zoom)
        th = float(decompose(f.dense(px, py, 1, 1))[0][0, 0]) if f is not None else 0.0
        check("the field runs along the stroke", abs(th - 90.0) < 5.0, f"{th:.1f} degrees")
        # The bricks turn: in the exemplar the mortar's gradients mostly change along x
        # (upright bricks); under the stroke, x runs down the screen, so along y.
        bx, by = int(sx - r.min.x), int(sy0 + 120 - r.min.y)
        g0 = before[by - 40:by + 40, bx - 24:bx + 24, 0]
        g1 = combed[by - 40:by + 40, bx - 24:bx + 24, 0]
        o0, o1 = orientation(g0), orientation(g1)
        turned = min(abs(o1 - o0 - 90) % 180, abs(o1 - o0 + 90) % 180)
        check("the bricks turn with the stroke", turned < 30.0, f"orientation {o0:.0f} -> {o1:.0f}")
        changed = np.any(combed != before, axis=-1)
        ys, xs = np.nonzero(changed)
        # The reach of correction through the coarse levels stays inside this (as
        # gui_labels; a coarse texel whose mean J the stroke turns also turns its jitter).
        far = 256
        check("the canvas changes near the stroke only", len(xs) > 500 and xs.max() < bx + 40 + far,
              f"changed up to x {xs.max() if len(xs) else None}; stroke x {bx}")

        # Grow, a guide and a placed flow map: one undo step each.
        ctx.set_ref(ctx.window_info("//Infinitex/Panels").window)
        ctx.item_click("Grow##direction-mode")
        ctx.set_ref("//Infinitex")
        ctx.mouse_move_to_pos((cx + 150, cy))
        ctx.mouse_down(0)
        for i in range(12):  # swipe after swipe over one spot, in one gesture
            ctx.mouse_move_to_pos((cx + (170 if i % 2 == 0 else 150), cy + 10 * (i % 2 == 0)))
        ctx.mouse_up(0)
        s = float(decompose(ed.doc.direction.dense(int(ed.view.x) + int(160 / ed.view.zoom),
                                                   int(ed.view.y) + int(5 / ed.view.zoom), 1, 1))[1][0, 0])
        check("Grow makes the texture larger, up to what the exemplar can give", 3.5 < s <= MAX_STRETCH + 1e-3,
              f"scale {s:.2f}")
        ctx.set_ref(ctx.window_info("//Infinitex/Panels").window)
        ctx.item_click("Guide##direction-mode")
        ctx.set_ref("//Infinitex")
        before_guide = ed.doc.direction
        for dx, dy in ((-60, 150), (0, 190), (80, 170)):
            ctx.mouse_move_to_pos((cx + dx, cy + dy))
            ctx.mouse_click(0)
        check("clicks add the guide's points", len(tool.guide) == 3, str(len(tool.guide)))
        ctx.key_press(imgui.Key.enter)
        ctx.yield_(2)
        check("Enter applies the guide", not tool.guide and ed.doc.direction != before_guide, "not applied")
        flow = np.zeros((40, 60, 3), np.uint8)
        flow[..., 0], flow[..., 1] = 128, 0  # green down: the exemplar's x runs down the screen (90 degrees)
        Image.fromarray(flow).save(os.path.join(out, "flow.png"))
        ctx.set_ref(ctx.window_info("//Infinitex/Panels").window)
        ctx.item_click("Place direction map...")
        ctx.set_ref("//Infinitex")
        ctx.yield_(2)
        ctx.item_input_value("//**/##path", os.path.join(out, "flow.png"))
        ctx.yield_(3)
        th = float(decompose(ed.doc.direction.dense(int(ed.view.x), int(ed.view.y), 1, 1))[0][0, 0])
        check("a flow map is placed in the view", len(ed.history.undo_stack) == steps + 4 and abs(th - 90) < 1,
              f"{len(ed.history.undo_stack) - steps} steps, {th:.1f} degrees")
        ed.viewer.show_painted(True)
        settle(ctx)
        testing.capture(ctx, os.path.join(out, "direction-editor.png"))
        for _ in range(4):  # map, guide, grow, comb
            ctx.key_press(imgui.Key.mod_ctrl | imgui.Key.z)
        settle(ctx)
        check("undo removes the field", ed.doc.direction is None, "field left")
        check("undo restores the canvas exactly", np.array_equal(canvas(ctx), before), "canvas differs")

    return h.run(test)


if __name__ == "__main__":
    sys.exit(main(sys.argv[1]))
