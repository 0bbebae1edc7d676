"""The Display panel: what the canvas shows (color, coordinate map, patches,
one pyramid level, shaded relief, the lit material and its light), which
map of a material, how magnified texels look, the zoom, 1:1 and Origin."""
from __future__ import annotations

from typing import TYPE_CHECKING

from imgui_bundle import imgui

from infinitex.engine.material import ROLE_LABELS
from infinitex.project import DISPLAY_MODES

from .widgets import tip, zoom_text

if TYPE_CHECKING:
    from . import Panels

MODE_LABELS = {"color": "Color", "coords": "Coordinate map", "patches": "Patch boundaries",
               "level": "Single pyramid level", "relief": "Shaded relief", "lit": "Lit material"}
MODE_TIPS = {"color": "The texture",
             "coords": "Where each pixel comes from in the exemplar (red = x, green = y)",
             "patches": "The patches of exemplar the texture is made of, each tinted, their seams dark",
             "level": "One scale of the synthesis pyramid on its own (the coarse levels are its mipmap)",
             "relief": "The texture's brightness shaded as a height map (terrain, bump maps)",
             "lit": "The material under a light you move: its normal map (else its height map, else the "
                    "brightness as height) shades the base color"}
MAGNIFY_LABELS = [("hires", "Synthesis magnification, hi-res exemplar"),
                  ("bilinear", "Synthesis magnification, bilinear"), ("nearest", "Nearest (texel blocks)")]


def draw(p: Panels) -> None:
    """The Display panel."""
    ed = p.ed
    d = ed.display
    L = ed.session.L
    for mode in DISPLAY_MODES:
        if imgui.radio_button(MODE_LABELS[mode], d.mode == mode):
            ed.viewer.set_display(mode=mode)
        tip(MODE_TIPS[mode])
    if ed.display.mode == "level":
        lvl = L if d.level < 0 else min(d.level, L)
        changed, v = imgui.slider_int("Level", lvl, 0, L)
        if changed:
            ed.viewer.set_display(level=v)
    mat = ed.session.material
    if mat is not None and not mat.single and ed.display.mode != "lit":
        roles = mat.roles
        cur = ed.session.shown_map(ed.display.map)
        imgui.set_next_item_width(-70)
        changed, i = imgui.combo("Map", roles.index(cur), [ROLE_LABELS[r] for r in roles])
        tip("The material's map the canvas shows (M: the next one)")
        if changed:
            ed.viewer.set_display(map=roles[i])
    if ed.display.mode == "lit":
        kind, shape = ed.session.shape_map()
        imgui.text_disabled({"normal": "Shaded by the normal map", "height": "Shaded by the height map",
                             "luma": "Shaded by the brightness (no normal or height map)"}[shape])
        imgui.push_item_width(-110)
        changed, az = imgui.slider_float("Light direction", ed.display.light_azimuth % 360.0, 0.0, 360.0, "%.0f deg")
        tip("Where the light comes from, around the surface (0: from the right, 90: from the top)")
        if changed:
            ed.viewer.set_display(light_azimuth=float(az))
        changed, el = imgui.slider_float("Light height", ed.display.light_elevation, 5.0, 90.0, "%.0f deg")
        tip("How high the light stands over the surface: low lights show the relief most")
        if changed:
            ed.viewer.set_display(light_elevation=float(el))
        changed, rel = imgui.slider_float("Relief", ed.display.relief, 0.0, 4.0, "%.2f")
        tip("How strongly the normal or height map tilts the surface (1: as authored)")
        if changed:
            ed.viewer.set_display(relief=float(rel))
        imgui.pop_item_width()
    keys = [k for k, _ in MAGNIFY_LABELS]
    labels = [lbl if k != "hires" or ed.canvas.has_hires else lbl + " (none: same as bilinear)"
              for k, lbl in MAGNIFY_LABELS]
    imgui.set_next_item_width(-70)
    changed, i = imgui.combo("Zoom in", keys.index(d.magnify), labels)
    tip("How the texture looks magnified: sharp patches drawn from the full-resolution image "
        "(synthesis magnification, LH05 5), or plain enlarged texels")
    if changed:
        ed.viewer.set_display(magnify=keys[i])
    imgui.text(f"Zoom {zoom_text(ed.view.zoom)}")
    imgui.same_line()
    if imgui.small_button("1:1"):
        ed.viewer.zoom_to(1.0)
    tip("Actual size: one texture pixel per screen pixel (1)")
    imgui.same_line()
    if imgui.small_button("Origin"):
        ed.viewer.center(0, 0)
    tip("Back to canvas position (0, 0)")
