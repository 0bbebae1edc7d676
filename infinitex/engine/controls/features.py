"""Exemplar features placed on the canvas (LH05 4.3): :class:`Feature` and
its documented JSON form."""
from __future__ import annotations

from dataclasses import dataclass, replace

MAX_FEATURE_RADIUS = 2047   # finest-level pixels: keeps the integer geometry inside 32 bits
FEATURE_CELL = 256          # spatial index cell, finest-level pixels


@dataclass(frozen=True)
class Feature:
    """An exemplar feature placed on the canvas (LH05 4.3; ALGORITHM.md section 5).

    At each level l of its range, inside a circle around the canvas point
    whose radius goes from ``outer`` (first level) to ``inner`` (last level),
    the coordinates are overridden: ``S_l[p] = (u_F + h_l (p - p_F,l)) mod m``
    with ``p_F,l = floor(p_F / 2^(L-l))``. A pixel is inside when its center is
    within the radius, in 1/16 level pixels (integers). ``levels`` None is the
    default range, every level but the finest two (so the feature gets fresh
    detail); ``(0, L)`` is an exact copy. Later features win where they overlap.
    """

    exemplar: tuple[int, int]          # u_F, exemplar pixels
    canvas: tuple[int, int]            # p_F, finest-level canvas pixels
    inner: int                         # radius at the last level of the range, canvas pixels
    outer: int                         # radius at the first level
    levels: tuple[int, int] | None = None

    def validate(self, m: int, L: int) -> None:
        ux, uy = self.exemplar
        if not (0 <= ux < m and 0 <= uy < m):
            raise ValueError(f"A feature's exemplar point {self.exemplar} lies outside the {m}x{m} exemplar.")
        if not 0 <= self.inner <= self.outer <= MAX_FEATURE_RADIUS:
            raise ValueError(f"Feature radii must satisfy 0 <= inner <= outer <= {MAX_FEATURE_RADIUS}.")
        if self.levels is not None:
            a, b = self.levels
            if not 0 <= a <= b <= L:
                raise ValueError(f"A feature's levels must lie within 0..{L}, first <= last.")

    def level_range(self, L: int) -> tuple[int, int]:
        return self.levels if self.levels is not None else (0, max(0, L - 2))

    def radius_at(self, level: int, L: int) -> int:
        """The radius (canvas pixels) at ``level``: outer at the first level of
        the range, inner at the last, linear (floored) between."""
        a, b = self.level_range(L)
        return self.outer - ((self.outer - self.inner) * (level - a)) // max(1, b - a)

    def bbox(self) -> tuple[int, int, int, int]:
        """(x0, y0, x1, y1) finest-level pixels the feature can touch at any level."""
        x, y = self.canvas
        r = self.outer + 2
        return (x - r, y - r, x + r + 1, y + r + 1)

    def clamped(self, m: int, toroidal: bool) -> Feature:
        """On an exemplar that does not tile, the exemplar point moved inward so
        the copied disc does not wrap across the exemplar's border."""
        if toroidal:
            return self
        r = self.outer

        def c(v: int) -> int:
            return m // 2 if 2 * r + 1 >= m else min(max(v, r), m - 1 - r)
        u = (c(self.exemplar[0]), c(self.exemplar[1]))
        return self if u == self.exemplar else replace(self, exemplar=u)


MAX_FEATURES = 65536


def features_to_json(features) -> list:
    """The documented JSON form (project files and ``--features FILE.json``)."""
    return [{"exemplar": list(f.exemplar), "canvas": list(f.canvas), "radius": [f.inner, f.outer],
             "levels": None if f.levels is None else list(f.levels)} for f in features]


def features_from_json(data: object) -> tuple[Feature, ...]:
    """Parse a JSON list of features (untrusted); ValueError with a sentence."""
    if not isinstance(data, list) or len(data) > MAX_FEATURES:
        raise ValueError(f"Features must be a JSON list of at most {MAX_FEATURES} objects.")

    def ints(v, n, lo, hi, what, i):
        if (not isinstance(v, list) or len(v) != n
                or not all(isinstance(x, int) and not isinstance(x, bool) and lo <= x <= hi for x in v)):
            raise ValueError(f"Feature {i + 1}: \"{what}\" must be {n} integers from {lo} to {hi}.")
        return tuple(v)
    out = []
    limit = 2 ** 31 - 2 ** 24
    for i, d in enumerate(data):
        if not isinstance(d, dict):
            raise ValueError(f"Feature {i + 1} is not an object.")
        u = ints(d.get("exemplar"), 2, 0, 4095, "exemplar", i)
        p = ints(d.get("canvas"), 2, -limit, limit, "canvas", i)
        r = ints(d.get("radius"), 2, 0, MAX_FEATURE_RADIUS, "radius", i)
        if r[0] > r[1]:
            raise ValueError(f"Feature {i + 1}: the inner radius is larger than the outer one.")
        lv = d.get("levels")
        levels = None if lv is None else ints(lv, 2, 0, 12, "levels", i)
        if levels is not None and levels[0] > levels[1]:
            raise ValueError(f"Feature {i + 1}: \"levels\" must be [first, last] with first <= last.")
        out.append(Feature(u, p, r[0], r[1], levels))
    return tuple(out)


def fit_features(features, m: int) -> tuple[Feature, ...]:
    """Features for an m x m exemplar: exemplar points and levels clamped to it."""
    L = m.bit_length() - 1
    out = []
    for f in features:
        u = (min(f.exemplar[0], m - 1), min(f.exemplar[1], m - 1))
        lv = None if f.levels is None else (min(f.levels[0], L), min(f.levels[1], L))
        out.append(f if (u, lv) == (f.exemplar, f.levels) else replace(f, exemplar=u, levels=lv))
    return tuple(out)
