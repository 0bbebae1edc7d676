"""File choosers and small modal dialogs.

Native dialogs come from imgui-bundle's portable-file-dialogs (asynchronous:
polled each frame, so the editor keeps drawing). Where no native chooser
exists (Linux without zenity/kdialog, or INFINITEX_NO_NATIVE_DIALOGS=1) the
in-window chooser of browser.py is used; INFINITEX_PATH_PROMPT=1 replaces it
with a plain path box (for scripted GUI tests, which type paths). Every chooser
starts in one place (``Dialogs.start_dir``): the project's folder once it is
saved, else the folder last used; a save proposes a file name there.
"""
from __future__ import annotations

import os
import shutil
import sys
from collections.abc import Callable
from dataclasses import dataclass, field

from imgui_bundle import imgui
from imgui_bundle import portable_file_dialogs as pfd

from .browser import FileBrowser

IMAGE_FILTER = ["Images and projects", "*.png *.jpg *.jpeg *.bmp *.tif *.tiff *.webp *.itex",
                "All files", "*"]
MAPS_FILTER = ["Images", "*.png *.jpg *.jpeg *.bmp *.tif *.tiff *.webp *.tga", "All files", "*"]
PROJECT_FILTER = ["Infinitex project", "*.itex"]
PNG_FILTER = ["PNG image", "*.png"]
TIFF_FILTER = ["BigTIFF image", "*.tif *.tiff"]
ZARR_FILTER = ["Zarr store", "*.zarr"]


def native_dialogs_available() -> bool:
    if os.environ.get("INFINITEX_NO_NATIVE_DIALOGS"):
        return False
    if sys.platform.startswith("linux"):
        return any(shutil.which(t) for t in ("zenity", "kdialog", "qarma", "matedialog"))
    return True


@dataclass
class PathRequest:
    title: str
    save: bool
    filters: list[str]
    on_done: Callable[[str], None]
    default: str = ""
    native: object = None
    browser: FileBrowser | None = None  # the in-window chooser
    text: str = ""
    opened: bool = False
    multi: bool = False  # several files (on_done gets a list; the path box takes them separated by ";")


@dataclass
class Modal:
    title: str
    body: str
    buttons: list[tuple[str, Callable[[], None] | None]] = field(default_factory=list)
    opened: bool = False


class Dialogs:
    def __init__(self):
        self.path_request: PathRequest | None = None
        self.modals: list[Modal] = []
        self.native = native_dialogs_available()
        self.prompt = bool(os.environ.get("INFINITEX_PATH_PROMPT"))
        self.last_dir = os.getcwd()  # the folder last used
        self.project_dir: str | None = None  # the open project's folder, once it is saved (the editor keeps it)

    def start_dir(self) -> str:
        """Where every chooser starts, and where a bare default file name goes:
        the project's folder once the project is saved, else the folder last used."""
        for d in (self.project_dir, self.last_dir):
            if d and os.path.isdir(d):
                return d
        return os.path.expanduser("~")

    @property
    def busy(self) -> bool:
        return self.path_request is not None or bool(self.modals)

    def ask_path(self, title: str, save: bool, filters: list[str], on_done: Callable[[str], None],
                 default: str = "") -> None:
        """Ask for a file to open or write; ``on_done(absolute path)`` when chosen.
        A relative ``default`` (a proposed file name) is taken in ``start_dir()``."""
        if default and not os.path.isabs(os.path.expanduser(default)):
            default = os.path.join(self.start_dir(), default)
        default = os.path.abspath(os.path.expanduser(default)) if default else ""

        def done(path: str) -> None:
            path = os.path.abspath(os.path.expanduser(path))
            self.last_dir = os.path.dirname(path)
            on_done(path)
        req = PathRequest(title, save, filters, done, default, text=default or self.start_dir() + os.sep)
        if self.native:
            try:
                req.native = (pfd.save_file(title, default, filters) if save
                              else pfd.open_file(title, default, filters))
            except Exception:
                req.native = None
        if req.native is None and not self.prompt:
            start = os.path.dirname(default) if default else self.start_dir()
            if not os.path.isdir(start):
                start = self.start_dir()
            req.browser = FileBrowser(title, save, filters, start, os.path.basename(default) if save else "")
        self.path_request = req

    def ask_paths(self, title: str, filters: list[str], on_done: Callable[[list[str]], None]) -> None:
        """Ask for one or more files to open (a material's maps; one file or a
        folder brings its siblings); ``on_done(absolute paths)`` when chosen."""
        def done(paths: list[str]) -> None:
            paths = [os.path.abspath(os.path.expanduser(p)) for p in paths]
            self.last_dir = os.path.dirname(paths[0])
            on_done(paths)
        start = self.start_dir()
        req = PathRequest(title, False, filters, done, text=start + os.sep, multi=True)
        if self.native:
            try:
                req.native = pfd.open_file(title, start, filters, pfd.opt.multiselect)
            except Exception:
                req.native = None
        if req.native is None and not self.prompt:
            req.browser = FileBrowser(title, False, filters, start, multi=True)
        self.path_request = req

    def message(self, title: str, body: str) -> None:
        self.modals.append(Modal(title, body, [("OK", None)]))

    def ask(self, title: str, body: str, buttons: list[tuple[str, Callable[[], None] | None]]) -> None:
        self.modals.append(Modal(title, body, buttons))

    def draw(self) -> None:
        self._draw_path()
        self._draw_modal()

    def _draw_path(self) -> None:
        req = self.path_request
        if req is None:
            return
        if req.browser is not None:
            req.browser.draw()
            if req.browser.done:
                self.path_request = None
                found = req.browser.result
                if found:
                    req.on_done(found if req.multi else found[0])
            return
        if req.native is not None:
            if req.native.ready(0):
                res = req.native.result()
                self.path_request = None
                found = [res] if isinstance(res, str) else [p for p in (res or []) if p]
                if found and found[0]:
                    req.on_done(found if req.multi else found[0])
            return
        name = f"{req.title}###pathprompt"
        if not req.opened:
            imgui.open_popup(name)
            req.opened = True
        imgui.set_next_window_size((620, 0))
        vp = imgui.get_main_viewport()
        imgui.set_next_window_pos((vp.pos.x + vp.size.x / 2, vp.pos.y + vp.size.y / 3), imgui.Cond_.always, (0.5, 0.5))
        opened, _ = imgui.begin_popup_modal(name, None, imgui.WindowFlags_.no_saved_settings)
        if not opened:
            return
        imgui.text("Path of the file to " + ("write:" if req.save else "open:") +
                   (" (several: separated by ;  a folder: a material's maps)" if req.multi else ""))
        imgui.set_next_item_width(-1)
        if imgui.is_window_appearing():
            imgui.set_keyboard_focus_here()
        enter, req.text = imgui.input_text("##path", req.text, imgui.InputTextFlags_.enter_returns_true)
        if imgui.button("OK", (120, 0)) or enter:
            path = os.path.expanduser(req.text.strip())
            if path:
                self.path_request = None
                imgui.close_current_popup()
                imgui.end_popup()
                if req.multi:
                    req.on_done([p.strip() for p in req.text.split(";") if p.strip()])
                else:
                    req.on_done(path)
                return
        imgui.same_line()
        if imgui.button("Cancel", (120, 0)) or imgui.is_key_pressed(imgui.Key.escape):
            self.path_request = None
            imgui.close_current_popup()
        imgui.end_popup()

    def _draw_modal(self) -> None:
        if not self.modals:
            return
        m = self.modals[0]
        name = f"{m.title}###modal"
        if not m.opened:
            imgui.open_popup(name)
            m.opened = True
        vp = imgui.get_main_viewport()
        imgui.set_next_window_pos((vp.pos.x + vp.size.x / 2, vp.pos.y + vp.size.y / 3), imgui.Cond_.always, (0.5, 0.5))
        imgui.set_next_window_size_constraints((360, 0), (720, 600))
        opened, _ = imgui.begin_popup_modal(name, None, imgui.WindowFlags_.always_auto_resize
                                            | imgui.WindowFlags_.no_saved_settings)
        if not opened:
            return
        imgui.push_text_wrap_pos(680)
        imgui.text_unformatted(m.body)
        imgui.pop_text_wrap_pos()
        imgui.spacing()
        chosen = None
        for i, (label, action) in enumerate(m.buttons):
            if i:
                imgui.same_line()
            if imgui.button(label, (110, 0)):
                chosen = (action,)
        if chosen is None and len(m.buttons) == 1 and imgui.is_key_pressed(imgui.Key.enter):
            chosen = (m.buttons[0][1],)
        if chosen is not None:
            self.modals.pop(0)
            imgui.close_current_popup()
        imgui.end_popup()
        if chosen is not None and chosen[0] is not None:
            chosen[0]()
