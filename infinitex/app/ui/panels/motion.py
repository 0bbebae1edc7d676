"""The Motion panel: texture in motion (LH06 section 7). Play / Pause (Space),
step (, and .), scrub, back to the still texture; the uniform velocity, the
animation's frames, frame rate and loop, the renewal period; and Export
animation (an image sequence, a flipbook atlas with its JSON, WebP, APNG or
MP4). The flow is painted with the Flow tool (W). Each slider drag is one
undo step; a flow changes no still texel, so nothing is synthesized again.

The frames are composed in a process of their own (app/player.py) and drawn
over the canvas where they belong as they come (:func:`tick_and_draw`)."""
from __future__ import annotations

import os
from dataclasses import replace
from typing import TYPE_CHECKING

import numpy as np
from imgui_bundle import imgui

from infinitex.engine.controls.flow import MAX_PERIOD, MIN_PERIOD, Q, Flow, FlowError
from infinitex.engine.rect import Rect
from infinitex.engine.safeio import WriteError, printable
from infinitex.project.flow_json import Motion

from ...player import play_rect
from .widgets import tip

if TYPE_CHECKING:
    from . import Panels

ANIMATION_FILTER = ["Animations", "*.png *.webp *.apng *.mp4"]
FORMAT_NOTE = ("A name without extension writes a folder of frames; .png a flipbook atlas (with its .json for "
               "Unity, Unreal and Godot); .webp or .apng an animated image; .mp4 a video.")
MAX_FRAME_SIDE = 4096


def _motion(doc) -> Motion:
    return doc.motion if doc.motion is not None else Motion(Flow())


def _edit(ed, motion: Motion, what: str, group=None) -> None:
    ed.edit(replace(ed.doc, motion=motion), what, group=group, region=())


def draw(p: Panels) -> None:
    """The Motion panel."""
    ed = p.ed
    doc = ed.doc
    pb = ed.playback
    if doc.lattice is not None:
        imgui.text_wrapped("Texture in motion does not work on a lattice yet: a flow would bend its grid.")
        return
    m = _motion(doc)
    flow = m.flow
    # Transport.
    if imgui.button("|<##motion-first"):
        pb.seek(0, m.frames)
    tip("The first frame")
    imgui.same_line()
    if imgui.button("<##motion-back"):
        pb.step(-1, m.frames)
    tip("A frame back (,)")
    imgui.same_line()
    if imgui.button(("Pause" if pb.playing else "Play") + "##motion-play", (70, 0)):
        toggle(ed)
    tip("Play the texture flowing, or pause it (Space)")
    imgui.same_line()
    if imgui.button(">##motion-next"):
        pb.step(1, m.frames)
    tip("A frame on (.)")
    imgui.same_line()
    if imgui.button("Still##motion-stop"):
        pb.stop()
    tip("Back to the still texture (to edit it)")
    imgui.push_item_width(-90)
    changed, t = imgui.slider_int("Frame", pb.t, 0, m.frames - 1)
    if changed:
        pb.seek(t, m.frames)
    imgui.text_disabled(status(ed))
    imgui.separator()
    # The flow and the animation.
    vx, vy = flow.velocity[0] / Q, flow.velocity[1] / Q
    changed, v = imgui.slider_float2("Velocity", [vx, vy], -8.0, 8.0, "%.2f")
    tip("A uniform velocity everywhere, in canvas pixels per frame (x right, y down); the Flow tool (W) paints "
        "more where you want it")
    if changed:
        try:
            f = replace(flow, velocity=Flow.of(float(v[0]), float(v[1])).velocity)
            f.validate()
            _edit(ed, replace(m, flow=f), "Velocity", group="motion-velocity")
        except FlowError as exc:
            ed.tell(str(exc))
    if imgui.is_item_deactivated():
        ed.history.end_group()
    changed, n = imgui.slider_int("Frames", m.frames, 2, 480)
    tip("How many frames the animation has (what plays and what is exported)")
    if changed:
        _set_frames(ed, m, int(n), bool(flow.loop))
    if imgui.is_item_deactivated():
        ed.history.end_group()
    changed, fps = imgui.slider_float("Frame rate", m.fps, 1.0, 60.0, "%.0f fps")
    tip("Frames a second, when it plays and in what is exported")
    if changed:
        _edit(ed, replace(m, fps=float(round(fps))), "Frame rate", group="motion-fps")
    if imgui.is_item_deactivated():
        ed.history.end_group()
    changed, loop = imgui.checkbox("Seamless loop", bool(flow.loop))
    tip("The last frame runs into the first: a flipbook that loops without a jump")
    if changed:
        _set_frames(ed, m, m.frames, loop, group=None)
    changed, period = imgui.slider_int("Renewal", flow.period, MIN_PERIOD, MAX_PERIOD, "every %d frames")
    tip("How often new texture takes over from the texture carried along (a frame depends on at most twice "
        "this many before it): shorter stays closer to the exemplar where the flow stretches it, longer "
        "renews less often. A loop's length is a multiple of it")
    if changed:
        p.auto_period = False
        _set_period(ed, m, int(period))
    if imgui.is_item_deactivated():
        ed.history.end_group()
    changed, p.auto_period = imgui.checkbox("Automatic renewal", p.auto_period)
    tip("Each Flow stroke sets the renewal period from how much the flow stretches the texture (LH06's "
        "distortion), dividing a loop")
    if changed and p.auto_period:
        try:
            _set_period(ed, m, flow.suggested_period(m.frames if flow.loop else 0), group=None)
        except FlowError as exc:
            ed.tell(str(exc))
    imgui.pop_item_width()
    imgui.separator()
    imgui.push_item_width(-90)
    changed, size = imgui.input_int2("Frame size", list(p.motion_size))
    if changed:
        p.motion_size = (int(np.clip(size[0], 16, MAX_FRAME_SIDE)), int(np.clip(size[1], 16, MAX_FRAME_SIDE)))
    tip("The exported frames' size in pixels, centered on the view (tile mode: the seamless tile)")
    imgui.pop_item_width()
    if imgui.button("Export animation...", (-1, 0)):
        ed.dialogs.ask_path("Export animation", True, ANIMATION_FILTER, lambda path: start_export(ed, path),
                            default="animation.png")
    tip(FORMAT_NOTE)


def status(ed) -> str:
    pb = ed.playback
    m = ed.doc.motion
    if pb.player.error:
        return pb.player.error
    if m is None or m.flow.still:
        return "Still: set a velocity or paint one with the Flow tool (W)."
    if pb.playing:
        r = pb.rate
        return f"Playing frame {pb.t}" + (f" at {r:.1f} fps" if r is not None else "") + f" (of {m.fps:g})"
    if pb.active:
        return f"Frame {pb.t} of {m.frames}" + (" (a loop)" if m.flow.loop else "")
    return "Showing the still texture; Play (Space) to see it flow."


def toggle(ed) -> None:
    """Play or pause (Space)."""
    if ed.doc is None or ed.doc.lattice is not None or ed.model_mode:
        return  # (a model shows the still texture)
    if ed.doc.motion is None or ed.doc.motion.flow.still:
        ed.tell("Nothing flows yet: set a velocity in the Motion panel or paint one with the Flow tool (W).")
        return
    ed.playback.toggle()


def _set_frames(ed, m: Motion, n: int, loop: bool, group="motion-frames") -> None:
    flow = m.flow
    try:
        if loop:
            period = flow.period if n % flow.period == 0 else flow.suggested_period(n)
            flow = replace(flow, loop=n, period=period)
        else:
            flow = replace(flow, loop=0)
        _edit(ed, replace(m, flow=flow, frames=n), "Animation frames", group=group)
    except FlowError as exc:
        ed.tell(str(exc))


def _set_period(ed, m: Motion, period: int, group="motion-period") -> None:
    flow = m.flow
    n = m.frames
    if flow.loop and n % period:  # a loop's length stays a multiple of the period
        n = max(period, round(n / period) * period)
        flow = replace(flow, loop=n)
    _edit(ed, replace(m, flow=replace(flow, period=period), frames=n), "Renewal period", group=group)


# -- the canvas ---------------------------------------------------------------------


class MotionLayer:
    """The frame being shown, as a texture drawn over the canvas at its place."""

    def __init__(self):
        self.tex = None
        self.key = None

    def texture(self, ed, frame):
        if self.key is not frame:
            h, w = frame.rgb.shape[:2]
            if self.tex is None or self.tex.size != (w, h):
                if self.tex is not None:
                    self.tex.release()
                self.tex = ed.gpu.ctx.texture((w, h), 3, frame.rgb.tobytes())
                self.tex.filter = (0x2600, 0x2600)  # nearest: a canvas pixel is a block when zoomed in
            else:
                self.tex.write(frame.rgb.tobytes())
            self.key = frame
        return self.tex

    def release(self) -> None:
        if self.tex is not None:
            self.tex.release()
        self.tex = self.key = None


def tick_and_draw(p: Panels, p0, w: int, h: int) -> None:
    """Each frame: the playhead's frame asked for and, once come, drawn over the canvas."""
    ed = p.ed
    pb = ed.playback
    doc = ed.doc
    if doc is None or ed.model_mode or not ed.session.ready:
        return
    rect = play_rect(ed.exports.view_rect())
    pb.tick(doc if doc.lattice is None else None, ed.canvas_input.tile_period(), rect, ed.shown_role())
    f = pb.shown
    if not pb.active or f is None:
        return
    tex = p.motion_layer.texture(ed, f)
    z = ed.view.zoom
    x0, y0 = ed.view.top_left(w, h)
    a = (p0.x + (f.rect.x0 - x0) * z, p0.y + (f.rect.y0 - y0) * z)
    dl = imgui.get_window_draw_list()
    dl.push_clip_rect(p0, (p0.x + w, p0.y + h), True)
    dl.add_image(imgui.ImTextureRef(tex.glo), a, (a[0] + f.rect.w * z, a[1] + f.rect.h * z))
    dl.pop_clip_rect()


def export_rect(ed, size: tuple[int, int]) -> tuple[Rect, int]:
    """The exported frames' rectangle and period: the seamless tile in tile mode, else ``size`` around the view's center."""
    n = ed.canvas_input.tile_period()
    if n:
        return Rect(0, 0, n, n), n
    w, h = size
    x0, y0 = int(ed.view.x) - w // 2, int(ed.view.y) - h // 2
    return Rect(x0, y0, x0 + w, y0 + h), 0


def start_export(ed, path: str, confirmed: bool = False) -> None:
    """Export the document's animation to ``path`` in a process of its own (progress and cancel in the export window)."""
    from infinitex.engine.advect import MAX_STATIC_SIDE, static_side
    from infinitex.engine.material import IMAGE, ROLES
    from infinitex.export.animation import animation_format, animation_outputs, check_animation_output
    from infinitex.export.animation_job import AnimationExport
    from infinitex.export.window import Writes, check_own_inputs
    doc = ed.doc
    m = doc.motion
    if m is None or m.flow.still:
        ed.dialogs.message("Export animation", "Nothing flows yet: set a velocity or paint one with the Flow tool.")
        return
    if ed.session.quick_analysis:
        ed.dialogs.message("Export animation", "The full analysis is still running; export once it is finished.")
        return
    rect, period = export_rect(ed, ed.panels.motion_size)
    try:
        fmt = animation_format(path)
        mat = ed.session.material
        roles = [IMAGE] if mat is None or mat.single else list(mat.roles)
        outputs = animation_outputs(path, fmt, roles)
        check_animation_output(path, fmt, outputs, m.frames, rect.w, rect.h, ROLES if len(roles) > 1 else ())
        flow = m.flow
        if static_side(flow, rect.w, rect.h) > MAX_STATIC_SIDE:
            raise WriteError("The flow carries content farther than one synthesis covers in a renewal; use a "
                             "shorter renewal period, a lower speed or smaller frames.")
        if period and not flow.uniform:
            raise WriteError("In tile mode only a uniform velocity flows (a painted flow is not periodic); "
                             "turn tile mode off to export it.")
        files = [o for _, o in outputs if fmt != "folder"]
        files += [os.path.splitext(o)[0] + ".json" for o in files if fmt == "atlas"]
        writes = Writes(files=files, folders=[o for _, o in outputs if fmt == "folder"])
        check_own_inputs(writes, ed.exports.inputs())
        if not confirmed and not ed.exports.confirm_replace(writes, ed.exports.asked(path, path),
                                                     lambda: start_export(ed, path, True)):
            return
        ed.exports.enqueue(AnimationExport(doc, rect, period, fmt, outputs))
    except (ValueError, WriteError) as exc:
        ed.dialogs.message("Export animation", printable(str(exc), 400))
