"""Exemplar features placed on the canvas (LH05 4.4): :class:`Feature` and
its documented JSON form."""
from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

MAX_FEATURE_RADIUS = 2047   # finest-level pixels: keeps the integer geometry inside 32 bits
FEATURE_CELL = 256          # (no longer used: the features are found by their arrays, see feature_arrays)
BIN_SHIFT = 2               # the shader's cells: 4 x 4 level pixels at first (coarser if the lists get too long)
MAX_BIN_ENTRIES = 1 << 21   # entries of the cells' feature lists per strip (then the cells grow)
MAX_BIN_CELLS = 1 << 20     # cells per strip (a large tile's strip gets larger cells)
TABLE_ROW = 512             # features per row of the table texture (2 texels each)
ENTRY_ROW = 4096            # entries per row of the cell lists' texture


@dataclass(frozen=True)
class Feature:
    """An exemplar feature placed on the canvas (LH05 4.4; docs/algorithm.md section 5).

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


def rescaled_features(features, factor: float) -> tuple[Feature, ...]:
    """Features placed on a model's atlas (engine/surface/features.py), for its
    texture at ``factor`` times the size: the centres keep their place on the
    surface; the radii are exemplar pixels and stay."""
    return tuple(replace(f, canvas=(int(np.floor((f.canvas[0] + 0.5) * factor)),
                                    int(np.floor((f.canvas[1] + 0.5) * factor)))) for f in features)


def level_values(f: np.ndarray, level: int, L: int, m: int, toroidal: bool):
    """For feature_arrays rows ``f`` at ``level``: which are active there
    (Feature.level_range), their radius (radius_at) and exemplar point
    (clamped), computed on arrays for all at once."""
    first = np.where(f[:, 8] == 1, f[:, 4], 0)
    last = np.where(f[:, 8] == 1, f[:, 5], max(0, L - 2))
    inner, outer = f[:, 2], f[:, 3]
    radius = outer - ((outer - inner) * (level - first)) // np.maximum(1, last - first)
    u = f[:, 6:8]
    if not toroidal:  # the copied disc does not wrap across the exemplar's border
        r = outer[:, None]
        u = np.where(2 * r + 1 >= m, m // 2, np.minimum(np.maximum(u, r), m - 1 - r))
    return (first <= level) & (level <= last), radius, u


def feature_arrays(features) -> np.ndarray:
    """int64 (N, 9): canvas x, y, inner, outer, first and last level, exemplar
    x, y, and 1 if the levels are given (0: the default range) of each feature, in order."""
    return np.array([(*f.canvas, f.inner, f.outer, *(f.levels or (0, 0)), *f.exemplar, f.levels is not None)
                     for f in features], dtype=np.int64).reshape(-1, 9)


def _intervals(p: np.ndarray, lim: np.ndarray, origin: int, size: int, shift: int, period: int):
    """Per feature, the cells (first, last; two intervals, the second possibly
    empty) along one axis whose pixels g may satisfy |g - p| <= lim (with a
    period: the offset wrapped as the shader wraps it, and g taken mod period)."""
    n = max(1, -(-size // (1 << shift)))
    if not period:
        a, b = p - lim - origin, p + lim - origin
        return [((np.clip(a >> shift, 0, n - 1), np.minimum(b >> shift, n - 1)), (b >= 0) & (a < size))], n
    q = (p - lim) & (period - 1)
    whole = 2 * lim + 1 >= period
    end = q + 2 * lim
    first = (np.where(whole, 0, q >> shift), np.where(whole | (end >= period), n - 1, end >> shift))
    second = (np.zeros_like(q), (end - period) >> shift)
    return [(first, np.ones(len(p), bool)), (second, ~whole & (end >= period))], n


def feature_bins(table: np.ndarray, x0: int, y0: int, w: int, h: int, period: int = 0):
    """The cells of the shader's feature lookup over a strip of level pixels
    [x0, x0+w) x [y0, y0+h) (with a period: over the period, the pixels taken
    mod period): per cell, the rows of ``table`` (feature_table's) whose reach
    (the shader's ``|d| <= r/16 + 2`` square) meets it, in table order, so a
    pixel tests only the features that can touch it (later features still
    win). Returns (cells int32 (ny, nx, 2): first entry and count; entries
    int32 (E,); origin (x, y); shift: a cell is 2^shift level pixels)."""
    p = table[:, 0, :2].astype(np.int64)
    lim = (table[:, 0, 3].astype(np.int64) >> 4) + 2
    return reach_bins(p, lim, len(table), x0, y0, w, h, period)


def reach_bins(p: np.ndarray, lim: np.ndarray, rows: int, x0: int, y0: int, w: int, h: int, period: int = 0):
    """feature_bins for rows centred at level pixels ``p`` reaching ``lim``
    level pixels around them (the shader's square): (cells, entries, origin, shift)."""
    ox, oy = (0, 0) if period else (x0, y0)
    sw, sh = (period, period) if period else (w, h)
    shift = min(BIN_SHIFT, 30)  # GLSL shifts stay below 32
    while True:
        xs, nx = _intervals(p[:, 0], lim, ox, sw, shift, period)
        ys, ny = _intervals(p[:, 1], lim, oy, sh, shift, period)
        if nx * ny > MAX_BIN_CELLS and shift < 30:
            shift += 1
            continue
        rects = []
        for (xa, xb), xok in xs:
            for (ya, yb), yok in ys:
                ok = xok & yok & (xa <= xb) & (ya <= yb)
                idx = np.flatnonzero(ok)
                rects.append((idx, xa[idx], xb[idx], ya[idx], yb[idx]))
        total = sum(int(((xb - xa + 1) * (yb - ya + 1)).sum()) for _, xa, xb, ya, yb in rects)
        if total <= max(MAX_BIN_ENTRIES, 4 * rows) or nx * ny == 1 or shift >= 30:
            break
        shift += 1
    row, xa, xb, ya, yb = (np.concatenate(a) for a in zip(*rects))
    cw = xb - xa + 1
    count = cw * (yb - ya + 1)
    owner = np.repeat(np.arange(len(row)), count)
    local = np.arange(int(count.sum())) - np.repeat(np.cumsum(count) - count, count)
    cell = (ya[owner] + local // cw[owner]) * nx + xa[owner] + local % cw[owner]
    key = np.sort(cell * rows + row[owner])  # by cell, then table order
    key = key[np.r_[True, key[1:] != key[:-1]]] if len(key) else key  # a cell meets a period's copies once
    cell, entries = key // rows, (key % rows).astype(np.int32)
    counts = np.bincount(cell, minlength=nx * ny)
    cells = np.stack([np.cumsum(counts) - counts, counts], axis=-1).astype(np.int32).reshape(ny, nx, 2)
    return cells, entries, (ox, oy), shift


def pack_rows(a: np.ndarray, per_row: int) -> np.ndarray:
    """A list of items (N, ...) as rows of ``per_row`` items, zero-padded: a texture's layout."""
    rows = max(1, -(-len(a) // per_row))
    out = np.zeros((rows * per_row, *a.shape[1:]), dtype=a.dtype)
    out[:len(a)] = a
    return out.reshape(rows, per_row, *a.shape[1:])
