"""The editor's menus, side panels, status bar and progress windows.

One module per panel: menu (the menu bar, Open dialogs, Open Recent), toolbar,
exemplar, material, randomness, synthesis
(the Advanced section), display, motion (texture in motion: play, scrub, export), export (and the File menu's view and tile
exports), tileset (the tile-set dialog), status (the status bar, canvas overlay and export progress window);
widgets holds what they share (``tip``, ``LAST_TIP``, ``size_combo``). Each
panel is a function taking the ``Panels`` object below: the editor's one handle
on them, holding the editor (``p.ed``) and the panels' own small state, and
dispatching to the modules under the names the editor and the tests use.
"""
from __future__ import annotations

from imgui_bundle import imgui

from infinitex.engine.params import DEFAULT_JITTER

from . import display, exemplar, export, material, menu, model, motion, randomness, status, synthesis, tileset, toolbar
from .display import MAGNIFY_LABELS, MODE_LABELS, MODE_TIPS
from .exemplar import FIT_LABELS, PANEL_IMAGE, TOROIDAL_LABELS
from .export import DEPTH_CHOICES, EXPORT_FORMATS, MAGNIFY_CHOICES, TILE_SIZES
from .synthesis import ADVANCED_SLIDERS
from .widgets import LAST_TIP, size_combo, tip

__all__ = ["ADVANCED_SLIDERS", "DEPTH_CHOICES", "EXPORT_FORMATS", "FIT_LABELS", "LAST_TIP", "MAGNIFY_CHOICES",
           "MAGNIFY_LABELS", "MODE_LABELS", "MODE_TIPS", "PANEL_IMAGE", "Panels", "TILE_SIZES", "TOROIDAL_LABELS",
           "size_combo", "tip"]


class Panels:
    """The editor's panels: holds the editor and the panels' own small state."""

    def __init__(self, ed):
        self.ed = ed
        self.overall = DEFAULT_JITTER  # the Randomness panel's "All levels" (the mean of the levels')
        self._export_popup = False     # the export progress window is open (read by the GUI tests)
        self._goto_open = False        # View > Go to coordinates was chosen: open its popup
        self._tile_prompt = 0          # File > Export toroidal tile: 1 = open its window, 2 = open
        self.tileset = tileset.TileSetDialog()  # File > Export tile set: its settings, set and preview
        self.motion_size = (512, 512)  # the Motion panel's exported frame size
        self.auto_period = True        # a Flow stroke sets the renewal period its field suggests
        self.motion_layer = motion.MotionLayer()  # the flowing frame drawn over the canvas

    # The panels: each module's function takes this object first, so it serves
    # as a method as it is (``ed.panels.export_view()`` is export.export_view(panels)).
    menu_bar, open_dialog, open_material_dialog = menu.draw, menu.open_dialog, menu.open_material_dialog
    toolbar = toolbar.draw
    randomness_panel = randomness.draw
    exemplar_panel, exemplar_thumbnail = exemplar.draw, exemplar.thumbnail
    material_panel = material.draw
    model_panel = model.draw
    display_panel = display.draw
    motion_panel, motion_tick = motion.draw, motion.tick_and_draw
    export_panel, rectangle_export = export.draw, export.rectangle
    export_view, export_tile, tile_prompt, tile_prompt_window = (export.export_view, export.export_tile,
                                                                 export.tile_prompt, export.tile_prompt_window)
    tileset_dialog, tileset_window = tileset.open_dialog, tileset.window
    synthesis_panel = synthesis.draw
    status_bar, canvas_overlay, progress_modals = status.status_bar, status.canvas_overlay, status.progress_modals

    # -- side panels --------------------------------------------------------

    def side_panels(self) -> None:
        ed = self.ed
        if ed.doc is None or not ed.session.ready:
            self._loading()
            return
        flags = imgui.TreeNodeFlags_.default_open
        if ed.tool.panel and imgui.collapsing_header(ed.tool.panel + "###tool-options", flags):
            ed.tool.options()  # (the paint tools' include clearing what they painted)
        # Artists' controls first; the synthesis internals wait in Advanced (collapsed).
        # Which sections are open is kept between runs (the user's settings).
        if ed.model_mode:
            imgui.set_next_item_open(True, imgui.Cond_.once)
            if imgui.collapsing_header("Model"):
                self.model_panel()
        for name, draw in (("Randomness", self.randomness_panel), ("Exemplar", self.exemplar_panel),
                           ("Material", self.material_panel),
                           ("Display", self.display_panel), ("Motion", self.motion_panel),
                           ("Export", self.export_panel),
                           ("Advanced", self.synthesis_panel)):
            imgui.set_next_item_open(name in ed.panels_open, imgui.Cond_.once)
            opened = imgui.collapsing_header(name)
            ed.panels_open.add(name) if opened else ed.panels_open.discard(name)
            if opened:
                draw()

    def _loading(self) -> None:
        job = self.ed.session.job
        imgui.text("Opening the exemplar...")
        if job is not None:
            imgui.progress_bar(job.progress, (-1, 0), job.message)
            if imgui.button("Cancel"):
                job.cancel()
