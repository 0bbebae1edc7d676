"""What the canvas did in the last frame, and the pointer on it: one owner,
written through its methods by whichever canvas draws (the plane's,
canvas_refine.py and canvas_input.py; a model's, model_mode.py), read by the
status bar, the idle wait, the frame pacer and the tests."""
from __future__ import annotations

import numpy as np


class CanvasState:
    def __init__(self) -> None:
        self.refined = False       # what the canvas shows is complete (exact, or the whole model)
        self.update_ms = 0.0       # the last frame's synthesis time
        self.pixels = 0            # level pixels that synthesis made
        self.read_asked = False    # a test asks for the canvas as drawn (read_back)
        self.read_back: np.ndarray | None = None
        self.button = -1           # the mouse button that went down on the canvas (-1: none)
        self.cursor: tuple[float, float] | None = None  # the canvas point under the mouse, if over it

    def synthesized(self, update_ms: float, pixels: int = 0) -> None:
        """This frame's synthesis: its time and the level pixels it made."""
        self.update_ms, self.pixels = update_ms, pixels

    def set_refined(self, refined: bool) -> None:
        self.refined = bool(refined)

    def ask_read_back(self) -> None:
        """(Tests) the next frame reads the canvas back (``read_back``)."""
        self.read_asked = True

    def give_read_back(self, pixels: np.ndarray) -> None:
        self.read_back, self.read_asked = pixels, False

    def press(self, button: int) -> None:
        self.button = button

    def release(self) -> None:
        self.button = -1

    def point(self, at: tuple[float, float] | None) -> None:
        self.cursor = at
