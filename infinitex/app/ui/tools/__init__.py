"""Canvas tools: each has its own module with press / drag / release handling,
its options panel and its overlay; a gesture (press to release) is one undo
step. The editor routes the left mouse button to the active tool; the right
and middle buttons always pan."""
from __future__ import annotations


MAX_CANVAS_RADIUS = 512.0  # canvas pixels: a brush zoomed far out still edits a bounded area (a dab of
#                            this radius takes about 60 ms to paint on this 2-core machine)


class Tool:
    """Base class. Positions are finest-level canvas pixels (floats)."""

    name = "tool"
    label = "Tool"
    key = ""          # shortcut letter
    tooltip = ""

    def __init__(self, ed):
        self.ed = ed

    def press(self, pos: tuple[float, float], screen: tuple[float, float]) -> None:
        pass

    def drag(self, pos: tuple[float, float], screen: tuple[float, float]) -> None:
        pass

    def release(self) -> None:
        pass

    def new_document(self) -> None:
        """Another document was opened: forget what belonged to the last one
        (messages, selections, drafts); the tool's own settings stay."""

    def options(self) -> None:
        """Tool options, drawn in the Tools panel."""

    def overlay(self, draw_list, p0, w: int, h: int) -> None:
        """Drawn over the canvas (cursor, handles)."""

    def keys(self) -> None:
        """Per-frame keyboard shortcuts while the tool is active."""

    def atlas_overlay(self, doc, n: int):
        """What "Show painted" (H) draws over a model while this tool is active:
        (key, a function making the n x n RGBA8 overlay), or None for the
        painted randomness (the default)."""
        return None

    def wheel(self, pos: tuple[float, float], amount: float) -> bool:
        """The mouse wheel over the canvas; True when the tool used it (else it zooms)."""
        return False


def begin_tool_window(ed, tool, title: str, size: tuple[float, float], image: tuple[int, int],
                      zoom_range: tuple[float, float], fmt: str) -> bool:
    """A tool's own zoomable image window (Paint exemplar, Lattice):
    placed at the top right on first use, closing it goes back to Navigate,
    a zoom slider (``tool.zoom``) and the image size on its first row. Returns
    whether its content is visible; call ``imgui.end()`` after it, always."""
    from imgui_bundle import imgui
    vp = imgui.get_main_viewport()
    imgui.set_next_window_size(size, imgui.Cond_.first_use_ever)
    imgui.set_next_window_pos((vp.work_pos.x + vp.work_size.x - size[0] - 24, vp.work_pos.y + 64),
                              imgui.Cond_.first_use_ever)
    opened, keep = imgui.begin(title, True)
    if not keep:
        ed.set_tool("navigate")
    if opened:
        imgui.set_next_item_width(160)
        _, tool.zoom = imgui.slider_float("Zoom", tool.zoom, zoom_range[0], zoom_range[1], fmt,
                                          imgui.SliderFlags_.logarithmic)
        imgui.same_line()
        imgui.text_disabled(f"{image[0]}x{image[1]} px")
    return opened


CANVAS_SPACE_TOOLS = ("paint-canvas", "feature", "labels", "direction")  # tools that work on the synthesized (rectified) canvas


def make_tools(ed) -> list[Tool]:
    from .direction import DirectionTool
    from .feature import FeatureTool
    from .labels import LabelTool
    from .lattice import LatticeTool
    from .navigate import NavigateTool
    from .paint import PaintCanvasTool, PaintExemplarTool
    return [NavigateTool(ed), PaintCanvasTool(ed), PaintExemplarTool(ed), FeatureTool(ed), LabelTool(ed),
            DirectionTool(ed), LatticeTool(ed)]
