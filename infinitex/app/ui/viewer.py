"""Where the canvas looks and how it draws the texture: the one owner of the
editor's :class:`View` (centre and zoom) and :class:`Display` (mode, level,
map, light, magnification, geometry). Both are immutable values saved with a
project; every change goes through a method here, whoever asks for it (a
tool's pan, the zoom keys, the View menu, the Display panel, a document
opened)."""
from __future__ import annotations

import math
from dataclasses import replace

from infinitex.project import Display, View


class Viewer:
    def __init__(self) -> None:
        self.view = View()
        self.display = Display()
        self.tile_mode = False    # the canvas shows the periodic texture of the tile size
        # Randomness fields drawn as heat maps: off until a paint tool is chosen
        # (the texture itself is what an artist looks at first); H toggles it.
        self.show_fields = False

    # -- the view ---------------------------------------------------------------

    def show(self, view: View | None = None, display: Display | None = None) -> None:
        """A document's own view and display (a new one: the defaults)."""
        self.view = view if view is not None else View()
        self.display = display if display is not None else Display()

    def pan(self, dx_screen: float, dy_screen: float) -> None:
        """Move the canvas by screen pixels (it follows the mouse)."""
        self.view = self.view.panned(dx_screen, dy_screen)

    def zoom_at(self, factor: float, sx: float, sy: float, w: int, h: int) -> None:
        """Zoom by ``factor`` keeping the canvas point under screen (sx, sy) of a w x h canvas."""
        self.view = self.view.zoom_at(factor, sx, sy, w, h)

    def zoom_to(self, zoom: float) -> None:
        """This zoom (screen pixels per canvas pixel), the centre kept."""
        self.view = replace(self.view, zoom=zoom).clamped()

    def fit(self, size: int, w: int, h: int) -> None:
        """A power-of-two zoom that fits ``size`` canvas pixels (an exemplar) across a w x h canvas."""
        self.zoom_to(2.0 ** math.floor(math.log2(max(1e-3, min(w, h) / size))))

    def center(self, x: float, y: float) -> None:
        """Centre the canvas on canvas point (x, y), the zoom kept."""
        self.view = View(float(x), float(y), self.view.zoom).clamped()

    # -- the display ------------------------------------------------------------

    def show_tile(self, on: bool) -> None:
        """Tile mode: the canvas shows the seamless tile's periodic texture (T)."""
        self.tile_mode = bool(on)

    def show_painted(self, on: bool) -> None:
        """What is painted (randomness, labels, direction...) over the texture (H)."""
        self.show_fields = bool(on)

    def set_display(self, **changes) -> None:
        """Change how the canvas draws (``Display``'s fields by name)."""
        self.display = replace(self.display, **changes)
