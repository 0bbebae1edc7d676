"""The in-window file chooser, for desktops without a native one (Linux
without zenity or kdialog, remote sessions): a modal window with the folder's
path, its folders and files (name, size, date), a file name box (a save
proposes one), the file-type filter, and Open or Save / Cancel.

It replaced imgui-bundle's ImFileDialog, which showed folders with sizes
like "18014398509481984.000 KiB" and could not propose a file name. The
listing and the choice are plain methods (``listing``, ``accept``), tested
without a window; ``draw`` is the imgui part.
"""
from __future__ import annotations

import os
import time
from dataclasses import dataclass

from imgui_bundle import imgui
from .tips import tip

WINDOW_ID = "infinitex-path"


@dataclass(frozen=True)
class Entry:
    name: str
    is_dir: bool
    size: int      # bytes (files)
    mtime: float


def size_text(n: int) -> str:
    """A file size as people read it: 532 B, 14.2 KiB, 3.1 MiB, 2.0 GiB."""
    if n < 1024:
        return f"{n} B"
    for unit in ("KiB", "MiB", "GiB", "TiB"):
        n /= 1024.0
        if n < 1024 or unit == "TiB":
            return f"{n:.1f} {unit}"
    return ""  # not reached


def filter_patterns(filters: list[str]) -> list[tuple[str, tuple[str, ...]]]:
    """Our ["Name", "*.png *.jpg", ...] pairs as (label, extensions); () = every file."""
    out = []
    for name, patterns in zip(filters[::2], filters[1::2]):
        exts = tuple(p[1:].lower() for p in patterns.split() if p.startswith("*."))
        out.append((f"{name} ({patterns})", () if patterns.strip() == "*" else exts))
    return out or [("All files (*)", ())]


class FileBrowser:
    """One open or save request. ``done`` once chosen or cancelled; ``result``:
    the chosen absolute paths (empty when cancelled)."""

    def __init__(self, title: str, save: bool, filters: list[str], folder: str, name: str = "",
                 multi: bool = False):
        self.title, self.save, self.multi = title, save, multi
        self.filters = filter_patterns(filters)
        self.filter_index = 0
        self.folder = os.path.abspath(folder)
        self.path_text = self.folder
        self.name = name
        self.selected: list[str] = []
        self.error = ""
        self.done = False
        self.result: list[str] = []
        self._entries: list[Entry] | None = None
        self._opened = False
        self._focus_name = True

    # -- the logic (no window) -------------------------------------------------

    def listing(self) -> list[Entry]:
        """The folder's visible entries: folders first, then the files the
        filter shows, each by name (case-insensitive); dot files hidden."""
        if self._entries is not None:
            return self._entries
        exts = self.filters[self.filter_index][1]
        entries = []
        try:
            with os.scandir(self.folder) as it:
                for e in it:
                    if e.name.startswith("."):
                        continue
                    try:
                        is_dir = e.is_dir()
                        st = e.stat()
                    except OSError:
                        continue  # a dangling link or a file that vanished
                    if not is_dir and exts and not e.name.lower().endswith(exts):
                        continue
                    entries.append(Entry(e.name, is_dir, 0 if is_dir else st.st_size, st.st_mtime))
            self.error = ""
        except OSError as exc:
            self.error = f"{self.folder}: {exc.strerror or exc}"
        entries.sort(key=lambda e: (not e.is_dir, e.name.lower()))
        self._entries = entries
        return entries

    def go(self, folder: str) -> bool:
        """Show another folder; False (and a line saying why) when it is not one."""
        folder = os.path.abspath(os.path.expanduser(folder))
        if not os.path.isdir(folder):
            self.error = f"{folder} is not a folder."
            return False
        self.folder = self.path_text = folder
        self.selected = []
        self._entries = None
        self.listing()
        return True

    def set_filter(self, index: int) -> None:
        self.filter_index = index
        self._entries = None

    def accept(self, text: str | None = None) -> bool:
        """Choose the typed name (or the selected files): a folder is entered;
        an open needs existing files. True when the choice is made."""
        text = (self.name if text is None else text).strip()
        if not text and self.multi:  # nothing chosen: the folder itself (a material's maps)
            self.result = [self.folder]
            self.done = True
            return True
        if not text:
            self.error = "Type a file name." if self.save else "Choose a file."
            return False
        names = [t.strip() for t in text.split(";") if t.strip()] if self.multi else [text]
        paths = [os.path.abspath(os.path.join(self.folder, os.path.expanduser(n))) for n in names]
        if len(paths) == 1 and os.path.isdir(paths[0]):
            self.go(paths[0])
            self.name = ""
            return False
        if not self.save:
            missing = [p for p in paths if not os.path.isfile(p)]
            if missing:
                self.error = f"{missing[0]} does not exist."
                return False
        elif not os.path.isdir(os.path.dirname(paths[0])):
            self.error = f"{os.path.dirname(paths[0])} is not a folder."
            return False
        self.result = paths
        self.done = True
        return True

    def cancel(self) -> None:
        self.result = []
        self.done = True

    def _click(self, e: Entry, double: bool, ctrl: bool) -> None:
        if e.is_dir:
            if double:
                self.go(os.path.join(self.folder, e.name))
            return
        if self.multi and ctrl:  # Ctrl-click: several files (a material's maps)
            if e.name in self.selected:
                self.selected.remove(e.name)
            else:
                self.selected.append(e.name)
        else:
            self.selected = [e.name]
        self.name = "; ".join(self.selected)
        if double:
            self.accept(e.name)

    # -- the window --------------------------------------------------------------

    @property
    def window_name(self) -> str:
        return f"{self.title}###{WINDOW_ID}"

    def draw(self) -> None:
        if self.done:
            return
        if not self._opened:
            imgui.open_popup(self.window_name)
            self._opened = True
        vp = imgui.get_main_viewport()
        imgui.set_next_window_pos((vp.pos.x + vp.size.x / 2, vp.pos.y + vp.size.y / 2), imgui.Cond_.appearing,
                                  (0.5, 0.5))
        imgui.set_next_window_size((min(820, vp.size.x - 40), min(560, vp.size.y - 40)), imgui.Cond_.appearing)
        imgui.push_style_color(imgui.Col_.popup_bg, (0.11, 0.11, 0.12, 1.0))  # opaque: a list over the canvas
        opened, _ = imgui.begin_popup_modal(self.window_name, None, imgui.WindowFlags_.no_saved_settings)
        imgui.pop_style_color()
        if not opened:
            return
        if imgui.is_key_pressed(imgui.Key.escape, False):
            self.cancel()
        if imgui.button("Up"):
            self.go(os.path.dirname(self.folder))
        imgui.same_line()
        if imgui.button("Home"):
            self.go(os.path.expanduser("~"))
        imgui.same_line()
        imgui.set_next_item_width(-1)
        enter, self.path_text = imgui.input_text("##folder", self.path_text, imgui.InputTextFlags_.enter_returns_true)
        if enter:
            self.go(self.path_text)
        footer = imgui.get_frame_height_with_spacing() * 3 + 8
        entries = self.listing()
        flags = (imgui.TableFlags_.row_bg | imgui.TableFlags_.borders_inner_v | imgui.TableFlags_.scroll_y
                 | imgui.TableFlags_.resizable)
        if imgui.begin_table("files", 3, flags, (0, -footer)):
            imgui.table_setup_scroll_freeze(0, 1)
            imgui.table_setup_column("Name", imgui.TableColumnFlags_.width_stretch)
            imgui.table_setup_column("Size", imgui.TableColumnFlags_.width_fixed, 90)
            imgui.table_setup_column("Modified", imgui.TableColumnFlags_.width_fixed, 130)
            imgui.table_headers_row()
            io = imgui.get_io()
            for i, e in enumerate(entries):
                imgui.table_next_row()
                imgui.table_next_column()
                label = f"[{e.name}]" if e.is_dir else e.name
                sel = e.name in self.selected
                if imgui.selectable(f"{label}##e{i}", sel, imgui.SelectableFlags_.span_all_columns
                                    | imgui.SelectableFlags_.allow_double_click)[0]:
                    self._click(e, imgui.is_mouse_double_clicked(imgui.MouseButton_.left), io.key_ctrl)
                imgui.table_next_column()
                imgui.text_disabled("folder" if e.is_dir else size_text(e.size))
                imgui.table_next_column()
                imgui.text_disabled(time.strftime("%Y-%m-%d %H:%M", time.localtime(e.mtime)))
            imgui.end_table()
        if self.error:
            imgui.text_colored((1.0, 0.55, 0.45, 1.0), self.error)
        else:
            imgui.text_disabled(f"{len(entries)} item{'s' * (len(entries) != 1)}")
        imgui.set_next_item_width(-300)
        if self._focus_name:
            imgui.set_keyboard_focus_here()
            self._focus_name = False
        enter, self.name = imgui.input_text("##name", self.name, imgui.InputTextFlags_.enter_returns_true)
        tip("The file name (or a path); a folder's name goes into it")
        imgui.same_line()
        imgui.set_next_item_width(-1)
        changed, i = imgui.combo("##filter", self.filter_index, [f[0] for f in self.filters])
        if changed:
            self.set_filter(i)
        if imgui.button("Save" if self.save else "Open", (120, 0)) or enter:
            self.accept()
        if self.multi:
            tip("Opens the files chosen (Ctrl-click for several), or with none, this folder's maps")
        imgui.same_line()
        if imgui.button("Cancel", (120, 0)):
            self.cancel()
        if self.done:
            imgui.close_current_popup()
        imgui.end_popup()
