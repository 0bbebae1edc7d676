"""The Exemplar panel: its thumbnail (drag a spot of it onto the canvas to
place a feature), what was imported and how, Replace exemplar, the import
fit and toroidal options, and the analysis's progress."""
from __future__ import annotations

from dataclasses import replace
from typing import TYPE_CHECKING

from imgui_bundle import imgui

from infinitex.engine.controls import MAX_LABELS
from infinitex.engine.tileable import recommended

from ..dialogs import IMAGE_FILTER
from ..tools.feature import PAYLOAD as FEATURE_PAYLOAD, FeatureTool
from ..tools.lattice import LatticeTool
from .widgets import tip

if TYPE_CHECKING:
    from . import Panels

FIT_LABELS = [("resize", "Resize to a power of two"), ("crop", "Crop a power-of-two square"),
              ("resize-2048", "Resize, up to 2048 px"), ("crop-2048", "Crop, up to 2048 px")]
TOROIDAL_LABELS = ["Auto", "Yes (tiles)", "No"]

PANEL_IMAGE = 320  # the thumbnail fills the panel: big enough to pick features from


def draw(p: Panels) -> None:
    """The Exemplar panel."""
    ed = p.ed
    doc, s = ed.doc, ed.session
    ex, an = s.exemplar, s.analysis
    if ed.canvas.exemplar_tex is not None:
        size = min(PANEL_IMAGE, imgui.get_content_region_avail().x)
        thumbnail(p, size)
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
                            lambda path: ed.files.open_path(path, replace_exemplar=True))
    tip("Use another image as the exemplar of this document, keeping its settings (undoable). "
        "File > Open makes a new document.")
    if not lattice:
        _palette(ed, doc)
    if doc.lattice is not None:
        lattice_line(ed, doc)
    if lattice:
        imgui.push_text_wrap_pos(0)
        imgui.text_disabled("The exemplar is the lattice's block of cells, rectified (it tiles).")
        imgui.pop_text_wrap_pos()
    else:
        _fit_options(ed, doc, ex)
    job = s.job
    if job is not None:
        imgui.progress_bar(job.progress, (-1, 0), f"Analysis: {job.message}")
        if imgui.button("Cancel analysis"):
            job.cancel()


def lattice_line(ed, doc) -> None:
    """What the document is synthesized on: the lattice's cell and block,
    whether it was found in the image (and how sure), one click to turn it off
    or to adjust it with the Lattice tool."""
    lat = doc.lattice
    found = ed.files.found_lattice
    imgui.push_text_wrap_pos(0)
    imgui.text_colored((0.55, 0.85, 1.0, 1.0), f"On a lattice: cells {lat.describe()}, a block of {lat.nx} x {lat.ny}")
    if found is not None and found.lattice is not None and replace(found.lattice, levels=lat.levels) == lat:
        imgui.text_disabled(f"Found in the image (confidence {found.confidence:.2f}): rows and columns stay straight.")
    imgui.pop_text_wrap_pos()
    if imgui.button("Turn off##lattice-off"):
        ed.edit(replace(doc, lattice=None), "Lattice off")
    tip("Synthesize the image as a stochastic texture, without its lattice (undoable)")
    imgui.same_line()
    if imgui.button("Adjust (L)##lattice-adjust"):
        ed.tools.choose(ed.tools.of(LatticeTool))
    tip("The Lattice tool: drag the cell's handles over the image, or mark one cell with a rectangle")


def _palette(ed, doc) -> None:
    """The palette: the document's exemplars, one label each (texture by numbers)."""
    entries = doc.entries()
    if len(entries) > 1:
        imgui.separator_text("Palette")
        colors = doc.labels.colors if doc.labels is not None else ()
        for i, entry in enumerate(entries):
            c = colors[i] if i < len(colors) else (128, 128, 128)
            imgui.color_button(f"##pal{i}", (c[0] / 255, c[1] / 255, c[2] / 255, 1.0), 0, (14, 14))
            imgui.same_line()
            imgui.text(f"{i + 1}  {entry[0][1].name}")
            imgui.same_line()
            if imgui.small_button(f"x##palette-remove-{i}"):
                ed.files.remove_from_palette(i)
            tip("Remove this exemplar from the palette (its label goes; the canvas where it was painted "
                "becomes free)")
    if len(entries) < MAX_LABELS and imgui.button("Add to palette...", (-1, 0)):
        ed.dialogs.ask_paths("Add an exemplar to the palette", IMAGE_FILTER, ed.files.add_to_palette)
    tip("Texture by numbers across several images: each exemplar of the palette becomes a label (grass, gravel, "
        "a dirt path...), named after its file. Paint on the canvas where each goes with the Labels tool (G); "
        "transitions come from where the exemplars meet. A material adds a material with the same maps")


def _fit_options(ed, doc, ex) -> None:
    fits = [f for f, _ in FIT_LABELS]
    changed, i = imgui.combo("Import", fits.index(doc.fit), [lbl for _, lbl in FIT_LABELS])
    tip("How an image that is not a power-of-two square becomes the exemplar: resized (keeps the whole "
        "image) or cropped (keeps its pixels exactly), to at most 512 px, or to at most 2048 px for large "
        "photos (more detail; analyzed in seconds with the random-walk search, slower to synthesize)")
    if changed:
        ed.edit(replace(doc, fit=fits[i]), "Import fit")
    if not doc.make_tileable:
        cur = 0 if doc.toroidal is None else (1 if doc.toroidal else 2)
        labels = list(TOROIDAL_LABELS)
        labels[0] = f"Auto (guess: {'tiles' if ex.toroidal_guess else 'does not tile'})"
        changed, i = imgui.combo("Toroidal", cur, labels)
        tip("Does the exemplar tile seamlessly? Then patches may cross its edges; Auto guesses from its border")
        if changed:
            ed.edit(replace(doc, toroidal=[None, True, False][i]), "Toroidal setting")
    if doc.lattice is not None or doc.palette:
        return
    if not doc.make_tileable and not ex.toroidal and recommended(ex):
        imgui.push_text_wrap_pos(0)
        imgui.text_colored((1.0, 0.8, 0.4, 1.0),
                           "This photo does not tile and its lighting varies: zoomed out, its dark and light "
                           "patches come back every exemplar width. Make tileable evens them out.")
        imgui.pop_text_wrap_pos()
    changed, on = imgui.checkbox("Make tileable", doc.make_tileable)
    tip("Re-synthesize the image's borders so that it wraps: its interior is kept, the shading is evened out "
        "between opposite borders, and elements cut by a border are replaced by whole ones from the other side. "
        "For photos that do not tile, above all unevenly lit ones; on evenly lit stochastic photos (gravel, "
        "pebbles) the plain synthesis often looks more natural")
    if changed:
        ed.edit(replace(doc, make_tileable=on), "Make tileable" if on else "Make tileable off")


def thumbnail(p: Panels, size: float) -> None:
    """The exemplar; drag from it onto the canvas to place that feature there."""
    ed = p.ed
    tex = imgui.ImTextureRef(ed.canvas.exemplar_tex.glo)
    p0 = imgui.get_cursor_screen_pos()
    imgui.image(tex, (size, size))
    imgui.set_cursor_screen_pos(p0)
    imgui.invisible_button("exemplar-thumb", (size, size))
    if not imgui.is_mouse_down(imgui.MouseButton_.left):
        tip("Drag a spot of the exemplar onto the canvas to place it there as a feature")
    if imgui.begin_drag_drop_source():
        try:
            m = ed.session.analysis.size
            pos, delta = imgui.get_io().mouse_pos, imgui.get_mouse_drag_delta(0)
            ux = int(min(m - 1, max(0, (pos.x - delta.x - p0.x) / size * m)))  # where the drag began
            uy = int(min(m - 1, max(0, (pos.y - delta.y - p0.y) / size * m)))
            imgui.set_drag_drop_payload_py_id(FEATURE_PAYLOAD, uy * 4096 + ux)
            # Preview: the exemplar around the point, at the size it will have on the canvas.
            tool = ed.tools.of(FeatureTool)
            r = max(8, tool.outer)
            prev = min(256.0, 2 * r * ed.view.zoom)
            imgui.image(tex, (prev, prev), ((ux - r) / m, (uy - r) / m), ((ux + r) / m, (uy + r) / m))
            imgui.text(f"feature at exemplar ({ux}, {uy})")
        finally:
            imgui.end_drag_drop_source()
