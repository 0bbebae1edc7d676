"""The tool bar over the canvas: one button per canvas tool (its shortcut in
brackets) and the painted-randomness overlay toggle."""
from __future__ import annotations

from typing import TYPE_CHECKING

from imgui_bundle import imgui

if TYPE_CHECKING:
    from . import Panels


def draw(p: Panels) -> None:
    """The tool bar over the canvas: one button per tool, the field overlay toggle."""
    ed = p.ed
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
    _, ed.show_fields = imgui.checkbox("Show painted (H)", ed.show_fields)
    if imgui.is_item_hovered():
        imgui.set_tooltip("Overlay what is painted: randomness as heat maps (blue = calm, red = rough), "
                          "labels in their colors, directions as short strokes")
