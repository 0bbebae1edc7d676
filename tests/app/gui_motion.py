"""Drive the real editor through texture in motion (run under Xvfb by
test_editor.py):

    xvfb-run -a python tests/app/gui_motion.py OUT_DIR

The Flow tool's comb stroke (one undo step; the velocity follows the stroke;
no still texel changes), Play (Space): frames come from the player process
while the editor keeps drawing its own, each the exact frame the engine
composes (the same window computed here on the editor's context); a pan while
playing is taken at once; step (.) and scrub; the Velocity slider; Export
animation writes a flipbook atlas and its JSON in a process of its own; undo
takes the stroke away. Writes "ok NAME" / "FAIL NAME: why" lines to
OUT_DIR/report.txt and motion-editor.png.
"""
from __future__ import annotations

import json
import math
import os
import sys
import time

HERE = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
sys.path.insert(0, HERE)

import numpy as np  # noqa: E402
from gui_harness import Harness  # noqa: E402
from imgui_bundle import imgui  # noqa: E402
from imgui_bundle.immapp import testing  # noqa: E402
from PIL import Image  # noqa: E402

from infinitex.engine.controls.flow import Q  # noqa: E402


def engine_frame(doc, shown) -> np.ndarray:
    """The frame as the engine composes it, on a headless context of its own
    (the test runs beside the editor's thread, not on its GL context)."""
    from dataclasses import replace

    from infinitex.engine.advect import FlowFrames, SynthSource
    from infinitex.engine.gpu import Gpu
    from infinitex.engine.imagefile import to_u8
    from infinitex.export.loaded import LoadedDocument
    gpu = Gpu()
    loaded = LoadedDocument(gpu)
    try:
        loaded.load_now(replace(doc, motion=None))
        src = SynthSource(loaded.synth, 0)
        frames = FlowFrames(src, doc.motion.flow, loaded.params.seed)
        coords = frames.frame(shown.t, shown.rect)
        frames.release()
        src.release()
        rgb = to_u8(loaded.material.lookup(loaded.material.primary, coords))
        return np.repeat(rgb, 3, axis=2) if rgb.shape[2] == 1 else rgb[..., :3]  # (gray shown as RGB)
    finally:
        loaded.release()
        gpu.release()


def main(out: str) -> int:
    h = Harness(out, window_size=(1000, 700))
    ed, check, settle, canvas, wait = h.ed, h.check, h.settle, h.canvas, h.wait

    def test(ctx) -> None:
        settle(ctx)
        ctx.set_ref("//Infinitex")
        before = canvas(ctx)
        ctx.item_click("//**/Flow (W)##tool-flow")
        ctx.yield_(2)
        check("the Flow tool is active", ed.tool.name == "flow", ed.tool.name)
        tool = ed.tool
        tool.brush.radius, tool.brush.strength, tool.brush.hardness = 60.0, 1.0, 0.8
        tool.speed = 2.0
        steps = len(ed.history.undo_stack)
        r = ctx.item_info("//**/canvas").rect_full
        cx, cy = (r.min.x + r.max.x) / 2, (r.min.y + r.max.y) / 2
        ctx.mouse_move_to_pos((cx - 200, cy + 40))
        ctx.mouse_down(0)
        for i in range(1, 21):  # a stroke to the right and a little up
            ctx.mouse_move_to_pos((cx - 200 + 20 * i, cy + 40 - 2 * i))
        ctx.mouse_up(0)
        ctx.yield_(2)
        check("a comb stroke is one undo step", len(ed.history.undo_stack) == steps + 1,
              f"{len(ed.history.undo_stack) - steps} steps")
        m = ed.doc.motion
        check("the stroke makes a flow in the document", m is not None and m.flow.map is not None, "no flow")
        if m is None or m.flow.map is None:
            return
        x0, y0 = ed.view.top_left(*ed.canvas_size)
        px, py = x0 + (cx - r.min.x) / ed.view.zoom, y0 + (cy + 20 - r.min.y) / ed.view.zoom
        vx, vy = m.flow.sample(np.array([int(px * Q)]), np.array([int(py * Q)]))
        ang = math.degrees(math.atan2(vy[0], vx[0]))
        check("the velocity follows the stroke at the speed set",
              abs(ang - math.degrees(math.atan2(-2, 20))) < 8 and abs(math.hypot(vx[0], vy[0]) / Q - 2.0) < 0.15,
              f"{ang:.1f} degrees, {math.hypot(vx[0], vy[0]) / Q:.2f} px/frame")
        check("painting a flow changes no still texel", np.array_equal(canvas(ctx), before), "canvas changed")

        # Play: frames come while the editor draws its own (at 200%: a quarter of the
        # pixels to compose, this driver's load on a machine running others).
        ed.viewer.zoom_to(2.0)
        ctx.yield_(2)
        ctx.key_press(imgui.Key.space)
        ctx.yield_(2)
        pb = ed.playback
        check("Space plays", pb.playing, "not playing")
        f0 = ed.frame_count
        got = wait(ctx, lambda: pb.shown is not None and pb.t >= 4, 120)
        check("frames play on", got, f"t {pb.t}, error {pb.player.error}")
        check("the editor draws its own frames meanwhile", ed.frame_count - f0 > 3 * max(1, pb.t),
              f"{ed.frame_count - f0} editor frames for {pb.t} played")
        # A pan while it plays is taken at once (the canvas never waits for a frame).
        vx0 = ed.view.x
        ctx.mouse_move_to_pos((cx, cy))
        ctx.mouse_down(1)
        ctx.mouse_move_to_pos((cx - 120, cy))
        ctx.mouse_up(1)
        ctx.yield_()
        check("a pan while playing moves the view at once", abs(ed.view.x - vx0 - 120 / ed.view.zoom) < 2,
              f"moved {ed.view.x - vx0:.1f}")
        ctx.mouse_down(1)
        ctx.mouse_move_to_pos((cx, cy))  # and back
        ctx.mouse_up(1)
        ctx.yield_()
        ctx.key_press(imgui.Key.space)
        ctx.yield_(2)
        check("Space pauses", not pb.playing, "still playing")
        # Step and scrub; the frame shown is the engine's own, bit for bit.
        ctx.key_press(imgui.Key.period)
        ctx.yield_()
        t = pb.t
        got = wait(ctx, lambda: pb.shown is not None and pb.shown.t == t and not pb.player.busy
                   and pb.shown.doc_id == pb.player.doc_id, 120)
        check("a step shows the next frame", got, f"t {pb.t}, shown {pb.shown and pb.shown.t}")
        shown = pb.shown
        ref = engine_frame(ed.doc, shown)
        same = np.array_equal(ref, shown.rgb)
        check("the frame shown is the engine's, bit for bit", same,
              f"{np.count_nonzero(np.any(ref != shown.rgb, axis=-1))} of {ref.shape} pixels differ (t {shown.t})")
        if not same:
            np.save(os.path.join(out, "shown.npy"), shown.rgb)
            np.save(os.path.join(out, "engine.npy"), ref)
        ed.viewer.show_painted(True)
        ctx.yield_(3)
        testing.capture(ctx, os.path.join(out, "motion-editor.png"))
        ed.viewer.show_painted(False)

        # The Motion panel's velocity (one undo step a drag) and the export.
        steps = len(ed.history.undo_stack)
        ctx.set_ref(ctx.window_info("//Infinitex/Panels").window)
        ctx.item_open("Motion")
        ctx.yield_(2)
        ctx.item_input_value("Frames", 8)
        ctx.yield_(2)
        check("Frames sets the animation's length", ed.doc.motion.frames == 8, str(ed.doc.motion.frames))
        wait(ctx, lambda: pb.shown is not None and pb.shown.exact and not pb.player.busy, 60)
        ctx.yield_(3)
        testing.capture(ctx, os.path.join(out, "motion-panel.png"))
        ctx.set_ref("//Infinitex")
        ed.panels.motion_size = (96, 64)
        path = os.path.join(out, "flow_atlas.png")
        from infinitex.app.ui.panels.motion import start_export
        start_export(ed, path)
        done = wait(ctx, lambda: ed.exports.job is None and os.path.exists(path), 300)
        check("Export animation writes a flipbook atlas", done, "not written")
        if done:
            meta = json.load(open(os.path.splitext(path)[0] + ".json"))
            img = np.asarray(Image.open(path))
            check("the atlas and its description agree", meta["frames"] == 8 and meta["frame_width"] == 96
                  and img.shape[1] == 96 * meta["columns"] and img.shape[0] == 64 * meta["rows"], str(meta))
        ctx.key_press(imgui.Key.mod_ctrl | imgui.Key.z)  # the frames
        ctx.key_press(imgui.Key.mod_ctrl | imgui.Key.z)  # the stroke
        ctx.yield_(2)
        check("undo takes the stroke away", ed.doc.motion is None or ed.doc.motion.flow.map is None,
              "flow left")
        pb.stop()
        ed.viewer.zoom_to(1.0)
        check("back to the still texture, unchanged", np.array_equal(canvas(ctx), before), "canvas differs")
        time.sleep(0)

    return h.run(test)


if __name__ == "__main__":
    sys.exit(main(sys.argv[1]))
