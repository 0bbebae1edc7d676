"""Drive the real editor with a model open (run under Xvfb by test_editor.py):

    xvfb-run -a python tests/app/gui_surface.py OUT_DIR

File > Open model (a generated cube whose faces are separate charts): the
canvas shows it textured; the project is saved with the atlas beside it
(test_editor.py checks it against the engine's); orbit (middle and
left buttons) and zoom change the view, not the texture; a Paint canvas
stroke on the model is one undo step and changes the texture; undo restores
the atlas exactly; the Features tool places a feature on the model
(its centre copies the exemplar exactly), the wheel resizes it and a drag
moves it, each one undo step; a Direction comb stroke down the model turns
the texture there (one undo step, undone exactly); Export model writes a GLB with the texture; Close model
returns to the plane. Writes "ok NAME" / "FAIL NAME: why" lines to
OUT_DIR/report.txt and model-editor.png.
"""
from __future__ import annotations

import os
import sys
import time

HERE = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
sys.path.insert(0, HERE)

import numpy as np  # noqa: E402
import trimesh  # noqa: E402
from gui_harness import Harness  # noqa: E402
from imgui_bundle import imgui  # noqa: E402
from imgui_bundle.immapp import testing  # noqa: E402

from infinitex.engine.surface.shapes import cube  # noqa: E402


def main(out: str) -> int:
    gravel = os.path.join(HERE, "infinitex", "assets", "gravel.png")
    m = cube(n=3)
    model_path = os.path.join(out, "cube.obj")
    trimesh.Trimesh(m.positions, m.faces, visual=trimesh.visual.TextureVisuals(uv=m.uvs),
                    process=False).export(model_path)
    h = Harness(out, gravel, window_size=(1100, 760))
    ed, check, settle, canvas = h.ed, h.check, h.settle, h.canvas

    def atlas_now(ctx):
        """The finished atlas's coordinates, read by the editor itself during a frame (GL is the main thread's)."""
        settle(ctx)
        ed.model.atlas_request = True
        t0 = time.monotonic()
        while ed.model.atlas_request:
            if time.monotonic() - t0 > 120 or not ed.model_mode:
                ed.model.atlas_request = False
                return None
            ctx.yield_()
        return ed.model.atlas_read

    def test(ctx) -> None:
        settle(ctx)
        ctx.set_ref("//Infinitex")
        ctx.item_input_value("//**/Structure", 0)  # Variety: the atlas is synthesized again quickly
        settle(ctx)
        steps = len(ed.history.undo_stack)
        ctx.menu_click("File/Open model...")
        ctx.yield_(2)
        ctx.item_input_value("//**/##path", model_path)
        ctx.yield_(3)
        check("Open model puts the model in the document (one undo step)",
              ed.doc.surface is not None and len(ed.history.undo_stack) == steps + 1,
              f"{len(ed.history.undo_stack) - steps} steps")
        first = atlas_now(ctx)
        pv = ed.session.model
        check("the model's six faces are its charts", pv.atlas is not None and pv.atlas.charts == 6,
              str(pv.atlas.charts if pv.atlas else None))
        # The project, saved, and its atlas: test_editor.py synthesizes it with the engine and compares.
        ctx.menu_click("File/Save As...")
        ctx.yield_(2)
        ctx.item_input_value("//**/##path", os.path.join(out, "model.itex"))
        ctx.yield_(3)
        check("the project with its model is saved", os.path.exists(os.path.join(out, "model.itex")), "not saved")
        if first is not None:
            np.save(os.path.join(out, "atlas.npy"), first)
        shot = canvas(ctx)
        lit = np.abs(shot.astype(int) - np.array([41, 43, 48])).sum(-1) > 30
        check("the canvas shows the model", lit.mean() > 0.1, f"{lit.mean():.2f} of the canvas")

        # Orbit with the middle button, then the left (Navigate), and zoom: the view moves, the texture stays.
        r = ctx.item_info("//**/canvas").rect_full
        cx, cy = (r.min.x + r.max.x) / 2, (r.min.y + r.max.y) / 2
        cam0 = ed.model.camera
        ctx.mouse_move_to_pos((cx, cy))
        ctx.mouse_down(2)
        ctx.mouse_move_to_pos((cx + 120, cy + 30))
        ctx.mouse_up(2)
        ctx.mouse_move_to_pos((cx, cy))
        ctx.mouse_down(0)
        ctx.mouse_move_to_pos((cx - 40, cy))
        ctx.mouse_up(0)
        ctx.mouse_wheel((0, 2))
        ctx.yield_(2)
        cam1 = ed.model.camera
        check("the mouse orbits and zooms", cam1.yaw != cam0.yaw and cam1.pitch != cam0.pitch
              and cam1.distance < cam0.distance, f"{cam0} -> {cam1}")
        orbited = canvas(ctx)
        check("orbiting redraws the model", not np.array_equal(orbited, shot), "same picture")
        again = atlas_now(ctx)
        np.save(os.path.join(out, "atlas2.npy"), again)
        check("orbiting leaves the texture", np.array_equal(again, first), "atlas changed")

        # A Paint canvas stroke on the model: one undo step, a new texture where it went.
        ctx.item_click("//**/Paint canvas (B)##tool-paint-canvas")
        ctx.yield_(2)
        tool = ed.tool
        tool.brush.value, tool.brush.strength, tool.brush.radius = 2.0, 1.0, 30.0
        steps = len(ed.history.undo_stack)
        ctx.mouse_move_to_pos((cx - 30, cy))
        ctx.mouse_down(0)
        for i in range(1, 6):
            ctx.mouse_move_to_pos((cx - 30 + 12 * i, cy + 4 * i))
        ctx.mouse_up(0)
        painted = atlas_now(ctx)
        field = ed.doc.randomness_canvas
        check("a stroke on the model is one undo step", len(ed.history.undo_stack) == steps + 1,
              f"{len(ed.history.undo_stack) - steps} steps")
        check("the stroke paints randomness in the atlas", field is not None and not field.neutral, "nothing painted")
        diff = np.any(painted != first, axis=-1) if painted is not None else np.zeros(1, bool)
        check("the stroke changes the texture", diff.sum() > 50, f"{diff.sum()} texels")
        # "Show painted" (on since the paint tool was chosen) shows the stroke as on the plane: rough is red.
        with_heat = canvas(ctx).astype(int)
        ed.viewer.show_painted(False)
        plain = canvas(ctx).astype(int)
        ed.viewer.show_painted(True)
        heat = np.abs(with_heat - plain).sum(-1) > 30
        redder = (with_heat[..., 0] - with_heat[..., 2] > plain[..., 0] - plain[..., 2])[heat]
        check("Show painted shows the stroke on the model, rough in red", heat.sum() > 200 and redder.mean() > 0.9,
              f"{heat.sum()} pixels, {redder.mean() if heat.any() else 0:.2f} redder")
        ed.model.show_seams = True
        settle(ctx)
        testing.capture(ctx, os.path.join(out, "model-editor.png"))
        ed.model.show_seams = False
        ctx.key_press(imgui.Key.mod_ctrl | imgui.Key.z)
        check("undo restores the atlas exactly", np.array_equal(atlas_now(ctx), first), "atlas differs")

        # Features on the model: a click places one (one undo step) whose centre copies the
        # exemplar exactly; the wheel over it resizes it; dragging its centre moves it over the surface.
        ctx.item_click("//**/Features (F)##tool-feature")
        ctx.yield_(2)
        tool = ed.tool
        tool.inner, tool.outer, tool.exact = 20, 40, True
        steps = len(ed.history.undo_stack)
        ctx.mouse_move_to_pos((cx + 10, cy + 10))
        ctx.mouse_click(0)
        placed = atlas_now(ctx)
        feats = ed.doc.features
        check("a click on the model places a feature (one undo step)",
              len(feats) == 1 and len(ed.history.undo_stack) == steps + 1, f"{len(feats)} features")
        if feats and placed is not None:
            f = feats[0]
            at = placed[f.canvas[1], f.canvas[0]]
            an = ed.session.analysis
            u = f.clamped(an.size, an.toroidal).exemplar  # (moved inward on an exemplar that does not tile)
            check("the feature's centre shows its exemplar point exactly",
                  tuple(at) == (u[0], u[1], 0, 0), f"{tuple(at)} vs {u}")
            np.save(os.path.join(out, "atlas-feature.npy"), placed)
            ctx.menu_click("File/Save As...")
            ctx.yield_(2)
            ctx.item_input_value("//**/##path", os.path.join(out, "model-feature.itex"))
            ctx.yield_(3)
            diff = np.any(placed != first, axis=-1)
            check("the feature changes the texture around it", diff.sum() > 50, f"{diff.sum()} texels")
            ctx.mouse_move_to_pos((cx + 10, cy + 10))  # (the dialog took the mouse)
            ctx.mouse_wheel((0, 2))
            ctx.yield_(2)
            g = ed.doc.features[0]
            check("the wheel over a feature resizes it", g.outer > f.outer and g.canvas == f.canvas,
                  f"{f.outer} -> {g.outer}")
            steps = len(ed.history.undo_stack)
            # A press inside the inner circle, well off the centre dot, grabs the feature too.
            w, h = ed.canvas_size
            handles = next(t for t in ed.tools if t.name == "feature").model_gesture()._handles(w, h)
            _, hx, hy, ri, _ = handles[0] if handles else (0, cx + 10 - r.min.x, cy + 10 - r.min.y, 0.0, 0.0)
            px, py = r.min.x + hx + 0.6 * ri, r.min.y + hy
            check("the inner circle is large enough to press off its centre", ri >= 15, f"inner {ri:.1f} px")
            ctx.mouse_move_to_pos((px, py))
            ctx.mouse_down(0)
            for i in range(1, 5):
                ctx.mouse_move_to_pos((px + 8 * i, py))
            ctx.mouse_up(0)
            moved = ed.doc.features
            check("dragging a feature from inside its inner circle moves it on the surface (one undo step)",
                  len(moved) == 1 and moved[0].canvas != g.canvas and len(ed.history.undo_stack) == steps + 1,
                  f"{g.canvas} -> {moved[0].canvas if moved else None}")
            for _ in range(3):
                ctx.key_press(imgui.Key.mod_ctrl | imgui.Key.z)
            check("undoing the feature restores the atlas exactly",
                  not ed.doc.features and np.array_equal(atlas_now(ctx), first), "atlas differs")

        # Combing on the model: a stroke down the side face turns the texture there (the exemplar's x
        # runs down the surface: 90 degrees in the model's frame), one undo step; undo restores the atlas.
        ctx.item_click("//**/Direction (D)##tool-direction")
        ctx.yield_(2)
        tool = ed.tool
        tool.mode, tool.axis = "comb", 0
        tool.brush.radius, tool.brush.strength, tool.brush.hardness = 40.0, 1.0, 1.0
        steps = len(ed.history.undo_stack)
        ctx.mouse_move_to_pos((cx - 60, cy - 120))
        ctx.mouse_down(0)
        for i in range(1, 13):
            ctx.mouse_move_to_pos((cx - 60, cy - 120 + 20 * i))
        ctx.mouse_up(0)
        combed = atlas_now(ctx)
        field = ed.doc.direction
        check("a comb stroke on the model is one undo step", field is not None
              and len(ed.history.undo_stack) == steps + 1, f"{len(ed.history.undo_stack) - steps} steps")
        if field is not None:
            from infinitex.engine.controls.direction import IDENTITY, decompose
            n = ed.doc.surface.size
            j = field.dense(0, 0, n, n)
            theta, _, _ = decompose(j[np.any(j != IDENTITY, axis=-1)])
            check("the stroke combs the texture down the surface", abs(float(np.median(theta)) - 90.0) < 25.0,
                  f"median {float(np.median(theta)):.0f} degrees")
        diff = np.any(combed != first, axis=-1) if combed is not None else np.zeros(1, bool)
        check("combing changes the texture", diff.sum() > 50, f"{diff.sum()} texels")
        np.save(os.path.join(out, "atlas-combed.npy"), combed)
        ctx.menu_click("File/Save As...")
        ctx.yield_(2)
        ctx.item_input_value("//**/##path", os.path.join(out, "model-combed.itex"))
        ctx.yield_(3)
        ctx.key_press(imgui.Key.mod_ctrl | imgui.Key.z)
        check("undoing the comb stroke restores the atlas exactly",
              ed.doc.direction is None and np.array_equal(atlas_now(ctx), first), "atlas differs")

        # Export model: a GLB with the texture; then Close model returns to the plane.
        glb = os.path.join(out, "cube_gravel.glb")
        ctx.menu_click("File/Export model...")
        ctx.yield_(2)
        req = ed.dialogs.path_request
        check("Export model proposes a file name", req is not None and os.path.basename(req.default)
              == os.path.splitext(ed.doc.surface.model.name)[0] + "_textured.glb", str(req and req.default))
        ctx.item_input_value("//**/##path", glb)
        ctx.yield_(3)
        while ed.exports.job is not None:
            ctx.yield_()
        ok = os.path.exists(glb) and os.path.exists(os.path.join(out, "cube_gravel_basecolor.png"))
        if ok:
            mesh = next(iter(trimesh.load(glb).geometry.values()))
            ok = mesh.visual.material.baseColorTexture.size == (ed.doc.surface.size,) * 2
        check("Export model writes a GLB with the texture", ok, "missing")
        ctx.menu_click("File/Close model")
        settle(ctx)
        check("Close model returns to the plane", ed.doc.surface is None and not ed.model_mode, "still a model")

    return h.run(test)


if __name__ == "__main__":
    sys.exit(main(sys.argv[1]))
