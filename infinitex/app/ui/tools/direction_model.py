"""The Direction tool on a model (AtlasDomain.combed): comb, smooth, grow,
shrink and erase the texture's direction and size over the surface, with the
same brush as on the plane (tools/direction.py), ray-picked into the atlas.

The field is kept in the atlas' texels and read in the model's own frame (the
Model panel's direction): where it is combed, J = J_comb J_frame. A stroke's
heading is measured in that frame (the stroke's step in atlas texels through
the frame's J), so on every chart the texture runs the way the mouse went on
the surface. A stroke is one undo step; the texture is synthesized again as
the field changes, as when painting randomness on the model.
"""
from __future__ import annotations

import math
from dataclasses import replace

import numpy as np

from infinitex.engine.controls.direction import DirectionField
from infinitex.engine.controls.fields import FieldTooLarge, dab_rect
from infinitex.engine.surface.features import across_seams

from . import BrushGesture
from .direction import MAX_BRUSH
from .paint import dab_centers

LABELS = {"comb": "Comb direction (model)", "smooth": "Smooth direction (model)", "grow": "Grow texture (model)",
          "shrink": "Shrink texture (model)", "erase": "Erase direction (model)"}


class ModelComb(BrushGesture):
    """Press / drag / release of the Direction tool on the model view (its brush circle at the mouse)."""

    def __init__(self, ed):
        super().__init__(ed)
        self._last: tuple[float, float] | None = None
        self._group: object = None

    def heading(self, a: tuple[float, float], b: tuple[float, float]) -> float | None:
        """The direction (degrees, the frame's x towards its y) of the step a -> b in atlas texels."""
        atlas = self.ed.session.model.atlas
        if atlas is None:
            return None
        n = atlas.size
        x, y = min(n - 1, max(0, int(b[0]))), min(n - 1, max(0, int(b[1])))
        t = int(atlas.nearest_triangle(0)[y, x])
        if t < 0:
            return None
        j = atlas.jac[t].astype(np.float64)  # the frame's J there (not the combed one)
        dx, dy = b[0] - a[0], b[1] - a[1]
        vx, vy = j[0] * dx + j[1] * dy, j[2] * dx + j[3] * dy
        return math.degrees(math.atan2(vy, vx)) if vx or vy else None

    def press(self, mx: float, my: float, w: int, h: int) -> None:
        self._group, self._last = object(), None
        tool = self.ed.tool
        if tool.mode == "guide":
            tool.mode = "comb"  # (guides are drawn on the plane)
        if tool.mode != "comb":
            self.drag(mx, my, w, h)
        else:
            hit = self.ed.model.pick_atlas(mx, my, w, h)
            self._last = None if hit is None else hit[0]

    def drag(self, mx: float, my: float, w: int, h: int) -> None:
        if self._group is None:
            return
        hit = self.ed.model.pick_atlas(mx, my, w, h)
        if hit is None:
            self._last = None
            return
        pos, per_px = hit
        tool = self.ed.tool
        b = tool.brush
        r = min(MAX_BRUSH, max(1.0, b.radius * per_px if b.screen_units else b.radius))
        last = self._last
        if last is not None and (math.hypot(pos[0] - last[0], pos[1] - last[1]) > 4 * r
                                 or self.ed.model.chart_at(last) != self.ed.model.chart_at(pos)):
            last = None  # onto another chart: no dabs in between (the atlas between is elsewhere), no heading
        dabs = dab_centers(last, pos, 0.25 * r)
        if not dabs:
            return
        doc = self.ed.doc
        field = doc.direction or DirectionField()
        before = field
        prev = last
        rects = []
        try:
            atlas = self.ed.session.model.atlas
            for cx, cy in dabs:
                heading = self.heading(prev, (cx, cy)) if prev is not None and (cx, cy) != prev else None
                # The dab, and its continuation over the seams it reaches (the heading is the frame's:
                # the same on both sides).
                for x, y, rr in [(cx, cy, r)] + (across_seams(atlas, cx, cy, r) if atlas is not None else []):
                    field = tool.dab(field, x, y, heading, rr)
                    rects.append(dab_rect(x, y, rr))
                prev = (cx, cy)
        except FieldTooLarge as exc:
            self.ed.tell(str(exc))
            self.release()
            return
        self._last = dabs[-1]
        tool.dabs += len(dabs)
        if field is not before:
            self.ed.edit(replace(doc, direction=None if field.identity else field), LABELS[tool.mode],
                         group=self._group, region=rects)

    def release(self) -> None:
        if self._group is not None and self.ed.history is not None:
            self.ed.history.end_group()
        self._group, self._last = None, None

