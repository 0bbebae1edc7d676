"""The Flow tool (W): where and how fast the texture moves when it plays
(texture in motion, LH06 section 7; engine/controls/flow.py, engine/advect.py).

Modes, as in flow-map painters: a *Comb* (drag the way the texture should
flow: the velocity follows the stroke, at the chosen speed), a *Brush* (paints
one direction and speed, set by the dial), an *Eraser* (back to still, or to
the uniform velocity of the Motion panel), and a velocity map image placed
centered in the view (red and green, mid-gray still). Every stroke and placed
map is one undo step; what is painted shows as arrows with "Show painted" (H).
The Motion panel plays it (Space) while you paint."""
from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
from imgui_bundle import imgui

from infinitex.engine.controls.fields import dab_rect, dab_weights
from infinitex.engine.controls.flow import MAX_SPEED, Q, Flow, FlowError, VelocityMap
from infinitex.engine.exemplar import ExemplarError
from infinitex.project.flow_json import MAX_STORED_MAP_SIDE, Motion

from . import MAX_CANVAS_RADIUS, Tool
from .paint import Brush, brush_keys, headed_dabs
from ..tips import tip

MODES = (("comb", "Comb", "Drag the way the texture should flow: it moves along your stroke at the speed set"),
         ("brush", "Brush", "Paint the direction set by the dial, at the speed set"),
         ("erase", "Eraser", "Back to still (or to the uniform velocity of the Motion panel)"))
MAP_FILTER = ["Velocity maps", "*.png *.tif *.tiff *.webp *.bmp"]
LABELS = {"comb": "Comb flow", "brush": "Paint flow", "erase": "Erase flow"}


def flow_of(doc) -> Flow:
    return doc.motion.flow if doc.motion is not None else Flow()


def with_flow(doc, flow: Flow):
    """The document with ``flow`` (a new animation of 48 frames at 24 fps when it had none)."""
    motion = doc.motion if doc.motion is not None else Motion(Flow())
    return replace(doc, motion=replace(motion, flow=flow))


class FlowTool(Tool):
    name = "flow"
    label = "Flow"
    key = "W"
    tooltip = "Paint where the texture flows and how fast: comb it, brush it, erase it, or place a velocity map (W)"
    space = "canvas"
    shows_painted = True
    on_model = False  # (texture in motion is made on the plane)

    def __init__(self, ed):
        super().__init__(ed)
        self.brush = Brush(radius=48.0, strength=0.8, hardness=0.3)
        self.mode = "comb"
        self.speed = 1.5        # px per frame
        self.angle = 0.0        # the Brush's direction: degrees, 0 right, 90 up
        self.map_speed = 2.0    # px per frame at a map's 0 and 1
        self.map_y_up = True
        self._last: tuple[float, float] | None = None
        self._group: object = None
        self._edited = False  # this gesture changed the flow
        self.dabs = 0

    def radius_canvas(self) -> float:
        b = self.brush
        return min(MAX_CANVAS_RADIUS, b.radius / self.ed.view.zoom if b.screen_units else b.radius)

    def _refused(self) -> bool:
        if self.ed.doc.lattice is None:
            return False
        self.ed.tell("Texture in motion does not work on a lattice yet (a flow would bend its grid).")
        return True

    def _set(self, flow: Flow, what: str, group: object = None) -> None:
        # A flow changes no still texel: the canvas is not synthesized again (region: none).
        self.ed.edit(with_flow(self.ed.doc, flow), what, group=group, region=())

    def target(self, heading: float | None) -> tuple[int, int] | None:
        """The velocity a dab paints (1/256 px per frame, the map's part: less the uniform velocity)."""
        u = flow_of(self.ed.doc).velocity
        if self.mode == "erase":
            return (0, 0)
        if self.mode == "comb":
            if heading is None:
                return None
            a = math.radians(heading)
            vx, vy = self.speed * math.cos(a), self.speed * math.sin(a)
        else:
            a = math.radians(self.angle)
            vx, vy = self.speed * math.cos(a), -self.speed * math.sin(a)  # (up is -y on the canvas)
        lim = MAX_SPEED * Q
        return (int(np.clip(round(vx * Q) - u[0], -lim, lim)), int(np.clip(round(vy * Q) - u[1], -lim, lim)))

    def dab(self, flow: Flow, cx: float, cy: float, heading: float | None) -> Flow:
        tgt = self.target(heading)
        if tgt is None or (flow.map is None and tgt == (0, 0)):
            return flow
        r = self.radius_canvas()
        x0, y0, x1, y1 = dab_rect(cx, cy, r)
        b = self.brush
        w = np.clip(b.strength, 0.0, 1.0) * dab_weights(cx, cy, r, b.hardness, x0, y0, x1 - x0, y1 - y0)
        vmap = flow.map if flow.map is not None else VelocityMap(np.zeros((1, 1, 2), np.int32), x0, y0)
        vmap = vmap.painted(x0, y0, w, tgt, MAX_STORED_MAP_SIDE)
        return replace(flow, map=vmap if vmap.tiles else None)

    # -- strokes -----------------------------------------------------------

    def press(self, pos, screen) -> None:
        if self._refused():
            return
        self._group, self._last = object(), None
        if self.mode != "comb":
            self.drag(pos, screen)
        else:
            self._last = pos

    def drag(self, pos, screen) -> None:
        if self._group is None:
            return
        dabs = headed_dabs(self._last, pos, 0.25 * self.radius_canvas())
        if not dabs:
            return
        flow = before = flow_of(self.ed.doc)
        try:
            for cx, cy, heading in dabs:
                flow = self.dab(flow, cx, cy, heading)
        except FlowError as exc:
            self.ed.tell(str(exc))
            self.release()
            return
        self._last = dabs[-1][:2]
        self.dabs += len(dabs)
        if flow != before:
            self._set(flow, LABELS[self.mode], self._group)
            self._edited = True

    def release(self) -> None:
        if self._group is not None and self.ed.history is not None:
            if self._edited:
                self.suggest_period(self._group)
            self.ed.history.end_group()
        self._group, self._last, self._edited = None, None, False

    def suggest_period(self, group: object = None) -> None:
        """While the renewal is automatic (the Motion panel), the period the
        painted field's shear suggests (in the same undo step as the edit)."""
        ed = self.ed
        m = ed.doc.motion
        if m is None or not ed.panels.auto_period:
            return
        try:
            period = m.flow.suggested_period(m.frames if m.flow.loop else 0)
        except FlowError:
            return
        if period != m.flow.period:
            ed.edit(replace(ed.doc, motion=replace(m, flow=replace(m.flow, period=period))), "Renewal period",
                    group=group, region=())

    def place_map(self, path: str) -> None:
        """A velocity map placed centered in the view, over what is painted there."""
        from infinitex.engine.controls.maps import load_velocity_map
        ed = self.ed
        if self._refused():
            return
        try:
            vmap = load_velocity_map(path, self.map_speed, self.map_y_up)
            vmap = replace_at(vmap, int(ed.view.x) - vmap.w // 2, int(ed.view.y) - vmap.h // 2)
            flow = flow_of(ed.doc)
            merged = flow.map.merged(vmap, MAX_STORED_MAP_SIDE) if flow.map is not None else vmap
            if max(merged.w, merged.h) > MAX_STORED_MAP_SIDE:
                raise FlowError(f"A velocity map is at most {MAX_STORED_MAP_SIDE} px a side in a project.")
            group = object()
            self._set(replace(flow, map=merged if merged.tiles else None), "Place velocity map", group)
            self.suggest_period(group)
            ed.history.end_group()
        except (ExemplarError, FlowError, ValueError) as exc:
            ed.dialogs.message("Velocity map", str(exc))

    # -- panel, keys, overlay ------------------------------------------------

    def options(self) -> None:
        ed = self.ed
        if self.offer_lattice_off("Texture in motion does not work on a lattice yet: a flow would bend its grid."):
            return
        for i, (mode, label, says) in enumerate(MODES):
            if i:
                imgui.same_line()
            if imgui.radio_button(f"{label}##flow-mode", self.mode == mode):
                self.mode = mode
            tip(says)
        imgui.push_item_width(-110)
        if self.mode != "erase":
            _, self.speed = imgui.slider_float("Speed", self.speed, 0.05, 8.0, "%.2f px/frame",
                                               imgui.SliderFlags_.logarithmic)
            tip("How far the texture moves each frame where you paint")
        if self.mode == "brush":
            _, self.angle = imgui.slider_float("Direction", self.angle, -180.0, 180.0, "%.0f deg")
            tip("The way the brush makes the texture flow: 0 right, 90 up, 180 left, -90 down")
        b = self.brush
        _, b.radius = imgui.slider_float("Radius", b.radius, 1.0, 400.0, "%.0f px", imgui.SliderFlags_.logarithmic)
        tip("Brush size on screen ([ and ] change it)")
        _, b.strength = imgui.slider_float("Strength", b.strength, 0.0, 1.0, "%.2f")
        _, b.hardness = imgui.slider_float("Hardness", b.hardness, 0.0, 1.0, "%.2f")
        imgui.pop_item_width()
        imgui.separator()
        imgui.push_item_width(-110)
        _, self.map_speed = imgui.slider_float("Map speed", self.map_speed, 0.1, float(MAX_SPEED), "%.1f px/frame",
                                               imgui.SliderFlags_.logarithmic)
        tip("A velocity map's full red or green (0 or 1) moves this many pixels a frame; mid-gray is still")
        imgui.pop_item_width()
        _, self.map_y_up = imgui.checkbox("Map green points up (OpenGL)", self.map_y_up)
        if imgui.button("Place velocity map...", (-1, 0)):
            ed.dialogs.ask_path("Velocity map", False, MAP_FILTER, self.place_map)
        tip("A velocity map (red: x, green: y; mid-gray still), placed centered in the view")
        flow = flow_of(ed.doc)
        if flow.map is not None and imgui.button("Clear painted flow", (-1, 0)):
            self._set(replace(flow, map=None), "Clear painted flow")
        if ed.doc.motion is None or flow.still:
            imgui.text_wrapped("Paint a flow, then press Play (Space) in the Motion panel.")

    def keys(self) -> None:
        brush_keys(self.brush)

    def overlay(self, draw_list, p0, w, h) -> None:
        if self.ed.canvas_state.cursor is None:
            return
        io = imgui.get_io()
        c = (io.mouse_pos.x, io.mouse_pos.y)
        r = self.radius_canvas() * self.ed.view.zoom
        draw_list.add_circle(c, r, imgui.get_color_u32((0, 0, 0, 0.8)), 0, 3.0)
        draw_list.add_circle(c, r, imgui.get_color_u32((0.3, 0.8, 1.0, 0.9)), 0, 1.5)
        if self.mode == "brush":
            a = math.radians(self.angle)
            tip_pt = (c[0] + 0.8 * r * math.cos(a), c[1] - 0.8 * r * math.sin(a))
            draw_list.add_line(c, tip_pt, imgui.get_color_u32((0.3, 0.8, 1.0, 0.9)), 2.0)


def replace_at(vmap, x: int, y: int):
    """The same map placed at (x, y)."""
    return VelocityMap(vmap.values, x, y)


def draw_flow(draw_list, flow: Flow | None, view, p0, w: int, h: int) -> None:
    """Arrows along the velocity over the canvas where it moves, one every ~32
    screen px (sampled exactly as the engine does), longer where faster."""
    if flow is None or flow.still:
        return
    z = view.zoom
    x0, y0 = view.top_left(w, h)
    step = max(1.0, 32.0 / z)
    xs = np.arange(math.floor(x0 / step), math.ceil((x0 + w / z) / step) + 1) * step
    ys = np.arange(math.floor(y0 / step), math.ceil((y0 + h / z) / step) + 1) * step
    if xs.size * ys.size > 6000:
        return
    X, Y = np.meshgrid(xs, ys)
    v = np.zeros(X.shape + (2,), np.float64) + np.array(flow.velocity, np.float64)
    if flow.map is not None:  # (the nearest texel, read from the tiles: no dense map made while painting)
        qx, qy = np.floor(X).astype(np.int64).ravel(), np.floor(Y).astype(np.int64).ravel()
        v += flow.map.nearest(qx, qy).reshape(X.shape + (2,))
    vx, vy = v[..., 0] / Q, v[..., 1] / Q
    speed = np.hypot(vx, vy)
    dark, light = imgui.get_color_u32((0, 0, 0, 0.7)), imgui.get_color_u32((0.3, 0.8, 1.0, 0.95))
    for iy, ix in zip(*np.nonzero(speed > 0.01)):
        s = speed[iy, ix]
        length = min(14.0, 4.0 + 4.0 * s)
        dx, dy = vx[iy, ix] / s * length, vy[iy, ix] / s * length
        cx, cy = p0.x + (X[iy, ix] - x0) * z, p0.y + (Y[iy, ix] - y0) * z
        a, b = (cx - dx, cy - dy), (cx + dx, cy + dy)
        draw_list.add_line(a, b, dark, 3.0)
        draw_list.add_line(a, b, light, 1.5)
        draw_list.add_circle_filled(b, 2.5, light)
