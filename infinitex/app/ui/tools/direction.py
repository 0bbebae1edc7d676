"""Direction fields (LH06 5; engine/controls/direction.py): the texture turns,
grows and stretches where the artist says, with tools as in flow-map painters
and hair-grooming combs: a *Comb* (drag the way the texture should run), a
*Smooth* brush (strokes flow into each other), *Grow* and *Shrink* brushes, an
*Eraser* back to the exemplar as it is, and *Guides*: click the points of a
curve, the texture follows it within a chosen width (Enter or *Apply guide*).
A flow or angle map can be placed on the view. Every stroke, guide and placed
map is one undo step and re-synthesizes only what it reaches. With "Show
painted" (H) short strokes over the canvas show the field."""
from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
from imgui_bundle import imgui

from infinitex.engine.controls.direction import (
    MAX_STRETCH,
    MIN_STRETCH,
    DirectionField,
    comb,
    decompose,
    erase,
    grow,
    smooth,
)
from infinitex.engine.controls.fields import FieldTooLarge, dab_rect, dab_weights
from infinitex.engine.exemplar import ExemplarError

from . import MAX_CANVAS_RADIUS, Tool
from .paint import Brush, brush_keys, headed_dabs
from ..tips import tip

MODES = (("comb", "Comb", "Drag the way the texture should run"),
         ("smooth", "Smooth", "Blend directions and sizes into their surroundings"),
         ("grow", "Grow", "Make the texture larger under the brush"),
         ("shrink", "Shrink", "Make the texture smaller under the brush"),
         ("erase", "Eraser", "Back to the exemplar's own direction and size"),
         ("guide", "Guide", "Click the points of a curve; Enter (or Apply guide) makes the texture follow it"))
MAP_FILTER = ["Direction maps", "*.png *.tif *.tiff *.webp *.bmp"]
MAX_GUIDE_AREA = 2048 * 2048  # canvas pixels a guide's box may cover (about a second of work)
MAX_BRUSH = MAX_CANVAS_RADIUS  # canvas pixels: a brush zoomed far out still edits a bounded area


# What the exemplar can give, said in the panel (engine/controls/direction.py limits).
GROW_NOTE = (f"Up to {MAX_STRETCH:g}x. Past the exemplar's own pixels the finest scales are magnified "
             "(softer, as when zooming in), never invented or blurred.")
SHRINK_NOTE = f"Down to 1/{1 / MIN_STRETCH:g}: smaller would read the exemplar too sparsely."


class DirectionTool(Tool):
    name = "direction"
    label = "Direction"
    key = "D"
    tooltip = ("Turn, grow and stretch the texture along curves: comb it, smooth it, grow or shrink it, "
               "or draw guides it follows (D)")
    space = "canvas"
    shows_painted = True

    def __init__(self, ed):
        super().__init__(ed)
        self._model = None
        self.brush = Brush(radius=40.0, strength=0.7)
        self.mode = "comb"
        self.axis = 0          # 0: the exemplar's x runs along strokes, 1: its y
        self.rate = 1.5        # grow / shrink per full-strength dab
        self.guide_width = 64.0
        self.guide_blend = 64.0  # px beyond the width over which a guide fades into what is there
        self.guide: list[tuple[float, float]] = []
        self.map_kind = "auto"
        self.map_y_up = True
        self._last: tuple[float, float] | None = None
        self._group: object = None
        self.dabs = 0

    # -- helpers -----------------------------------------------------------

    @property
    def field(self) -> DirectionField:
        return self.ed.doc.direction or DirectionField()

    def _set(self, field: DirectionField, what: str, group: object = None, region=None) -> None:
        ed = self.ed
        ed.edit(replace(ed.doc, direction=None if field.identity else field), what, group=group, region=region)

    def radius_canvas(self) -> float:
        b = self.brush
        return min(MAX_BRUSH, b.radius / self.ed.view.zoom if b.screen_units else b.radius)

    def _refused(self) -> bool:
        """A lattice and a direction field do not go together: say so, once per gesture."""
        if self.ed.doc.lattice is None:
            return False
        self.ed.tell("A direction field does not work on a lattice; turn the lattice off first.")
        return True

    def _axis_offset(self) -> float:
        return 90.0 * self.axis

    def dab(self, field: DirectionField, cx: float, cy: float, heading: float | None,
            r: float | None = None) -> DirectionField:
        """The field after one dab of the current mode at (cx, cy), of radius ``r``
        (canvas or atlas pixels; default: the brush's on the canvas)."""
        r = self.radius_canvas() if r is None else r
        x0, y0, x1, y1 = dab_rect(cx, cy, r)
        b = self.brush
        w = np.clip(b.strength, 0.0, 1.0) * dab_weights(cx, cy, r, b.hardness, x0, y0, x1 - x0, y1 - y0)
        if self.mode == "comb":
            if heading is None:
                return field
            op = comb(heading - self._axis_offset())
        elif self.mode == "smooth":
            op = smooth(max(3, int(r)))
        elif self.mode in ("grow", "shrink"):
            op = grow(self.rate ** (0.25 if self.mode == "grow" else -0.25))  # 4 dabs a radius: the rate
        else:
            op = erase()
        return field.edited(x0, y0, w, op)[0]

    # -- strokes -----------------------------------------------------------

    def press(self, pos, screen) -> None:
        if self._refused():
            return
        if self.mode == "guide":
            if not self.guide or math.hypot(pos[0] - self.guide[-1][0], pos[1] - self.guide[-1][1]) > 1.0:
                self.guide.append((float(pos[0]), float(pos[1])))
            return
        self._group, self._last = object(), None
        if self.mode != "comb":
            self.drag(pos, screen)
        else:
            self._last = pos

    def drag(self, pos, screen) -> None:
        if self._group is None:
            return
        r = self.radius_canvas()
        dabs = headed_dabs(self._last, pos, 0.25 * r)
        if not dabs:
            return
        field = self.field
        rects = []
        try:
            for cx, cy, heading in dabs:
                field = self.dab(field, cx, cy, heading)
                rects.append(dab_rect(cx, cy, r))
        except FieldTooLarge as exc:
            self.ed.tell(str(exc))
            self.release()
            return
        self._last = dabs[-1][:2]
        self.dabs += len(dabs)
        if field is not self.field:
            self._set(field, {"comb": "Comb direction", "smooth": "Smooth direction", "grow": "Grow texture",
                              "shrink": "Shrink texture", "erase": "Erase direction"}[self.mode], self._group, rects)

    def release(self) -> None:
        if self._group is not None and self.ed.history is not None:
            self.ed.history.end_group()
        self._group, self._last = None, None

    def apply_guide(self) -> None:
        """The texture follows the guide's curve within its width, then fades into
        what is there over the blend distance: between two guides closer than that,
        the direction turns smoothly from one to the other."""
        pts = np.array(self.guide, np.float64)
        self.guide = []
        if len(pts) < 2 or self._refused():
            return
        try:
            field = self.field.guided(pts, self.guide_width, self.guide_blend, self.brush.strength,
                                      self._axis_offset(), MAX_GUIDE_AREA)
        except (ValueError, FieldTooLarge) as exc:
            self.ed.tell(str(exc))
            return
        self._set(field, "Direction guide")

    def place_map(self, path: str) -> None:
        """A flow or angle map placed centered in the view (replacing the field there)."""
        from infinitex.engine.controls.maps import load_direction_map
        ed = self.ed
        if self._refused():
            return
        try:
            values = load_direction_map(path, self.map_kind, self.map_y_up)
            h, w = values.shape[:2]
            x, y = int(ed.view.x) - w // 2, int(ed.view.y) - h // 2
            field = self.field.replaced(values, x, y)
        except (ExemplarError, FieldTooLarge, ValueError) as exc:
            ed.dialogs.message("Direction map", str(exc))
            return
        self._set(field, "Place direction map", region=[(x, y, x + w, y + h)])

    # -- panel, keys, overlay ------------------------------------------------

    def model_gesture(self):
        if self._model is None:
            from .direction_model import ModelComb
            self._model = ModelComb(self.ed)
        return self._model

    def options(self) -> None:
        ed = self.ed
        if self.offer_lattice_off("A direction field does not work on a lattice: its cells would not follow it."):
            return
        for i, (mode, label, says) in enumerate(MODES):
            if mode == "guide" and ed.model_mode:
                continue  # (guides and maps are placed on the plane)
            if i % 3:
                imgui.same_line()
            if imgui.radio_button(f"{label}##direction-mode", self.mode == mode):
                if mode != "guide":
                    self.guide = []
                self.mode = mode
            tip(says)
        imgui.push_item_width(-110)
        if imgui.radio_button("x along strokes##direction-axis", self.axis == 0):
            self.axis = 0
        tip("The exemplar's horizontal runs along your strokes and guides")
        imgui.same_line()
        if imgui.radio_button("y along strokes##direction-axis", self.axis == 1):
            self.axis = 1
        tip("The exemplar's vertical runs along your strokes and guides")
        if self.mode == "guide" and ed.model_mode:
            self.mode = "comb"
        if self.mode == "guide":
            _, self.guide_width = imgui.slider_float("Guide width", self.guide_width, 4.0, 1024.0, "%.0f px",
                                                     imgui.SliderFlags_.logarithmic)
            tip("Within this width the texture follows the guide fully")
            _, self.guide_blend = imgui.slider_float("Blend", self.guide_blend, 0.0, 1024.0, "%.0f px",
                                                     imgui.SliderFlags_.logarithmic)
            tip("Beyond the width, the guide fades into what is there over this distance: "
                "between two guides, the texture turns smoothly from one to the other")
            _, self.brush.strength = imgui.slider_float("Strength", self.brush.strength, 0.0, 1.0, "%.2f")
            imgui.pop_item_width()
            imgui.text_disabled(f"{len(self.guide)} points: click to add, Backspace removes, Enter applies")
            if imgui.button("Apply guide") and len(self.guide) >= 2:
                self.apply_guide()
            imgui.same_line()
            if imgui.button("Cancel guide"):
                self.guide = []
        else:
            if self.mode in ("grow", "shrink"):
                _, self.rate = imgui.slider_float("Rate", self.rate, 1.05, 4.0, "%.2fx")
                tip("How much larger (or smaller) a stroke over a spot makes the texture")
                imgui.text_wrapped(GROW_NOTE if self.mode == "grow" else SHRINK_NOTE)
            imgui.pop_item_width()
            b = self.brush
            imgui.push_item_width(-110)
            _, b.radius = imgui.slider_float("Radius", b.radius, 1.0, 400.0, "%.0f px", imgui.SliderFlags_.logarithmic)
            _, b.strength = imgui.slider_float("Strength", b.strength, 0.0, 1.0, "%.2f")
            _, b.hardness = imgui.slider_float("Hardness", b.hardness, 0.0, 1.0, "%.2f")
            imgui.pop_item_width()
        imgui.separator()
        if ed.model_mode:
            imgui.text_wrapped("On the model, strokes follow the surface; the direction is read in the model's "
                               "own (Model panel).")
            if ed.doc.direction is not None and imgui.button("Clear direction field", (-1, 0)):
                self._set(DirectionField(), "Clear direction field")
            return
        if imgui.radio_button("Flow map##direction-map", self.map_kind == "flow"):
            self.map_kind = "flow"
        imgui.same_line()
        if imgui.radio_button("Angle map##direction-map", self.map_kind == "angle"):
            self.map_kind = "angle"
        imgui.same_line()
        if imgui.radio_button("Guess##direction-map", self.map_kind == "auto"):
            self.map_kind = "auto"
        _, self.map_y_up = imgui.checkbox("Flow map green points up (OpenGL)", self.map_y_up)
        if imgui.button("Place direction map...", (-1, 0)):
            ed.dialogs.ask_path("Direction map", False, MAP_FILTER, self.place_map)
        tip("A flow map (red and green, mid-gray = as is) or an angle map (gray: 0 to 360 "
            "degrees), placed centered in the view")
        if ed.doc.direction is not None and imgui.button("Clear direction field", (-1, 0)):
            self._set(DirectionField(), "Clear direction field")

    def atlas_overlay(self, doc, n: int):
        """On a model: the combed field as short strokes (render/overlays.direction_rgba)."""
        from ...render.overlays import direction_rgba
        d = doc.direction
        if d is None or d.identity:
            return None
        return ("direction", d.key, n, self.axis), lambda: direction_rgba(d, n, self.axis)

    def keys(self) -> None:
        brush_keys(self.brush)
        if self.mode != "guide" or imgui.get_io().want_text_input:
            return
        if imgui.is_key_pressed(imgui.Key.enter, False) or imgui.is_key_pressed(imgui.Key.keypad_enter, False):
            self.apply_guide()
        if imgui.is_key_pressed(imgui.Key.backspace) and self.guide:
            self.guide.pop()
        if imgui.is_key_pressed(imgui.Key.escape, False):
            self.guide = []

    def overlay(self, draw_list, p0, w, h) -> None:
        ed = self.ed
        z = ed.view.zoom
        x0, y0 = ed.view.top_left(w, h)
        if self.guide:
            pts = [(p0.x + (px - x0) * z, p0.y + (py - y0) * z) for px, py in self.guide]
            io = imgui.get_io()
            for a, b in zip(pts, pts[1:] + [(io.mouse_pos.x, io.mouse_pos.y)]):
                draw_list.add_line(a, b, imgui.get_color_u32((0, 0, 0, 0.8)), 3.0)
                draw_list.add_line(a, b, imgui.get_color_u32((1, 0.8, 0.2, 1.0)), 1.5)
            for c in pts:
                draw_list.add_circle_filled(c, 4.0, imgui.get_color_u32((1, 0.8, 0.2, 1.0)))
        if ed.canvas_state.cursor is None:
            return
        io = imgui.get_io()
        c = (io.mouse_pos.x, io.mouse_pos.y)
        r = self.guide_width * z / 2 if self.mode == "guide" else self.radius_canvas() * z
        if self.mode == "guide" and self.guide_blend > 0:
            draw_list.add_circle(c, r + self.guide_blend * z, imgui.get_color_u32((1, 0.8, 0.2, 0.4)), 0, 1.0)
        draw_list.add_circle(c, r, imgui.get_color_u32((0, 0, 0, 0.8)), 0, 3.0)
        draw_list.add_circle(c, r, imgui.get_color_u32((1, 0.8, 0.2, 0.9)), 0, 1.5)


def draw_field(draw_list, field: DirectionField | None, view, p0, w: int, h: int, axis: int = 0) -> None:
    """Short strokes along the exemplar's x (or y) over the canvas where the
    field is painted, one every ~28 screen px (read from the field's mipmap at
    that spacing, so drawing costs the same at any zoom)."""
    if field is None or field.identity:
        return
    z = view.zoom
    x0, y0 = view.top_left(w, h)
    step = max(1, int(round(math.log2(max(1.0, 28.0 / z)))))
    cell = 1 << step
    gx0, gy0 = math.floor(x0) >> step, math.floor(y0) >> step
    gw, gh = int(w / z) // cell + 2, int(h / z) // cell + 2
    if gw * gh > 20000:
        return
    j = field.region(step, gx0, gy0, gw, gh)
    if j is None:
        return
    painted = np.any(j != np.array([4096, 0, 0, 4096], np.int16), axis=-1)
    th, sc, _ = decompose(j)
    a = np.radians(th + 90.0 * axis)
    half = 0.35 * cell * z * np.clip(sc, 0.5, 2.0)
    dark, light = imgui.get_color_u32((0, 0, 0, 0.7)), imgui.get_color_u32((1, 0.8, 0.2, 0.95))
    for iy, ix in zip(*np.nonzero(painted)):
        cx = p0.x + ((gx0 + ix + 0.5) * cell - x0) * z
        cy = p0.y + ((gy0 + iy + 0.5) * cell - y0) * z
        if not (p0.x - 20 <= cx <= p0.x + w + 20 and p0.y - 20 <= cy <= p0.y + h + 20):
            continue
        dx, dy = half[iy, ix] * math.cos(a[iy, ix]), half[iy, ix] * math.sin(a[iy, ix])
        draw_list.add_line((cx - dx, cy - dy), (cx + dx, cy + dy), dark, 3.0)
        draw_list.add_line((cx - dx, cy - dy), (cx + dx, cy + dy), light, 1.5)
        draw_list.add_circle_filled((cx + dx, cy + dy), 2.0, light)
