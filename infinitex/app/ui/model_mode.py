"""The editor with a model open (texture on a surface, LH06 6): the canvas
shows the model lit, with its texture synthesized live in its atlas
(app/model_session.py), and takes the mouse the way Blender's viewport does:
the middle button orbits (Shift: pans), the wheel zooms, the right button
pans; the left button orbits too, except with the Paint canvas brush, which
paints randomness on the model (ray-picked into the atlas), the Features
tool (tools/feature_model.py) and the Direction tool, which combs the
texture over the surface (tools/direction_model.py). File > Open model,
Export model (GLB and every map) and Close model; the Model panel.

``ModelMode`` is a part of the editor (``Editor.model``): it owns the camera,
the model view and its framebuffer; the document's model is the document's.
"""
from __future__ import annotations

import os
import time
from dataclasses import replace

import moderngl
import numpy as np
from imgui_bundle import imgui

from infinitex.engine.controls import rescaled_features
from infinitex.engine.safeio import WriteError, check_output, printable
from infinitex.engine.surface import AtlasError, ModelError, load_model
from infinitex.project import ProjectError
from infinitex.project.surface import SurfaceSettings, default_repeats

from ..render.model_view import ModelView, OrbitCamera, atlas_footprint
from ..render.overlays import heat_rgba
from .tools.feature import PAYLOAD as FEATURE_PAYLOAD, FeatureTool

MODEL_FILTER = ["Models (*.obj *.glb *.gltf)", "*.obj *.glb *.gltf"]
MODEL_BUDGET_S = 0.030  # atlas synthesis per frame
ORBIT_DEG_PER_PX = 0.4


class ModelMode:
    """Opening, showing, orbiting, painting on and exporting a model."""

    def __init__(self, ed) -> None:
        self.ed = ed
        self.camera = OrbitCamera()
        self.view: ModelView | None = None
        self._view_key = None
        self._fbo = None
        self._drawn = None  # what the framebuffer shows: drawn again only when it changes
        self._uv = None  # (camera, size, uv image) of the last pick
        self.show_seams = False
        self._seams_key = None
        self._overlay_key = None
        self._tex_version = -1
        self.export_magnify = 1
        self.atlas_request = False  # tests: read the finished atlas's coordinates during a frame
        self.atlas_read = None

    # -- open, close, export --------------------------------------------------

    def open_dialog(self) -> None:
        self.ed.dialogs.ask_path("Open model", False, MODEL_FILTER, self.open)

    def open(self, path: str, unwrap: bool = False) -> None:
        """Put a model in the document (one undo step): the texture is synthesized in its atlas."""
        if self.ed.doc is None or not self.ed.session.ready:
            return
        try:
            model = load_model(path, unwrap_missing=unwrap)
        except ModelError as exc:
            if "--unwrap" in str(exc) and not unwrap:
                self.ed.dialogs.ask("Open model", f"{printable(os.path.basename(path))} has no texture coordinates. "
                                 "Generate them (xatlas)?",
                                 [("Generate", lambda: self.open(path, True)), ("Cancel", None)])
            else:
                self.ed.dialogs.message("Open model", str(exc))
            return
        m = self.ed.session.analysis.size
        size = max(m, 1024 if len(model.faces) > 20000 else 512)
        try:
            settings = SurfaceSettings(model, size, repeats=default_repeats(model, size, m))
            settings.validate(m)
            # The canvas randomness, the features and the directions are placed on the model from now
            # on (in its atlas): the plane's are set aside until the model closes (Document.with_model).
            self.ed.edit(self.ed.doc.with_model(settings), f"Open model {os.path.basename(path)}")
        except (ProjectError, AtlasError, ValueError) as exc:
            self.ed.dialogs.message("Open model", str(exc))
            return
        self.camera = OrbitCamera.framing(model.positions)
        self._view_key = None

    def close(self) -> None:
        if self.ed.model_mode:
            self.ed.edit(self.ed.doc.without_model(), "Close model")  # the plane's controls come back
            self.release()
            self.view, self._fbo, self._view_key = None, None, None

    def set_surface(self, label: str, group: object = None, **changes) -> None:
        """An edit of the model's settings (size, scale, frame); ``group``: the
        gesture it belongs to (a slider's drag: one undo step)."""
        try:
            s = replace(self.ed.doc.surface, **changes)
            s.validate(self.ed.session.analysis.size)
        except (ProjectError, ValueError) as exc:
            self.ed.dialogs.message("Model", str(exc))
            return
        if "size" in changes and changes["size"] != self.ed.doc.surface.size:
            # What is painted or placed on the model is in its texels: it keeps its place on the surface.
            n = self.ed.doc.surface.size
            factor = changes["size"] / n
            rc, dr = self.ed.doc.randomness_canvas, self.ed.doc.direction
            try:
                doc = replace(self.ed.doc, surface=s, randomness_canvas=None if rc is None else rc.rescaled(factor, n),
                              features=rescaled_features(self.ed.doc.features, factor),
                              direction=None if dr is None else dr.rescaled(factor, n))
            except ValueError as exc:  # (FieldTooLarge)
                self.ed.dialogs.message("Model", str(exc))
                return
            self.ed.edit(doc, label, group)
            return
        self.ed.edit(replace(self.ed.doc, surface=s), label, group)

    def export_dialog(self) -> None:
        stem = os.path.splitext(self.ed.doc.surface.model.name)[0] or "model"
        self.ed.dialogs.ask_path("Export model", True, ["glTF binary (*.glb)", "*.glb"], self.start_export,
                              default=f"{stem}_textured.glb")

    def start_export(self, path: str, magnify: int | None = None, confirmed: bool = False) -> None:
        from infinitex.export.surface import ModelExportJob
        from infinitex.export.window import Writes, check_own_inputs
        chosen = path
        if not path.lower().endswith(".glb"):
            path += ".glb"
        s = self.ed.doc.surface
        size = s.size * (magnify or self.export_magnify)
        job = None
        try:
            check_output(path, (".glb",), "export")
            job = ModelExportJob(self.ed.session, s, path, size, self.ed.exports.settings.depth)
            writes = Writes(files=[p for _, p, _ in job.outputs])
            # (a model read from a file this session: it and the files it names, load_model's meta)
            check_own_inputs(writes, self.ed.exports.inputs() + s.model.meta.get("files", []))
            if not confirmed and not self.ed.exports.confirm_replace(
                    writes, self.ed.exports.asked(chosen, path), lambda: self.start_export(path, magnify, True)):
                job.cancel()
                return
        except (ValueError, WriteError) as exc:
            if job is not None:
                job.cancel()  # its synthesis's GL textures
            self.ed.dialogs.message("Export model", str(exc))
            return
        self.ed.exports.enqueue(job)

    # -- the canvas ---------------------------------------------------------------

    def frame(self) -> None:
        """The orbit camera framing the whole model."""
        if self.view is not None:
            self.camera = OrbitCamera.framing(self.view.positions)

    def look_with(self, camera: OrbitCamera) -> None:
        """The model seen through ``camera`` (a tool turns it to a feature)."""
        self.camera = camera

    def _overlay(self, mv, pv):
        """With "Show painted" on (H), what the active tool paints, over the
        model's texture: the direction field as short strokes with the Direction
        tool, else the randomness as a heat map (calm blue, rough red, as on the
        plane); the key of what is shown."""
        n = pv.atlas.size if pv.atlas is not None else 0
        key, make = None, None
        if self.ed.viewer.show_fields and n:
            shown = self.ed.tool.atlas_overlay(self.ed.doc, n)
            field = self.ed.doc.randomness_canvas
            if shown is not None:
                key, make = shown
            elif field is not None and not field.neutral:
                key, make = ("randomness", field.key, n), lambda: heat_rgba(field.region(0, 0, 0, n, n))
        if key != self._overlay_key:
            mv.set_overlay(make() if make is not None else None)
            self._overlay_key = key
        return key

    def canvas(self, p0, w: int, h: int) -> None:
        s = self.ed.session
        model = self.ed.doc.surface.model
        if self._view_key != model.key or self.view is None:
            if self.view is not None:
                self.view.release()
            self.view = ModelView(self.ed.gpu.ctx, model.positions, model.faces, model.uvs)
            if self._view_key is None:  # a model opened with the document (a project): frame it
                self.camera = OrbitCamera.framing(model.positions)
            self._view_key = model.key
            self._tex_version = -1
            self._seams_key = None
            self._overlay_key = None
        hovered = self._input(p0, w, h)
        self.ed.sync_session()  # (the model's texture with it: Session.sync keeps s.model in step)
        pv = s.model
        t0 = time.perf_counter()
        refined = pv.step(MODEL_BUDGET_S, self.ed.shown_role())
        self.ed.canvas_state.set_refined(refined)
        self.ed.canvas_state.synthesized((time.perf_counter() - t0) * 1000.0)
        mv = self.view
        if pv.image is not None and pv.version != self._tex_version:
            mv.set_texture(pv.image)
            mag = pv.magnification(self.ed.shown_role())  # the finest level: magnified when zoomed in
            mv.set_synthesis(*(mag or (None,)))
            self._tex_version = pv.version
        seams_key = (self.show_seams, pv.atlas.key if pv.atlas is not None else None)
        if seams_key != self._seams_key and pv.atlas is not None:
            own = pv.atlas.owner(0)
            border = np.zeros_like(own, bool)
            if self.show_seams:
                border[:, 1:] |= own[:, 1:] != own[:, :-1]
                border[:, :-1] |= own[:, :-1] != own[:, 1:]
                border[1:] |= own[1:] != own[:-1]
                border[:-1] |= own[:-1] != own[1:]
                border &= own >= 0
            mv.set_seams(border if self.show_seams else None)
            self._seams_key = seams_key
        overlay_key = self._overlay(mv, pv)
        fbo = self._fbo
        if fbo is None or fbo.size != (w, h):
            if fbo is not None:
                fbo.release()
            self._fbo = fbo = self.ed.gpu.ctx.framebuffer(
                color_attachments=[self.ed.gpu.ctx.texture((w, h), 4)],
                depth_attachment=self.ed.gpu.ctx.depth_renderbuffer((w, h)))
            fbo.color_attachments[0].filter = (moderngl.NEAREST, moderngl.NEAREST)
        # While the mouse orbits or pans, the texture's mipmaps (a frame rate that
        # follows the hand); at rest, synthesis magnification. A picture that would
        # not change is not drawn again (magnification costs llvmpipe 150 ms a frame).
        magnify = mv.magnify and self.ed.canvas_state.button < 0
        drawn = (self.camera, w, h, self._tex_version, self.show_seams, magnify, pv.image is None, overlay_key)
        if drawn != self._drawn or self.ed.canvas_state.read_asked:
            fbo.use()
            fbo.clear(0.16, 0.17, 0.19, 1.0, depth=1.0)
            if pv.image is not None:
                keep, mv.magnify = mv.magnify, magnify
                mv.draw(self.camera, (0, 0, w, h), mode=2 if self.show_seams else 0)
                mv.magnify = keep
            self._drawn = drawn
        if self.ed.canvas_state.read_asked:
            fbo.use()
            self.ed.canvas_state.give_read_back(np.frombuffer(fbo.read(components=3), np.uint8).reshape(h, w, 3)[::-1].copy())
        if self.atlas_request and pv.done:
            self.atlas_read = pv.coords()
            self.atlas_request = False
        self.ed.screen_fbo.use()
        imgui.set_cursor_screen_pos(p0)
        imgui.image(imgui.ImTextureRef(fbo.color_attachments[0].glo), (w, h), (0, 1), (1, 0))
        dl = imgui.get_window_draw_list()
        text = None
        if pv.error:
            text = pv.error
        elif pv.image is None:
            text = f"Texturing {printable(model.name)}: {pv.progress * 100:.0f}%"
        elif not pv.done:
            text = f"Refining the texture: {pv.progress * 100:.0f}%"
        if text:
            tw = imgui.calc_text_size(text).x
            dl.add_rect_filled((p0.x + 8, p0.y + 8), (p0.x + 24 + tw, p0.y + 30), imgui.get_color_u32((0, 0, 0, 0.55)), 4)
            dl.add_text((p0.x + 16, p0.y + 11), imgui.get_color_u32((1, 1, 1, 1)), text)
        gesture = self.ed.tool.model_gesture()
        if gesture is not None:
            gesture.draw(dl, p0, w, h)
            if hovered:
                io = imgui.get_io()
                gesture.cursor(dl, (io.mouse_pos.x, io.mouse_pos.y))

    def _input(self, p0, w: int, h: int) -> bool:
        imgui.invisible_button("canvas", (w, h), imgui.ButtonFlags_.mouse_button_left
                               | imgui.ButtonFlags_.mouse_button_right | imgui.ButtonFlags_.mouse_button_middle)
        io = imgui.get_io()
        hovered = imgui.is_item_hovered()
        mx, my = io.mouse_pos.x - p0.x, io.mouse_pos.y - p0.y
        # The active tool seen through the model's mapping (Alt: the left button orbits).
        tool_gesture = self.ed.tool.model_gesture()
        gesture = None if io.key_alt else tool_gesture
        if imgui.is_item_activated():
            left = imgui.is_mouse_down(imgui.MouseButton_.left)
            self.ed.canvas_state.press(0 if left else (2 if imgui.is_mouse_down(imgui.MouseButton_.middle) else 1))
            if left and gesture is not None:
                gesture.press(mx, my, w, h)
        elif imgui.is_item_active() and self.ed.canvas_state.button >= 0:
            d = io.mouse_delta
            if self.ed.canvas_state.button == 0 and gesture is not None:
                if d.x or d.y:
                    gesture.drag(mx, my, w, h)
            elif (self.ed.canvas_state.button == 1 or (self.ed.canvas_state.button == 2 and io.key_shift)) and (d.x or d.y):
                self.camera = self.camera.pan(-d.x / h, d.y / h, w / max(1, h))
            elif d.x or d.y:
                self.camera = self.camera.orbit(-d.x * ORBIT_DEG_PER_PX, d.y * ORBIT_DEG_PER_PX)
        if imgui.is_item_deactivated() and self.ed.canvas_state.button >= 0:
            if self.ed.canvas_state.button == 0 and gesture is not None:
                gesture.finish(mx, my, w, h)  # (a move in the release's frame counts)
            self.ed.canvas_state.release()
        if imgui.begin_drag_drop_target():  # an exemplar feature dropped from the Exemplar panel
            payload = imgui.accept_drag_drop_payload_py_id(FEATURE_PAYLOAD)
            if payload is not None:
                self.ed.tools.choose(self.ed.tools.of(FeatureTool))
                self.ed.tool.model_gesture().drop((payload.data_id % 4096, payload.data_id // 4096), mx, my, w, h)
            imgui.end_drag_drop_target()
        if hovered and io.mouse_wheel and not (tool_gesture is not None
                                               and tool_gesture.wheel(mx, my, w, h, io.mouse_wheel)):
            self.camera = self.camera.zoom(0.85 ** io.mouse_wheel)
        self.ed.canvas_state.point(None)
        return hovered

    def uv_image(self, w: int, h: int) -> np.ndarray:
        key = (self.camera, w, h, self._view_key)
        if self._uv is None or self._uv[0] != key:
            self._uv = (key, self.view.render(self.camera, (w, h), mode=1, background=(0, 0, 0)))
        return self._uv[1]

    def pick_atlas(self, x: float, y: float, w: int, h: int) -> tuple[tuple[float, float], float] | None:
        """Where the ray under view pixel (x, y) meets the model: (atlas
        position in finest texels, atlas texels per screen pixel there), or None
        (render/model_view.py: atlas_footprint)."""
        atlas = self.ed.session.model.atlas
        return atlas_footprint(self.uv_image(w, h), x, y, self.ed.doc.surface.size,
                               atlas.owner(0) if atlas is not None and atlas.size == self.ed.doc.surface.size else None)

    def chart_at(self, pos: tuple[float, float]) -> int:
        """The chart of the atlas texel at ``pos`` (finest texels; -1 off the charts)."""
        atlas = self.ed.session.model.atlas
        if atlas is None:
            return -1
        n = atlas.size
        return int(atlas.owner(0)[min(n - 1, max(0, int(pos[1]))), min(n - 1, max(0, int(pos[0])))])

    def release(self) -> None:
        for o in (self.view, self._fbo):
            if o is not None:
                o.release()

