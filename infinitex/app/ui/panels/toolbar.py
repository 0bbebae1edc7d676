"""The tool bar over the canvas: one button per canvas tool (its shortcut in
brackets) and the painted-randomness overlay toggle."""
from __future__ import annotations

from typing import TYPE_CHECKING

from imgui_bundle import imgui
from ..tips import hint

if TYPE_CHECKING:
    from . import Panels


def draw(p: Panels) -> None:
    """The tool bar over the canvas: one button per tool, the field overlay toggle."""
    ed = p.ed
    style = imgui.get_style()

    def next_item(label: str, extra: float = 0.0) -> None:
        """On the same row while it fits, else on the next (a narrow window wraps the bar)."""
        w = imgui.calc_text_size(label).x + 2 * style.frame_padding.x + extra
        imgui.same_line()
        if imgui.get_content_region_avail().x < w:
            imgui.new_line()
    shown = ed.tools.offered(ed.model_mode)
    for i, t in enumerate(shown):
        if i:
            next_item(f"{t.label} ({t.key})")
        active = t is ed.tool
        if active:
            imgui.push_style_color(imgui.Col_.button, imgui.get_style_color_vec4(imgui.Col_.button_active))
        if imgui.button(f"{t.label} ({t.key})##tool-{t.name}"):
            ed.tools.choose(t)
        if active:
            imgui.pop_style_color()
        hint(t.tooltip)
    next_item("Show painted (H)", imgui.get_frame_height() + style.item_inner_spacing.x)
    ed.viewer.show_painted(imgui.checkbox("Show painted (H)", ed.viewer.show_fields)[1])
    hint("Overlay what is painted: randomness as heat maps (blue = calm, red = rough), "
        "labels in their colors, directions as short strokes")
