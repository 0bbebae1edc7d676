"""Navigate: drag to pan (from where the button went down), wheel to zoom."""
from __future__ import annotations

from . import Tool


class NavigateTool(Tool):
    name = "navigate"
    label = "Navigate"
    key = "N"
    tooltip = "Drag to move around the infinite canvas; the wheel zooms (N)"
    panel = ""

    def __init__(self, ed):
        super().__init__(ed)
        self._last: tuple[float, float] | None = None

    def press(self, pos, screen) -> None:
        self._last = screen

    def drag(self, pos, screen) -> None:
        if self._last is not None:
            dx, dy = screen[0] - self._last[0], screen[1] - self._last[1]
            if dx or dy:
                self.ed.viewer.pan(dx, dy)
        self._last = screen

    def release(self) -> None:
        self._last = None
