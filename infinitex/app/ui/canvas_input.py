"""The canvas's input and what is drawn over it: the mouse (the left button
to the active tool, right and middle to pan, the wheel to zoom, features
dropped from the Exemplar panel), tile mode's period, and the overlays (the randomness heat map, the tool's handles and
cursor, the tile borders).

``CanvasInput`` is a part of the editor (``Editor.canvas_input``); it keeps no
state of its own (the pointer and the button held are ``CanvasState``'s, the
active tool is ``Tools.active``).
"""
from __future__ import annotations

import math

import numpy as np
from imgui_bundle import imgui


from .tools.direction import DirectionTool, draw_field
from .tools.flow import draw_flow
from .tools.feature import PAYLOAD as FEATURE_PAYLOAD, FeatureTool


class CanvasInput:
    """Mouse input on the canvas (to the active tool), and the overlays drawn over it."""

    def __init__(self, ed) -> None:
        self.ed = ed

    # -- canvas input and overlays ------------------------------------------

    def read(self, p0, w: int, h: int) -> bool:
        """The canvas's mouse input: the left button goes to the active tool, the
        right and middle buttons always pan (from the press position), the
        wheel zooms around the cursor. Returns whether the canvas is hovered."""
        s = self.ed.session
        imgui.invisible_button("canvas", (w, h), imgui.ButtonFlags_.mouse_button_left
                               | imgui.ButtonFlags_.mouse_button_right | imgui.ButtonFlags_.mouse_button_middle)
        io = imgui.get_io()
        hovered = imgui.is_item_hovered()
        x0, y0 = self.ed.view.top_left(w, h)
        mouse = (io.mouse_pos.x, io.mouse_pos.y)
        at = (x0 + (mouse[0] - p0.x) / self.ed.view.zoom, y0 + (mouse[1] - p0.y) / self.ed.view.zoom)
        view_before = self.ed.view
        tool = self.ed.tool if s.ready and self.ed.doc is not None else self.ed.tools[0]
        if imgui.is_item_activated():
            self.ed.canvas_state.press(0 if imgui.is_mouse_down(imgui.MouseButton_.left) else 1)
            (tool if self.ed.canvas_state.button == 0 else self.ed.tools[0]).press(at, mouse)
        elif imgui.is_item_active() and self.ed.canvas_state.button >= 0:
            (tool if self.ed.canvas_state.button == 0 else self.ed.tools[0]).drag(at, mouse)
        if imgui.is_item_deactivated() and self.ed.canvas_state.button >= 0:
            # The last move can come in the same frame as the release (a quick
            # flick, or input queued while a frame was busy): it counts.
            held = tool if self.ed.canvas_state.button == 0 else self.ed.tools[0]
            held.drag(at, mouse)
            held.release()
            self.ed.canvas_state.release()
        if imgui.begin_drag_drop_target():  # an exemplar feature dropped from the Exemplar panel
            payload = imgui.accept_drag_drop_payload_py_id(FEATURE_PAYLOAD)
            if payload is not None and s.ready and self.ed.doc is not None and self.ed.geometry() is None:
                self.ed.tools.choose(self.ed.tools.of(FeatureTool))
                self.ed.tool.place((payload.data_id % 4096, payload.data_id // 4096), at)
            imgui.end_drag_drop_target()
        if hovered and io.mouse_wheel and not (s.ready and self.ed.doc is not None and self.ed.tool.wheel(at, io.mouse_wheel)):
            self.ed.viewer.zoom_at(2.0 ** (io.mouse_wheel * 0.25), mouse[0] - p0.x, mouse[1] - p0.y, w, h)
        if self.ed.view != view_before:  # the wheel or a pan moved the canvas under the mouse
            x0, y0 = self.ed.view.top_left(w, h)
            at = (x0 + (mouse[0] - p0.x) / self.ed.view.zoom, y0 + (mouse[1] - p0.y) / self.ed.view.zoom)
        self.ed.canvas_state.point(at if hovered else None)
        return hovered

    def overlays(self, p0, w: int, h: int, hovered: bool) -> None:
        """Over the canvas image: the randomness heat map, the panels' overlay,
        the feature handles, the tile borders and the tool's cursor."""
        s = self.ed.session
        if s.ready and self.ed.doc is not None:
            dl = imgui.get_window_draw_list()
            if self.ed.viewer.show_fields and self.ed.geometry() is None:
                self._field_overlay(dl, p0, w, h)
            self.ed.panels.canvas_overlay(p0, w, h)
            self.ed.tool.handles(dl, p0, w, h)
            if s.period:
                self._tile_borders(dl, p0, w, h, s.period)
            if hovered:
                self.ed.tool.overlay(dl, p0, w, h)

    def tile_period(self) -> int:
        """The tile size while tile mode is on (whole lattice cells required), else 0."""
        if not self.ed.viewer.tile_mode or not self.ed.session.ready:
            return 0
        n = self.ed.exports.settings.tile_size
        lat = self.ed.session.controls.lattice
        if lat is not None:
            cx, cy = lat.cell(self.ed.session.analysis.size)
            if n % cx or n % cy:
                self.ed.viewer.show_tile(False)
                self.ed.dialogs.message("Tile mode", f"A tile of {n} px is not made of whole lattice cells "
                                     f"({cx}x{cy} px); choose a larger tile size.")
                return 0
        return n

    def _tile_borders(self, dl, p0, w: int, h: int, n: int) -> None:
        """The tile's borders over the canvas (mapped into the input's geometry with a lattice)."""
        z = self.ed.view.zoom
        x0, y0 = self.ed.view.top_left(w, h)
        G = self.ed.geometry()
        Ginv = None if G is None else np.linalg.inv(G)

        def scr(px: float, py: float):
            if Ginv is not None:
                px, py = Ginv @ np.array([px, py])
            return (p0.x + (px - x0) * z, p0.y + (py - y0) * z)
        # The synthesized canvas rectangle the view covers (a bounding box with a lattice).
        corners = np.array([[x0, y0], [x0 + w / z, y0], [x0, y0 + h / z], [x0 + w / z, y0 + h / z]])
        if G is not None:
            corners = corners @ G.T
        lo, hi = corners.min(axis=0), corners.max(axis=0)
        i0, i1 = math.floor(lo[0] / n), math.ceil(hi[0] / n)
        j0, j1 = math.floor(lo[1] / n), math.ceil(hi[1] / n)
        if (i1 - i0) + (j1 - j0) > 400:
            return  # tiles smaller than a few screen pixels: no lines
        col = imgui.get_color_u32((1.0, 0.85, 0.2, 0.8))
        dl.push_clip_rect(p0, (p0.x + w, p0.y + h), True)
        for i in range(i0, i1 + 1):
            dl.add_line(scr(i * n, j0 * n), scr(i * n, j1 * n), col, 1.5)
        for j in range(j0, j1 + 1):
            dl.add_line(scr(i0 * n, j * n), scr(i1 * n, j * n), col, 1.5)
        dl.pop_clip_rect()

    def _field_overlay(self, dl, p0, w: int, h: int) -> None:
        """The canvas randomness field as a translucent heat map over the
        canvas, and the canvas labels in their colors."""
        z = self.ed.view.zoom
        x0, y0 = self.ed.view.top_left(w, h)
        lab = self.ed.doc.labels
        shown = [(self.ed.overlay_canvas, self.ed.overlay_canvas.canvas(self.ed.doc.randomness_canvas, x0, y0, w / z, h / z))]
        if lab is not None:
            shown.append((self.ed.overlay_canvas_labels, self.ed.overlay_canvas_labels.canvas_labels(
                lab.canvas, lab.colors, x0, y0, w / z, h / z)))
        dl.push_clip_rect(p0, (p0.x + w, p0.y + h), True)
        for overlay, tex in shown:
            if tex is None:
                continue
            fx, fy, fw, fh = overlay.placement
            a = (p0.x + (fx - x0) * z, p0.y + (fy - y0) * z)
            dl.add_image(imgui.ImTextureRef(tex.glo), a, (a[0] + fw * z, a[1] + fh * z))
        draw_field(dl, self.ed.doc.direction, self.ed.view, p0, w, h, self.ed.tools.of(DirectionTool).axis)
        if self.ed.doc.motion is not None:
            draw_flow(dl, self.ed.doc.motion.flow, self.ed.view, p0, w, h)
        dl.pop_clip_rect()
