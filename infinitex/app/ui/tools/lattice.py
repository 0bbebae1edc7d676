"""The lattice tool (LH05 4.5): near-regular textures keep their rows.

In its own window the exemplar *image* (the whole input, not the fitted
square) is shown zoomable with the lattice drawn over it: the block of
``nx x ny`` cells that becomes the exemplar, and three handles (the origin,
the ends of t1 and t2) to drag. Auto-detect finds the lattice
(engine.controls.lattice_detect.detect) and shows its confidence; below the image, the
rectified exemplar is previewed live while a handle moves. The options panel
holds the on/off switch, the cell counts, the number of lattice levels and
whether the canvas shows the texture in the input's geometry or rectified.
One handle drag (press to release) is one undo step.
"""
from __future__ import annotations

import math
from dataclasses import replace

import moderngl
import numpy as np
from imgui_bundle import imgui

from infinitex.engine.controls.lattice import (
    MIN_VECTOR,
    Lattice,
    LatticeError,
    row_offset,
)
from infinitex.engine.controls.lattice_block import choose_block, fit_block
from infinitex.engine.controls.lattice import Detection
from infinitex.engine.exemplar import ExemplarError, decode_full
from infinitex.engine.imagefile import to_u8

from ...render.canvas import to_rgba
from . import Tool, begin_tool_window
from ..tips import tip

CELLS = (1, 2, 4, 8, 16)
HANDLE_PX = 7.0
PREVIEW = 128


class LatticeTool(Tool):
    name = "lattice"
    label = "Lattice"
    key = "L"
    tooltip = ("Near-regular textures (bricks, tiles, weaves): mark or detect the lattice on the exemplar "
               "image; the synthesis moves whole cells and keeps rows (L)")
    panel = "Lattice"
    on_model = False

    def __init__(self, ed):
        super().__init__(ed)
        self.zoom = 1.0
        self.draft: Lattice | None = None     # the lattice while a handle moves
        self.handle = -1                      # 0 origin, 1 t1, 2 t2
        self.cell: tuple | None = None        # a rectangle marking one cell, while dragged (image pixels)
        self._fitted = None                   # the image the window's zoom was fitted to
        self.detection: Detection | None = None
        self.message = ""
        self._image: tuple[str, np.ndarray] | None = None   # (sha256, pixels)
        self._image_tex = None
        self._preview_key = None
        self._preview_tex = None
        self.preview_pixels: np.ndarray | None = None  # the rectified block shown
        self.proposal: Lattice | None = None  # staggered rows found after a cell was marked (a button offers it)

    def new_document(self) -> None:
        self.draft, self.handle, self.cell = None, -1, None
        self.detection, self.message, self.proposal = None, "", None
        self._fitted = self._preview_key = None
        self.preview_pixels = None

    # -- data -----------------------------------------------------------------

    def image(self) -> np.ndarray | None:
        """The whole input image of the document (decoded once per exemplar)."""
        ex = self.ed.doc.exemplar
        if self._image is None or self._image[0] != ex.sha256:
            try:
                px = decode_full(ex.data, ex.name)
            except ExemplarError as exc:
                self.message = str(exc)
                return None
            self._image = (ex.sha256, px)
            self.zoom = float(min(4.0, max(0.25, 2.0 ** round(math.log2(480.0 / max(px.shape[:2]))))))
            self._release(self._image_tex)
            self._image_tex = self._texture(px)
            self.detection = None
        return self._image[1]

    def _texture(self, px: np.ndarray):
        rgba = to_rgba(to_u8(px))
        tex = self.ed.gpu.ctx.texture((rgba.shape[1], rgba.shape[0]), 4, np.ascontiguousarray(rgba).tobytes())
        tex.filter = (moderngl.LINEAR, moderngl.NEAREST)
        return tex

    @staticmethod
    def _release(tex) -> None:
        if tex is not None:
            tex.release()

    def current(self) -> Lattice | None:
        return self.draft if self.draft is not None else self.ed.doc.lattice

    def _commit(self, lat: Lattice | None, label: str) -> None:
        """Make ``lat`` the document's lattice (one undo step). A block that does
        not fit the image shrinks to the most cells that do, its origin kept
        (the cells stay where they were put); refused only when not one fits."""
        img = self.image()
        self.message = ""
        if lat is not None and img is not None:
            H, W = img.shape[:2]
            try:
                lat.check_shape()
                lat.validate(W, H)
            except LatticeError as exc:
                fit = None
                try:
                    lat.check_shape()
                    fit = fit_block(lat.origin, lat.t1, lat.t2, W, H, (lat.nx, lat.ny), lat.levels, keep_origin=True)
                except LatticeError:
                    pass
                if fit is None:
                    self.message = str(exc)
                    return
                self.message = (f"{lat.nx}x{lat.ny} cells do not fit in the image here: "
                                f"{fit.nx}x{fit.ny} cells used.")
                lat = fit
        self.ed.edit(replace(self.ed.doc, lattice=lat), label)

    def cell_lattice(self, a: tuple[float, float], b: tuple[float, float]) -> Lattice | None:
        """The lattice of one cell marked by a rectangle from ``a`` to ``b``
        (image pixels): axis-aligned vectors, as many cells as fit."""
        img = self.image()
        if img is None:
            return None
        x0, x1 = sorted((a[0], b[0]))
        y0, y1 = sorted((a[1], b[1]))
        w, h = round(x1 - x0, 2), round(y1 - y0, 2)
        if min(w, h) < MIN_VECTOR:
            return None
        old = self.ed.doc.lattice
        return fit_block((round(x0, 2), round(y0, 2)), (w, 0.0), (0.0, h), img.shape[1], img.shape[0],
                         levels=old.levels if old is not None else None)

    def propose_offset(self, lat: Lattice) -> None:
        """After a cell is marked: when the image's rows are staggered (the next
        row matches this one shifted sideways: running-bond bricks, shingles),
        propose that offset (a button in the panel) and say so."""
        img = self.image()
        w, h = lat.t1[0], lat.t2[1]
        found = row_offset(img, w, h) if img is not None and lat.t1[1] == 0 and lat.t2[0] == 0 else None
        self.proposal = None
        if found is None:
            return
        s, staggered, stacked = found
        old = self.ed.doc.lattice
        self.proposal = fit_block(lat.origin, lat.t1, (s, h), img.shape[1], img.shape[0],
                                  levels=old.levels if old is not None else None)
        if self.proposal is not None:
            self.message = (f"The rows look staggered: each row matches the one above shifted {s:.0f} px "
                            f"(correlation {staggered:.2f}, against {stacked:.2f} stacked).")

    def use_offset(self) -> None:
        lat, self.proposal = self.proposal, None
        if lat is not None:
            self._commit(lat, "Offset lattice rows")

    def auto_detect(self) -> None:
        img = self.image()
        if img is None:
            return
        from infinitex.engine.controls.lattice_cache import find_lattice  # the search (scipy) loaded when used
        d = find_lattice(img)
        self.detection = d
        if d.lattice is not None:
            self._commit(replace(d.lattice, levels=self.ed.doc.lattice.levels if self.ed.doc.lattice else None),
                         "Detect lattice")
        else:
            self.message = (f"No lattice found (confidence {d.confidence:.2f}, below 0.30). "
                            "Place the handles by hand, or use the best guess.")

    def use_guess(self) -> None:
        d, img = self.detection, self.image()
        if d is None or d.t1 is None or img is None:
            return
        lat = choose_block(d.t1, d.t2, img.shape[1], img.shape[0])
        if lat is None:
            self.message = "The best guess's cells are too large for a block in this image."
            return
        self._commit(lat, "Use lattice guess")

    def default_lattice(self, img: np.ndarray) -> Lattice:
        """A starting lattice when nothing was detected: 2 x 2 cells over the middle."""
        H, W = img.shape[:2]
        c = min(W, H) / 4.0
        return Lattice((W / 2 - c, H / 2 - c), (c, 0.0), (0.0, c), 2, 2)

    # -- options panel --------------------------------------------------------

    def options(self) -> None:
        ed = self.ed
        doc = ed.doc
        lat = doc.lattice
        on = lat is not None
        changed, want = imgui.checkbox("Synthesize on a lattice", on)
        tip("Coarse levels move whole cells only, so rows and columns stay aligned")
        if changed:
            if want:
                self.auto_detect()
                if ed.doc.lattice is None and (img := self.image()) is not None:
                    self._commit(self.default_lattice(img), "Lattice on")
            else:
                self._commit(None, "Lattice off")
        if imgui.button("Auto-detect"):
            self.auto_detect()
        d = self.detection
        if d is not None:
            imgui.same_line()
            imgui.text(f"confidence {d.confidence:.2f}" + ("" if d.lattice else " (none)"))
            if d.lattice is None and d.t1 is not None:
                if imgui.button("Use the best guess anyway"):
                    self.use_guess()
        lat = ed.doc.lattice
        if lat is not None:
            imgui.push_item_width(70)
            for axis, label in ((0, "Cells along t1"), (1, "Cells along t2")):
                n = lat.nx if axis == 0 else lat.ny
                changed, i = imgui.combo(label, CELLS.index(n), [str(c) for c in CELLS])
                if changed:
                    new = replace(lat, nx=CELLS[i]) if axis == 0 else replace(lat, ny=CELLS[i])
                    self._commit(new, "Lattice cells")
            imgui.pop_item_width()
            s = ed.session
            if s.ready and s.controls.lattice is not None:
                m = s.analysis.size
                cur = s.controls.lattice
                count = cur.level_count(m)
                imgui.push_item_width(120)
                changed, v = imgui.slider_int("Lattice levels", count, 0, cur.max_levels(m))
                imgui.pop_item_width()
                tip("Coarse levels (h >= spacing shown below) keep whole cells; finer levels vary "
                    "the detail of each cell freely")
                if changed:
                    ed.edit(replace(ed.doc, lattice=replace(lat, levels=v)), "Lattice levels")
                imgui.same_line()
                if imgui.small_button("Default"):
                    ed.edit(replace(ed.doc, lattice=replace(lat, levels=None)), "Lattice levels")
                cx, cy = cur.cell(m)
                finest = m >> max(0, count - 1)
                imgui.push_text_wrap_pos(0)
                imgui.text_disabled(f"Cell {cx}x{cy} px of the {m} px exemplar; lattice levels 0-{count - 1} "
                                    f"(spacing down to {finest} px).")
                imgui.pop_text_wrap_pos()
            geom = ed.display.geometry
            if imgui.radio_button("Original geometry", geom == "original"):
                ed.viewer.set_display(geometry="original")
                if ed.tool.space == "canvas":  # (those work on the rectified canvas)
                    ed.tools.choose(ed.tools[0])
            imgui.same_line()
            if imgui.radio_button("Rectified", geom == "rectified"):
                ed.viewer.set_display(geometry="rectified")
            tip("Show the texture as synthesized: cells axis-aligned")
            imgui.push_text_wrap_pos(0)
            imgui.text_disabled(f"lattice: {lat.to_text()}")
            imgui.pop_text_wrap_pos()
        if self.message:
            imgui.push_text_wrap_pos(0)
            imgui.text_colored((1.0, 0.6, 0.4, 1.0), self.message)
            imgui.pop_text_wrap_pos()
        if self.proposal is not None and self.proposal != ed.doc.lattice:
            if imgui.button(f"Offset the rows by {self.proposal.t2[0]:.0f} px", (-1, 0)):
                self.use_offset()
            tip("Staggered rows (running bond, shingles): each row of cells starts half a cell "
                "(or what the image shows) further along; one undo step")
        imgui.push_text_wrap_pos(0)
        imgui.text_disabled("In the Lattice window: drag a rectangle over one cell, or drag the handles "
                            "(the block shrinks to what fits).")
        imgui.pop_text_wrap_pos()

    # -- the Lattice window -----------------------------------------------------

    def _handles(self, lat: Lattice) -> list[tuple[float, float]]:
        o = lat.origin
        return [o, (o[0] + lat.t1[0], o[1] + lat.t1[1]), (o[0] + lat.t2[0], o[1] + lat.t2[1])]

    def press_at(self, pos: tuple[float, float]) -> None:
        """Start a drag at image position ``pos``: a handle's if one is there,
        else a rectangle marking one cell."""
        lat = self.ed.doc.lattice
        best = -1
        for i, (hx, hy) in enumerate(self._handles(lat) if lat is not None else []):
            if math.hypot(hx - pos[0], hy - pos[1]) * self.zoom <= HANDLE_PX + 3:
                best = i
        self.handle = best
        self.draft = lat if best >= 0 else None
        self.cell = (pos, pos) if best < 0 else None

    def drag_to(self, pos: tuple[float, float]) -> None:
        if self.cell is not None:
            self.cell = (self.cell[0], pos)
            return
        lat = self.draft
        if lat is None or self.handle < 0:
            return
        o = lat.origin
        v = (round(pos[0] - o[0], 2), round(pos[1] - o[1], 2))
        if self.handle == 0:
            self.draft = replace(lat, origin=(round(pos[0], 2), round(pos[1], 2)))
        elif self.handle == 1:
            self.draft = replace(lat, t1=v)
        else:
            self.draft = replace(lat, t2=v)

    def release_drag(self) -> None:
        if self.cell is not None:
            a, b = self.cell
            self.cell = None
            if math.hypot(b[0] - a[0], b[1] - a[1]) * self.zoom < 4:
                return  # a click, not a rectangle
            lat = self.cell_lattice(a, b)
            if lat is None:
                self.message = (f"Mark one cell with a rectangle at least {MIN_VECTOR:g} px a side "
                                "that fits in the image.")
                return
            self._commit(lat, "Mark lattice cell")
            self.propose_offset(lat)
            return
        if self.draft is not None and self.draft != self.ed.doc.lattice:
            lat, self.draft = self.draft, None
            try:
                lat.check_shape()
            except LatticeError as exc:
                self.message = str(exc)
                self.handle = -1
                return
            self._commit(lat, ("Move lattice origin", "Move lattice vector t1", "Move lattice vector t2")[self.handle])
        self.draft, self.handle = None, -1

    def window(self) -> None:
        ed = self.ed
        img = self.image()
        if img is None:
            return
        H, W = img.shape[:2]
        vp = imgui.get_main_viewport()
        # Out of the canvas's way: at most 30% of the window's width, the image
        # zoomed to fit that when first shown (the zoom slider and resizing take it further).
        avail = (0.3 * vp.work_size.x - 40, vp.work_size.y - PREVIEW - 220)
        if self._fitted != self._image[0]:
            self._fitted = self._image[0]
            fit = min(avail[0] / W, avail[1] / H)
            self.zoom = float(min(4.0, max(0.25, 2.0 ** math.floor(math.log2(max(fit, 1e-3))))))
        size = (min(avail[0] + 40, W * self.zoom + 40), min(vp.work_size.y - 80, H * self.zoom + PREVIEW + 130))
        if begin_tool_window(ed, self, "Lattice", size, (W, H), (0.25, 8.0), "%.2fx"):
            self._preview(img)
            imgui.begin_child("lattice-view", (0, 0), 0, imgui.WindowFlags_.horizontal_scrollbar)
            p0 = imgui.get_cursor_screen_pos()
            imgui.image(imgui.ImTextureRef(self._image_tex.glo), (W * self.zoom, H * self.zoom))
            imgui.set_cursor_screen_pos(p0)
            imgui.invisible_button("lattice-handles", (W * self.zoom, H * self.zoom))
            io = imgui.get_io()
            pos = ((io.mouse_pos.x - p0.x) / self.zoom, (io.mouse_pos.y - p0.y) / self.zoom)
            if imgui.is_item_activated():
                self.press_at(pos)
            elif imgui.is_item_active():
                self.drag_to(pos)
            if imgui.is_item_deactivated():
                self.release_drag()
            lat = self.current()
            dl = imgui.get_window_draw_list()
            if lat is not None:
                self._draw(dl, p0, lat, W, H)
            if self.cell is not None:
                (ax, ay), (bx, by) = self.cell
                z = self.zoom
                dl.add_rect((p0.x + min(ax, bx) * z, p0.y + min(ay, by) * z),
                            (p0.x + max(ax, bx) * z, p0.y + max(ay, by) * z),
                            imgui.get_color_u32((0.3, 1.0, 0.5, 1.0)), thickness=2.0)
            imgui.end_child()
        imgui.end()

    def _preview(self, img: np.ndarray) -> None:
        lat = self.current()
        if lat is None:
            return
        if lat != self._preview_key:
            self._preview_key = lat
            self._release(self._preview_tex)
            self._preview_tex = None
            try:
                lat.check_shape()
                self.preview_pixels = lat.rectify(img, PREVIEW)
                self._preview_tex = self._texture(self.preview_pixels)
            except (LatticeError, np.linalg.LinAlgError):
                pass
        if self._preview_tex is not None:
            imgui.image(imgui.ImTextureRef(self._preview_tex.glo), (PREVIEW, PREVIEW))
            imgui.same_line()
            imgui.text_disabled("rectified block\n(the exemplar\nthe synthesis uses)")

    def _draw(self, dl, p0, lat: Lattice, W: int, H: int) -> None:
        z = self.zoom

        def scr(x, y):
            return (p0.x + x * z, p0.y + y * z)
        ok = True
        try:
            lat.validate(W, H)
        except LatticeError:
            ok = False
        grid = imgui.get_color_u32((1.0, 0.85, 0.2, 0.55) if ok else (1.0, 0.3, 0.2, 0.7))
        edge = imgui.get_color_u32((1.0, 0.85, 0.2, 1.0) if ok else (1.0, 0.3, 0.2, 1.0))
        o, a, b = np.array(lat.origin), np.array(lat.t1), np.array(lat.t2)
        for i in range(lat.nx + 1):
            p, q = o + i * a, o + i * a + lat.ny * b
            dl.add_line(scr(*p), scr(*q), edge if i in (0, lat.nx) else grid, 2.0 if i in (0, lat.nx) else 1.0)
        for j in range(lat.ny + 1):
            p, q = o + j * b, o + j * b + lat.nx * a
            dl.add_line(scr(*p), scr(*q), edge if j in (0, lat.ny) else grid, 2.0 if j in (0, lat.ny) else 1.0)
        colors = [(1, 1, 1, 1), (1.0, 0.35, 0.3, 1), (0.3, 0.7, 1.0, 1)]
        for i, (hx, hy) in enumerate(self._handles(lat)):
            c = scr(hx, hy)
            if i:
                dl.add_line(scr(*lat.origin), c, imgui.get_color_u32(colors[i]), 2.5)
            dl.add_circle_filled(c, HANDLE_PX, imgui.get_color_u32((0, 0, 0, 0.8)))
            dl.add_circle_filled(c, HANDLE_PX - 2, imgui.get_color_u32(colors[i]))
