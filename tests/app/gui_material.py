"""Drive the real editor through a material session (run under Xvfb by
test_editor.py):

    xvfb-run -a python tests/app/gui_material.py OUT_DIR

File > Open material with several maps; the Material panel (a role
reassigned, then undone); the Display panel's map choice and the M key; the
lit preview and its light; File > Export view writing every map. Writes
"ok NAME" / "FAIL NAME: why" lines to OUT_DIR/report.txt.
"""
from __future__ import annotations

import os
import sys

HERE = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
sys.path.insert(0, HERE)
sys.path.insert(0, os.path.join(HERE, "scripts"))

import numpy as np  # noqa: E402
from gui_harness import Harness  # noqa: E402
from imgui_bundle import imgui  # noqa: E402
from imgui_bundle.immapp import testing  # noqa: E402
from make_material import cobbles  # noqa: E402

from infinitex.engine.imagefile import write_image  # noqa: E402


def choose(ctx, combo: str, item: str) -> None:
    ctx.set_ref(ctx.window_info("//Infinitex/Panels").window)
    ctx.combo_click(f"{combo}/{item}")
    ctx.yield_(2)
    ctx.set_ref("//Infinitex")


def main(out: str) -> int:
    maps = cobbles(64, seed=4, stones=12)
    paths = {}
    for role, depth in (("basecolor", 8), ("height", 16), ("normal", 16)):
        paths[role] = os.path.join(out, f"pebbles_{role}.png")
        write_image(paths[role], maps[role], depth)
    h = Harness(out)
    ed, check, settle, canvas, wait = h.ed, h.check, h.settle, h.canvas, h.wait

    def test(ctx) -> None:
        settle(ctx)
        ctx.set_ref("//Infinitex")
        ctx.menu_click("File/Open material...")
        ctx.yield_(2)
        ctx.item_input_value("//**/##path", ";".join(paths[r] for r in ("normal", "height", "basecolor")))
        settle(ctx)
        doc = ed.doc
        check("File > Open material loads every map", doc.is_material and
              [r for r, _ in doc.maps] == ["basecolor", "normal", "height"] and ed.session.material is not None
              and ed.session.material.roles == ["basecolor", "normal", "height"],
              str([r for r, _ in doc.maps]))
        check("the analysis sees base color and height", ed.session.exemplar.channels == 4,
              str(ed.session.exemplar.channels))
        for header in ("Randomness", "Exemplar"):
            ctx.item_close(f"**/{header}")
        ctx.item_open("**/Material")
        ctx.item_open("**/Display")
        ctx.yield_(2)
        testing.capture(ctx, os.path.join(out, "material-panel.png"))

        # Reassign a role in the Material panel (analyzed, then one undo step).
        ctx.set_ref(ctx.window_info("//Infinitex/Panels").window)
        ctx.item_click("map2/##role")  # (combo_click takes no nested ID)
        ctx.yield_(2)
        popup = ctx.window_info("//$FOCUSED").window
        ctx.item_click(f"//{popup.name}/**/Roughness")
        ctx.set_ref("//Infinitex")
        settle(ctx)
        check("a role is reassigned in the panel", [r for r, _ in ed.doc.maps] == ["basecolor", "roughness", "normal"]
              or [r for r, _ in ed.doc.maps] == ["basecolor", "normal", "roughness"], str([r for r, _ in ed.doc.maps]))
        ctx.key_press(imgui.Key.mod_ctrl | imgui.Key.z)
        settle(ctx)
        check("undo gives the height map back", [r for r, _ in ed.doc.maps] == ["basecolor", "normal", "height"],
              str([r for r, _ in ed.doc.maps]))

        # Switch the displayed map.
        color = canvas(ctx)
        choose(ctx, "Map", "Height")
        height = canvas(ctx)
        check("the Display panel shows the height map", ed.display.map == "height"
              and np.array_equal(height[..., 0], height[..., 1]) and not np.array_equal(color, height),
              ed.display.map)
        ctx.mouse_move("**/canvas")
        ctx.key_press(imgui.Key.m)
        ctx.yield_(2)
        check("M shows the next map", ed.session.shown_map(ed.display.map) == "basecolor", ed.display.map)
        choose(ctx, "Map", "Normal")
        normal = canvas(ctx)
        check("and the normal map", ed.display.map == "normal" and normal[..., 2].mean() > normal[..., 0].mean(),
              ed.display.map)

        # The lit preview, and its light moved.
        ctx.item_click("**/Lit material")
        ctx.yield_(2)
        lit_a = canvas(ctx)
        ctx.item_input_value("**/Light direction", 315.0)
        ctx.yield_(2)
        lit_b = canvas(ctx)
        check("the lit preview shows and follows the light", ed.display.mode == "lit"
              and ed.display.light_azimuth == 315.0 and not np.array_equal(lit_a, color)
              and np.abs(lit_a.astype(int) - lit_b.astype(int)).mean() > 3, str(ed.display))
        testing.capture(ctx, os.path.join(out, "material-lit.png"))

        # Export every map through the menu.
        target = os.path.join(out, "view.png")
        ctx.set_ref("//Infinitex")
        ctx.menu_click("File/Export view as PNG...")
        ctx.yield_(2)
        ctx.item_input_value("//**/##path", target)
        wait(ctx, lambda: ed.exports.job is None, 180)  # an export in a process of its own
        names = sorted(n for n in os.listdir(out) if n.startswith("view"))
        check("File > Export view writes every map", names == ["view_basecolor.png", "view_height.png",
                                                               "view_normal.png"]
              and ed.notice is not None and "3 maps" in ed.notice[0], f"{names} {ed.notice}")

    return h.run(test)


if __name__ == "__main__":
    sys.exit(main(sys.argv[1]))
