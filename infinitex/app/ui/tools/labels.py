"""Texture by numbers (TBN10; engine/controls/labels.py): say which kind of
texture goes where. The exemplar gets a label map (imported from an image,
proposed by clustering its appearance, painted by hand in the Labels window);
on the canvas a label brush, an eraser back to free, and a fill say which label
each place should get; synthesis follows, taking transitions from the
exemplar's own. A stroke (press to release), a fill, a rename and an import are
each one undo step; a canvas stroke re-synthesizes only what it reaches."""
from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
from imgui_bundle import imgui

from infinitex.engine.controls import CanvasLabels, ExemplarLabels
from infinitex.engine.controls.label_maps import (
    canvas_labels_from_colors,
    exemplar_labels_from_colors,
    fit_label_map,
    load_label_image,
)
from infinitex.engine.controls.labels import LABEL_COLORS, propose_labels
from infinitex.engine.exemplar import ExemplarError
from infinitex.project.document import LabelMaps

from . import MAX_CANVAS_RADIUS, Tool, begin_tool_window
from .paint import Brush, brush_keys, dab_centers
from ..tips import tip

FILL_LIMIT = 4096  # a fill covers at most this many canvas pixels a side (the view, at most)
LABEL_FILTER = ["Label maps", "*.png *.bmp *.tif *.tiff *.gif *.webp"]


class LabelTool(Tool):
    name = "labels"
    label = "Labels"
    key = "G"
    tooltip = ("Texture by numbers: give the exemplar's regions labels (stones, grass, mortar...), then paint "
               "on the canvas which label goes where (G)")
    space = "canvas"
    shows_painted = True
    panel = "Labels"
    on_model = False

    def __init__(self, ed):
        super().__init__(ed)
        self.brush = Brush(radius=32.0, hardness=0.8)
        self.active = 0          # the label the brush paints
        self.mode = "brush"      # "brush", "fill" (canvas) or "exemplar" (paint the exemplar's map)
        self.propose_n = 3
        self.zoom = 3.0
        self._last: tuple[float, float] | None = None
        self._group: object = None
        self._strength_group: object = None
        self.strokes = 0         # strokes painted (tests)
        self.dabs = 0            # dabs painted on the canvas (benchmarks)

    # -- the document ------------------------------------------------------

    @property
    def labels(self) -> LabelMaps | None:
        lab = self.ed.doc.labels if self.ed.doc is not None else None
        if lab is not None and self.active >= len(lab.colors):
            self.active = len(lab.colors) - 1  # an undo or another document has fewer labels
        return lab

    def _set(self, labels: LabelMaps | None, what: str, group: object = None, region=None) -> None:
        self.ed.edit(replace(self.ed.doc, labels=labels), what, group=group, region=region)

    def _value(self) -> int:
        return 0 if self.brush.eraser else self.active + 1

    def import_map(self, path: str) -> None:
        """The exemplar's label map from an image (each distinct color a label)."""
        ed = self.ed
        s = ed.session
        try:
            ids, colors = exemplar_labels_from_colors(load_label_image(path, "label map"))
            ids = fit_label_map(ids, ed.doc.fit, s.analysis.size, s.exemplar.original_size, "label map")
        except ExemplarError as exc:
            ed.dialogs.message("Label map", str(exc))
            return
        old = self.labels
        keep = old is not None and list(old.colors) == colors
        self._set(LabelMaps(ExemplarLabels(ids), tuple(colors), old.names if keep else (),
                            old.canvas if keep else CanvasLabels(), old.strength if old else 1.0),
                  "Import label map")
        self.active = 0

    def place_image(self, path: str) -> None:
        """A label image (the exemplar map's colors, transparent = free) placed
        centered in the view; its free pixels keep what is painted there."""
        ed = self.ed
        lab = self.labels
        try:
            values = canvas_labels_from_colors(load_label_image(path, "canvas label map"), list(lab.colors))
            h, w = values.shape
            canvas = lab.canvas.replaced(values, int(ed.view.x) - w // 2, int(ed.view.y) - h // 2, keep_free=True)
        except (ExemplarError, ValueError) as exc:
            ed.dialogs.message("Canvas label map", str(exc))
            return
        self._set(replace(lab, canvas=canvas), "Place label image")

    def propose(self) -> None:
        """Labels proposed by clustering the exemplar's appearance into ``propose_n`` regions."""
        ed = self.ed
        ids = propose_labels(ed.session.analysis, self.propose_n)
        n = int(ids.max()) + 1
        old = self.labels
        self._set(LabelMaps(ExemplarLabels(ids), LABEL_COLORS[:n], (), CanvasLabels(), old.strength if old else 1.0),
                  f"Propose {n} labels")
        self.active = 0

    # -- options -----------------------------------------------------------

    def options(self) -> None:
        ed = self.ed
        lab = self.labels
        if imgui.button("Import label map..."):
            ed.dialogs.ask_path("Exemplar label map", False, LABEL_FILTER, self.import_map)
        tip("An image the size of the exemplar whose flat colors mark its regions: each "
            "distinct color is a label (at most 16; an indexed PNG works well)")
        imgui.same_line()
        if imgui.button("Propose"):
            self.propose()
        tip("Split the exemplar into regions that look alike (then correct them by hand "
            "in the Labels window)")
        imgui.same_line()
        imgui.set_next_item_width(-1)
        _, self.propose_n = imgui.slider_int("##propose-n", self.propose_n, 2, 8, "%d labels")
        if lab is None:
            imgui.text_wrapped("Give the exemplar labels first: import a label map or let Infinitex propose one.")
            return
        self._label_list(lab)
        if imgui.radio_button("Brush##labels-mode", self.mode == "brush"):
            self.mode = "brush"
        imgui.same_line()
        if imgui.radio_button("Fill##labels-mode", self.mode == "fill"):
            self.mode = "fill"
        tip("Click inside a closed region of the canvas (within the view) to give it the label")
        imgui.same_line()
        if imgui.radio_button("Exemplar##labels-mode", self.mode == "exemplar"):
            self.mode = "exemplar"
        tip("Paint the exemplar's own labels, in the Labels window")
        imgui.push_item_width(-110)
        _, self.brush.radius = imgui.slider_float("Radius", self.brush.radius, 1.0, 400.0, "%.0f px",
                                                  imgui.SliderFlags_.logarithmic)
        if self.mode == "brush":
            _, self.brush.hardness = imgui.slider_float("Hardness", self.brush.hardness, 0.0, 1.0, "%.2f")
            tip("A soft edge mixes the labels over a wider band: a wider transition")
        changed, strength = imgui.slider_float("Label strength", lab.strength, 0.0, 8.0, "%.2f")
        tip("How strictly the texture follows the painted labels: low lets the texture flow "
            "across label borders, high keeps every label in its place (more at coarse scales)")
        imgui.pop_item_width()
        if imgui.is_item_activated():
            self._strength_group = object()
        if changed:
            self._set(replace(lab, strength=float(strength)), "Label strength", self._strength_group)
        if imgui.is_item_deactivated_after_edit() and ed.history is not None:
            ed.history.end_group()
        _, self.brush.eraser = imgui.checkbox("Eraser (back to the first exemplar)" if self.ed.doc.palette
                                              else "Eraser (back to free)", self.brush.eraser)
        if imgui.button("Place label image..."):
            ed.dialogs.ask_path("Canvas label map", False, LABEL_FILTER, self.place_image)
        tip("An image in the exemplar's label colors, placed centered in the view; its "
            "transparent pixels leave the canvas as it is")
        if not lab.canvas.empty and imgui.button("Clear canvas labels"):
            self._set(replace(lab, canvas=CanvasLabels()), "Clear canvas labels")
        imgui.same_line()
        if imgui.button("Remove labels"):
            self._set(None, "Remove labels")

    def _label_list(self, lab: LabelMaps) -> None:
        present = set(lab.exemplar.present)
        for i, c in enumerate(lab.colors):
            imgui.push_id(f"label-{i}")
            imgui.color_button("##swatch", (c[0] / 255, c[1] / 255, c[2] / 255, 1.0), 0, (18, 18))
            imgui.same_line()
            if imgui.radio_button("##active", self.active == i and not self.brush.eraser):
                self.active, self.brush.eraser = i, False
            imgui.same_line()
            imgui.set_next_item_width(-1)
            changed, name = imgui.input_text_with_hint("##name", f"Label {i + 1}" + (
                "" if i in present else " (not on the exemplar)"), lab.names[i] if i < len(lab.names) else "")
            if imgui.is_item_deactivated_after_edit() or (changed and imgui.is_key_pressed(imgui.Key.enter)):
                names = list(lab.names) + [""] * (len(lab.colors) - len(lab.names))
                names[i] = name[:64]
                self._set(replace(lab, names=tuple(names)), "Rename label")
            imgui.pop_id()

    def keys(self) -> None:
        brush_keys(self.brush)

    # -- the canvas ----------------------------------------------------------

    def radius_canvas(self) -> float:
        return min(MAX_CANVAS_RADIUS, self.brush.radius / self.ed.view.zoom)

    def press(self, pos, screen) -> None:
        lab = self.labels
        if lab is None or self.mode == "exemplar":
            return
        if self.active not in lab.exemplar.present and not self.brush.eraser:
            self.ed.tell(f"{lab.name(self.active)} is not on the exemplar: give the exemplar some of it "
                         "first (Exemplar mode).")
            return
        if self.mode == "fill":
            self.fill(pos)
            return
        self._group, self._last = object(), None
        self.drag(pos, screen)

    def drag(self, pos, screen) -> None:
        lab = self.labels
        if self._group is None or lab is None:
            return
        r = self.radius_canvas()
        dabs = dab_centers(self._last, pos, 0.25 * r)
        if not dabs:
            return
        canvas = lab.canvas
        rects = []
        for cx, cy in dabs:
            canvas, rect = canvas.painted(cx, cy, r, self._value(), self.brush.hardness, seed=self.strokes)
            rects.append(rect)
        self._last = dabs[-1]
        self.dabs += len(dabs)
        self._set(replace(lab, canvas=canvas), "Paint labels", self._group, rects)

    def release(self) -> None:
        if self._group is not None:
            self.strokes += 1
            if self.ed.history is not None:
                self.ed.history.end_group()
        self._group, self._last = None, None

    def fill(self, pos) -> None:
        """Give the label to the connected region of equal canvas labels around
        ``pos``, within the view (at most FILL_LIMIT pixels a side)."""
        from scipy import ndimage
        ed = self.ed
        lab = self.labels
        w, h = ed.canvas_size
        x0, y0 = ed.view.top_left(w, h)
        x0, y0 = math.floor(x0), math.floor(y0)
        x1, y1 = math.ceil(x0 + w / ed.view.zoom) + 1, math.ceil(y0 + h / ed.view.zoom) + 1
        px, py = math.floor(pos[0]), math.floor(pos[1])
        half = FILL_LIMIT // 2
        x0, y0, x1, y1 = max(x0, px - half), max(y0, py - half), min(x1, px + half), min(y1, py + half)
        if not (x0 <= px < x1 and y0 <= py < y1):
            return
        area = lab.canvas.sample(np.arange(x0, x1), np.arange(y0, y1))
        same = area == area[py - y0, px - x0]
        comp, _ = ndimage.label(same)
        region = comp == comp[py - y0, px - x0]
        value = self._value()
        if np.all(area[region] == value):
            return
        area = np.where(region, value, area).astype(np.uint8)
        ys, xs = np.nonzero(region)
        bx0, by0, bx1, by1 = xs.min(), ys.min(), xs.max() + 1, ys.max() + 1
        canvas = lab.canvas.replaced(area[by0:by1, bx0:bx1], x0 + int(bx0), y0 + int(by0))
        self._set(replace(lab, canvas=canvas), "Fill labels",
                  region=[(x0 + int(bx0), y0 + int(by0), x0 + int(bx1), y0 + int(by1))])

    def overlay(self, draw_list, p0, w, h) -> None:
        ed = self.ed
        lab = self.labels
        if ed.canvas_state.cursor is None or lab is None or self.mode == "exemplar":
            return
        io = imgui.get_io()
        c = (io.mouse_pos.x, io.mouse_pos.y)
        col = (1, 1, 1, 0.9) if self.brush.eraser else tuple(v / 255 for v in lab.colors[self.active]) + (1.0,)
        if self.mode == "fill":
            draw_list.add_circle_filled(c, 6.0, imgui.get_color_u32(col))
            draw_list.add_circle(c, 6.0, imgui.get_color_u32((0, 0, 0, 0.9)), 0, 1.5)
            return
        r = self.brush.radius
        draw_list.add_circle(c, r, imgui.get_color_u32((0, 0, 0, 0.8)), 0, 3.0)
        draw_list.add_circle(c, r, imgui.get_color_u32(col), 0, 1.5)

    # -- the Labels window: the exemplar's own map ----------------------------

    def _paint_exemplar(self, pos) -> None:
        lab = self.labels
        dabs = dab_centers(self._last, pos, 0.25 * self.brush.radius)
        if not dabs or lab is None or self.brush.eraser:
            return
        ex = lab.exemplar.scaled(self.ed.session.analysis.size)  # the window shows it at the exemplar's size
        for cx, cy in dabs:
            ex = ex.painted(cx, cy, self.brush.radius, self.active)
        self._last = dabs[-1]
        self._set(replace(lab, exemplar=ex), "Paint exemplar labels", self._group)

    def window(self) -> None:
        """The Labels window (in Exemplar mode, out of the canvas's way
        otherwise): the exemplar, zoomable, its labels in their colors, which
        the brush paints."""
        ed = self.ed
        s = ed.session
        lab = self.labels
        if not s.ready or ed.canvas.exemplar_tex is None or lab is None or self.mode != "exemplar":
            return
        m = s.analysis.size
        w, h = min(760, m * self.zoom + 40), min(760, m * self.zoom + 90)
        if begin_tool_window(ed, self, "Labels", (w, h), (m, m), (0.5, 8.0), "%.1fx"):
            imgui.begin_child("labels-view", (0, 0), 0, imgui.WindowFlags_.horizontal_scrollbar)
            size = m * self.zoom
            p0 = imgui.get_cursor_screen_pos()
            imgui.image(imgui.ImTextureRef(ed.canvas.exemplar_tex.glo), (size, size))
            dl = imgui.get_window_draw_list()
            tex = ed.overlay_labels.exemplar_labels(lab.exemplar.scaled(m), lab.colors)
            if ed.viewer.show_fields:
                dl.add_image(imgui.ImTextureRef(tex.glo), p0, (p0.x + size, p0.y + size))
            imgui.set_cursor_screen_pos(p0)
            imgui.invisible_button("labels-paint", (size, size))
            io = imgui.get_io()
            at = ((io.mouse_pos.x - p0.x) / self.zoom, (io.mouse_pos.y - p0.y) / self.zoom)
            painting = True
            if imgui.is_item_activated() and painting:
                self._group, self._last = object(), None
            if imgui.is_item_active() and self._group is not None and painting:
                self._paint_exemplar(at)
            if imgui.is_item_deactivated() and self._group is not None and painting:
                ed.history.end_group()
                self._group, self._last = None, None
            if imgui.is_item_hovered():
                xi, yi = int(min(m - 1, max(0, at[0]))), int(min(m - 1, max(0, at[1])))
                under = int(lab.exemplar.scaled(m).values[yi, xi])
                imgui.set_tooltip(lab.name(under))
                if painting:
                    r = self.brush.radius * self.zoom
                    c = lab.colors[self.active]
                    dl.add_circle(io.mouse_pos, r, imgui.get_color_u32((0, 0, 0, 0.8)), 0, 3.0)
                    dl.add_circle(io.mouse_pos, r, imgui.get_color_u32((c[0] / 255, c[1] / 255, c[2] / 255, 1)),
                                  0, 1.5)
            imgui.end_child()
        imgui.end()
