"""The editor's menus, side panels, status bar and progress windows."""
from __future__ import annotations

import os
import time
from dataclasses import replace

import numpy as np
from imgui_bundle import imgui

from infinitex.engine.material import IMAGE, ROLE_LABELS, ROLES, role_of
from infinitex.engine.params import DEFAULT_JITTER, FIRST_CORRECTED_LEVEL
from infinitex.engine.pyramid import Rect

from infinitex.engine.safeio import printable

from infinitex.export.jobs import duration_text
from infinitex.project import DISPLAY_MODES, ExemplarSource, View

from ..settings import save_settings
from .dialogs import IMAGE_FILTER, MAPS_FILTER, PNG_FILTER, TIFF_FILTER, ZARR_FILTER
from .tools.feature import PAYLOAD as FEATURE_PAYLOAD

MODE_LABELS = {"color": "Color", "coords": "Coordinate map", "patches": "Patch boundaries",
               "level": "Single pyramid level", "relief": "Shaded relief", "lit": "Lit material"}
MODE_TIPS = {"color": "The texture",
             "coords": "Where each pixel comes from in the exemplar (red = x, green = y)",
             "patches": "The patches of exemplar the texture is made of, each tinted, their seams dark",
             "level": "One scale of the synthesis pyramid on its own (the coarse levels are its mipmap)",
             "relief": "The texture's brightness shaded as a height map (terrain, bump maps)",
             "lit": "The material under a light you move: its normal map (else its height map, else the "
                    "brightness as height) shades the base color"}
DEPTH_CHOICES = [(None, "Each map's own depth"), (8, "8-bit PNG"), (16, "16-bit PNG"), (32, "32-bit float TIFF")]
MAGNIFY_CHOICES = [1, 2, 4, 8]
MAGNIFY_LABELS = [("hires", "Synthesis magnification, hi-res exemplar"),
                  ("bilinear", "Synthesis magnification, bilinear"), ("nearest", "Nearest (texel blocks)")]
FIT_LABELS = [("resize", "Resize to a power of two"), ("crop", "Crop a power-of-two square"),
              ("resize-2048", "Resize, up to 2048 px"), ("crop-2048", "Crop, up to 2048 px")]
TOROIDAL_LABELS = ["Auto", "Yes (tiles)", "No"]
TILE_SIZES = [64, 128, 256, 512, 1024, 2048, 4096]
# Formats of rectangle exports: key, label, tooltip.
EXPORT_FORMATS = [
    ("png", "PNG image", "One PNG, made in memory: up to 16384 px a side and 64 Mpixels"),
    ("tiles", "PNG tiles (UDIM)", "A set of PNG tiles, NAME.1001.png, NAME.1002.png... (1001 + column + 10 x row; "
                                  "past 10 columns NAME_u1_v1.png): any size up to 2^20 px a side"),
    ("tiff", "BigTIFF (tiled)", "One tiled, compressed BigTIFF that GIS and terrain tools open: any size up to "
                                "2^20 px a side"),
    ("zarr", "Zarr pyramid", "A multiscale Zarr store (NAME.zarr, OME-NGFF 0.4) that napari and other zarr viewers "
                             "open: full resolution, then the synthesis's own coarser levels (the mipmap comes "
                             "free); any size up to 2^20 px a side"),
]
# The Advanced section's sliders: document field, label, range, what it does in plain words.
ADVANCED_SLIDERS = [
    ("passes", "Correction passes", 0, 4, "How many times each scale is cleaned up to look like the exemplar: "
     "more looks closer to it, costs more; sets every cleaned-up scale (each has its own under Passes per scale) "
     "(correction passes, LH05 3.3)"),
    ("subgrid", "Subpasses (s x s)", 1, 4, "In how many interleaved groups a clean-up pass visits the pixels; "
     "2 x 2 is the paper's choice (subpasses s^2, LH05 3.3)"),
    ("kappa", "Coherence", 0.0, 2.0, "Preference for continuing the current patch of exemplar over jumping to a "
     "similar spot: higher gives larger intact patches and less variety (coherence kappa, LH05)"),
    ("k", "Similar spots", 0, 4, "How many similar exemplar spots each pixel may jump to: more gives more variety "
     "and a longer analysis (k-coherence candidates k, LH05); 0: none, a random walk over the whole exemplar "
     "searches instead, with no analysis time (random-walk search, TBN10). Exemplars over 512 px always use it"),
    ("feature_weight", "Feature distance", 0.0, 2.0, "How much each pixel's distance to the exemplar's elements "
     "(the bright shapes against their background) counts when matching: keeps spots, cells and glyphs more "
     "whole, at some cost in fine detail; 0 off (feature-distance channel, LH06; Appearance matching only)"),
]


LAST_TIP: list[str] = [""]  # the last tooltip shown (read by the GUI tests)


def tip(text: str) -> None:
    """A plain-words tooltip for the last item (the paper's name in brackets)."""
    if imgui.is_item_hovered(imgui.HoveredFlags_.for_tooltip):
        imgui.set_tooltip(text)
        LAST_TIP[0] = text


class Panels:
    def __init__(self, ed):
        self.ed = ed
        self.overall = DEFAULT_JITTER
        self._export_popup = False

    # -- menu ---------------------------------------------------------------

    def open_dialog(self) -> None:
        ed = self.ed
        ed.confirm_discard(lambda: ed.dialogs.ask_path("Open exemplar or project", False, IMAGE_FILTER, ed.open_path))

    def open_material_dialog(self) -> None:
        ed = self.ed
        ed.confirm_discard(lambda: ed.dialogs.ask_paths("Open material", MAPS_FILTER, ed.open_paths))

    def _open_recent(self, path: str) -> None:
        ed = self.ed
        if not os.path.exists(path):
            ed.settings = ed.settings.without_recent(path)
            save_settings(ed.settings)
            ed.dialogs.message("Open Recent", f"{printable(path)} is no longer there; it was removed from the list.")
            return
        ed.open_path(path)

    def menu_bar(self) -> None:
        ed = self.ed
        if not imgui.begin_menu_bar():
            return
        if imgui.begin_menu("File"):
            if imgui.menu_item_simple("New"):
                ed.confirm_discard(ed.new_document)
            if imgui.menu_item_simple("Open...", "Ctrl+O"):
                self.open_dialog()
            if imgui.menu_item_simple("Open material..."):
                self.open_material_dialog()
            tip("A material's maps: choose them all, or one map (its siblings named NAME_normal, NAME_height... "
                "come along), or their folder")
            if imgui.begin_menu("Open Recent", bool(ed.settings.recent)):
                for i, path in enumerate(ed.settings.recent):
                    if imgui.menu_item_simple(f"{os.path.basename(path)}##recent{i}"):
                        ed.confirm_discard(lambda p=path: self._open_recent(p))
                    tip(path)
                imgui.separator()
                if imgui.menu_item_simple("Clear the list"):
                    ed.settings = replace(ed.settings, recent=())
                    save_settings(ed.settings)
                imgui.end_menu()
            imgui.separator()
            if imgui.menu_item_simple("Save", "Ctrl+S", enabled=ed.doc is not None):
                ed.save()
            if imgui.menu_item_simple("Save As...", "Ctrl+Shift+S", enabled=ed.doc is not None):
                ed.save_as()
            imgui.separator()
            if imgui.menu_item_simple("Export view as PNG...", enabled=ed.session.ready):
                self.export_view()
            if imgui.menu_item_simple("Export toroidal tile...", enabled=ed.session.ready):
                self.export_tile()
            imgui.separator()
            if imgui.menu_item_simple("Quit", "Ctrl+Q"):
                ed.request_quit()
            imgui.end_menu()
        if imgui.begin_menu("Edit"):
            h = ed.history
            if imgui.menu_item_simple(f"Undo {h.undo_label() if h else ''}".strip(), "Ctrl+Z",
                                      enabled=bool(h and h.can_undo())):
                ed.undo()
            if imgui.menu_item_simple(f"Redo {h.redo_label() if h else ''}".strip(), "Ctrl+Shift+Z",
                                      enabled=bool(h and h.can_redo())):
                ed.redo()
            imgui.end_menu()
        if imgui.begin_menu("View"):
            if imgui.menu_item_simple("Go to origin"):
                ed.view = View(0.0, 0.0, ed.view.zoom)
            if imgui.menu_item_simple("Go to coordinates..."):
                self._goto_open = True
            if imgui.menu_item_simple("Actual size (1:1)", "1"):
                ed.view = View(ed.view.x, ed.view.y, 1.0)
            if imgui.menu_item_simple("Shortcuts", "F1"):
                ed.show_shortcuts = True
            imgui.separator()
            _, ed.show_fields = imgui.menu_item("Show painted randomness", "H", ed.show_fields)
            _, ed.tile_mode = imgui.menu_item(f"Tile mode ({ed.tile_size} px)", "T", ed.tile_mode)
            imgui.end_menu()
        imgui.end_menu_bar()
        if getattr(self, "_goto_open", False):
            imgui.open_popup("Go to coordinates")
            self._goto_open = False
        if imgui.begin_popup("Go to coordinates"):
            imgui.text("Canvas position (finest-level pixels):")
            imgui.set_next_item_width(220)
            _, ed.goto = imgui.input_int2("x, y", ed.goto)
            if imgui.button("Go", (100, 0)):
                ed.view = View(float(ed.goto[0]), float(ed.goto[1]), ed.view.zoom).clamped()
                imgui.close_current_popup()
            imgui.end_popup()

    # -- side panels --------------------------------------------------------

    def side_panels(self) -> None:
        ed = self.ed
        if ed.doc is None or not ed.session.ready:
            self._loading()
            return
        flags = imgui.TreeNodeFlags_.default_open
        if ed.tool.name != "navigate" and imgui.collapsing_header(
                {"feature": "Features", "lattice": "Lattice"}.get(ed.tool.name, "Brush") + "###tool-options", flags):
            self.brush_panel()
        # Artists' controls first; the synthesis internals wait in Advanced (collapsed).
        # Which sections are open is kept between runs (the user's settings).
        for name, draw in (("Randomness", self.randomness_panel), ("Exemplar", self.exemplar_panel),
                           ("Material", self.material_panel),
                           ("Display", self.display_panel), ("Export", self.export_panel),
                           ("Advanced", self.synthesis_panel)):
            imgui.set_next_item_open(name in ed.panels_open, imgui.Cond_.once)
            opened = imgui.collapsing_header(name)
            ed.panels_open.add(name) if opened else ed.panels_open.discard(name)
            if opened:
                draw()

    def toolbar(self) -> None:
        """The tool bar over the canvas: one button per tool, the field overlay toggle."""
        ed = self.ed
        for i, t in enumerate(ed.tools):
            if i:
                imgui.same_line()
            active = t is ed.tool
            if active:
                imgui.push_style_color(imgui.Col_.button, imgui.get_style_color_vec4(imgui.Col_.button_active))
            if imgui.button(f"{t.label} ({t.key})##tool-{t.name}"):
                ed.set_tool(t.name)
            if active:
                imgui.pop_style_color()
            if imgui.is_item_hovered():
                imgui.set_tooltip(t.tooltip)
        imgui.same_line()
        _, ed.show_fields = imgui.checkbox("Show painted randomness (H)", ed.show_fields)
        if imgui.is_item_hovered():
            imgui.set_tooltip("Overlay the painted fields as heat maps: blue = calm, red = rough")

    def brush_panel(self) -> None:
        ed = self.ed
        ed.tool.options()
        doc = ed.doc
        if ed.tool.name.startswith("paint") and (doc.randomness_canvas is not None
                                                 or doc.randomness_exemplar is not None):
            if imgui.button("Clear painted randomness", (-1, 0)):
                ed.edit(replace(doc, randomness_canvas=None, randomness_exemplar=None), "Clear painted randomness")

    def _loading(self) -> None:
        job = self.ed.session.job
        imgui.text("Opening the exemplar...")
        if job is not None:
            imgui.progress_bar(job.progress, (-1, 0), job.message)
            if imgui.button("Cancel"):
                job.cancel()

    def exemplar_panel(self) -> None:
        ed = self.ed
        doc, s = ed.doc, ed.session
        ex, an = s.exemplar, s.analysis
        if ed.canvas.exemplar_tex is not None:
            size = min(PANEL_IMAGE, imgui.get_content_region_avail().x)
            self.exemplar_thumbnail(size)
        imgui.text(doc.exemplar.name)
        if doc.is_material and s.material is not None and not s.material.single:
            n = len(s.material.roles)
            imgui.same_line()
            imgui.text_disabled(f"+ {n - 1} map{'s' if n > 2 else ''}")
            ex = s.material.maps[s.material.primary].exemplar  # the first map describes the import
        ow, oh = ex.original_size
        chans = {1: "gray", 2: "gray + alpha", 3: "RGB", 4: "RGBA"}[ex.channels]
        lattice = ex.fit == "lattice"
        how = f"lattice block {ex.size}x{ex.size}" if lattice else f"{ex.size}x{ex.size}"
        imgui.text_disabled(f"{ow}x{oh} -> {how}, {chans}, {an.L + 1} levels")
        if ex.hires is not None:
            imgui.text_disabled(f"hi-res {ex.hires.shape[1]}x{ex.hires.shape[0]} kept for magnification")
        if imgui.button("Replace exemplar...", (-1, 0)):
            ed.dialogs.ask_path("Replace the exemplar", False, IMAGE_FILTER,
                                lambda p: ed.open_path(p, replace_exemplar=True))
        if imgui.is_item_hovered():
            imgui.set_tooltip("Use another image as the exemplar of this document, keeping its settings (undoable). "
                              "File > Open makes a new document.")
        if lattice:
            imgui.push_text_wrap_pos(0)
            imgui.text_disabled("The exemplar is the lattice's block of cells, rectified (it tiles); "
                                "the Lattice tool (L) sets it.")
            imgui.pop_text_wrap_pos()
        else:
            self._fit_options(doc, ex)
        job = s.job
        if job is not None:
            imgui.progress_bar(job.progress, (-1, 0), f"Analysis: {job.message}")
            if imgui.button("Cancel analysis"):
                job.cancel()

    # -- material ------------------------------------------------------------

    def material_panel(self) -> None:
        """The maps of the document, their roles and analysis weights."""
        ed = self.ed
        doc, mat = ed.doc, ed.session.material
        sources = list(doc.sources())
        single = not doc.is_material
        weights = doc.weight_dict() or mat.default_weights()
        imgui.push_text_wrap_pos(0)
        if single:
            imgui.text_disabled("A single image. Add its other maps (normal, height, roughness...) to make a "
                                "material: every map follows the same synthesis.")
        imgui.pop_text_wrap_pos()
        busy = ed.pending is not None
        imgui.begin_disabled(busy or doc.lattice is not None)
        for i, (role, src) in enumerate(sources):
            imgui.push_id(f"map{i}")
            roles = [IMAGE, *ROLES] if single else list(ROLES)
            imgui.set_next_item_width(140)
            changed, j = imgui.combo("##role", roles.index(role), [ROLE_LABELS[r] for r in roles])
            tip("What this map is; a role another map has swaps the two")
            if changed and roles[j] != role:
                self._set_role(sources, i, roles[j])
            imgui.same_line()
            imgui.text(src.name)
            mp = mat.maps.get(role)
            if mp is not None:
                ex = mp.exemplar
                chans = {1: "gray", 2: "gray + alpha", 3: "RGB", 4: "RGBA"}[ex.channels]
                kind = "float" if ex.depth == 32 else f"{ex.depth}-bit"
                imgui.text_disabled(f"{ex.original_size[0]}x{ex.original_size[1]}, {kind} {chans}")
            if not single:
                imgui.same_line(150)
                imgui.set_next_item_width(70)
                w = float(weights.get(role, 0.0))
                changed, v = imgui.slider_float("Analysis", w, 0.0, 2.0, "%.2f")
                tip("How much this map decides which exemplar spots look alike (0: it only follows). "
                    "Applied when you let go: the exemplar is analyzed again")
                if imgui.is_item_deactivated_after_edit():
                    nw = {**weights, role: float(v)}
                    self._set_weights(nw)
                imgui.same_line()
                if imgui.small_button("Remove"):
                    rest = [m for k, m in enumerate(sources) if k != i]
                    ed._begin_load("exemplar", doc.with_maps(rest), None, None, f"Remove the {role} map")
                tip("Drop this map from the material")
            imgui.pop_id()
        if imgui.button("Add map...", (-1, 0)):
            ed.dialogs.ask_path("Add a map", False, MAPS_FILTER, self._add_map)
        tip("Another map aligned with these (same size): its role comes from its name (NAME_normal, "
            "NAME_height...), else the first free role")
        imgui.end_disabled()
        if doc.lattice is not None:
            imgui.text_disabled("A lattice works on a single image.")

    def _set_role(self, sources, i: int, new: str) -> None:
        ed = self.ed
        maps = list(sources)
        role, src = maps[i]
        taken = next((k for k, (r, _) in enumerate(maps) if r == new), None)
        if taken is not None:
            maps[taken] = (role, maps[taken][1])
        maps[i] = (new, src)
        ed._begin_load("exemplar", ed.doc.with_maps(maps), None, None, "Map role")

    def _set_weights(self, weights: dict) -> None:
        ed = self.ed
        w = tuple((r, float(weights.get(r, 0.0))) for r, _ in ed.doc.sources())
        if not any(v > 0 for _, v in w):
            ed.dialogs.message("Analysis weights", "At least one map must feed the analysis (a weight above 0).")
            return
        ed._begin_load("exemplar", replace(ed.doc, weights=w), None, None, "Analysis weights")

    def _add_map(self, path: str) -> None:
        ed = self.ed
        try:
            src = ExemplarSource.from_file(path)
        except OSError as exc:
            ed.dialogs.message("Add a map", str(exc))
            return
        maps = list(ed.doc.sources())
        used = {r for r, _ in maps}
        named = role_of(path)
        if maps[0][0] == IMAGE:  # a single image becomes the base color (or the first free role)
            new_role = named[1] if named else None
            first = "basecolor" if new_role != "basecolor" else next(r for r in ROLES if r != "basecolor")
            maps = [(first, maps[0][1])]
            used = {first}
        role = named[1] if named and named[1] not in used else next((r for r in ROLES if r not in used), None)
        if role is None:
            ed.dialogs.message("Add a map", "The material already has a map for every role.")
            return
        ed._begin_load("exemplar", ed.doc.with_maps(maps + [(role, src)]), None, None, f"Add the {role} map")

    def _fit_options(self, doc, ex) -> None:
        ed = self.ed
        fits = [f for f, _ in FIT_LABELS]
        changed, i = imgui.combo("Import", fits.index(doc.fit), [lbl for _, lbl in FIT_LABELS])
        tip("How an image that is not a power-of-two square becomes the exemplar: resized (keeps the whole "
            "image) or cropped (keeps its pixels exactly), to at most 512 px, or to at most 2048 px for large "
            "photos (more detail; analyzed in seconds with the random-walk search, slower to synthesize)")
        if changed:
            ed.edit(replace(doc, fit=fits[i]), "Import fit")
        cur = 0 if doc.toroidal is None else (1 if doc.toroidal else 2)
        labels = list(TOROIDAL_LABELS)
        labels[0] = f"Auto (guess: {'tiles' if ex.toroidal_guess else 'does not tile'})"
        changed, i = imgui.combo("Toroidal", cur, labels)
        tip("Does the exemplar tile seamlessly? Then patches may cross its edges; Auto guesses from its border")
        if changed:
            ed.edit(replace(doc, toroidal=[None, True, False][i]), "Toroidal setting")

    def exemplar_thumbnail(self, size: float) -> None:
        """The exemplar; drag from it onto the canvas to place that feature there."""
        ed = self.ed
        tex = imgui.ImTextureRef(ed.canvas.exemplar_tex.glo)
        p0 = imgui.get_cursor_screen_pos()
        imgui.image(tex, (size, size))
        imgui.set_cursor_screen_pos(p0)
        imgui.invisible_button("exemplar-thumb", (size, size))
        if imgui.is_item_hovered() and not imgui.is_mouse_down(imgui.MouseButton_.left):
            imgui.set_tooltip("Drag a spot of the exemplar onto the canvas to place it there as a feature")
        if imgui.begin_drag_drop_source():
            try:
                m = ed.session.analysis.size
                pos, delta = imgui.get_io().mouse_pos, imgui.get_mouse_drag_delta(0)
                ux = int(min(m - 1, max(0, (pos.x - delta.x - p0.x) / size * m)))  # where the drag began
                uy = int(min(m - 1, max(0, (pos.y - delta.y - p0.y) / size * m)))
                imgui.set_drag_drop_payload_py_id(FEATURE_PAYLOAD, uy * 4096 + ux)
                # Preview: the exemplar around the point, at the size it will have on the canvas.
                tool = next(t for t in ed.tools if t.name == "feature")
                r = max(8, tool.outer)
                prev = min(256.0, 2 * r * ed.view.zoom)
                imgui.image(tex, (prev, prev), ((ux - r) / m, (uy - r) / m), ((ux + r) / m, (uy + r) / m))
                imgui.text(f"feature at exemplar ({ux}, {uy})")
            finally:
                imgui.end_drag_drop_source()

    def randomness_panel(self) -> None:
        ed = self.ed
        doc, L = ed.doc, ed.session.L
        jit = doc.jitter_for(L)
        imgui.push_item_width(-90)
        self.overall = sum(jit) / len(jit)
        changed, v = imgui.slider_float("All levels", self.overall, 0.0, 1.0, "%.2f")
        tip("Randomness at every scale at once: 0 repeats the exemplar as it is (a plain tiling), "
            "1 rearranges it the most (jitter r, LH05)")
        if changed:
            ed.edit(doc.with_all_jitter(L, v), "Randomness (all levels)", group="jitter-all")
        if imgui.is_item_deactivated():
            ed.history.end_group()
        for l in range(L + 1):
            size = 1 << (L - l)
            changed, v = imgui.slider_float(f"{size} px##jit{l}", jit[l], 0.0, 1.0, "%.2f")
            tip(f"How much features about {size} px across are moved: 0 keeps the exemplar's arrangement "
                f"at this scale, 1 moves them up to their own size (level {l}, jitter r_{l})")
            if changed:
                ed.edit(ed.doc.with_jitter(L, l, v), f"Randomness of level {l}", group=("jitter", l))
            if imgui.is_item_deactivated():
                ed.history.end_group()
        imgui.pop_item_width()
        if imgui.button("Reset"):
            ed.edit(replace(doc, jitter=()), "Reset randomness")
        tip(f"Back to the default randomness ({DEFAULT_JITTER}) at every scale")
        imgui.same_line()
        imgui.set_next_item_width(120)
        changed, seed = imgui.input_int("Seed", doc.seed, 1, 100, imgui.InputTextFlags_.enter_returns_true)
        tip("Another seed gives another texture with the same look; the same seed always gives the same one")
        if changed:
            ed.edit(replace(ed.doc, seed=int(seed) % (2 ** 32)), "Seed")
        imgui.same_line()
        if imgui.button("New seed"):
            ed.new_seed()
        tip("A random seed: a new variation")

    def synthesis_panel(self) -> None:
        ed = self.ed
        doc, L = ed.doc, ed.session.L
        imgui.push_text_wrap_pos(0)
        imgui.text_disabled("How the synthesis works inside; the defaults suit most exemplars.")
        imgui.pop_text_wrap_pos()
        imgui.push_item_width(-150)
        for field, label, lo, hi, text in ADVANCED_SLIDERS:
            value = getattr(ed.doc, field)
            if isinstance(value, float):
                changed, v = imgui.slider_float(label, value, lo, hi, "%.2f")
                v = round(v, 3)
            else:
                changed, v = imgui.slider_int(label, value, lo, hi)
            tip(text)
            if changed:  # a drag is one undo step
                change = {field: v}
                if field == "passes" and ed.doc.level_passes:  # every cleaned-up scale gets the new count
                    change["level_passes"] = tuple(v if c else 0 for c in ed.doc.passes_for(L))
                ed.edit(replace(ed.doc, **change), label, group=field)
            if imgui.is_item_deactivated():
                ed.history.end_group()
            an = ed.session.analysis
            if field == "k" and an is not None and an.k != ed.doc.k:
                imgui.push_text_wrap_pos(0)
                imgui.text_disabled(f"The exemplar is {an.size} px: a random walk searches it (k = 0).")
                imgui.pop_text_wrap_pos()
        models = ["appearance", "color"]
        changed, i = imgui.combo("Matching", models.index(doc.model), ["Appearance (LH06)", "Colors 5x5 (LH05)"])
        tip("What 'looks alike' means when cleaning up: Appearance compares smoothed, compressed "
            "neighborhoods (better; appearance space, LH06); Colors compares 5x5 colors (LH05)")
        if changed:
            ed.edit(replace(ed.doc, model=models[i]), "Neighborhood model")
        imgui.pop_item_width()
        if imgui.tree_node("Passes per scale"):
            imgui.push_text_wrap_pos(0)
            imgui.text_disabled("Clean-up passes at each scale, finest last; 0 leaves a scale as jittered. "
                                "Coarse scales cost little.")
            imgui.pop_text_wrap_pos()
            counts = ed.doc.passes_for(L)
            imgui.push_item_width(-150)
            for l in range(L + 1):
                size = 1 << (L - l)
                changed, v = imgui.slider_int(f"{size} px##pass{l}", counts[l], 0, 8)
                tip(f"How many times features about {size} px across are cleaned up (level {l}); "
                    "0: not at all (correction passes per level, LH05 3.3)")
                if changed:
                    ed.edit(ed.doc.with_level_passes(L, l, v), f"Passes of level {l}", group=("passes", l))
                if imgui.is_item_deactivated():
                    ed.history.end_group()
            imgui.pop_item_width()
            if imgui.small_button("Default passes"):
                ed.edit(replace(ed.doc, level_passes=(), corrected=None), "Default passes")
            tip(f"Back to {ed.doc.passes} passes (Correction passes) on every scale but the coarsest "
                f"{FIRST_CORRECTED_LEVEL}")
            imgui.tree_pop()

    def display_panel(self) -> None:
        ed = self.ed
        d = ed.display
        L = ed.session.L
        for mode in DISPLAY_MODES:
            if imgui.radio_button(MODE_LABELS[mode], d.mode == mode):
                ed.display = replace(d, mode=mode)
            tip(MODE_TIPS[mode])
        if ed.display.mode == "level":
            lvl = L if d.level < 0 else min(d.level, L)
            changed, v = imgui.slider_int("Level", lvl, 0, L)
            if changed:
                ed.display = replace(ed.display, level=v)
        mat = ed.session.material
        if mat is not None and not mat.single and ed.display.mode != "lit":
            roles = mat.roles
            cur = ed.session.shown_map(ed.display.map)
            imgui.set_next_item_width(-70)
            changed, i = imgui.combo("Map", roles.index(cur), [ROLE_LABELS[r] for r in roles])
            tip("The material's map the canvas shows (M: the next one)")
            if changed:
                ed.display = replace(ed.display, map=roles[i])
        if ed.display.mode == "lit":
            kind, shape = ed.session.shape_map()
            imgui.text_disabled({"normal": "Shaded by the normal map", "height": "Shaded by the height map",
                                 "luma": "Shaded by the brightness (no normal or height map)"}[shape])
            imgui.push_item_width(-110)
            changed, az = imgui.slider_float("Light direction", ed.display.light_azimuth % 360.0, 0.0, 360.0, "%.0f deg")
            tip("Where the light comes from, around the surface (0: from the right, 90: from the top)")
            if changed:
                ed.display = replace(ed.display, light_azimuth=float(az))
            changed, el = imgui.slider_float("Light height", ed.display.light_elevation, 5.0, 90.0, "%.0f deg")
            tip("How high the light stands over the surface: low lights show the relief most")
            if changed:
                ed.display = replace(ed.display, light_elevation=float(el))
            changed, rel = imgui.slider_float("Relief", ed.display.relief, 0.0, 4.0, "%.2f")
            tip("How strongly the normal or height map tilts the surface (1: as authored)")
            if changed:
                ed.display = replace(ed.display, relief=float(rel))
            imgui.pop_item_width()
        keys = [k for k, _ in MAGNIFY_LABELS]
        labels = [lbl if k != "hires" or ed.canvas.has_hires else lbl + " (none: same as bilinear)"
                  for k, lbl in MAGNIFY_LABELS]
        imgui.set_next_item_width(-70)
        changed, i = imgui.combo("Zoom in", keys.index(d.magnify), labels)
        tip("How the texture looks magnified: sharp patches drawn from the full-resolution image "
            "(synthesis magnification, LH05 5), or plain enlarged texels")
        if changed:
            ed.display = replace(ed.display, magnify=keys[i])
        imgui.text(f"Zoom {_zoom_text(ed.view.zoom)}")
        imgui.same_line()
        if imgui.small_button("1:1"):
            ed.view = View(ed.view.x, ed.view.y, 1.0)
        tip("Actual size: one texture pixel per screen pixel (1)")
        imgui.same_line()
        if imgui.small_button("Origin"):
            ed.view = View(0.0, 0.0, ed.view.zoom)
        tip("Back to canvas position (0, 0)")

    def export_panel(self) -> None:
        ed = self.ed
        _, ed.write_coords = imgui.checkbox("Also write the coordinate map", ed.write_coords)
        tip("NAME_coords.png: the exemplar position of every pixel, exactly "
            "(x = R + 256 (B & 15), y = G + 256 (B >> 4)); to look up other maps through the same synthesis")
        keys = [k for k, _ in DEPTH_CHOICES]
        imgui.set_next_item_width(-70)
        changed, i = imgui.combo("Depth", keys.index(ed.export_depth), [lbl for _, lbl in DEPTH_CHOICES])
        tip("Bits per channel of the exported maps: each map's own (8-bit sources 8, 16-bit 16, float 32), "
            "or the same for all; 32-bit maps are float TIFFs")
        if changed:
            ed.export_depth = keys[i]
        imgui.set_next_item_width(-70)
        changed, i = imgui.combo("Scale", MAGNIFY_CHOICES.index(ed.export_magnify),
                                 ["1:1"] + [f"{f}x (magnified)" for f in MAGNIFY_CHOICES[1:]])
        tip("View and tile exports: N x N pixels per synthesized pixel, sharp from the full-resolution maps "
            "(synthesis magnification, LH05 5); normals stay unit length")
        if changed:
            ed.export_magnify = MAGNIFY_CHOICES[i]
        mat = ed.session.material
        if mat is not None and not mat.single:
            imgui.push_text_wrap_pos(0)
            imgui.text_disabled(f"A material: one file per map, NAME_{mat.roles[0]}.png, ... ({', '.join(mat.roles)}); "
                                "tile sets, BigTIFFs and Zarr write the map shown.")
            imgui.pop_text_wrap_pos()
        if imgui.button("Export view as PNG...", (-1, 0)):
            self.export_view()
        tip("What the canvas shows now, at 1:1 (or the scale above); a material: every map")
        imgui.separator_text("Rectangle")
        self.rectangle_export()
        imgui.separator_text("Seamless tile")
        ed.tile_size = size_combo("Tile size", TILE_SIZES, ed.tile_size)
        tip("Side of the seamless tile")
        _, ed.tile_mode = imgui.checkbox("Show the tile on the canvas (T)", ed.tile_mode)
        tip("The canvas shows the periodic texture this tile size makes, tile borders drawn: "
            "tune exactly what the toroidal export will write")
        if imgui.button("Export toroidal tile...", (-1, 0)):
            self.export_tile()
        tip("A square that repeats without a seam (a periodic synthesis of the same look)")
        lat = ed.session.controls.lattice if ed.session is not None and ed.session.ready else None
        if lat is not None:
            cx, cy = lat.cell(ed.session.analysis.size)
            imgui.push_text_wrap_pos(0)
            imgui.text_disabled(f"Lattice: the view and PNG rectangles export as the canvas shows them "
                                f"({'input geometry' if ed.geometry() is not None else 'rectified'}); "
                                f"tile sets, BigTIFFs and seamless tiles are rectified (tiles: whole {cx}x{cy} px "
                                f"cells).")
            imgui.pop_text_wrap_pos()

    def rectangle_export(self) -> None:
        """A rectangle of the infinite canvas as one PNG, a UDIM tile set or a
        BigTIFF, with its size and time estimated before it starts."""
        from infinitex.engine.synth import MAX_WINDOW_PIXELS, MAX_WINDOW_SIDE
        from infinitex.export import MAX_SIDE
        from infinitex.export import TILE_SIZES as STREAM_TILES

        from infinitex.export.jobs import ExportEstimate
        ed = self.ed
        imgui.set_next_item_width(-90)
        _, ed.export_rect = imgui.input_int4("x y w h", ed.export_rect)
        tip("A rectangle of the infinite canvas: its top-left corner and size, in texture pixels")
        if imgui.small_button("The view"):
            r = ed.view_rect()
            ed.export_rect = [r.x0, r.y0, r.w, r.h]
        tip("The rectangle the canvas shows now")
        for n, label in ((8192, "8k"), (32768, "32k"), (65536, "64k")):
            imgui.same_line()
            if imgui.small_button(f"{label}##square"):
                ed.export_rect = [ed.export_rect[0], ed.export_rect[1], n, n]
                if ed.export_format == "png":
                    ed.export_format = "tiff"
            tip(f"{n} x {n} px from the same corner")
        keys = [k for k, _, _ in EXPORT_FORMATS]
        imgui.set_next_item_width(-90)
        changed, i = imgui.combo("Format", keys.index(ed.export_format), [label for _, label, _ in EXPORT_FORMATS])
        if changed:
            ed.export_format = keys[i]
        tip(EXPORT_FORMATS[keys.index(ed.export_format)][2])
        x, y, w, h = ed.export_rect
        streamed = ed.export_format != "png"
        problem = None
        if w < 1 or h < 1:
            problem = "The rectangle is empty."
        elif streamed and (w > MAX_SIDE or h > MAX_SIDE):
            problem = f"At most {MAX_SIDE} px a side."
        elif not streamed and (w > MAX_WINDOW_SIDE or h > MAX_WINDOW_SIDE or w * h > MAX_WINDOW_PIXELS):
            problem = (f"Too large for one PNG (at most {MAX_WINDOW_SIDE} px a side and "
                       f"{MAX_WINDOW_PIXELS // 2**20} Mpixels): choose PNG tiles or BigTIFF.")
        elif abs(x) > 2**30 or abs(y) > 2**30:
            problem = "The corner must be within +-2^30."
        low = False
        if streamed:
            ed.stream_tile = size_combo("Tile##stream", STREAM_TILES, ed.stream_tile)
            tip("Side of the tiles the export is rendered in (and, for PNG tiles, of each file)")
            imgui.set_next_item_width(-90)
            cores = os.cpu_count() or 1
            _, ed.export_workers = imgui.slider_int("Workers", ed.export_workers, 1, max(2, cores))
            tip("Processes rendering tiles, each with its own GL context, while the editor stays live "
                f"(this machine has {cores} cores)")
            if problem is None and ed.session is not None and ed.session.ready:
                key = (ed.doc.analysis_key(), ed.export_format, ed.stream_tile)
                if ed.estimate is None or ed.estimate.key != key:
                    if ed.estimate is not None:
                        ed.estimate.close()
                    ed.estimate = ExportEstimate(ed.doc, ed.export_format, ed.stream_tile)
                ed.estimate.poll()
                text, low = ed.estimate.describe(w, h, ed.export_workers, ed.dialogs.last_dir or ".")
                imgui.push_text_wrap_pos(0)
                if low:
                    imgui.text_colored((1.0, 0.55, 0.35, 1.0), text)
                else:
                    imgui.text_disabled(text)
                imgui.pop_text_wrap_pos()
        elif problem is None:
            imgui.text_disabled(f"{w} x {h} px, {w * h / 1e6:.1f} Mpixels")
        if problem:
            imgui.push_text_wrap_pos(0)
            imgui.text_colored((1.0, 0.55, 0.35, 1.0), problem)
            imgui.pop_text_wrap_pos()
        imgui.begin_disabled(problem is not None or ed.export_job is not None)
        if imgui.button("Export rectangle...", (-1, 0)):
            r = Rect.of(x, y, w, h)
            if streamed:
                fmt = ed.export_format
                filt = {"tiff": TIFF_FILTER, "zarr": ZARR_FILTER}.get(fmt, PNG_FILTER)
                ed.dialogs.ask_path("Export rectangle", True, filt, lambda p: ed.start_streamed_export(p, r),
                                    default="rectangle" + {"tiff": ".tif", "zarr": ".zarr"}.get(fmt, ".png"))
            else:
                flt, ext = self._export_filter()
                ed.dialogs.ask_path("Export rectangle", True, flt, lambda p: ed.start_export(p, r),
                                    default="rectangle" + ext)
        imgui.end_disabled()
        if streamed:
            tip("Rendered tile by tile in bounded memory. Stopped (Cancel, a crash), the same export continues "
                "where it stopped: the finished tiles are kept in NAME.parts beside it")

    def export_view(self) -> None:
        ed = self.ed
        r = ed.view_rect()
        flt, ext = self._export_filter()
        ed.dialogs.ask_path("Export view", True, flt, lambda p: ed.start_export(p, r), default="view" + ext)

    def _export_filter(self) -> tuple[list[str], str]:
        """A single image exported at 32 bits is a float TIFF; everything else is named .png."""
        ed = self.ed
        if ed.export_depth == 32 and ed.session.material is not None and ed.session.material.single:
            return ["Float TIFF", "*.tif *.tiff"], ".tif"
        return PNG_FILTER, ".png"

    def export_tile(self) -> None:
        ed = self.ed
        n = ed.tile_size
        flt, ext = self._export_filter()
        ed.dialogs.ask_path("Export toroidal tile", True, flt,
                            lambda p: ed.start_export(p, Rect(0, 0, n, n), toroidal=n), default=f"tile{n}{ext}")

    # -- status and overlays --------------------------------------------------

    def status_bar(self) -> None:
        ed = self.ed
        imgui.separator()
        s = ed.session
        parts = [f"{ed.update_ms:5.1f} ms/update", f"{ed.pixels:>8,} px synthesized", f"{ed.fps:5.1f} fps"]
        if ed.cursor is not None:
            cx, cy = ed.cursor
            parts.append(f"x {int(np.floor(cx))}  y {int(np.floor(cy))}")
        parts.append(f"zoom {_zoom_text(ed.view.zoom)}")
        if ed.frame is not None:
            parts.append(f"level {ed.frame.level}/{s.L}")
        parts.append(ed.title.rsplit(" - ", 1)[0])
        imgui.text("   |   ".join(parts))
        if ed.notice is not None:
            text, t = ed.notice
            if time.monotonic() - t < 15.0:
                imgui.same_line()
                imgui.text_colored((0.55, 0.9, 0.55, 1.0), f"   {text}")

    def canvas_overlay(self, p0, w, h) -> None:
        ed = self.ed
        job = ed.session.job
        text = None
        if job is not None:
            text = f"Analyzing {job.doc.exemplar.name}: {job.progress * 100:.0f}%  {job.message}"
        elif not ed.refined:
            text = "Refining..."
        if text:
            dl = imgui.get_window_draw_list()
            tw = imgui.calc_text_size(text).x
            dl.add_rect_filled((p0.x + 8, p0.y + 8), (p0.x + 24 + tw, p0.y + 30), imgui.get_color_u32((0, 0, 0, 0.55)), 4)
            dl.add_text((p0.x + 16, p0.y + 11), imgui.get_color_u32((1, 1, 1, 1)), text)

    def progress_modals(self) -> None:
        ed = self.ed
        job = ed.export_job
        name = "Exporting###export"
        if job is None:
            if self._export_popup:  # the export ended: close its window
                opened, _ = imgui.begin_popup_modal(name, None, imgui.WindowFlags_.no_saved_settings)
                if opened:
                    imgui.close_current_popup()
                    imgui.end_popup()
                self._export_popup = False
            return
        if not self._export_popup:
            imgui.open_popup(name)
            self._export_popup = True
        vp = imgui.get_main_viewport()
        imgui.set_next_window_pos((vp.pos.x + vp.size.x / 2, vp.pos.y + vp.size.y / 3), imgui.Cond_.always, (0.5, 0.5))
        imgui.set_next_window_size((420, 0))
        opened, _ = imgui.begin_popup_modal(name, None, imgui.WindowFlags_.no_saved_settings)
        if opened:
            imgui.text(f"{os.path.basename(job.out_path)}: {job.out_rect.w} x {job.out_rect.h}")
            elapsed = time.monotonic() - job.started
            streamed = hasattr(job, "done_tiles")
            if streamed:
                total = job.job.total
                label = f"{job.done_tiles} / {total} tiles  ({elapsed:.0f} s)"
                imgui.progress_bar(job.progress, (-1, 0), label)
                rate, left = job.rate(), job.seconds_left()
                if job.kept:
                    imgui.text_disabled(f"{job.kept} tiles kept from an earlier run")
                if rate is not None:
                    imgui.text(f"{rate / 1e6:.2f} Mpixel/s with {job.workers} worker{'s' * (job.workers > 1)}, "
                               f"{'?' if left is None else duration_text(left)} left")
                else:
                    imgui.text_disabled(f"Starting {job.workers} worker{'s' * (job.workers > 1)}...")
            else:
                imgui.progress_bar(job.progress, (-1, 0), f"{job.progress * 100:.0f} %  ({elapsed:.0f} s)")
            if streamed and job.cancelling:
                imgui.text_disabled("Stopping after the tiles being rendered...")
            elif imgui.button("Cancel", (120, 0)):
                job.cancel()
                if not streamed:
                    ed.export_job = None
                    imgui.close_current_popup()
            if streamed and not job.cancelling:
                tip("Stops after the tiles being rendered; they and every finished tile are kept, and the "
                    "same export continues from them")
            imgui.end_popup()


def size_combo(label: str, sizes, value: int) -> int:
    """A combo box of sizes (px); returns the one chosen."""
    imgui.set_next_item_width(-90)
    changed, i = imgui.combo(label, list(sizes).index(value), [str(s) for s in sizes])
    return sizes[i] if changed else value


PANEL_IMAGE = 160


def _zoom_text(z: float) -> str:
    return f"{z * 100:.0f}%" if z >= 0.1 else f"1/{1 / z:.0f}"
