"""The Model panel (a model is open: texture on a surface): what the model is,
the texture's size, scale and direction on it, the seams, exporting it."""
from __future__ import annotations

from typing import TYPE_CHECKING

from imgui_bundle import imgui

from infinitex.project.surface import MAX_REPEATS, MIN_REPEATS, SIZES

from .widgets import tip

if TYPE_CHECKING:
    from . import Panels

FRAME_LABELS = {"up": "Upright", "uv": "Along the UVs"}


def draw(p: Panels) -> None:
    ed = p.ed
    s = ed.doc.surface
    pv = ed.session.model
    charts = f", {pv.atlas.charts} charts" if pv.atlas is not None else ""
    imgui.text_wrapped(f"{s.model.name}: {len(s.model.faces):,} triangles{charts}")
    m = ed.session.analysis.size
    imgui.push_item_width(-110)
    sizes = [n for n in SIZES if n >= m]
    if imgui.begin_combo("Texture size", f"{s.size} px"):
        for n in sizes:
            if imgui.selectable(f"{n} px", n == s.size)[0] and n != s.size:
                ed.model.set_surface("Model texture size", size=n)
        imgui.end_combo()
    tip("Texels a side of the model's texture, synthesized here and exported (the painted randomness "
        "is in its texels). Larger is sharper and slower")
    changed, rep = imgui.slider_float("Scale", float(s.repeats), MIN_REPEATS, min(MAX_REPEATS, 64.0),
                                      "%.2f repeats", imgui.SliderFlags_.logarithmic)
    if changed:
        ed.model.set_surface("Model texture scale", group=("model-scale", p), repeats=round(float(rep), 3))
    if imgui.is_item_deactivated() and ed.history is not None:
        ed.history.end_group()  # one drag, one undo step
    tip("How many times the exemplar's width fits across the model's largest side")
    if imgui.begin_combo("Direction", FRAME_LABELS[s.frame]):
        for key, label in FRAME_LABELS.items():
            if imgui.selectable(label, key == s.frame)[0] and key != s.frame:
                ed.model.set_surface("Model texture direction", frame=key)
        imgui.end_combo()
    tip("Upright: the exemplar's top points up the model (bricks stay level), running on over its top and "
        "bottom. Along the UVs: the exemplar's x follows the model's u direction")
    imgui.pop_item_width()
    _, ed.model.show_seams = imgui.checkbox("Show seams", ed.model.show_seams)
    tip("Mark the borders of the model's UV charts: the texture runs across them")
    if ed.model.view is not None:
        imgui.same_line()
        _, ed.model.view.magnify = imgui.checkbox("Magnify", ed.model.view.magnify)
        tip("Draw the texture by synthesis magnification: sharp when zoomed in close (each pixel reads the "
            "exemplar, or its full-resolution copy, through the synthesized coordinates). Off: the texture's texels")
    if imgui.button("Frame the model"):
        ed.model.frame()
    tip("Orbit: middle or left button; pan: Shift+middle or right button; zoom: the wheel")
    imgui.set_next_item_width(90)
    if imgui.begin_combo("##model-magnify", f"x{ed.model.export_magnify}"):
        for k in (1, 2, 4):
            if s.size * k <= 8192 and imgui.selectable(f"x{k} ({s.size * k} px)", k == ed.model.export_magnify)[0]:
                ed.model.export_magnify = k
        imgui.end_combo()
    tip("Exported texture size: the synthesized texture, or magnified 2x or 4x (synthesis magnification)")
    imgui.same_line()
    if imgui.button("Export model...", (-1, 0)):
        ed.model.export_dialog()
    tip("A GLB of the model with the texture (every map of a material) attached, and each map as an image")
    if pv.left_out:
        imgui.text_disabled(f"Not used on the model: {', '.join(pv.left_out)}")
    if imgui.button("Close model", (-1, 0)):
        ed.model.close()
