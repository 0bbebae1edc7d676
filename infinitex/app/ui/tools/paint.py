"""Painting randomness (LH05 4.2): on the canvas, or on the exemplar in its own
window, where regions to avoid (never copied) are painted too. Brush conventions as in Krita / Photoshop: radius (screen or canvas
pixels), strength, hardness, a value from calm (0) through neutral (1) to
rough (2), an eraser back to neutral; [ and ] resize the brush, Alt-click
picks the value under the cursor, a circle shows the brush. One stroke (press
to release) is one undo step. Painting on the canvas re-synthesizes only what
the stroke reaches (engine.pyramid.Pyramid.update_controls)."""
from __future__ import annotations

import math
from dataclasses import dataclass, replace

from imgui_bundle import imgui

from infinitex.engine.controls import NEUTRAL, CanvasField, ExemplarField, ExemplarMask
from infinitex.engine.surface.features import across_seams

from . import MAX_CANVAS_RADIUS, BrushGesture, Tool, begin_tool_window
from ..tips import tip


@dataclass
class Brush:
    radius: float = 24.0        # in screen pixels (canvas) or exemplar pixels (exemplar)
    screen_units: bool = True   # canvas: radius in screen pixels (else canvas pixels)
    strength: float = 0.8
    hardness: float = 0.5
    value: float = 0.0          # 0 calm .. 1 neutral .. 2 rough
    eraser: bool = False

    @property
    def value_u16(self) -> int:
        return NEUTRAL if self.eraser else int(min(65535, max(0, round(self.value * NEUTRAL))))


def brush_options(brush: Brush, canvas: bool, values: bool = True,
                  eraser_label: str = "Eraser (back to neutral)") -> None:
    """The brush's controls; ``values`` False: only its size and the eraser (a mask brush)."""
    imgui.push_item_width(-110)
    _, brush.radius = imgui.slider_float("Radius", brush.radius, 1.0, 400.0, "%.0f px",
                                         imgui.SliderFlags_.logarithmic)
    tip("Brush size ([ and ] change it)")
    if canvas:
        _, brush.screen_units = imgui.checkbox("Radius in screen pixels", brush.screen_units)
        tip("On: the brush keeps its size on screen at any zoom. Off: it covers a "
            "fixed area of the canvas")
    if values:
        _, brush.value = imgui.slider_float("Paint value", brush.value, 0.0, 2.0, "%.2f")
        tip("0 = calm (no randomness: the exemplar is copied as it is), 1 = neutral, "
            "2 = rough (twice the randomness). Alt-click picks the value under the cursor")
        _, brush.strength = imgui.slider_float("Strength", brush.strength, 0.0, 1.0, "%.2f")
        _, brush.hardness = imgui.slider_float("Hardness", brush.hardness, 0.0, 1.0, "%.2f")
    imgui.pop_item_width()
    _, brush.eraser = imgui.checkbox(eraser_label, brush.eraser)


def brush_keys(brush: Brush) -> None:
    if imgui.get_io().want_text_input:
        return
    if imgui.is_key_pressed(imgui.Key.left_bracket):
        brush.radius = max(1.0, brush.radius / 1.25)
    if imgui.is_key_pressed(imgui.Key.right_bracket):
        brush.radius = min(400.0, brush.radius * 1.25)


def dab_centers(last: tuple[float, float] | None, pos: tuple[float, float], spacing: float) -> list[tuple[float, float]]:
    """Dab centers from the last dab to pos, every ``spacing`` (the last one at pos)."""
    if last is None:
        return [pos]
    d = math.hypot(pos[0] - last[0], pos[1] - last[1])
    n = int(d // max(spacing, 0.5))
    if n == 0:
        return []
    return [(last[0] + (pos[0] - last[0]) * i / n, last[1] + (pos[1] - last[1]) * i / n) for i in range(1, n + 1)]


def headed_dabs(last: tuple[float, float] | None, pos: tuple[float, float],
                spacing: float) -> list[tuple[float, float, float | None]]:
    """:func:`dab_centers` with the stroke's heading at each (degrees, canvas y
    down; None at a first dab, which has none yet): what a comb paints."""
    out = []
    prev = last
    for c in dab_centers(last, pos, spacing):
        heading = None
        if prev is not None and c != prev:
            heading = math.degrees(math.atan2(c[1] - prev[1], c[0] - prev[0]))
        out.append((c[0], c[1], heading))
        prev = c
    return out


def model_stroke(field: CanvasField | None, atlas, n: int, last: tuple[float, float] | None,
                 pos: tuple[float, float], radius: float, brush: Brush) -> tuple[CanvasField, tuple | None, int, list]:
    """A Paint canvas stroke on a model carried on to ``pos`` (finest atlas
    texels, n a side): dabs every quarter radius from ``last`` (none in
    between when ``pos`` is on another chart or farther than 4 radii: the atlas
    between is elsewhere on the surface), each continued over the seams it
    reaches (at most twice its radius there) and painted only inside the
    atlas. Returns the field, the stroke's new last dab, the dabs painted and
    the rectangles (x0, y0, x1, y1) they changed."""
    owner = atlas.owner(0) if atlas is not None else None

    def chart(p) -> int:
        if owner is None:
            return 0
        return int(owner[min(n - 1, max(0, int(p[1]))), min(n - 1, max(0, int(p[0])))])

    if last is not None and (math.hypot(pos[0] - last[0], pos[1] - last[1]) > 4 * radius or chart(last) != chart(pos)):
        last = None
    dabs = dab_centers(last, pos, 0.25 * radius)
    field = field or CanvasField()
    rects = []
    for cx, cy in dabs:
        for x, y, rr in [(cx, cy, radius)] + (across_seams(atlas, cx, cy, radius) if atlas is not None else []):
            field, rect = field.painted(x, y, min(rr, 2 * radius), brush.value_u16, brush.strength, brush.hardness,
                                        bounds=(0, 0, n, n))
            rects.append(rect)
    return field, (dabs[-1] if dabs else last), len(dabs), rects


class ModelPaint(BrushGesture):
    """The Paint canvas brush on a model: dabs where the ray under the mouse
    meets it, in atlas texels (the brush keeps its size on screen), along the
    stroke (:func:`model_stroke`); one undo step per stroke."""

    def __init__(self, ed):
        super().__init__(ed)
        self._last: tuple[float, float] | None = None
        self._group: object = None

    def press(self, mx: float, my: float, w: int, h: int) -> None:
        self._last, self._group = None, object()
        self.drag(mx, my, w, h)

    def drag(self, mx: float, my: float, w: int, h: int) -> None:
        from ...render.model_view import dab_radius
        ed = self.ed
        if self._group is None:
            return
        hit = ed.model.pick_atlas(mx, my, w, h)
        if hit is None:
            self._last = None
            return
        pos, per_px = hit  # (atlas texels per screen pixel here)
        tool = ed.tool
        b = tool.brush
        n = ed.doc.surface.size
        r = dab_radius(b.radius, b.screen_units, per_px, n)
        field, self._last, count, rects = model_stroke(ed.doc.randomness_canvas, ed.session.model.atlas, n,
                                                       self._last, pos, r, b)
        if not count:
            return
        tool.dabs += count
        ed.edit(replace(ed.doc, randomness_canvas=field), "Paint randomness (model)", group=self._group,
                region=rects)

    def finish(self, mx: float, my: float, w: int, h: int) -> None:
        self.release()  # (no dab where the button came up: the last move's was made)

    def release(self) -> None:
        if self._group is not None and self.ed.history is not None:
            self.ed.history.end_group()
        self._last, self._group = None, None


def clear_painted(ed) -> None:
    """The "Clear painted randomness" button of the paint tools (when there is some)."""
    doc = ed.doc
    if doc.randomness_canvas is not None or doc.randomness_exemplar is not None:
        if imgui.button("Clear painted randomness", (-1, 0)):
            ed.edit(replace(doc, randomness_canvas=None, randomness_exemplar=None), "Clear painted randomness")


class PaintCanvasTool(Tool):
    name = "paint-canvas"
    label = "Paint canvas"
    key = "B"
    tooltip = "Paint where the texture may vary: calm (0) keeps the exemplar's look, rough (2) varies more (B)"
    space = "canvas"
    shows_painted = True

    def __init__(self, ed):
        super().__init__(ed)
        self.brush = Brush()
        self._last: tuple[float, float] | None = None
        self._group: object = None
        self.dabs = 0  # dabs painted (benchmarks, tests)
        self._model = ModelPaint(ed)

    def model_gesture(self) -> ModelPaint:
        return self._model

    def radius_canvas(self) -> float:
        b = self.brush
        return min(MAX_CANVAS_RADIUS, b.radius / self.ed.view.zoom if b.screen_units else b.radius)

    def press(self, pos, screen) -> None:
        ed = self.ed
        if imgui.get_io().key_alt:
            field = ed.doc.randomness_canvas
            x, y = math.floor(pos[0]), math.floor(pos[1])
            v = field.region(0, x, y, 1, 1) if field is not None else None
            self.brush.value = (NEUTRAL if v is None else int(v[0, 0])) / NEUTRAL
            self.brush.eraser = False
            return
        self._group = object()
        self._last = None
        self.drag(pos, screen)

    def drag(self, pos, screen) -> None:
        if self._group is None:
            return
        r = self.radius_canvas()
        dabs = dab_centers(self._last, pos, 0.25 * r)
        if not dabs:
            return
        ed = self.ed
        field = ed.doc.randomness_canvas or CanvasField()
        b = self.brush
        rects = []
        for cx, cy in dabs:
            field, rect = field.painted(cx, cy, r, b.value_u16, b.strength, b.hardness)
            rects.append(rect)
        self._last = dabs[-1]
        self.dabs += len(dabs)
        ed.edit(replace(ed.doc, randomness_canvas=field), "Paint randomness (canvas)", group=self._group,
                region=rects)

    def release(self) -> None:
        if self._group is not None and self.ed.history is not None:
            self.ed.history.end_group()
        self._group = None
        self._last = None

    def options(self) -> None:
        brush_options(self.brush, canvas=True)
        clear_painted(self.ed)

    def keys(self) -> None:
        brush_keys(self.brush)

    def overlay(self, draw_list, p0, w, h) -> None:
        ed = self.ed
        if ed.canvas_state.cursor is None:
            return
        io = imgui.get_io()
        r = self.radius_canvas() * ed.view.zoom
        c = (io.mouse_pos.x, io.mouse_pos.y)
        draw_list.add_circle(c, r, imgui.get_color_u32((0, 0, 0, 0.8)), 0, 3.0)
        draw_list.add_circle(c, r, imgui.get_color_u32((1, 1, 1, 0.9)), 0, 1.5)


class PaintExemplarTool(Tool):
    """Paints over the exemplar, in the Paint exemplar window (zoomable): the
    randomness field (what is protected there stays whole wherever it appears on
    the canvas), or regions to avoid (the synthesis never copies them: a
    blemish, a logo, an element that would recur once per exemplar area)."""

    name = "paint-exemplar"
    label = "Paint exemplar"
    key = "E"
    tooltip = ("Paint on the exemplar (in its window): randomness (calm keeps those features whole wherever "
               "they appear, rough breaks them up more), or regions to avoid, never copied (E)")
    space = "exemplar"
    shows_painted = True

    def __init__(self, ed):
        super().__init__(ed)
        self.brush = Brush(radius=6.0, screen_units=False)
        self.mode = "randomness"   # or "avoid"
        self.zoom = 3.0
        self._last: tuple[float, float] | None = None
        self._group: object = None

    def options(self) -> None:
        if imgui.radio_button("Randomness##paint-mode", self.mode == "randomness"):
            self.mode = "randomness"
        tip("Paint how much the exemplar's features may vary: calm keeps them whole, "
            "rough breaks them up")
        imgui.same_line()
        if imgui.radio_button("Avoid##paint-mode", self.mode == "avoid"):
            self.mode = "avoid"
        tip("Mark exemplar regions the synthesis must not copy: a blemish, a logo, or an "
            "element that stands out and would recur once per exemplar area")
        if self.mode == "avoid":
            brush_options(self.brush, canvas=False, values=False, eraser_label="Eraser (usable again)")
            ed = self.ed
            mask = ed.doc.avoid_exemplar
            if mask is not None and not mask.empty:
                imgui.text(f"{100 * mask.fraction:.1f}% of the exemplar avoided")
                if imgui.small_button("Clear avoided regions"):
                    ed.edit(replace(ed.doc, avoid_exemplar=None), "Clear avoided regions")
        else:
            brush_options(self.brush, canvas=False)
        imgui.text_disabled("Paint in the Paint exemplar window.")
        clear_painted(self.ed)

    def keys(self) -> None:
        brush_keys(self.brush)

    def _paint(self, pos) -> None:
        ed = self.ed
        m = ed.session.analysis.size
        dabs = dab_centers(self._last, pos, 0.25 * self.brush.radius)
        if not dabs:
            return
        doc = ed.doc
        b = self.brush
        self._last = dabs[-1]
        if self.mode == "avoid":
            mask = doc.controls(m).avoid or ExemplarMask.blank(m)
            for cx, cy in dabs:
                mask = mask.painted(cx, cy, b.radius, avoid=not b.eraser)
            if mask.full:
                ed.tell("The whole exemplar cannot be avoided: leave some of it usable.")
                return
            ed.edit(replace(doc, avoid_exemplar=None if mask.empty else mask), "Avoid exemplar regions",
                    group=self._group)
            return
        field = doc.controls(m).randomness_exemplar or ExemplarField.blank(m)
        for cx, cy in dabs:
            field = field.painted(cx, cy, b.radius, b.value_u16, b.strength, b.hardness)
        ed.edit(replace(doc, randomness_exemplar=field), "Paint randomness (exemplar)", group=self._group)

    def window(self) -> None:
        """The Paint exemplar window: the exemplar, zoomable, with its field as a
        heat map and its avoided regions hatched."""
        ed = self.ed
        s = ed.session
        if not s.ready or ed.canvas.exemplar_tex is None:
            return
        m = s.analysis.size
        w, h = min(760, m * self.zoom + 40), min(760, m * self.zoom + 90)
        if begin_tool_window(ed, self, "Paint exemplar", (w, h), (m, m), (0.5, 8.0), "%.1fx"):
            imgui.begin_child("exemplar-view", (0, 0), 0, imgui.WindowFlags_.horizontal_scrollbar)
            size = m * self.zoom
            p0 = imgui.get_cursor_screen_pos()
            imgui.image(imgui.ImTextureRef(ed.canvas.exemplar_tex.glo), (size, size))
            dl = imgui.get_window_draw_list()
            controls = ed.doc.controls(m)
            heat = ed.overlay_exemplar.exemplar(controls.randomness_exemplar, m)
            if heat is not None and ed.viewer.show_fields:
                dl.add_image(imgui.ImTextureRef(heat.glo), p0, (p0.x + size, p0.y + size))
            hatch = ed.overlay_avoid.mask(controls.avoid)
            if hatch is not None:
                dl.add_image(imgui.ImTextureRef(hatch.glo), p0, (p0.x + size, p0.y + size))
            imgui.set_cursor_screen_pos(p0)
            imgui.invisible_button("exemplar-paint", (size, size))
            io = imgui.get_io()
            ex = ((io.mouse_pos.x - p0.x) / self.zoom, (io.mouse_pos.y - p0.y) / self.zoom)
            if imgui.is_item_activated():
                if io.key_alt and self.mode == "randomness":
                    f = controls.randomness_exemplar
                    xi, yi = int(min(m - 1, max(0, ex[0]))), int(min(m - 1, max(0, ex[1])))
                    self.brush.value = (NEUTRAL if f is None else int(f.values[yi, xi])) / NEUTRAL
                    self.brush.eraser = False
                else:
                    self._group, self._last = object(), None
            if imgui.is_item_active() and self._group is not None:
                self._paint(ex)
            if imgui.is_item_deactivated() and self._group is not None:
                ed.history.end_group()
                self._group, self._last = None, None
            if imgui.is_item_hovered():
                r = self.brush.radius * self.zoom
                dl.add_circle(io.mouse_pos, r, imgui.get_color_u32((0, 0, 0, 0.8)), 0, 3.0)
                color = (1, 0.3, 0.85, 0.95) if self.mode == "avoid" else (1, 1, 1, 0.9)
                dl.add_circle(io.mouse_pos, r, imgui.get_color_u32(color), 0, 1.5)
            imgui.end_child()
        imgui.end()
