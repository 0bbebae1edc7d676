"""The editor: an imgui-bundle (hello_imgui) application around one document.

Per frame: install a finished analysis, keep the session in step with the
document, refine the view's synthesis within a time budget, draw the canvas
texture, then the panels. Nothing blocks: analysis runs on a thread, synthesis
and exports are sliced into budgeted steps.

``Editor`` keeps the start-up, the frame loop and what every part reads (the
document through ``doc`` and ``edit``, the view, the session, the dialogs);
its other concerns are parts with their own state, one a module, each reached
through an attribute and changed through its methods: ``files`` (files.py:
documents, saving, the questions before unsaved edits are lost, autosave, the
undo history), ``exports`` (exports.py: starting and following exports),
``canvas_input`` (canvas_input.py: the mouse on the canvas, the overlays),
``refinement`` (canvas_refine.py: what the canvas shows while a change is
made), ``model`` (model_mode.py: a model's camera and view), ``shortcuts``
(shortcuts.py: the keys and their F1 list), ``tools`` (tools/: the tools and
the active one), ``viewer`` (the view and the display), ``canvas_state``
(what the canvas did last frame). When it sleeps between frames and how long
a frame synthesizes: pacing.py.
"""
from __future__ import annotations

import os
import signal
import subprocess
import sys
import time

from imgui_bundle import (  # imported before glfw (bundled libglfw)
    hello_imgui,
    imgui,
    immapp,
)

from infinitex.engine.gpu import GLUnavailable, Gpu
from infinitex.engine.material import IMAGE
from infinitex.engine.safeio import WriteError, printable
from infinitex.project import Display, Document, History, View

from ..player import Playback
from ..render.canvas import Canvas
from ..render.overlays import FieldOverlay, LabelOverlay
from ..session import Frame, Session, frame_for
from ..settings import check_config_file, config_dir
from . import panels
from .canvas_input import CanvasInput
from .canvas_state import CanvasState
from .canvas_refine import CanvasRefine
from .dialogs import Dialogs
from .exports import Exports
from .files import DEFAULT_EXEMPLAR, Documents, adopt_found_lattice
from .keylog import KeyLog
from .model_mode import ModelMode
from .pacing import FramePacer, InputWait
from .shortcuts import Shortcuts
from .prefs import Preferences
from .tools import Tool, make_tools
from .viewer import Viewer

__all__ = ["DEFAULT_EXEMPLAR", "Editor", "probe_gl", "run_editor"]  # DEFAULT_EXEMPLAR: where it always was

PANEL_WIDTH = 340
# The editor spawns worker processes (streamed exports, their estimate) while
# GL and the UI threads run. CPython's vfork() path for that (multiprocessing
# uses it through subprocess) aborted the editor now and then, under the imgui
# test engine, during a spawn; plain fork + exec (the documented switch) did not.
subprocess._USE_VFORK = False
DEFAULT_PANELS = ("Randomness", "Exemplar", "Display")  # side-panel sections open on a first run


class Editor:
    def __init__(self, path: str | None = None, *, screenshot: str | None = None, frames: int = 10,
                 window_size: tuple[int, int] | None = None, recover: bool = True):
        self.start_path = path
        self.screenshot = screenshot
        self.min_frames = frames
        self.prefs = Preferences()  # the user's settings kept between runs
        # The size the window had when the editor last closed (a screenshot keeps the documented 1280 x 800).
        self.window_size = window_size or (None if screenshot else self.prefs.settings.window) or (1280, 800)
        self.shortcuts = Shortcuts(self)  # the keys and their F1 list
        self.panels_open = set(self.prefs.settings.panels if self.prefs.settings.panels is not None else DEFAULT_PANELS)
        self.offer_recovery = recover and screenshot is None
        self.files = Documents(self)  # the document, its history and file, the autosave
        self.viewer = Viewer()           # the view and the display, their one owner
        self.gpu: Gpu | None = None
        self.renderer = ""
        self.session: Session | None = None
        self.canvas: Canvas | None = None
        self.dialogs = Dialogs()
        if self.prefs.settings.recent:  # the file browser starts in the folder last used
            self.dialogs.last_dir = os.path.dirname(self.prefs.settings.recent[0])
        self.exports = Exports(self)  # the running export, those waiting, the Export panel's settings
        self.goto = [0, 0]
        self.frame: Frame | None = None
        self.canvas_size = (1, 1)
        self.frame_count = 0
        self.frame_pacer = FramePacer()
        self.canvas_state = CanvasState()  # what the canvas did last frame, the pointer on it
        self.cursor_uv: tuple[int, int] | None = None
        self.fatal: str | None = None
        self.refinement = CanvasRefine(self)  # what the flat canvas shows while a change is made
        self.model = ModelMode(self)  # a model's camera and view
        self.playback = Playback()  # texture in motion: the playhead and its player process
        self.panels = panels.Panels(self)
        self.tools = make_tools(self)  # the tools and the active one
        self.canvas_input = CanvasInput(self)  # the mouse on the canvas, the overlays over it
        # Overlay textures: the canvas and exemplar randomness, the avoid mask, the
        # exemplar's labels (Labels window) and the canvas labels.
        self.overlay_canvas = self.overlay_exemplar = self.overlay_avoid = None
        self.overlay_labels = self.overlay_canvas_labels = None
        self.notice: tuple[str, float] | None = None  # (text, monotonic time): e.g. where an export went
        self._title = ""
        self.keys = KeyLog()             # this frame's key presses, each with its own modifiers
        self.waits = InputWait(self.keys)  # whether the editor may sleep between frames, and its sleep

    def fail(self, text: str) -> None:
        """Nothing can be shown (no GL, no exemplar): the window says why and offers Quit."""
        self.fatal = text

    def tell(self, text: str) -> None:
        """A one-line notice over the canvas for a few seconds (where an export
        went, why a stroke did nothing)."""
        self.notice = (text, time.monotonic())

    @property
    def refined(self) -> bool:
        """What the canvas shows is complete (canvas_state)."""
        return self.canvas_state.refined

    @property
    def doc(self) -> Document | None:
        """The document (``files`` owns it and its history)."""
        return self.files.doc

    @property
    def history(self) -> History | None:
        return self.files.history

    def edit(self, doc: Document, label: str, group: object = None, region: tuple | None = None) -> None:
        """Apply an edit: one undo step (``Documents.edit``)."""
        self.files.edit(doc, label, group, region)

    @property
    def model_mode(self) -> bool:
        """A model is open: the canvas shows it (``model``)."""
        return self.doc is not None and self.doc.surface is not None

    @property
    def tool(self) -> Tool:
        """The active tool (chosen through ``tools.choose``)."""
        return self.tools.active

    def shown_role(self) -> str:
        """The map the canvas shows: the Display panel's choice; the lit preview
        shows the base color (or the first map) shaded."""
        s = self.session
        mat = s.material
        if self.display.mode == "lit":
            return next((r for r in ("basecolor", IMAGE) if r in mat.maps), mat.primary)
        return s.shown_map(self.display.map)

    def geometry(self):
        """The 2x2 map from view positions to the synthesized canvas when a
        lattice is shown in the input's geometry; None when the canvas shows
        the synthesized (rectified) texture itself."""
        s = self.session
        lat = s.controls.lattice if s is not None and s.ready and s.controls is not None else None
        if lat is None or self.display.geometry != "original":
            return None
        return lat.canvas_matrix(s.analysis.size)

    @property
    def view(self) -> View:
        """Where the canvas looks (changed through ``viewer``)."""
        return self.viewer.view

    @property
    def display(self) -> Display:
        """How the canvas draws (changed through ``viewer``)."""
        return self.viewer.display

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
        if not p.ini_disable:  # hello_imgui opens it blocking: nothing but a small regular file there
            usable, note = check_config_file(p.ini_filename)
            p.ini_disable = not usable
            if note:
                self.tell(note)
        p.imgui_window_params.background_color = (0.06, 0.06, 0.065, 1.0)
        # Idle means idle, and no input is lost: the editor does its own waiting
        # (InputWait.before_frame), so the events that wake it are handled by the
        # very frame they wake; the runner's own idling (which handled the waking
        # event one frame late, that is up to a whole idle period late) stays off.
        # No multisampled window: imgui smooths its own edges, and on a software
        # GL (llvmpipe) the runner's default 8x multisampling cost 12 of the
        # 18 ms a 1280 x 800 frame took to draw, time taken from the synthesis.
        p.renderer_backend_options.open_gl_options.anti_aliasing_samples = 0
        p.fps_idling.enable_idling = False
        p.fps_idling.remember_enable_idling = False
        p.callbacks.pre_new_frame = self.waits.before_frame
        p.callbacks.post_init = self.post_init
        p.callbacks.show_gui = self.gui
        p.callbacks.before_exit = self.before_exit
        p.callbacks.confirm_exit = self.files.confirm_exit
        self.params = p
        return p

    def run(self) -> int:
        immapp.run(self.runner_params(), immapp.AddOnsParams())
        if self.screenshot:
            import numpy as np

            from infinitex.engine.imagefile import write_png
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
            self.overlay_canvas, self.overlay_exemplar, self.overlay_avoid = (FieldOverlay(ctx) for _ in range(3))
            self.overlay_labels, self.overlay_canvas_labels = LabelOverlay(ctx), LabelOverlay(ctx)
        except (GLUnavailable, Exception) as exc:
            self.fail(f"OpenGL 3.3 is not usable here: {exc}\nThe editor needs OpenGL 3.3; "
                      "on Linux install libgl1 and a Mesa driver.")
            return
        self.files.install_drop_callback()
        # The imgui test engine drives the frames itself: no sleeping between them.
        self.waits.never = bool(getattr(self.params, "use_imgui_test_engine", False))
        if not self.waits.never:  # (its keys go to imgui, not the window)
            try:
                from imgui_bundle import glfw_utils
                self.keys.install(glfw_utils.glfw_window_hello_imgui())
            except Exception:
                pass  # no glfw window: imgui's own key state serves
        self.files.open_first()

    def before_exit(self) -> None:
        if not self.screenshot:
            try:
                import glfw
                from imgui_bundle import glfw_utils
                self.prefs.keep_window(glfw.get_window_size(glfw_utils.glfw_window_hello_imgui()), self.panels_open)
            except Exception:
                pass  # no window: nothing to keep
        self.files.keep_unsaved_work()
        self.exports.stop()
        self.playback.close()
        self.panels.motion_layer.release()
        if self.session is not None:
            self.session.release()
        if self.canvas is not None:
            self.canvas.release()
        self.model.release()
        for o in (self.overlay_canvas, self.overlay_exemplar, self.overlay_avoid, self.overlay_labels,
                  self.overlay_canvas_labels):
            if o is not None:
                o.release()

    # -- the frame ----------------------------------------------------------

    def gui(self) -> None:
        self.frame_count += 1
        if self.waits.never and hasattr(signal, "SIGPIPE"):
            # Under the imgui test engine, whose crash handler also takes SIGPIPE:
            # ignored again, as Python has it (a write to a closed worker's pipe is
            # then a BrokenPipeError, not an abort). Each frame: set from C, unseen.
            signal.signal(signal.SIGPIPE, signal.SIG_IGN)
        self.waits.frame_began()
        self.frame_pacer.frame_began(self.canvas_state.update_ms)
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
        self.dialogs.project_dir = os.path.dirname(os.path.abspath(self.files.project_path)) if self.files.project_path else None
        self._update_engine()
        self.files.close_requested()
        self.panels.menu_bar()
        self.shortcuts.read()
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
        if self.doc is not None:
            self.tool.window()
        self.shortcuts.window()
        self._after_frame()

    def _update_engine(self) -> None:
        s = self.session
        self.files.open_dropped()
        job = s.poll()
        if job is not None and self.files.pending is not None and job.asked_key == self.files.pending[1].analysis_key():
            self.files.finish_load(job)
        elif job is not None and job.done and job.analysis is not None:
            adopt_found_lattice(self, job)
        elif job is not None and job.error:
            self.dialogs.message("Analysis failed", job.error)
        if s.ready:
            self._show_maps()
        self.exports.poll()
        self.files.autosave_tick()

    def sync_session(self) -> None:
        """The frame's one ``Session.sync``, after the canvas's input (so a tool's
        edit of this frame is synthesized, or its local update started, in this
        frame; an edit made later in a frame, in a dialog, is taken by the next)."""
        s = self.session
        if self.doc is not None and (self.files.pending is None or s.job is None):
            doc = self.refinement.session_doc()
            # Where the edits since the document the session holds reached.
            s.sync(doc, self.history.changes_between(s.synced_doc, doc))
            if s.ready:
                self._show_maps()

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

    def _canvas(self) -> None:
        avail = imgui.get_content_region_avail()
        w, h = max(16, int(avail.x)), max(16, int(avail.y))
        self.canvas_size = (w, h)
        s = self.session
        p0 = imgui.get_cursor_screen_pos()
        if self.model_mode and s.ready:
            self.model.canvas(p0, w, h)  # a model is open: it is what the canvas shows
            return
        # Input first, so this frame already shows what a tool or a pan did.
        hovered = self.canvas_input.read(p0, w, h)
        if s.ready and self.doc is not None:
            s.period = self.canvas_input.tile_period()
        self.sync_session()  # a tool's edit of this frame (a paint dab is re-synthesized locally here)
        if s.ready and self.doc is not None:
            level = None
            if self.display.mode == "level":
                level = s.L if self.display.level < 0 else min(self.display.level, s.L)
            geom = self.geometry()
            self.frame = frame_for(self.view, w, h, s.L, level, geom)
            self.refinement.draw(s, geom)
        else:
            self.canvas.ensure_size(w, h)
            self.canvas.render(None, None, self.view, self.display)
            self.canvas.shown_key = None
            self.canvas_state.set_refined(False)
        self.screen_fbo.use()
        imgui.set_cursor_screen_pos(p0)
        imgui.image(imgui.ImTextureRef(self.canvas.tex.glo), (w, h))
        self.panels.motion_tick(p0, w, h)  # a flowing frame over the still canvas
        self.canvas_input.overlays(p0, w, h, hovered)

    def _update_title(self) -> None:
        title = self.files.title
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
        analyzing = self.files.pending is not None or (self.session is not None and self.session.job is not None)
        working = (self.exports.job is not None and not self.exports.apart()
                   or self.panels.tileset.building)
        # Nothing to refine while no document is open and a question waits for the user.
        waiting = self.history is None and bool(self.dialogs.modals)
        shown = self.session is not None and self.session.ready and self.doc is not None
        busy = working or (shown and not self.canvas_state.refined) or (not shown and not waiting and not analyzing)
        # Worker processes doing the work (a streamed export, an estimate) need
        # the cores more than a full frame rate: a few frames a second show progress.
        background = (self.exports.apart()
                      or (self.exports.settings.estimate is not None and not self.exports.settings.estimate.poll()))
        pb = self.playback  # a flow playing: wake as often as its frames are due; a frame asked for: 10 a second
        playing = 0.0
        if pb.active and self.doc is not None and self.doc.motion is not None:
            playing = self.doc.motion.fps if pb.playing else 10.0 if pb.player.busy else 0.0
        self.waits.frame_ended(busy=busy, analyzing=analyzing, working=working, background=background,
                               playing=playing)
        if self.files.quit_requested:
            self.params.app_shall_exit = True
        if self.screenshot and ((self.frame_count >= self.min_frames and not busy and not analyzing)
                                or self.frame_count >= self.min_frames + 3000):
            self.params.app_shall_exit = True


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
