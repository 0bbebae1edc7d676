"""File choosers and small modal dialogs.

Native dialogs come from imgui-bundle's portable-file-dialogs (asynchronous:
polled each frame, so the editor keeps drawing). Where no native chooser
exists (Linux without zenity/kdialog, or INFINITEX_NO_NATIVE_DIALOGS=1) an
in-window path prompt is used instead.
"""
from __future__ import annotations

import os
import shutil
import sys
from collections.abc import Callable
from dataclasses import dataclass, field

from imgui_bundle import imgui
from imgui_bundle import portable_file_dialogs as pfd

IMAGE_FILTER = ["Images and projects", "*.png *.jpg *.jpeg *.bmp *.tif *.tiff *.webp *.itex",
                "All files", "*"]
PROJECT_FILTER = ["Infinitex project", "*.itex"]
PNG_FILTER = ["PNG image", "*.png"]


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
    text: str = ""
    opened: bool = False


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

    @property
    def busy(self) -> bool:
        return self.path_request is not None or bool(self.modals)

    def ask_path(self, title: str, save: bool, filters: list[str], on_done: Callable[[str], None],
                 default: str = "") -> None:
        req = PathRequest(title, save, filters, on_done, default, text=default or os.getcwd() + os.sep)
        if self.native:
            try:
                req.native = (pfd.save_file(title, default, filters) if save
                              else pfd.open_file(title, default, filters))
            except Exception:
                req.native = None
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
        if req.native is not None:
            if req.native.ready(0):
                res = req.native.result()
                self.path_request = None
                path = res if isinstance(res, str) else (res[0] if res else "")
                if path:
                    req.on_done(path)
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
        imgui.text("Path of the file to " + ("write:" if req.save else "open:"))
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
