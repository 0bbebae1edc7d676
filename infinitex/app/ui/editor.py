"""The editor: an imgui-bundle (hello_imgui) application around one document.

Per frame: install a finished analysis, keep the session in step with the
document, refine the view's synthesis within a time budget, draw the canvas
texture, then the panels. Nothing blocks: analysis runs on a thread, synthesis
and exports are sliced into budgeted steps.
"""
from __future__ import annotations

import math
import os
import random
import subprocess
import sys
import time
from dataclasses import replace

import numpy as np
from imgui_bundle import (  # imported before glfw (bundled libglfw)
    hello_imgui,
    imgui,
    immapp,
)

from infinitex.engine.gpu import GLUnavailable, Gpu
from infinitex.engine.material import IMAGE, MaterialError, assign_roles, map_path
from infinitex.engine.pyramid import Rect, SynthesisError
from infinitex.engine.safeio import ReadError, WriteError, check_output, printable
from infinitex.export import check_zarr_output
from infinitex.export.jobs import ExportEstimate, StreamedExport
from infinitex.export.window import ExportJob

from infinitex.project import (
    PROJECT_SUFFIX,
    Autosave,
    Display,
    Document,
    ExemplarOutside,
    ExemplarSource,
    History,
    Project,
    ProjectError,
    View,
    is_project_file,
    load_project,
    save_project,
)
from ..render.canvas import Canvas
from ..render.overlays import FieldOverlay
from ..session import Frame, Session, frame_for
from ..settings import config_dir, load_settings, save_settings
from . import panels
from .dialogs import PROJECT_FILTER, Dialogs
from .tools import CANVAS_SPACE_TOOLS, make_tools
from .tools.feature import PAYLOAD as FEATURE_PAYLOAD

ASSETS = os.path.join(os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__)))), "assets")
DEFAULT_EXEMPLAR = os.path.join(ASSETS, "gravel.png")
FRAME_BUDGET_S = 0.030       # synthesis time per frame: keeps the UI above 15 fps on llvmpipe
REST_BUDGET_S = 0.060        # refining at rest: more work per frame, still a live UI
PREVIEW_BUDGET_S = 0.012     # while a control is dragged: a complete coarse preview per frame
INTERACTIVE_S = 0.25         # seconds after the last edit that still count as dragging
PANEL_WIDTH = 340
SHORTCUTS = [
    ("1", "Actual size (100%)"), ("+  /  -", "Zoom in / out (also the mouse wheel)"),
    ("0", "Fit one exemplar across the canvas"), ("Right or middle drag", "Pan (any tool)"),
    ("Ctrl+Z / Ctrl+Shift+Z", "Undo / redo"), ("Ctrl+O", "Open an image or a project"),
    ("Ctrl+S / Ctrl+Shift+S", "Save / save as"), ("Ctrl+Q", "Quit"),
    ("H", "Show or hide the painted randomness (cursor over the canvas)"),
    ("T", "Tile mode: the periodic texture of the export tile size (cursor over the canvas)"),
    ("M", "Show the next map of a material (cursor over the canvas)"),
    ("[  /  ]", "Brush smaller / larger (painting)"), ("Alt+click", "Pick the painted value (painting)"),
    ("F1  or  ?", "This list"),
]
# The editor spawns worker processes (streamed exports, their estimate) while
# GL and the UI threads run. CPython's vfork() path for that (multiprocessing
# uses it through subprocess) aborted the editor now and then, under the imgui
# test engine, during a spawn; plain fork + exec (the documented switch) did not.
subprocess._USE_VFORK = False
IDLE_FPS = 0.25
BACKGROUND_FPS = 4.0  # while worker processes export: progress, and the cores left to them
DEFAULT_PANELS = ("Randomness", "Exemplar", "Display")  # side-panel sections open on a first run              # frames per second with nothing to do (input wakes the editor at once)


class Editor:
    def __init__(self, path: str | None = None, *, screenshot: str | None = None, frames: int = 10,
                 window_size: tuple[int, int] | None = None, recover: bool = True):
        self.start_path = path
        self.screenshot = screenshot
        self.min_frames = frames
        self.settings = load_settings()
        # The size the window had when the editor last closed (a screenshot keeps the documented 1280 x 800).
        self.window_size = window_size or (None if screenshot else self.settings.window) or (1280, 800)
        self.show_shortcuts = False
        self.panels_open = set(self.settings.panels if self.settings.panels is not None else DEFAULT_PANELS)
        self.tile_mode = False           # the canvas shows the periodic texture of the tile size
        self.offer_recovery = recover and screenshot is None
        self.history: History | None = None
        self.view = View()
        self.display = Display()
        self.project_path: str | None = None
        self.gpu: Gpu | None = None
        self.renderer = ""
        self.session: Session | None = None
        self.canvas: Canvas | None = None
        self.dialogs = Dialogs()
        if self.settings.recent:  # the file browser starts in the folder last used
            self.dialogs.last_dir = os.path.dirname(self.settings.recent[0])
        self.autosave = Autosave()
        self.pending: tuple | None = None    # (kind, candidate Document, project or None, path) being analyzed
        self.export_job: ExportJob | StreamedExport | None = None
        self.export_rect = [0, 0, 2048, 2048]
        self.export_format = "png"       # png (one image, in memory) | tiles (UDIM PNG set) | tiff (BigTIFF)
        self.stream_tile = 1024          # tile size of the streamed formats
        self.export_workers = max(1, (os.cpu_count() or 2) - 1)  # leave a core to the editor
        self.estimate: ExportEstimate | None = None
        self.tile_size = 1024
        self.write_coords = False
        self.export_depth: int | None = None  # bit depth of exported maps; None: each map's own
        self.export_magnify = 1               # exported pixels per texel (synthesis magnification)
        self.goto = [0, 0]
        self.frame: Frame | None = None
        self.canvas_size = (1, 1)
        self.refined = False
        self.frame_count = 0
        self.fps = 0.0
        self._fps_t = time.perf_counter()
        self._fps_n = 0
        self.update_ms = 0.0
        self.pixels = 0
        self.cursor: tuple[float, float] | None = None
        self.cursor_uv: tuple[int, int] | None = None
        self.fatal: str | None = None
        self._dropped: list[str] = []
        self.quit_requested = False
        self._close_requested = False
        self.canvas_request = False
        self.canvas_pixels = None      # last canvas read back on request (tests)
        self._canvas_key = None
        self._last_doc = None
        self._last_edit = 0.0
        self.panels = panels.Panels(self)
        self.tools = make_tools(self)
        self.tool = self.tools[0]
        self.show_fields = True          # randomness fields drawn as heat maps
        self.overlay_canvas: FieldOverlay | None = None
        self.overlay_exemplar: FieldOverlay | None = None
        self.overlay_avoid: FieldOverlay | None = None
        self._canvas_button = -1         # mouse button that went down on the canvas
        self.notice: tuple[str, float] | None = None  # (text, monotonic time): e.g. where an export went
        self._title = ""

    # -- running ------------------------------------------------------------

    def runner_params(self) -> hello_imgui.RunnerParams:
        p = hello_imgui.RunnerParams()
        p.app_window_params.window_title = "Infinitex"
        p.app_window_params.window_geometry.size = self.window_size
        p.imgui_window_params.default_imgui_window_type = hello_imgui.DefaultImGuiWindowType.no_default_window
        # Floating windows (Lattice, Paint exemplar, Shortcuts) keep their place
        # between runs: imgui's ini in the user's config folder (none for screenshots).
        p.ini_disable = bool(self.screenshot)
        try:
            os.makedirs(config_dir(), exist_ok=True)
        except OSError:
            p.ini_disable = True
        p.ini_folder_type = hello_imgui.IniFolderType.absolute_path
        p.ini_filename = os.path.join(config_dir(), "imgui.ini")
        p.imgui_window_params.background_color = (0.06, 0.06, 0.065, 1.0)
        # Idle means idle: with nothing to refine and no job, the runner waits for
        # events (input wakes it at once) and draws one frame every few seconds
        # (the autosave clock); working or refining turns idling off (_after_frame).
        p.fps_idling.fps_idle = IDLE_FPS
        p.fps_idling.fps_idling_mode = hello_imgui.FpsIdlingMode.sleep
        p.callbacks.post_init = self.post_init
        p.callbacks.show_gui = self.gui
        p.callbacks.before_exit = self.before_exit
        p.callbacks.confirm_exit = self._confirm_exit
        self.params = p
        return p

    def run(self) -> int:
        immapp.run(self.runner_params(), immapp.AddOnsParams())
        if self.screenshot:
            import numpy as np

            from infinitex.engine.exemplar import write_png
            shot = hello_imgui.final_app_window_screenshot()
            if shot is None or not getattr(shot, "size", 0):
                print("infinitex: the screenshot could not be taken.")
                return 1
            img = np.asarray(shot)
            try:
                write_png(self.screenshot, np.ascontiguousarray(img[..., :3] if img.shape[-1] == 4 else img))
            except WriteError as exc:
                sys.stderr.write(f"error: {printable(exc)}\n")
                return 1
        return 1 if self.fatal else 0

    def post_init(self) -> None:
        import moderngl
        try:
            ctx = moderngl.create_context()
            self.gpu = Gpu(ctx)
            self.screen_fbo = ctx.detect_framebuffer()  # where imgui draws: restored after our passes
            self.renderer = self.gpu.renderer
            self.session = Session(self.gpu)
            self.canvas = Canvas(self.gpu)
            self.overlay_canvas = FieldOverlay(ctx)
            self.overlay_exemplar = FieldOverlay(ctx)
            self.overlay_avoid = FieldOverlay(ctx)
        except (GLUnavailable, Exception) as exc:
            self.fatal = (f"OpenGL 3.3 is not usable here: {exc}\nThe editor needs OpenGL 3.3; "
                          "on Linux install libgl1 and a Mesa driver.")
            return
        self._install_drop_callback()
        recovered = self.autosave.pending() if self.offer_recovery else None
        if self.start_path:
            self.open_path(self.start_path, first=True)
        else:
            self.new_document()
        if self.autosave.set_aside is not None:
            where, why = self.autosave.set_aside
            self.dialogs.message("Autosave set aside",
                                 f"The autosaved work of an earlier session could not be read ({why})\n"
                                 f"It was kept as {printable(where)}.")
        if recovered is not None:
            t = self.autosave.pending_time()
            when = time.strftime("%Y-%m-%d %H:%M", time.localtime(t)) if t else "an earlier session"
            self.dialogs.ask(
                "Recover unsaved work",
                f"Infinitex did not close normally. Unsaved work from {when} was kept.\n"
                "Recover it?",
                [("Recover", lambda: self._recover(recovered)), ("Discard", self.autosave.clear)])

    def _install_drop_callback(self) -> None:
        try:
            import glfw
            from imgui_bundle import glfw_utils
            win = glfw_utils.glfw_window_hello_imgui()
            glfw.set_drop_callback(win, lambda _w, paths: self._dropped.extend(paths))
        except Exception:
            pass

    def remember(self, path: str) -> None:
        """Put a file at the top of File > Open Recent (kept in the user's config folder)."""
        self.settings = self.settings.with_recent(path)
        save_settings(self.settings)

    def _save_window_size(self) -> None:
        if self.screenshot:
            return
        try:
            import glfw
            from imgui_bundle import glfw_utils
            w, h = glfw.get_window_size(glfw_utils.glfw_window_hello_imgui())
        except Exception:
            return
        if w >= 320 and h >= 320:
            self.settings = replace(self.settings, window=(int(w), int(h)), panels=tuple(sorted(self.panels_open)))
            save_settings(self.settings)

    def before_exit(self) -> None:
        self._save_window_size()
        if self.history is not None and self.history.dirty:
            try:
                self.autosave.tick(self.autosave_project(), True, force=True)  # keep unsaved work for recovery
            except ProjectError:
                pass
        else:
            self.autosave.clear()
        if self.export_job is not None:
            self.export_job.cancel()
            if isinstance(self.export_job, StreamedExport):
                self.export_job.wait(120)  # the tiles being rendered finish; every finished one is kept
        if self.estimate is not None:
            self.estimate.close(wait=10.0)
        if self.session is not None:
            self.session.release()
        if self.canvas is not None:
            self.canvas.release()
        for o in (self.overlay_canvas, self.overlay_exemplar, self.overlay_avoid):
            if o is not None:
                o.release()

    # -- documents ----------------------------------------------------------

    @property
    def doc(self) -> Document | None:
        return self.history.current if self.history else None

    def project(self) -> Project:
        return Project(self.doc, self.view, self.display)

    def autosave_project(self) -> Project:
        """The project with the file it belongs to, so recovery restores its name."""
        return replace(self.project(), origin=os.path.abspath(self.project_path) if self.project_path else None)

    @property
    def title(self) -> str:
        """The window title: the document's name, * when it has unsaved edits."""
        if self.project_path:
            name = os.path.basename(self.project_path)
        elif self.doc is not None:
            name = f"untitled ({self.doc.exemplar.name})"
        else:
            name = "untitled"
        dirty = self.history is not None and self.history.dirty
        return f"{'*' if dirty else ''}{name} - Infinitex"

    def new_document(self) -> None:
        try:
            src = ExemplarSource.from_file(DEFAULT_EXEMPLAR)
        except OSError as exc:
            self.dialogs.message("Error", f"The default exemplar could not be read: {exc}")
            return
        self._begin_load("new", Document(src), None, None)

    def open_path(self, path: str, first: bool = False, allow_outside=False, replace_exemplar: bool = False) -> None:
        """Open a project, or an image as a new document (untitled, default
        settings); with ``replace_exemplar`` the image replaces the exemplar of
        the open document instead (undoable; the Exemplar panel's button).
        One map of a material brings its siblings (named by the rule), and a
        folder is one material's maps.

        A project whose exemplar file lies outside the project's folder is
        opened only after the user confirms that file."""
        path = os.path.expanduser(path)
        try:
            if os.path.isfile(path) and is_project_file(path):
                proj = load_project(path, allow_outside=allow_outside)
                self._begin_load("project", proj.document, proj, path)
                return
        except ExemplarOutside as exc:
            allow = {exc.path}  # (exc itself is gone once the except block ends)
            self.dialogs.ask("Exemplar outside the project's folder",
                             f"{exc}\nRead this file as the exemplar?",
                             [("Read it", lambda: self.open_path(path, first, allow_outside=allow,
                                                                 replace_exemplar=replace_exemplar)),
                              ("Cancel", lambda: self._open_failed(None, first))])
            return
        except ProjectError as exc:
            self._open_failed(str(exc), first)
            return
        except OSError as exc:
            self._open_failed(f"{printable(os.path.basename(path))} could not be read: {exc.strerror or exc}.", first)
            return
        self.open_paths([path], first, replace_exemplar)

    def open_paths(self, paths: list[str], first: bool = False, replace_exemplar: bool = False) -> None:
        """Open images as a document: one image, one map of a material (its
        siblings come along), a material's folder, or several maps at once
        (their roles from their names). All or nothing."""
        try:
            found = assign_roles([os.path.expanduser(p) for p in paths])
            maps = [(role, ExemplarSource.from_file(p)) for role, p in found.items()]
        except (MaterialError, ReadError) as exc:
            self._open_failed(str(exc), first)
            return
        except OSError as exc:
            self._open_failed(f"The maps could not be read: {exc.strerror or exc}.", first)
            return
        path = paths[0] if len(paths) == 1 else None
        base = self.doc if replace_exemplar and self.doc is not None else None
        if base is not None:
            # A lattice is marked in the old image's pixels: the new image starts without one.
            doc = replace(base, toroidal=None, lattice=None, weights=None).with_maps(maps)
            self._begin_load("exemplar", doc, None, path)
        else:
            self._begin_load("image", Document(maps[0][1]).with_maps(maps), None, path)

    def _open_failed(self, msg: str | None, first: bool) -> None:
        if msg:
            self.dialogs.message("Could not open", msg)
        if first and self.history is None:
            self.new_document()

    def _begin_load(self, kind: str, doc: Document, proj: Project | None, path: str | None,
                    label: str = "Load exemplar") -> None:
        """Analyze ``doc`` and make it current only when that succeeds (a new
        document, or with kind "exemplar" an edit named ``label``)."""
        self.pending = (kind, doc, proj, path)
        self.pending_label = label
        self.session.load(doc)

    def _finish_load(self, job) -> None:
        kind, doc, proj, path = self.pending
        self.pending = None
        if job.error or job.cancelled:
            if job.error:
                self.dialogs.message("Could not open", job.error)
            if self.history is None:
                if kind != "new":
                    self.new_document()
                else:
                    self.fatal = job.error or "The default exemplar could not be loaded."
            return
        if path and kind in ("project", "image", "exemplar") and path != self.autosave.path:
            self.remember(path)
        if kind == "exemplar" and self.history is not None:
            self.edit(doc, getattr(self, "pending_label", "Load exemplar"))
            return
        self.history = History(doc)
        if kind == "project":
            self.view, self.display = proj.view, proj.display
            self.project_path = path if path != self.autosave.path else None
        elif kind == "recovered":  # the unsaved work of a project (or of an untitled document)
            self.view, self.display = proj.view, proj.display
            self.project_path = proj.origin if proj.origin and os.path.isfile(proj.origin) else None
            self.history.saved = None
        else:
            self.view, self.display = View(), Display()
            self.project_path = None

    def _recover(self, proj: Project) -> None:
        self._begin_load("recovered", proj.document, proj, None)

    def edit(self, doc: Document, label: str, group: object = None) -> None:
        """Apply an edit (one undo step; same ``group`` = same step)."""
        if self.history is None:
            return
        try:
            self.history.apply(doc, label, group)
        except ProjectError as exc:
            self.dialogs.message("Invalid setting", str(exc))

    def undo(self) -> None:
        if self.history:
            self.history.undo()

    def redo(self) -> None:
        if self.history:
            self.history.redo()

    def save(self, path: str | None = None) -> bool:
        path = path or self.project_path
        if path is None:
            self.save_as()
            return False
        if not os.path.splitext(path)[1]:
            path += PROJECT_SUFFIX
        try:
            save_project(path, self.project())
        except ProjectError as exc:
            self.dialogs.message("Save failed", f"{exc}\nNothing was changed on disk.")
            return False
        self.project_path = path
        self.remember(path)
        self.history.mark_saved()
        self.autosave.clear()
        return True

    def save_as(self, then=None) -> None:
        """Ask where to save; ``then()`` runs once the project is saved."""
        def done(path: str) -> None:
            if self.save(path) and then is not None:
                then()
        folder = os.path.dirname(os.path.abspath(self.project_path)) if self.project_path else os.getcwd()
        name = self.project_path or os.path.join(folder, "untitled" + PROJECT_SUFFIX)
        self.dialogs.ask_path("Save project as", True, PROJECT_FILTER, done, default=os.path.abspath(name))

    def save_then(self, action) -> None:
        """Save (asking where for an untitled document), then run ``action``."""
        if self.project_path is None:
            self.save_as(then=action)
        elif self.save():
            action()

    def confirm_discard(self, action) -> None:
        """Run ``action`` (which replaces the document), offering to save unsaved edits first."""
        if self.history is not None and self.history.dirty:
            self.dialogs.ask("Unsaved changes", f"{self.title.split(' - ')[0].lstrip('*')} has unsaved changes. "
                             "Save them first?",
                             [("Save", lambda: self.save_then(action)), ("Discard", action), ("Cancel", None)])
        else:
            action()

    def request_quit(self) -> None:
        """Quit, asking first when there are unsaved edits (menu, Ctrl+Q, window close)."""
        def quit_now():
            if self.history is not None:
                self.history.saved = self.history.current
            self.quit_requested = True

        def save_and_quit():
            self.save_then(quit_now)
        if self.history is not None and self.history.dirty:
            self.dialogs.ask("Unsaved changes", "The project has unsaved changes. Save them before quitting?",
                             [("Save", save_and_quit), ("Discard", quit_now), ("Cancel", None)])
        else:
            quit_now()

    def _confirm_exit(self) -> bool:
        # Called by the runner outside the frame (no imgui calls here): defer to a modal.
        if self.history is not None and self.history.dirty and not self.screenshot:
            self._close_requested = True
            return False
        return True

    # -- export -------------------------------------------------------------

    def view_rect(self) -> Rect:
        w, h = self.canvas_size
        x0, y0 = self.view.top_left(w, h)
        return Rect(math.floor(x0), math.floor(y0), math.ceil(x0 + w / self.view.zoom), math.ceil(y0 + h / self.view.zoom))

    def start_export(self, path: str, rect: Rect, toroidal: int = 0) -> None:
        if not os.path.splitext(path)[1]:
            single = self.session.material is None or self.session.material.single
            path += ".tif" if self.export_depth == 32 and single else ".png"
        coords = os.path.splitext(path)[0] + "_coords.png" if self.write_coords else None
        try:
            check_output(path, (".png", ".tif", ".tiff"), "export")  # before any work
            if coords:
                check_output(coords, (".png",), "coordinate map")
            geometry = "original" if self.geometry() is not None else "rectified"  # what the canvas shows
            job = ExportJob(self.session, rect, path, toroidal=toroidal, coords_path=coords,
                            geometry=geometry, depth=self.export_depth, magnify=1 if coords else self.export_magnify)
            try:
                for _, out, _ in job.outputs:
                    check_output(out, (".png", ".tif"), "export")
            except WriteError:
                job.cancel()
                raise
            self.export_job = job
        except (SynthesisError, ValueError, WriteError) as exc:
            self.dialogs.message("Export", str(exc))

    def start_streamed_export(self, path: str, rect: Rect) -> None:
        """A tile set or BigTIFF of ``rect``, rendered by worker processes while the editor stays live."""
        fmt = self.export_format
        ext = {"tiff": ".tif", "zarr": ".zarr"}.get(fmt, ".png")
        if not os.path.splitext(path)[1]:
            path += ext
        try:
            if fmt == "zarr":
                check_zarr_output(path)
            else:
                check_output(path, (".tif", ".tiff") if ext == ".tif" else (".png",), "export")
            if self.write_coords and fmt != "zarr":
                check_output(os.path.splitext(path)[0] + "_coords" + ext, (ext,), "coordinate map")
            role = "" if self.session.material.single else self.shown_role()
            if role:  # one map per streamed export: the one shown
                path = map_path(path, role)
            self.export_job = StreamedExport(self.doc, self.session.L, rect, path, fmt, self.stream_tile,
                                             self.export_workers, coords=self.write_coords and fmt != "zarr",
                                             role=role)
        except (SynthesisError, ValueError, WriteError) as exc:
            self.dialogs.message("Export", str(exc))

    # -- the frame ----------------------------------------------------------

    def gui(self) -> None:
        self.frame_count += 1
        self._tick_fps()
        vp = imgui.get_main_viewport()
        imgui.set_next_window_pos(vp.work_pos)
        imgui.set_next_window_size(vp.work_size)
        flags = (imgui.WindowFlags_.no_decoration | imgui.WindowFlags_.no_move | imgui.WindowFlags_.menu_bar
                 | imgui.WindowFlags_.no_bring_to_front_on_focus | imgui.WindowFlags_.no_saved_settings
                 | imgui.WindowFlags_.no_background)
        imgui.push_style_var(imgui.StyleVar_.window_padding, (6, 4))
        imgui.begin("Infinitex", None, flags)
        imgui.pop_style_var()
        if self.fatal:
            imgui.text_wrapped(self.fatal)
            if imgui.button("Quit"):
                self.params.app_shall_exit = True
            imgui.end()
            return
        self._update_engine()
        if self._close_requested:
            self._close_requested = False
            self.request_quit()
        self.panels.menu_bar()
        self._shortcuts()
        status_h = imgui.get_frame_height_with_spacing() + 4
        avail = imgui.get_content_region_avail()
        imgui.begin_child("Panels", (PANEL_WIDTH, avail.y - status_h), imgui.ChildFlags_.borders)
        self.panels.side_panels()
        imgui.end_child()
        imgui.same_line()
        imgui.begin_child("Canvas", (0, avail.y - status_h), imgui.ChildFlags_.borders,
                          imgui.WindowFlags_.no_scrollbar | imgui.WindowFlags_.no_scroll_with_mouse
                          | imgui.WindowFlags_.no_background)
        if self.doc is not None and self.session.ready:
            self.panels.toolbar()
        self._canvas()
        imgui.end_child()
        self.panels.status_bar()
        self.dialogs.draw()
        self.panels.progress_modals()
        imgui.end()
        if self.tool.name in ("paint-exemplar", "lattice") and self.doc is not None:
            self.tool.window()
        self.shortcuts_window()
        self._after_frame()

    def _tick_fps(self) -> None:
        self._fps_n += 1
        now = time.perf_counter()
        if now - self._fps_t >= 0.5:
            self.fps = self._fps_n / (now - self._fps_t)
            self._fps_t, self._fps_n = now, 0

    def _update_engine(self) -> None:
        s = self.session
        if len(self._dropped) > 1 and not any(is_project_file(p) for p in self._dropped if os.path.isfile(p)):
            paths, self._dropped = list(self._dropped), []  # several images dropped at once: one material's maps
            self.confirm_discard(lambda: self.open_paths(paths))
        while self._dropped:
            path = self._dropped.pop(0)
            self.confirm_discard(lambda: self.open_path(path))
        job = s.poll()
        if job is not None and self.pending is not None and job.key == self.pending[1].analysis_key():
            self._finish_load(job)
        elif job is not None and job.error:
            self.dialogs.message("Analysis failed", job.error)
        if self.doc is not None and (self.pending is None or s.job is None):
            s.sync(self.doc)
        if s.ready:
            self._show_maps()
        if isinstance(self.export_job, StreamedExport):
            job = self.export_job
            if job.finished:
                self.export_job = None
                if job.error:
                    self.dialogs.message("Export failed", job.error)
                elif job.cancelled:
                    self.notice = (f"Export stopped: {job.done_tiles} of {job.job.total} tiles are kept; the same "
                                   f"export continues from them", time.monotonic())
                else:
                    r = job.rect
                    where = " and ".join(os.path.abspath(o) for o in job.job.outputs())
                    kept = f" ({job.kept} tiles kept from an earlier run)" if job.kept else ""
                    self.notice = (f"Exported {r.w}x{r.h} to {where}{kept}", time.monotonic())
        elif self.export_job is not None:
            self.export_job.step(FRAME_BUDGET_S)
            self.screen_fbo.use()
            if self.export_job.done or self.export_job.cancelled:
                job, self.export_job = self.export_job, None
                if job.error:
                    self.dialogs.message("Export failed", job.error)
                elif not job.cancelled:
                    r = job.out_rect
                    names = [os.path.abspath(o) for _, o, _ in job.outputs]
                    where = names[0] if len(names) == 1 else f"{len(names)} maps ({', '.join(names)})"
                    extra = f" and {os.path.abspath(job.coords_path)}" if job.coords_path else ""
                    self.notice = (f"Exported {r.w}x{r.h} to {where}{extra}", time.monotonic())
        if self.doc is not None and self.history is not None:
            try:
                self.autosave.tick(self.autosave_project(), self.history.dirty)
            except ProjectError:
                pass

    def shown_role(self) -> str:
        """The map the canvas shows: the Display panel's choice; the lit preview
        shows the base color (or the first map) shaded."""
        s = self.session
        mat = s.material
        if self.display.mode == "lit":
            return next((r for r in ("basecolor", IMAGE) if r in mat.maps), mat.primary)
        return s.shown_map(self.display.map)

    def _show_maps(self) -> None:
        """Upload the shown map's stack (and, lit, the shaping map's) when they change."""
        s = self.session
        role = self.shown_role()
        key = (s.generation, role)
        if self.canvas.shown != key:
            ex = s.material.maps[role].exemplar
            self.canvas.set_exemplar(s.display_stack(role), s.analysis.toroidal, ex.hires, s.generation)
            self.canvas.shown = key
        if self.display.mode == "lit":
            kind, shape_role = s.shape_map()
            skey = (s.generation, shape_role)
            if self.canvas.shape_key != skey:
                self.canvas.set_shape(s.shape_stack(shape_role), kind, s.analysis.toroidal, skey)

    def _shortcuts(self) -> None:
        if self.dialogs.busy or imgui.get_io().want_text_input:
            return
        ctrl = imgui.Key.mod_ctrl
        if imgui.is_key_chord_pressed(ctrl | imgui.Key.mod_shift | imgui.Key.z) or imgui.is_key_chord_pressed(ctrl | imgui.Key.y):
            self.redo()
        elif imgui.is_key_chord_pressed(ctrl | imgui.Key.z):
            self.undo()
        if imgui.is_key_chord_pressed(ctrl | imgui.Key.s):
            self.save()
        if imgui.is_key_chord_pressed(ctrl | imgui.Key.mod_shift | imgui.Key.s):
            self.save_as()
        if imgui.is_key_chord_pressed(ctrl | imgui.Key.o):
            self.panels.open_dialog()
        if imgui.is_key_chord_pressed(ctrl | imgui.Key.q):
            self.request_quit()
        io = imgui.get_io()
        if imgui.is_key_pressed(imgui.Key.f1, False) or (
                imgui.is_key_pressed(imgui.Key.slash, False) and io.key_shift):
            self.show_shortcuts = not self.show_shortcuts
        if not (io.key_ctrl or io.key_alt or io.key_super) and not imgui.is_any_item_active():
            self._zoom_keys()
        # Tool keys act on the canvas (under the mouse), never while typing or dragging a control.
        if (self.cursor is not None and not (io.key_ctrl or io.key_alt or io.key_super)
                and not imgui.is_any_item_active()):
            for t in self.tools:
                if t.key and imgui.is_key_pressed(getattr(imgui.Key, t.key.lower()), False):
                    self.set_tool(t.name)
            if imgui.is_key_pressed(imgui.Key.h, False):
                self.show_fields = not self.show_fields
            if imgui.is_key_pressed(imgui.Key.t, False):
                self.tile_mode = not self.tile_mode
            if imgui.is_key_pressed(imgui.Key.m, False) and self.session.ready:
                roles = self.session.material.roles  # the next map of a material
                cur = self.session.shown_map(self.display.map)
                self.display = replace(self.display, map=roles[(roles.index(cur) + 1) % len(roles)])
            self.tool.keys()

    def _zoom_keys(self) -> None:
        """1: actual size; + and -: zoom in and out around the canvas centre;
        0: fit one exemplar across the canvas (as in Krita and Blender)."""
        w, h = self.canvas_size
        K = imgui.Key
        if imgui.is_key_pressed(K._1, False) or imgui.is_key_pressed(K.keypad1, False):
            self.view = replace(self.view, zoom=1.0).clamped()
        elif imgui.is_key_pressed(K.equal) or imgui.is_key_pressed(K.keypad_add):
            self.view = self.view.zoom_at(2.0, w / 2, h / 2, w, h)
        elif imgui.is_key_pressed(K.minus) or imgui.is_key_pressed(K.keypad_subtract):
            self.view = self.view.zoom_at(0.5, w / 2, h / 2, w, h)
        elif (imgui.is_key_pressed(K._0, False) or imgui.is_key_pressed(K.keypad0, False)) and self.session.ready:
            m = self.session.analysis.size
            z = 2.0 ** math.floor(math.log2(max(1e-3, min(w, h) / m)))
            self.view = replace(self.view, zoom=z).clamped()

    def shortcuts_window(self) -> None:
        """F1 or ?: every keyboard and mouse shortcut."""
        if not self.show_shortcuts:
            return
        vp = imgui.get_main_viewport()
        imgui.set_next_window_pos((vp.work_pos.x + vp.work_size.x / 2, vp.work_pos.y + vp.work_size.y / 2),
                                  imgui.Cond_.appearing, (0.5, 0.5))
        opened, keep = imgui.begin("Shortcuts (F1)", True, imgui.WindowFlags_.always_auto_resize
                                   | imgui.WindowFlags_.no_collapse)
        if opened and imgui.begin_table("shortcuts", 2, imgui.TableFlags_.row_bg | imgui.TableFlags_.borders_inner_v):
            for key, what in SHORTCUTS + [(f"{t.key}", f"{t.label} tool (cursor over the canvas)")
                                          for t in self.tools if t.key]:
                imgui.table_next_row()
                imgui.table_next_column()
                imgui.text(key)
                imgui.table_next_column()
                imgui.text(what)
            imgui.end_table()
        imgui.end()
        if not keep:
            self.show_shortcuts = False
        self.panels_open = set(self.settings.panels if self.settings.panels is not None else DEFAULT_PANELS)
        self.tile_mode = False           # the canvas shows the periodic texture of the tile size

    def _canvas(self) -> None:
        avail = imgui.get_content_region_avail()
        w, h = max(16, int(avail.x)), max(16, int(avail.y))
        self.canvas_size = (w, h)
        s = self.session
        p0 = imgui.get_cursor_screen_pos()
        # Input first, so this frame already shows what a tool or a pan did.
        hovered = self._canvas_input(p0, w, h)
        if s.ready and self.doc is not None:
            s.period = self.tile_period()
            s.sync(self.doc)  # a tool's edit of this frame (a paint dab is re-synthesized locally here)
            level = None
            if self.display.mode == "level":
                level = s.L if self.display.level < 0 else min(self.display.level, s.L)
            geom = self.geometry()
            self.frame = frame_for(self.view, w, h, s.L, level, geom)
            if self.doc is not self._last_doc:
                prev, self._last_doc = self._last_doc, self.doc
                # Canvas paint and features are re-synthesized locally and exactly: no coarse preview.
                local = replace(prev, randomness_canvas=self.doc.randomness_canvas,
                                features=self.doc.features) if prev is not None else None
                if local != self.doc:
                    self._last_edit = time.monotonic()
            interactive = (time.monotonic() - self._last_edit < INTERACTIVE_S) and not self.canvas_request
            t0 = time.perf_counter()
            scale = 1
            try:
                if interactive:
                    # A control is being dragged: a complete coarser preview every
                    # frame, drawn at its own resolution, keeps the editor fluid.
                    c = s.refiner.preview(self.frame, PREVIEW_BUDGET_S)
                    self.refined = False
                    texel_px = self.view.zoom * (1 << (s.L - c)) if c >= 0 else 1
                    if self.display.magnify == "nearest":  # plain texel blocks: draw them at their own size
                        scale = 1 << max(0, min(3, int(math.floor(math.log2(max(1.0, texel_px))))))
                else:
                    self.refined = s.refine(self.frame, REST_BUDGET_S)
            except SynthesisError as exc:
                self.view = View(0, 0, self.view.zoom)
                self.dialogs.message("Synthesis", str(exc))
            self.update_ms = (time.perf_counter() - t0) * 1000.0
            self.pixels = s.refiner.last_pixels if s.refiner else 0
            self.canvas.ensure_size(w // scale, h // scale)
            view = self.view if scale == 1 else View(self.view.x, self.view.y, self.view.zoom / scale)
            key = (s.generation, s.params, s.refiner.version, self.frame, view, self.display, (w, h))
            if key != self._canvas_key or self.canvas_request:
                self.canvas.render(s.pyramid, self.frame, view, self.display, geom)
                self._canvas_key = key
            if self.canvas_request:
                self.canvas_pixels = self.canvas.read()
                self.canvas_request = False
        else:
            self.canvas.ensure_size(w, h)
            self.canvas.render(None, None, self.view, self.display)
            self._canvas_key = None
            self.refined = False
        self.screen_fbo.use()
        imgui.set_cursor_screen_pos(p0)
        imgui.image(imgui.ImTextureRef(self.canvas.tex.glo), (w, h))
        if s.ready and self.doc is not None:
            dl = imgui.get_window_draw_list()
            if self.show_fields and self.geometry() is None:
                self._field_overlay(dl, p0, w, h)
            self.panels.canvas_overlay(p0, w, h)
            if self.tool.name == "feature":
                self.tool.draw_handles(dl, p0, w, h)
            if s.period:
                self._tile_borders(dl, p0, w, h, s.period)
            if hovered:
                self.tool.overlay(dl, p0, w, h)

    def _canvas_input(self, p0, w: int, h: int) -> bool:
        """The canvas's mouse input: the left button goes to the active tool, the
        right and middle buttons always pan (from the press position), the
        wheel zooms around the cursor. Returns whether the canvas is hovered."""
        s = self.session
        imgui.invisible_button("canvas", (w, h), imgui.ButtonFlags_.mouse_button_left
                               | imgui.ButtonFlags_.mouse_button_right | imgui.ButtonFlags_.mouse_button_middle)
        io = imgui.get_io()
        hovered = imgui.is_item_hovered()
        x0, y0 = self.view.top_left(w, h)
        mouse = (io.mouse_pos.x, io.mouse_pos.y)
        at = (x0 + (mouse[0] - p0.x) / self.view.zoom, y0 + (mouse[1] - p0.y) / self.view.zoom)
        view_before = self.view
        tool = self.tool if s.ready and self.doc is not None else self.tools[0]
        if imgui.is_item_activated():
            self._canvas_button = 0 if imgui.is_mouse_down(imgui.MouseButton_.left) else 1
            (tool if self._canvas_button == 0 else self.tools[0]).press(at, mouse)
        elif imgui.is_item_active() and self._canvas_button >= 0:
            (tool if self._canvas_button == 0 else self.tools[0]).drag(at, mouse)
        if imgui.is_item_deactivated() and self._canvas_button >= 0:
            (tool if self._canvas_button == 0 else self.tools[0]).release()
            self._canvas_button = -1
        if imgui.begin_drag_drop_target():  # an exemplar feature dropped from the Exemplar panel
            payload = imgui.accept_drag_drop_payload_py_id(FEATURE_PAYLOAD)
            if payload is not None and s.ready and self.doc is not None and self.geometry() is None:
                self.set_tool("feature")
                self.tool.place((payload.data_id % 4096, payload.data_id // 4096), at)
            imgui.end_drag_drop_target()
        if hovered and io.mouse_wheel and not (s.ready and self.doc is not None and self.tool.wheel(at, io.mouse_wheel)):
            self.view = self.view.zoom_at(2.0 ** (io.mouse_wheel * 0.25), mouse[0] - p0.x, mouse[1] - p0.y, w, h)
        if self.view != view_before:  # the wheel or a pan moved the canvas under the mouse
            x0, y0 = self.view.top_left(w, h)
            at = (x0 + (mouse[0] - p0.x) / self.view.zoom, y0 + (mouse[1] - p0.y) / self.view.zoom)
        self.cursor = at if hovered else None
        return hovered

    def tile_period(self) -> int:
        """The tile size while tile mode is on (whole lattice cells required), else 0."""
        if not self.tile_mode or not self.session.ready:
            return 0
        n = self.tile_size
        lat = self.session.controls.lattice
        if lat is not None:
            cx, cy = lat.cell(self.session.analysis.size)
            if n % cx or n % cy:
                self.tile_mode = False
                self.dialogs.message("Tile mode", f"A tile of {n} px is not made of whole lattice cells "
                                     f"({cx}x{cy} px); choose a larger tile size.")
                return 0
        return n

    def _tile_borders(self, dl, p0, w: int, h: int, n: int) -> None:
        """The tile's borders over the canvas (mapped into the input's geometry with a lattice)."""
        z = self.view.zoom
        x0, y0 = self.view.top_left(w, h)
        G = self.geometry()
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
        """The canvas randomness field as a translucent heat map over the canvas."""
        z = self.view.zoom
        x0, y0 = self.view.top_left(w, h)
        tex = self.overlay_canvas.canvas(self.doc.randomness_canvas, x0, y0, w / z, h / z)
        if tex is None:
            return
        fx, fy, fw, fh = self.overlay_canvas.placement
        a = (p0.x + (fx - x0) * z, p0.y + (fy - y0) * z)
        dl.push_clip_rect(p0, (p0.x + w, p0.y + h), True)
        dl.add_image(imgui.ImTextureRef(tex.glo), a, (a[0] + fw * z, a[1] + fh * z))
        dl.pop_clip_rect()

    def _update_title(self) -> None:
        title = self.title
        if title == self._title:
            return
        self._title = title
        try:
            import glfw
            from imgui_bundle import glfw_utils
            glfw.set_window_title(glfw_utils.glfw_window_hello_imgui(), title)
        except Exception:
            pass  # no window (a test driver's runner without one): nothing to title

    def _after_frame(self) -> None:
        self._update_title()
        # Worker processes doing the work (a streamed export, an estimate) need
        # the cores more than a full frame rate: a few frames a second show progress.
        background = (isinstance(self.export_job, StreamedExport)
                      or (self.estimate is not None and not self.estimate.poll()))
        self.params.fps_idling.fps_idle = BACKGROUND_FPS if background else IDLE_FPS
        working = (isinstance(self.export_job, ExportJob) or self.pending is not None
                   or (self.session is not None and self.session.job is not None))
        # Nothing to refine while no document is open and a question waits for the user.
        waiting = self.history is None and bool(self.dialogs.modals)
        busy = working or (not self.refined and not waiting)
        self.params.fps_idling.enable_idling = not busy
        if self.quit_requested:
            self.params.app_shall_exit = True
        if self.screenshot and ((self.frame_count >= self.min_frames and not busy)
                                or self.frame_count >= self.min_frames + 3000):
            self.params.app_shall_exit = True

    # -- small helpers for panels -----------------------------------------

    def geometry(self):
        """The 2x2 map from view positions to the synthesized canvas when a
        lattice is shown in the input's geometry; None when the canvas shows
        the synthesized (rectified) texture itself."""
        s = self.session
        lat = s.controls.lattice if s is not None and s.ready and s.controls is not None else None
        if lat is None or self.display.geometry != "original":
            return None
        return lat.canvas_matrix(s.analysis.size)

    def set_tool(self, name: str) -> None:
        if name in CANVAS_SPACE_TOOLS and self.geometry() is not None:
            # Paint and features live on the synthesized canvas: show it rectified.
            self.display = replace(self.display, geometry="rectified")
        for t in self.tools:
            if t.name == name and t is not self.tool:
                self.tool.release()
                self.tool = t

    def new_seed(self) -> None:
        self.edit(replace(self.doc, seed=random.randrange(1, 2 ** 31)), "New seed")


def probe_gl() -> str | None:
    """Why no OpenGL 3.3 core window can be made here, or None when one can.

    Run before the window runner, which would otherwise stop with a traceback
    (no display, no GLX, a driver below 3.3)."""
    import glfw
    errors: list[str] = []
    glfw.set_error_callback(lambda code, text: errors.append(
        text.decode("utf-8", "replace") if isinstance(text, bytes) else str(text)))
    try:
        if not glfw.init():
            return errors[-1] if errors else "the window system could not be initialized"
        try:
            glfw.window_hint(glfw.VISIBLE, glfw.FALSE)
            glfw.window_hint(glfw.CONTEXT_VERSION_MAJOR, 3)
            glfw.window_hint(glfw.CONTEXT_VERSION_MINOR, 3)
            glfw.window_hint(glfw.OPENGL_PROFILE, glfw.OPENGL_CORE_PROFILE)
            glfw.window_hint(glfw.OPENGL_FORWARD_COMPAT, glfw.TRUE)
            win = glfw.create_window(64, 64, "Infinitex GL probe", None, None)
            if not win:
                return errors[-1] if errors else "no OpenGL 3.3 window could be created"
            glfw.destroy_window(win)
            return None
        finally:
            glfw.terminate()
    except Exception as exc:  # a missing or broken libglfw
        return str(exc) or type(exc).__name__
    finally:
        glfw.set_error_callback(None)


def run_editor(path: str | None = None, screenshot: str | None = None, frames: int = 10) -> int:
    import warnings
    warnings.filterwarnings("ignore", module=r"PIL(\.|$)")  # damaged files get our one message instead
    why = probe_gl()
    if why is not None:
        sys.stderr.write(f"error: the editor needs an OpenGL 3.3 window, and none can be made here "
                         f"({printable(why, 200)}). The headless commands (synth, export) may still work.\n")
        return 4
    try:
        return Editor(path, screenshot=screenshot, frames=frames).run()
    except RuntimeError as exc:  # the window runner failed after all
        sys.stderr.write(f"error: the editor window could not run ({printable(exc, 200)}).\n")
        return 4
