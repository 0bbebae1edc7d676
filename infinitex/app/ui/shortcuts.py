"""Keyboard shortcuts: undo and redo, open, save, quit, the zoom keys, the
tool keys and H / T / M (anywhere but in a text field; Escape closes an open
menu first), and the F1 window listing them all
(``SHORTCUTS`` plus each tool's key).

``Shortcuts`` is a part of the editor (``Editor.shortcuts``): it owns whether
the list is shown and reads the keys through the editor it is given.
"""
from __future__ import annotations


from imgui_bundle import imgui

SHORTCUTS = [
    ("1", "Actual size (100%)"), ("+  /  -", "Zoom in / out (also the mouse wheel)"),
    ("0", "Fit one exemplar across the canvas"), ("Right or middle drag", "Pan (any tool)"),
    ("Ctrl+Z / Ctrl+Shift+Z", "Undo / redo"), ("Ctrl+O", "Open an image or a project"),
    ("Ctrl+S / Ctrl+Shift+S", "Save / save as"), ("Ctrl+Q", "Quit"),
    ("H", "Show or hide what is painted (randomness, labels, directions)"),
    ("T", "Tile mode: the periodic texture of the export tile size"),
    ("M", "Show the next map of a material"),
    ("Space", "Play or pause the texture flowing (Motion panel)"), (",  /  .", "A frame back / on"),
    ("[  /  ]", "Brush smaller / larger (painting)"), ("Alt+click", "Pick the painted value (painting)"),
    ("F1  or  ?", "This list"),
]


class Shortcuts:
    """The editor's keys, read once a frame (``read``), and their list (F1, ``window``)."""

    def __init__(self, ed) -> None:
        self.ed = ed
        self.listed = False  # the F1 list is shown

    def show_list(self, on: bool) -> None:
        """The list of shortcuts (F1) shown or not."""
        self.listed = bool(on)

    def read(self) -> None:
        """This frame's key presses, in the order they came, each with the
        modifiers held when it went down (keylog.py): a chord as short as the
        window system can make is seen, and a letter typed with Ctrl held is
        never a tool key. Once a press opens a dialog, the presses after it
        are the dialog's, not shortcuts."""
        keys = self.ed.keys
        if self.ed.dialogs.busy or imgui.get_io().want_text_input:
            keys.drop()
            return
        if imgui.is_popup_open("", imgui.PopupFlags_.any_popup_id | imgui.PopupFlags_.any_popup_level):
            # An open menu (or other popup) takes the keys; Escape closes it, as
            # everywhere else, and the next key acts again.
            if imgui.is_key_pressed(imgui.Key.escape, False):
                imgui.internal.close_popups_except_modals()
            keys.drop()
            return
        K = imgui.Key
        for _ in range(keys.take(K.z, ctrl=True, shift=True) + keys.take(K.y, ctrl=True)):
            self.ed.files.redo()
        for _ in range(keys.take(K.z, ctrl=True)):
            self.ed.files.undo()
        if keys.take(K.s, ctrl=True):
            self.ed.files.save()
        if keys.take(K.s, ctrl=True, shift=True):
            self.ed.files.save_as()
        if keys.take(K.o, ctrl=True):
            self.ed.panels.open_dialog()
        if keys.take(K.q, ctrl=True):
            self.ed.files.request_quit()
        if self.ed.dialogs.busy:  # a question or a file chooser opens: what is typed next is its
            keys.drop()
            return
        if keys.take(K.f1, shift=None) or keys.take(K.slash, shift=True):
            self.listed = not self.listed
        io = imgui.get_io()
        if io.key_ctrl or io.key_alt or io.key_super or imgui.is_any_item_active():
            keys.drop()
            return
        self._zoom_keys()
        # Single keys: tools, H, T, M (anywhere a text field or a dialog does not
        # take the keys, as in Krita and Photoshop; never while a control is dragged).
        for t in self.ed.tools.offered(self.ed.model_mode):  # (the Lattice and Labels keys do nothing on a model)
            if t.key and keys.plain(getattr(K, t.key.lower())):
                self.ed.tools.choose(t)
        if keys.plain(K.h):
            self.ed.viewer.show_painted(not self.ed.viewer.show_fields)
        if keys.plain(K.t):
            self.ed.viewer.show_tile(not self.ed.viewer.tile_mode)
        if keys.plain(K.m) and self.ed.session.ready:
            roles = self.ed.session.material.roles  # the next map of a material
            cur = self.ed.session.shown_map(self.ed.display.map)
            self.ed.viewer.set_display(map=roles[(roles.index(cur) + 1) % len(roles)])
        if keys.plain(K.space):
            from .panels.motion import toggle
            toggle(self.ed)
        if self.ed.doc is not None and self.ed.doc.motion is not None:
            for key, d in ((K.comma, -1), (K.period, 1)):
                if keys.plain(key):
                    self.ed.playback.step(d, self.ed.doc.motion.frames)
        self.ed.tool.keys()

    def _zoom_keys(self) -> None:
        """1: actual size; + and -: zoom in and out around the canvas centre;
        0: fit one exemplar across the canvas (as in Krita and Blender)."""
        w, h = self.ed.canvas_size
        K = imgui.Key
        if imgui.is_key_pressed(K._1, False) or imgui.is_key_pressed(K.keypad1, False):
            self.ed.viewer.zoom_to(1.0)
        elif imgui.is_key_pressed(K.equal) or imgui.is_key_pressed(K.keypad_add):
            self.ed.viewer.zoom_at(2.0, w / 2, h / 2, w, h)
        elif imgui.is_key_pressed(K.minus) or imgui.is_key_pressed(K.keypad_subtract):
            self.ed.viewer.zoom_at(0.5, w / 2, h / 2, w, h)
        elif (imgui.is_key_pressed(K._0, False) or imgui.is_key_pressed(K.keypad0, False)) and self.ed.session.ready:
            self.ed.viewer.fit(self.ed.session.analysis.size, w, h)

    def window(self) -> None:
        """F1 or ?: every keyboard and mouse shortcut."""
        if not self.listed:
            return
        vp = imgui.get_main_viewport()
        imgui.set_next_window_pos((vp.work_pos.x + vp.work_size.x / 2, vp.work_pos.y + vp.work_size.y / 2),
                                  imgui.Cond_.appearing, (0.5, 0.5))
        opened, keep = imgui.begin("Shortcuts (F1)", True, imgui.WindowFlags_.always_auto_resize
                                   | imgui.WindowFlags_.no_collapse)
        if opened and imgui.begin_table("shortcuts", 2, imgui.TableFlags_.row_bg | imgui.TableFlags_.borders_inner_v):
            for key, what in SHORTCUTS + [(f"{t.key}", f"{t.label} tool")
                                          for t in self.ed.tools if t.key]:
                imgui.table_next_row()
                imgui.table_next_column()
                imgui.text(key)
                imgui.table_next_column()
                imgui.text(what)
            imgui.end_table()
        imgui.end()
        if not keep:
            self.listed = False
