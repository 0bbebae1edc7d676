"""Canvas tools: each has its own module with press / drag / release handling,
its options panel and its overlay; a gesture (press to release) is one undo
step. The editor routes the left mouse button to the active tool; the right
and middle buttons always pan."""
from __future__ import annotations


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

    def options(self) -> None:
        """Tool options, drawn in the Tools panel."""

    def overlay(self, draw_list, p0, w: int, h: int) -> None:
        """Drawn over the canvas (cursor, handles)."""

    def keys(self) -> None:
        """Per-frame keyboard shortcuts while the tool is active."""

    def wheel(self, pos: tuple[float, float], amount: float) -> bool:
        """The mouse wheel over the canvas; True when the tool used it (else it zooms)."""
        return False


CANVAS_SPACE_TOOLS = ("paint-canvas", "feature")  # tools that work on the synthesized (rectified) canvas


def make_tools(ed) -> list[Tool]:
    from .feature import FeatureTool
    from .lattice import LatticeTool
    from .navigate import NavigateTool
    from .paint import PaintCanvasTool, PaintExemplarTool
    return [NavigateTool(ed), PaintCanvasTool(ed), PaintExemplarTool(ed), FeatureTool(ed), LatticeTool(ed)]
