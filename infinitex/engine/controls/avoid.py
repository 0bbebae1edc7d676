"""Avoided exemplar regions: an m x m mask the correction never copies from
while any other candidate is left (see the package docstring)."""
from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

import numpy as np

from .fields import ExemplarArray, dab_rect


@dataclass(frozen=True, eq=False)
class ExemplarMask(ExemplarArray):
    """Exemplar regions to avoid: uint8 (m, m), 1 = avoid, 0 = usable."""

    values: np.ndarray
    _salt = b"avoid"

    def __post_init__(self):
        v = np.asarray(self.values)
        if v.dtype != np.uint8 or v.ndim != 2 or v.shape[0] != v.shape[1] or v.shape[0] & (v.shape[0] - 1):
            raise ValueError(f"an avoid mask is a uint8 power-of-two square, not {v.dtype} {v.shape}")
        if v.max(initial=0) > 1:
            raise ValueError("an avoid mask holds 0 (usable) and 1 (avoid) only")
        object.__setattr__(self, "values", np.ascontiguousarray(v))

    @cached_property
    def empty(self) -> bool:
        return not bool(self.values.any())

    @cached_property
    def full(self) -> bool:
        """The whole exemplar avoided (refused: nothing would be left to copy)."""
        return bool(self.values.all())

    @cached_property
    def fraction(self) -> float:
        """The fraction of the exemplar avoided."""
        return float(self.values.mean())

    @classmethod
    def blank(cls, m: int) -> ExemplarMask:
        return cls(np.zeros((m, m), np.uint8))

    def painted(self, cx: float, cy: float, radius: float, avoid: bool = True) -> ExemplarMask:
        """A disc (exemplar pixels whose centers lie within ``radius`` of (cx, cy))
        marked avoided, or usable again; clipped at the exemplar's border."""
        m = self.size
        x0, y0, x1, y1 = dab_rect(cx, cy, radius)
        x0, y0, x1, y1 = max(0, x0), max(0, y0), min(m, x1), min(m, y1)
        if x0 >= x1 or y0 >= y1:
            return self
        ys, xs = np.mgrid[y0:y1, x0:x1]
        inside = np.hypot(xs + 0.5 - cx, ys + 0.5 - cy) <= max(radius, 0.5)
        if not inside.any():
            return self
        v = self.values.copy()
        v[y0:y1, x0:x1][inside] = 1 if avoid else 0
        return self if np.array_equal(v, self.values) else ExemplarMask(v)
