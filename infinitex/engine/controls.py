"""User controls of the synthesis: the one engine input built from a document.

Everything an artist paints, places or marks reaches the synthesis passes
through a :class:`Controls` value (immutable): today the two randomness fields
of LH05 section 4.2 (ALGORITHM.md section 5), placed features (4.3) and the
lattice of a near-regular texture (4.5, :mod:`engine.lattice`). The pyramid asks it, per strip and level, for what the passes read.

**Randomness fields** modulate the jitter: ``J_l(p) = floor(h H(p) r_l M_l(p) + 1/2)``
with the effective ``r_l M_l(p)`` clamped to [0, 1]. Field values are uint16 in
1/32768ths: 0 = calm (no jitter), 32768 = neutral, 65535 = almost 2 (rough).

- :class:`ExemplarField` (over the exemplar, m x m): ``M_l(p) = R_E,l[S_l(p)]``
  where ``S_l(p)`` is the upsampled coordinate before jitter and ``R_E,l`` the
  min-mipmap (a level-l texel covers h_l x h_l exemplar pixels and takes their
  minimum, so a protected feature stays protected at every scale).
- :class:`CanvasField` (over the infinite canvas, finest-level pixels, sparse
  64 x 64 tiles; unpainted = neutral): ``M_l(p) = R_S,l[p]``, mipmapped toward
  neutral: a level-l pixel (covering h_l x h_l canvas pixels) takes the value
  closest to neutral that its whole footprint agrees on (the largest of an
  all-calm footprint, the smallest of an all-rough one, else neutral). Paint
  thus acts on the features that fit inside the painted area: a small dab
  changes fine detail, a large area calms or roughens large features too, and
  no dab re-rolls the big features around it (LH05's mean mipmap would). With
  a toroidal period n, the field is read at ``p mod n_l``.

Both multiply: ``t = (E * C + 2^14) >> 15``, ``r'_q = min(1024, (r_q t + 2^14) >> 15)``,
so a neutral field gives exactly the unmodulated jitter.

**Avoided exemplar regions** (:class:`ExemplarMask`, m x m, 1 = avoid): a
blemish, a logo, or one distinctive element that would recur once per
exemplar area. Correction never picks a candidate inside the mask while any
candidate outside it is left (its cost is above every real cost), and the
search adds TBN10's random walk so that a pixel deep inside the region still
finds a way out; coordinates the jitter puts there are corrected away on the
corrected levels.
"""
from __future__ import annotations

from dataclasses import dataclass, field, replace
from functools import cached_property

import numpy as np

from .lattice import Lattice

NEUTRAL = 32768
TILE = 64  # canvas field tile side, finest-level pixels


def reduce_toward_neutral(a: np.ndarray) -> np.ndarray:
    """One canvas-field mip step (2x2 -> 1): the value closest to neutral that
    all four agree on: the largest if all are calm (below neutral), the
    smallest if all are rough (above), else neutral. Repeated, a level-l pixel
    gets the value closest to neutral over its whole footprint, so paint acts
    on the features that fit inside the painted area and never re-rolls the
    larger features around a small dab."""
    q = [a[0::2, 0::2], a[1::2, 0::2], a[0::2, 1::2], a[1::2, 1::2]]
    lo = np.minimum(np.minimum(q[0], q[1]), np.minimum(q[2], q[3]))
    hi = np.maximum(np.maximum(q[0], q[1]), np.maximum(q[2], q[3]))
    return np.where(hi < NEUTRAL, hi, np.where(lo > NEUTRAL, lo, NEUTRAL)).astype(np.uint16)


def modulated_rq(rq: int | np.ndarray, e: int | np.ndarray, c: int | np.ndarray) -> np.ndarray:
    """The effective r_l in 1024ths for field values e (exemplar) and c (canvas)."""
    t = (np.asarray(e, dtype=np.int64) * np.asarray(c, dtype=np.int64) + (1 << 14)) >> 15
    return np.minimum(1024, (np.asarray(rq, dtype=np.int64) * t + (1 << 14)) >> 15)


def _u16(a: np.ndarray) -> np.ndarray:
    a = np.asarray(a)
    if a.dtype != np.uint16:
        raise ValueError("randomness fields are uint16 (1/32768ths)")
    return np.ascontiguousarray(a)


def dab_weights(cx: float, cy: float, radius: float, hardness: float, x0: int, y0: int, w: int, h: int) -> np.ndarray:
    """Brush coverage in [0, 1] over pixels [x0, x0+w) x [y0, y0+h) (pixel centers):
    1 inside ``hardness * radius``, then a smooth falloff to 0 at ``radius``."""
    ys, xs = np.mgrid[y0:y0 + h, x0:x0 + w]
    d = np.hypot(xs + 0.5 - cx, ys + 0.5 - cy) / max(radius, 1e-6)
    inner = min(max(hardness, 0.0), 0.999)
    t = np.clip((d - inner) / (1.0 - inner), 0.0, 1.0)
    return np.where(d >= 1.0, 0.0, 1.0 - t * t * (3.0 - 2.0 * t))


def apply_dab(old: np.ndarray, weights: np.ndarray, value: int, strength: float) -> np.ndarray:
    """old + (value - old) * strength * weights, rounded, as uint16."""
    a = np.clip(strength, 0.0, 1.0) * weights
    new = old.astype(np.float64) + (float(value) - old) * a
    return np.clip(np.rint(new), 0, 65535).astype(np.uint16)


def dab_rect(cx: float, cy: float, radius: float) -> tuple[int, int, int, int]:
    """(x0, y0, x1, y1): the pixels a dab can touch."""
    return (int(np.floor(cx - radius)), int(np.floor(cy - radius)),
            int(np.ceil(cx + radius)) + 1, int(np.ceil(cy + radius)) + 1)


class _ExemplarArray:
    """An m x m array over the exemplar (``values``), compared by content:
    what ExemplarField and ExemplarMask share."""

    values: np.ndarray
    _salt = b""

    @property
    def size(self) -> int:
        return int(self.values.shape[0])

    @cached_property
    def key(self) -> str:
        import hashlib
        return hashlib.sha256(self._salt + self.values.tobytes() + repr(self.values.shape).encode()).hexdigest()

    def __eq__(self, other):
        return type(other) is type(self) and self.key == other.key

    def __hash__(self):
        return hash(self.key)

    def scaled(self, m: int):
        """The same for an m x m exemplar (nearest)."""
        if m == self.size:
            return self
        idx = (np.arange(m) * self.size) // m
        return type(self)(np.ascontiguousarray(self.values[idx[:, None], idx[None, :]]))


@dataclass(frozen=True, eq=False)
class ExemplarField(_ExemplarArray):
    """Randomness over the exemplar: uint16 (m, m), 32768 = neutral."""

    values: np.ndarray

    def __post_init__(self):
        v = _u16(self.values)
        if v.ndim != 2 or v.shape[0] != v.shape[1] or v.shape[0] & (v.shape[0] - 1):
            raise ValueError(f"an exemplar randomness field is a power-of-two square, not {v.shape}")
        object.__setattr__(self, "values", v)

    @cached_property
    def mips(self) -> list[np.ndarray]:
        """mips[k]: the min-mipmap reduced k times ((m >> k) square)."""
        out = [self.values]
        while out[-1].shape[0] > 1:
            a = out[-1]
            out.append(np.minimum(np.minimum(a[0::2, 0::2], a[1::2, 0::2]),
                                  np.minimum(a[0::2, 1::2], a[1::2, 1::2])))
        return out

    def level(self, L: int, level: int) -> np.ndarray:
        """R_E,l: the field seen by level ``level`` of an exemplar with finest level L."""
        return self.mips[L - level]

    @cached_property
    def neutral(self) -> bool:
        return bool(np.all(self.values == NEUTRAL))

    @classmethod
    def blank(cls, m: int) -> ExemplarField:
        return cls(np.full((m, m), NEUTRAL, np.uint16))

    def painted(self, cx: float, cy: float, radius: float, value: int, strength: float = 1.0,
                hardness: float = 0.5) -> ExemplarField:
        """A dab (exemplar pixels; clipped at the exemplar's border)."""
        m = self.size
        x0, y0, x1, y1 = dab_rect(cx, cy, radius)
        x0, y0, x1, y1 = max(0, x0), max(0, y0), min(m, x1), min(m, y1)
        if x0 >= x1 or y0 >= y1:
            return self
        v = self.values.copy()
        wts = dab_weights(cx, cy, radius, hardness, x0, y0, x1 - x0, y1 - y0)
        v[y0:y1, x0:x1] = apply_dab(v[y0:y1, x0:x1], wts, value, strength)
        return ExemplarField(v)


@dataclass(frozen=True, eq=False)
class ExemplarMask(_ExemplarArray):
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


@dataclass(frozen=True, eq=False)
class CanvasField:
    """Randomness over the canvas: sparse uint16 TILE x TILE tiles keyed by
    tile index (tx, ty) (pixels [tx*TILE, (tx+1)*TILE)); absent tiles are neutral."""

    tiles: dict = field(default_factory=dict)

    def __post_init__(self):
        clean = {}
        for (tx, ty), t in self.tiles.items():
            t = _u16(t)
            if t.shape != (TILE, TILE):
                raise ValueError(f"canvas field tiles are {TILE}x{TILE}, not {t.shape}")
            if not np.all(t == NEUTRAL):
                clean[(int(tx), int(ty))] = t
        object.__setattr__(self, "tiles", clean)

    @classmethod
    def from_image(cls, values: np.ndarray, x: int, y: int) -> CanvasField:
        """A painted region (uint16 H x W) placed with its top-left at canvas (x, y)."""
        values = _u16(values)
        h, w = values.shape
        tiles = {}
        for ty in range(y // TILE, (y + h - 1) // TILE + 1):
            for tx in range(x // TILE, (x + w - 1) // TILE + 1):
                t = np.full((TILE, TILE), NEUTRAL, np.uint16)
                x0, y0 = tx * TILE, ty * TILE
                ix0, iy0 = max(x0, x), max(y0, y)
                ix1, iy1 = min(x0 + TILE, x + w), min(y0 + TILE, y + h)
                t[iy0 - y0:iy1 - y0, ix0 - x0:ix1 - x0] = values[iy0 - y:iy1 - y, ix0 - x:ix1 - x]
                tiles[(tx, ty)] = t
        return cls(tiles)

    def painted(self, cx: float, cy: float, radius: float, value: int, strength: float = 1.0,
                hardness: float = 0.5) -> tuple[CanvasField, "tuple[int, int, int, int]"]:
        """A dab (finest-level canvas pixels): the new field, sharing every
        untouched tile with this one, and the rectangle (x0, y0, x1, y1) it changed."""
        x0, y0, x1, y1 = dab_rect(cx, cy, radius)
        tiles = dict(self.tiles)
        for ty in range(y0 // TILE, (y1 - 1) // TILE + 1):
            for tx in range(x0 // TILE, (x1 - 1) // TILE + 1):
                old = tiles.get((tx, ty))
                base = old if old is not None else np.full((TILE, TILE), NEUTRAL, np.uint16)
                wts = dab_weights(cx, cy, radius, hardness, tx * TILE, ty * TILE, TILE, TILE)
                if not wts.any():
                    continue
                tiles[(tx, ty)] = apply_dab(base, wts, value, strength)
        return CanvasField(tiles), (x0, y0, x1, y1)

    def changed_rects(self, other: CanvasField) -> list:
        """(x0, y0, x1, y1) per tile: the box of the pixels that differ between two fields."""
        out = []
        for k in set(self.tiles) | set(other.tiles):
            a, b = self.tiles.get(k), other.tiles.get(k)
            if a is b:
                continue
            a = a if a is not None else np.full((TILE, TILE), NEUTRAL, np.uint16)
            b = b if b is not None else np.full((TILE, TILE), NEUTRAL, np.uint16)
            ys, xs = np.nonzero(a != b)
            if len(xs):  # the bounding box of the pixels that differ
                x0, y0 = k[0] * TILE, k[1] * TILE
                out.append((x0 + int(xs.min()), y0 + int(ys.min()), x0 + int(xs.max()) + 1, y0 + int(ys.max()) + 1))
        return out

    @cached_property
    def key(self) -> str:
        import hashlib
        hsh = hashlib.sha256()
        for k in sorted(self.tiles):
            hsh.update(repr(k).encode())
            hsh.update(self.tiles[k].tobytes())
        return hsh.hexdigest()

    def __eq__(self, other):
        return isinstance(other, CanvasField) and self.key == other.key

    def __hash__(self):
        return hash(self.key)

    @property
    def neutral(self) -> bool:
        return not self.tiles

    def _mip_tiles(self, k: int) -> dict:
        """Tiles of the field reduced k times (reduce_toward_neutral), same tile size."""
        cache = self.__dict__.setdefault("_mips", {0: self.tiles})
        if k in cache:
            return cache[k]
        finer = self._mip_tiles(k - 1)
        out: dict = {}
        parents = {(tx >> 1, ty >> 1) for tx, ty in finer}
        for px, py in parents:
            big = np.full((2 * TILE, 2 * TILE), NEUTRAL, np.uint16)
            for dy in (0, 1):
                for dx in (0, 1):
                    t = finer.get((2 * px + dx, 2 * py + dy))
                    if t is not None:
                        big[dy * TILE:(dy + 1) * TILE, dx * TILE:(dx + 1) * TILE] = t
            out[(px, py)] = reduce_toward_neutral(big)
        cache[k] = out
        return out

    def region(self, k: int, x0: int, y0: int, w: int, h: int, period: int = 0) -> np.ndarray | None:
        """The field reduced k times over [x0, x0+w) x [y0, y0+h) (level pixels),
        uint16 (h, w); None when no painted tile touches it. With ``period`` n
        (a level period), pixel p reads the field at p mod n."""
        tiles = self._mip_tiles(k) if self.tiles else {}
        if not tiles:
            return None
        if period:
            ys = np.arange(y0, y0 + h) & (period - 1)
            xs = np.arange(x0, x0 + w) & (period - 1)
            base = self.region(k, 0, 0, period, period)
            return None if base is None else np.ascontiguousarray(base[ys[:, None], xs[None, :]])
        out = None
        for ty in range(y0 // TILE, (y0 + h - 1) // TILE + 1):
            for tx in range(x0 // TILE, (x0 + w - 1) // TILE + 1):
                t = tiles.get((tx, ty))
                if t is None:
                    continue
                if out is None:
                    out = np.full((h, w), NEUTRAL, np.uint16)
                ix0, iy0 = max(tx * TILE, x0), max(ty * TILE, y0)
                ix1, iy1 = min((tx + 1) * TILE, x0 + w), min((ty + 1) * TILE, y0 + h)
                out[iy0 - y0:iy1 - y0, ix0 - x0:ix1 - x0] = t[iy0 - ty * TILE:iy1 - ty * TILE,
                                                            ix0 - tx * TILE:ix1 - tx * TILE]
        return out


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


@dataclass(frozen=True)
class Controls:
    """Everything painted or placed by the user that the passes read."""

    randomness_exemplar: ExemplarField | None = None
    randomness_canvas: CanvasField | None = None
    features: tuple[Feature, ...] = ()
    lattice: Lattice | None = None  # near-regular mode: the exemplar is this lattice's rectified block
    avoid: ExemplarMask | None = None  # exemplar regions the correction does not copy

    def normalized(self) -> Controls:
        """Neutral fields and empty masks dropped (they change nothing), so equal effects compare equal."""
        e = self.randomness_exemplar
        c = self.randomness_canvas
        a = self.avoid
        return Controls(None if e is None or e.neutral else e, None if c is None or c.neutral else c,
                        tuple(self.features), self.lattice, None if a is None or a.empty else a)

    def exemplar_inputs(self) -> tuple:
        """What is painted over the exemplar (randomness field, avoid mask): a
        change of either reaches the whole canvas."""
        return (self.randomness_exemplar, self.avoid)

    def lattice_shift(self, m: int, level: int) -> tuple[int, int] | None:
        """(log2 cx, log2 cy) when ``level`` is a lattice level: jitter is
        quantized to whole cells and the lattice similarity sets are used."""
        return None if self.lattice is None else self.lattice.quant_shift(m, level)

    def validate(self, m: int, lattice_grid: tuple[int, int] | None = None) -> None:
        """Raise ValueError if these controls cannot drive an m x m exemplar
        analyzed with ``lattice_grid`` (the analysis' (nx, ny); None: unchecked)."""
        if self.lattice is not None and lattice_grid is not None \
                and (self.lattice.nx, self.lattice.ny) != tuple(lattice_grid):
            raise ValueError(f"The lattice has {self.lattice.nx}x{self.lattice.ny} cells but the exemplar was "
                             f"analyzed for {lattice_grid[0]}x{lattice_grid[1]}.")
        e = self.randomness_exemplar
        if e is not None and e.size != m:
            raise ValueError(f"The exemplar randomness field is {e.size}x{e.size}; the exemplar is {m}x{m}.")
        a = self.avoid
        if a is not None and a.size != m:
            raise ValueError(f"The avoid mask is {a.size}x{a.size}; the exemplar is {m}x{m}.")
        if a is not None and a.full:
            raise ValueError("The avoid mask covers the whole exemplar: leave some of it usable.")
        L = m.bit_length() - 1
        for f in self.features:
            f.validate(m, L)

    @cached_property
    def features_key(self) -> str:
        import hashlib
        return hashlib.sha256(repr(self.features).encode()).hexdigest()

    def level_signature(self, level: int, m: int = 0) -> tuple:
        """What level ``level`` reads of the controls (fields change all levels)."""
        e, c = self.randomness_exemplar, self.randomness_canvas
        return (None if e is None else e.key, None if c is None else c.key,
                self.features_key if self.features else None,
                None if self.lattice is None else (self.lattice.nx, self.lattice.ny, self.lattice_shift(m, level)),
                None if self.avoid is None else self.avoid.key)

    @cached_property
    def _feature_index(self) -> dict:
        """Spatial index: FEATURE_CELL-sized canvas cells -> feature indices."""
        index: dict = {}
        for i, f in enumerate(self.features):
            x0, y0, x1, y1 = f.bbox()
            for cy in range(y0 // FEATURE_CELL, (y1 - 1) // FEATURE_CELL + 1):
                for cx in range(x0 // FEATURE_CELL, (x1 - 1) // FEATURE_CELL + 1):
                    index.setdefault((cx, cy), []).append(i)
        return index

    def features_in(self, x0: int, y0: int, x1: int, y1: int) -> list[int]:
        """Indices (in order) of the features whose reach meets a finest-level rectangle."""
        if not self.features:
            return []
        index = self._feature_index
        cells = ((x1 - 1) // FEATURE_CELL - x0 // FEATURE_CELL + 1) * ((y1 - 1) // FEATURE_CELL - y0 // FEATURE_CELL + 1)
        if cells > len(index):
            found = {i for lst in index.values() for i in lst}
        else:
            found = set()
            for cy in range(y0 // FEATURE_CELL, (y1 - 1) // FEATURE_CELL + 1):
                for cx in range(x0 // FEATURE_CELL, (x1 - 1) // FEATURE_CELL + 1):
                    found.update(index.get((cx, cy), ()))
        out = []
        for i in sorted(found):
            fx0, fy0, fx1, fy1 = self.features[i].bbox()
            if fx0 < x1 and x0 < fx1 and fy0 < y1 and y0 < fy1:
                out.append(i)
        return out

    def feature_table(self, level: int, L: int, m: int, toroidal: bool, x0: int, y0: int, x1: int, y1: int,
                      period: int = 0) -> np.ndarray | None:
        """The features active at ``level`` over a level-pixel rectangle, as the
        int32 (N, 2, 4) table the passes read: (p_F,l x, y, frac x + 16 frac y,
        radius in 1/16 level pixels), (u_F x, y, 0, 0); None when there are none.
        With a period (a toroidal tile) every feature applies, modulo the tile."""
        k = L - level
        rows = []
        found = range(len(self.features)) if period else self.features_in(x0 << k, y0 << k, x1 << k, y1 << k)
        for i in found:
            f = self.features[i]
            a, b = f.level_range(L)
            if not a <= level <= b:
                continue
            f = f.clamped(m, toroidal)
            r16 = (f.radius_at(level, L) << 4) >> k
            px, py = f.canvas
            fx, fy = ((px << 4) >> k) & 15, ((py << 4) >> k) & 15
            rows.append([[px >> k, py >> k, fx + 16 * fy, r16], [f.exemplar[0], f.exemplar[1], 0, 0]])
        return np.asarray(rows, dtype=np.int32) if rows else None

    def changed_rects(self, other: Controls) -> list | None:
        """Finest-level rectangles outside which ``other`` reads the same as this
        one; None when the change reaches everywhere (the exemplar field, the avoid mask)."""
        if self.exemplar_inputs() != other.exemplar_inputs() or self.lattice != other.lattice:
            return None
        before = self.randomness_canvas or CanvasField()
        after = other.randomness_canvas or CanvasField()
        out = before.changed_rects(after)
        if self.features != other.features:
            old, new = set(self.features), set(other.features)
            out += [f.bbox() for f in old ^ new]  # added, removed, moved or resized
            # Which feature wins an overlap follows the list order: features whose
            # relative order changed are changes too.
            ka = [f for f in self.features if f in new]
            kb = [f for f in other.features if f in old]
            out += [f.bbox() for x, y in zip(ka, kb) if x != y for f in (x, y)]
        return out


NO_CONTROLS = Controls()
