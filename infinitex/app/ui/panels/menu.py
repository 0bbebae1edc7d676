"""The menu bar (File, Edit, View), the Open and Open material dialogs, the
Open Recent list and the Go to coordinates popup."""
from __future__ import annotations

import os
from typing import TYPE_CHECKING

from imgui_bundle import imgui

from infinitex.engine.safeio import printable

from ..dialogs import IMAGE_FILTER, MAPS_FILTER
from .widgets import tip

if TYPE_CHECKING:
    from . import Panels


def open_dialog(p: Panels) -> None:
    ed = p.ed
    ed.files.confirm_discard(lambda: ed.dialogs.ask_path("Open exemplar or project", False, IMAGE_FILTER, ed.files.open_path))


def open_material_dialog(p: Panels) -> None:
    ed = p.ed
    ed.files.confirm_discard(lambda: ed.dialogs.ask_paths("Open material", MAPS_FILTER, ed.files.open_paths))


def _open_recent(ed, path: str) -> None:
    if not os.path.exists(path):
        ed.prefs.forget(path)
        ed.dialogs.message("Open Recent", f"{printable(path)} is no longer there; it was removed from the list.")
        return
    ed.files.open_path(path)


def draw(p: Panels) -> None:
    """The menu bar and the popups its items open."""
    ed = p.ed
    if not imgui.begin_menu_bar():
        return
    if imgui.begin_menu("File"):
        if imgui.menu_item_simple("New"):
            ed.files.confirm_discard(ed.files.new_document)
        if imgui.menu_item_simple("Open...", "Ctrl+O"):
            p.open_dialog()
        if imgui.menu_item_simple("Open material..."):
            p.open_material_dialog()
        tip("A material's maps: choose them all, or one map (its siblings named NAME_normal, NAME_height... "
            "come along), or their folder")
        if imgui.menu_item_simple("Open model...", enabled=ed.doc is not None and ed.session.ready):
            ed.model.open_dialog()
        tip("Texture a model (OBJ, glTF, GLB): the texture is synthesized in its atlas, seamless across "
            "its UV seams")
        if imgui.begin_menu("Open Recent", bool(ed.prefs.settings.recent)):
            for i, path in enumerate(ed.prefs.settings.recent):
                if imgui.menu_item_simple(f"{os.path.basename(path)}##recent{i}"):
                    ed.files.confirm_discard(lambda path=path: _open_recent(ed, path))
                tip(path)
            imgui.separator()
            if imgui.menu_item_simple("Clear the list"):
                ed.prefs.forget(None)
            imgui.end_menu()
        imgui.separator()
        if imgui.menu_item_simple("Save", "Ctrl+S", enabled=ed.doc is not None):
            ed.files.save()
        if imgui.menu_item_simple("Save As...", "Ctrl+Shift+S", enabled=ed.doc is not None):
            ed.files.save_as()
        imgui.separator()
        if imgui.menu_item_simple("Export view as PNG...", enabled=ed.session.ready):
            p.export_view()
        if imgui.menu_item_simple("Export model...", enabled=ed.model_mode and ed.session.ready):
            ed.model.export_dialog()
        if imgui.menu_item_simple("Close model", enabled=ed.model_mode):
            ed.model.close()
        if imgui.menu_item_simple("Export toroidal tile...", enabled=ed.session.ready):
            p.tile_prompt()  # its size first
        if imgui.menu_item_simple("Export tile set for game engines...", enabled=ed.session.ready):
            p.tileset_dialog()
        imgui.separator()
        if imgui.menu_item_simple("Quit", "Ctrl+Q"):
            ed.files.request_quit()
        imgui.end_menu()
    if imgui.begin_menu("Edit"):
        h = ed.history
        if imgui.menu_item_simple(f"Undo {h.undo_label() if h else ''}".strip(), "Ctrl+Z",
                                  enabled=bool(h and h.can_undo())):
            ed.files.undo()
        if imgui.menu_item_simple(f"Redo {h.redo_label() if h else ''}".strip(), "Ctrl+Shift+Z",
                                  enabled=bool(h and h.can_redo())):
            ed.files.redo()
        imgui.end_menu()
    if imgui.begin_menu("View"):
        if imgui.menu_item_simple("Go to origin"):
            ed.viewer.center(0, 0)
        if imgui.menu_item_simple("Go to coordinates..."):
            p._goto_open = True
        if imgui.menu_item_simple("Actual size (1:1)", "1"):
            ed.viewer.zoom_to(1.0)
        if imgui.menu_item_simple("Shortcuts", "F1"):
            ed.shortcuts.show_list(True)
        imgui.separator()
        ed.viewer.show_painted(imgui.menu_item("Show painted maps", "H", ed.viewer.show_fields)[1])
        ed.viewer.show_tile(imgui.menu_item(f"Tile mode ({ed.exports.settings.tile_size} px)", "T",
                                            ed.viewer.tile_mode)[1])
        imgui.end_menu()
    imgui.end_menu_bar()
    if p._goto_open:
        imgui.open_popup("Go to coordinates")
        p._goto_open = False
    if imgui.begin_popup("Go to coordinates"):
        imgui.text("Canvas position (finest-level pixels):")
        imgui.set_next_item_width(220)
        _, ed.goto = imgui.input_int2("x, y", ed.goto)
        if imgui.button("Go", (100, 0)):
            ed.viewer.center(ed.goto[0], ed.goto[1])
            imgui.close_current_popup()
        imgui.end_popup()
