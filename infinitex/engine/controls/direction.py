"""Direction and scale fields (LH06 section 5, anisometric synthesis): the
texture turns, grows and stretches locally, following a field painted over the
infinite canvas.

**The field** is a 2x2 Jacobian per finest-level canvas pixel, ``J``, mapping an
offset on the canvas to the exemplar offset that shows there (``J = I``: the
exemplar as it is). It is built from what an artist sets: the direction
``theta`` (degrees, from +x towards +y, so clockwise on screen) along which the
exemplar's +x axis runs, a scale ``s`` (the texture shows ``s`` times larger)
and an aspect ``a`` (stretched ``a`` times along the direction, ``1/a`` across):
``A = R(theta) diag(s a, s / a)`` maps exemplar offsets to canvas offsets and
``J = A^-1``. Stored in Q12 (4096 = 1) as int16 (j00, j01, j10, j11), in sparse
TILE x TILE tiles (absent: identity). Stretches ``s a`` and ``s / a`` are kept
within [MIN_STRETCH, MAX_STRETCH], so every entry fits int16 and det J > 0.

**Levels**: a level-l pixel covers 2^k x 2^k canvas pixels (k = L - l) and takes
the mean of its four children, each entry ``floor(sum / 4)``, repeated k times
(a box mipmap with the floor at every step: exact integers, the same in numpy
and in the oracle); where the mean's determinant falls below MIN_DET (opposite
directions cancel), it takes its top-left child instead. A toroidal tile of n
px sees the field inside [0, n)^2 repeated with period n.

**Coordinates with a field** carry a sub-pixel part (engine/fixed.py
``FRAC_ONE``): a state texel holds the nearest exemplar texel (x, y) and the
signed remainder in 1/256 px in [-128, 128). Without a field the remainder is
always 0 and every pass is the one without fields (identity field = no field,
bit for bit). The passes' formulas are in the shaders' headers.
"""
from __future__ import annotations

import weakref
from dataclasses import dataclass, field
from functools import cached_property

import numpy as np

from .fields import (
    TILE,
    FieldTooLarge,
    dab_rect,
    dab_weights,
    mip_parents,
    rescaled_pixels,
    tile_changes,
    tiles_key,
    tiles_region,
    tiles_within,
)

J_ONE = 4096  # Q12
MAX_DIRECTION_TILES = 16384  # a field covers at most this many tiles (an 8192 x 8192 px area; 512 MB of J)
IDENTITY = np.array([J_ONE, 0, 0, J_ONE], np.int16)
MIN_STRETCH = 0.25
MAX_STRETCH = 4.0


def _identity_tile() -> np.ndarray:
    return np.broadcast_to(IDENTITY, (TILE, TILE, 4)).copy()


def clamp_stretch(J: np.ndarray, lo: float, hi: float) -> tuple[np.ndarray, np.ndarray]:
    """2x2 matrices (n, 4) with their singular values held within [lo, hi]
    (J V diag(s'/s) V^T), and which were changed; closed-form, elementwise."""
    a = J[:, 0] ** 2 + J[:, 2] ** 2  # J^T J = [[a, b], [b, c]]
    b = J[:, 0] * J[:, 1] + J[:, 2] * J[:, 3]
    c = J[:, 1] ** 2 + J[:, 3] ** 2
    half, mid = 0.5 * (a - c), 0.5 * (a + c)
    r = np.sqrt(half * half + b * b)
    l1, l2 = mid + r, np.maximum(mid - r, 0.0)
    s1, s2 = np.sqrt(l1), np.sqrt(l2)
    changed = (s1 > hi) | (s2 < lo)
    if not changed.any():
        return J, changed
    # The eigenvector of l1: (b, l1 - a), or (l1 - c, b), whichever is longer; the other is its normal.
    va = np.stack([b, l1 - a], -1)
    vb = np.stack([l1 - c, b], -1)
    v = np.where((np.abs(va).sum(-1) >= np.abs(vb).sum(-1))[:, None], va, vb)
    length = np.sqrt((v * v).sum(-1))
    v = np.where(length[:, None] > 0, v / np.where(length > 0, length, 1.0)[:, None], [1.0, 0.0])
    f1 = np.clip(s1, lo, hi) / np.where(s1 > 0, s1, 1.0)
    f2 = np.clip(s2, lo, hi) / np.where(s2 > 0, s2, 1.0)
    f2 = np.where(s2 > 0, f2, 1.0)
    # S = V diag(f1, f2) V^T, then J S.
    x, y = v[:, 0], v[:, 1]
    S00, S01, S11 = f1 * x * x + f2 * y * y, (f1 - f2) * x * y, f1 * y * y + f2 * x * x
    out = np.stack([J[:, 0] * S00 + J[:, 1] * S01, J[:, 0] * S01 + J[:, 1] * S11,
                    J[:, 2] * S00 + J[:, 3] * S01, J[:, 2] * S01 + J[:, 3] * S11], -1)
    return np.where(changed[:, None], out, J), changed


def jacobian(theta_deg, scale=1.0, aspect=1.0) -> np.ndarray:
    """J in Q12 (..., 4) int16 for directions (degrees), scales and aspects (arrays broadcast).
    ValueError when a stretch leaves [MIN_STRETCH, MAX_STRETCH]."""
    th = np.radians(np.asarray(theta_deg, np.float64))
    s = np.asarray(scale, np.float64)
    a = np.asarray(aspect, np.float64)
    sx, sy = s * a, s / a
    if np.any(~np.isfinite(sx)) or np.any(sx < MIN_STRETCH - 1e-9) or np.any(sx > MAX_STRETCH + 1e-9) \
            or np.any(sy < MIN_STRETCH - 1e-9) or np.any(sy > MAX_STRETCH + 1e-9):
        raise ValueError(f"A direction field's scale times aspect and scale over aspect must stay within "
                         f"{MIN_STRETCH:g} and {MAX_STRETCH:g}.")
    c, n = np.cos(th), np.sin(th)
    # J = diag(1/sx, 1/sy) R(-theta), R(-theta) = [[c, n], [-n, c]]
    j = np.stack(np.broadcast_arrays(c / sx, n / sx, -n / sy, c / sy), axis=-1)
    return np.rint(j * J_ONE).astype(np.int16)


def decompose(j: np.ndarray):
    """(theta degrees, scale, aspect) of Q12 Jacobians (..., 4), for overlays and tools:
    the inverse of :func:`jacobian` up to rounding."""
    j = np.asarray(j, np.float64) / J_ONE
    j00, j01, j10, j11 = j[..., 0], j[..., 1], j[..., 2], j[..., 3]
    det = j00 * j11 - j01 * j10
    # A = J^-1; its first column is sx (cos, sin), its second sy (-sin, cos).
    a00, a10 = j11 / det, -j10 / det
    a01, a11 = -j01 / det, j00 / det
    sx = np.hypot(a00, a10)
    sy = np.hypot(a01, a11)
    theta = np.degrees(np.arctan2(a10, a00))
    s = np.sqrt(sx * sy)
    return theta, s, np.sqrt(sx / np.maximum(sy, 1e-12))


def _i16x4(t: np.ndarray) -> np.ndarray:
    t = np.asarray(t)
    if t.dtype != np.int16 or t.shape != (TILE, TILE, 4):
        raise ValueError(f"direction field tiles are int16 {TILE}x{TILE}x4, not {t.dtype} {t.shape}")
    return np.ascontiguousarray(t)


# Tiles already checked, by id (weak: an entry goes with its tile, so an id is
# never mistaken for a freed tile's): a new field made from another's tiles
# checks only the tiles that changed.
_CHECKED: weakref.WeakValueDictionary = weakref.WeakValueDictionary()
ENTRY_LIMIT = int(J_ONE / MIN_STRETCH)  # |J entries| <= 16384
MIN_DET = int(J_ONE * J_ONE / (MAX_STRETCH * MAX_STRETCH)) // 2  # det J (Q24) >= half of 1 / MAX_STRETCH^2


def _dets(v: np.ndarray) -> np.ndarray:
    v = v.astype(np.int64)
    return v[..., 0] * v[..., 3] - v[..., 1] * v[..., 2]


def valid_jacobians(t: np.ndarray) -> bool:
    """Every J in Q12 with entries within what MIN_STRETCH allows and det J >= MIN_DET (no mirror)."""
    return bool(np.all(np.abs(t.astype(np.int64)) <= ENTRY_LIMIT) and np.all(_dets(t) >= MIN_DET))


@dataclass(frozen=True, eq=False)
class DirectionField:
    """The direction field over the canvas: sparse TILE x TILE x 4 int16 tiles
    of J in Q12 keyed by tile index; absent tiles are the identity."""

    tiles: dict = field(default_factory=dict)

    def __post_init__(self):
        clean = {}
        for (tx, ty), t in self.tiles.items():
            if id(t) not in _CHECKED:  # tiles shared with a field already made were checked then
                t = _i16x4(t)
                if not valid_jacobians(t):
                    raise ValueError("A direction field holds a mirrored or too strongly stretched Jacobian.")
                if np.all(t == IDENTITY):
                    continue
            clean[(int(tx), int(ty))] = t
        if len(clean) > MAX_DIRECTION_TILES:
            raise FieldTooLarge(f"A direction field may cover at most {MAX_DIRECTION_TILES} tiles of {TILE}x{TILE} px "
                                "(about 8192 x 8192 px); clear some of it first.")
        for t in clean.values():
            _CHECKED[id(t)] = t
        object.__setattr__(self, "tiles", clean)

    @classmethod
    def from_jacobians(cls, values: np.ndarray, x: int, y: int) -> DirectionField:
        """A Q12 (H, W, 4) int16 map of J placed with its top-left at canvas (x, y).
        FieldTooLarge, before any tile is made, if it would cover more than MAX_DIRECTION_TILES tiles."""
        return cls().replaced(values, x, y)

    def replaced(self, values: np.ndarray, x: int, y: int) -> DirectionField:
        """This field with the rectangle of a Q12 (H, W, 4) int16 map placed at
        (x, y) replaced by it (the rest of the tiles it touches kept).
        FieldTooLarge, before any tile is made, if the map would cover more
        than MAX_DIRECTION_TILES tiles."""
        values = np.asarray(values)
        if values.ndim != 3 or values.shape[2] != 4 or values.dtype != np.int16:
            raise ValueError("a direction map is an (H, W, 4) int16 array of Q12 Jacobians")
        h, w = values.shape[:2]
        count = ((x + w - 1) // TILE - x // TILE + 1) * ((y + h - 1) // TILE - y // TILE + 1)
        if count > MAX_DIRECTION_TILES:
            raise FieldTooLarge(f"The direction map ({w}x{h} px) would cover {count} tiles of {TILE}x{TILE} "
                                f"px; at most {MAX_DIRECTION_TILES} are allowed (about 8192 x 8192 px).")
        tiles = dict(self.tiles)
        for ty in range(y // TILE, (y + h - 1) // TILE + 1):
            for tx in range(x // TILE, (x + w - 1) // TILE + 1):
                old = tiles.get((tx, ty))
                t = _identity_tile() if old is None else old.copy()
                ix0, iy0 = max(tx * TILE, x), max(ty * TILE, y)
                ix1, iy1 = min((tx + 1) * TILE, x + w), min((ty + 1) * TILE, y + h)
                t[iy0 - ty * TILE:iy1 - ty * TILE, ix0 - tx * TILE:ix1 - tx * TILE] = \
                    values[iy0 - y:iy1 - y, ix0 - x:ix1 - x]
                tiles[(tx, ty)] = t
        return DirectionField(tiles)

    @classmethod
    def uniform(cls, theta: float, scale: float, aspect: float, x0: int, y0: int, x1: int, y1: int) -> DirectionField:
        """One direction, scale and aspect over the rectangle [x0, x1) x [y0, y1)."""
        j = jacobian(theta, scale, aspect)
        return cls.from_jacobians(np.broadcast_to(j, (y1 - y0, x1 - x0, 4)).copy(), x0, y0)

    def painted(self, cx: float, cy: float, radius: float, target: np.ndarray, strength: float = 1.0,
                hardness: float = 0.5) -> tuple[DirectionField, tuple[int, int, int, int]]:
        """A dab towards the Q12 Jacobian ``target`` (4,) (or one per pixel of the
        dab's rectangle, (h, w, 4)): each J moves towards it by the brush weight,
        rounded. Returns the new field and the rectangle the dab can change."""
        x0, y0, x1, y1 = dab_rect(cx, cy, radius)
        target = np.asarray(target, np.float64)
        tiles = dict(self.tiles)
        for ty in range(y0 // TILE, (y1 - 1) // TILE + 1):
            for tx in range(x0 // TILE, (x1 - 1) // TILE + 1):
                wts = dab_weights(cx, cy, radius, hardness, tx * TILE, ty * TILE, TILE, TILE)
                if not wts.any():
                    continue
                old = tiles.get((tx, ty))
                base = old if old is not None else _identity_tile()
                tgt = target
                if tgt.ndim == 3:  # per pixel of the dab rectangle: the part inside this tile
                    tgt = np.broadcast_to(IDENTITY, (TILE, TILE, 4)).astype(np.float64)
                    ix0, iy0 = max(tx * TILE, x0), max(ty * TILE, y0)
                    ix1, iy1 = min((tx + 1) * TILE, x1), min((ty + 1) * TILE, y1)
                    tgt[iy0 - ty * TILE:iy1 - ty * TILE, ix0 - tx * TILE:ix1 - tx * TILE] = \
                        target[iy0 - y0:iy1 - y0, ix0 - x0:ix1 - x0]
                a = (np.clip(strength, 0.0, 1.0) * wts)[..., None]
                new = np.rint(base + (tgt - base) * a).astype(np.int16)
                if not valid_jacobians(new):
                    new = np.where(a > 0, np.rint(tgt).astype(np.int16), base) if valid_jacobians(
                        np.rint(tgt).astype(np.int16)) else base
                tiles[(tx, ty)] = new
        return DirectionField(tiles), (x0, y0, x1, y1)

    def edited(self, x0: int, y0: int, weights: np.ndarray, op) -> tuple[DirectionField, tuple[int, int, int, int]]:
        """The field with the pixels of [x0, x0+w) x [y0, y0+h) changed by
        ``op(theta, scale, aspect, J, weights) -> (theta, scale, aspect)`` where
        ``weights`` (h, w) > 0 (the others are kept; arrays in degrees, J the
        current Q12 values). New values are clamped to the stretch limits.
        Returns the new field and the rectangle it may change."""
        h, w = weights.shape
        if not np.any(weights > 0):
            return self, (x0, y0, x0, y0)
        cur = self.dense(x0, y0, w, h)
        th, sc, asp = decompose(cur)
        th, sc, asp = op(th, sc, asp, cur, weights)
        sx = np.clip(sc * asp, MIN_STRETCH, MAX_STRETCH)
        sy = np.clip(sc / asp, MIN_STRETCH, MAX_STRETCH)
        new = jacobian(th, np.sqrt(sx * sy), np.sqrt(sx / sy))
        new = np.where((weights > 0)[..., None], new, cur).astype(np.int16)
        tiles = dict(self.tiles)
        for ty in range(y0 // TILE, (y0 + h - 1) // TILE + 1):
            for tx in range(x0 // TILE, (x0 + w - 1) // TILE + 1):
                ix0, iy0 = max(tx * TILE, x0), max(ty * TILE, y0)
                ix1, iy1 = min((tx + 1) * TILE, x0 + w), min((ty + 1) * TILE, y0 + h)
                part = weights[iy0 - y0:iy1 - y0, ix0 - x0:ix1 - x0]
                if not np.any(part > 0):
                    continue
                old = tiles.get((tx, ty))
                t = _identity_tile() if old is None else old.copy()
                t[iy0 - ty * TILE:iy1 - ty * TILE, ix0 - tx * TILE:ix1 - tx * TILE] = \
                    new[iy0 - y0:iy1 - y0, ix0 - x0:ix1 - x0]
                tiles[(tx, ty)] = t
        return DirectionField(tiles), (x0, y0, x0 + w, y0 + h)

    def guided(self, points, width: float, blend: float = 0.0, strength: float = 1.0, axis_offset: float = 0.0,
               max_area: int = 4096 * 4096) -> DirectionField:
        """The texture follows a curve (a Catmull-Rom spline through ``points``,
        canvas pixels): fully within ``width``, then fading into what is there
        over ``blend`` px (so between two guides closer than that the direction
        turns smoothly from one to the other). The exemplar's x runs along the
        curve (``axis_offset`` 90: its y). ValueError when the curve's box
        exceeds ``max_area`` pixels."""
        pts = np.asarray(points, np.float64)
        if len(pts) < 2:
            return self
        core = width / 2.0
        half = core + max(0.0, blend)
        x0, y0 = int(np.floor(pts[:, 0].min() - half)) - 1, int(np.floor(pts[:, 1].min() - half)) - 1
        x1, y1 = int(np.ceil(pts[:, 0].max() + half)) + 2, int(np.ceil(pts[:, 1].max() + half)) + 2
        if (x1 - x0) * (y1 - y0) > max_area:
            raise ValueError("This guide covers too large an area; draw it in pieces.")
        dist, ang = polyline_frame(pts, x0, y0, x1 - x0, y1 - y0, half + 1.0)
        t = np.clip((dist - core) / max(half - core, 1e-6), 0.0, 1.0)
        w = np.where(dist >= half, 0.0, 1.0 - t * t * (3.0 - 2.0 * t)) * np.clip(strength, 0.0, 1.0)
        return self.edited(x0, y0, w, comb(ang - axis_offset))[0]

    def rescaled(self, factor: float, size: int) -> DirectionField:
        """The field over a model's texture of ``size`` texels (its tiles beyond
        it dropped: they are never read) on one ``factor`` times larger: each new
        pixel takes the J of the one it came from."""
        inside = tiles_within(self.tiles, size)
        if not inside or factor == 1:
            return DirectionField(inside) if len(inside) != len(self.tiles) else self
        return DirectionField.from_jacobians(*rescaled_pixels(inside, factor, IDENTITY))

    def dense(self, x0: int, y0: int, w: int, h: int) -> np.ndarray:
        """J (h, w, 4) int16 over a finest-level rectangle (identity where unpainted)."""
        out = self.region(0, x0, y0, w, h)
        return out if out is not None else np.broadcast_to(IDENTITY, (h, w, 4)).copy()

    def changed_rects(self, other: DirectionField) -> list:
        """(x0, y0, x1, y1) per tile: the box of the pixels that differ between two fields."""
        keys = {k for k in set(self.tiles) | set(other.tiles) if self.tiles.get(k) is not other.tiles.get(k)}

        def flat(tiles):  # one int64 a pixel, for the tiles that may differ
            return {k: tiles[k].view(np.int64).reshape(TILE, TILE) for k in keys if k in tiles}
        return tile_changes(flat(self.tiles), flat(other.tiles), _identity_tile().view(np.int64).reshape(TILE, TILE))

    @cached_property
    def key(self) -> str:
        return tiles_key(self.tiles, b"direction")

    def __eq__(self, other):
        return isinstance(other, DirectionField) and self.key == other.key

    def __hash__(self):
        return hash(self.key)

    @property
    def identity(self) -> bool:
        return not self.tiles

    def painted_tiles(self, k: int) -> list[tuple[int, int]]:
        """The (x, y) origins (level-k pixels) of the TILE x TILE tiles painted at level k."""
        return sorted((tx * TILE, ty * TILE) for tx, ty in (self._mip_tiles(k) if self.tiles else {}))

    def _mip_tiles(self, k: int) -> dict:
        """Tiles of the field reduced k times (2 x 2 means, floor at each step), same tile size."""
        cache = self.__dict__.setdefault("_mips", {0: self.tiles})
        if k in cache:
            return cache[k]
        out = mip_parents(self._mip_tiles(k - 1), IDENTITY, reduce_once)
        cache[k] = {p: t for p, t in out.items() if not np.all(t == IDENTITY)}
        return cache[k]

    def _periodic(self, n: int, k: int) -> np.ndarray | None:
        """The field repeated with period n, reduced k <= log2 n times: (n >> k)^2 x 4, or None (identity)."""
        cache = self.__dict__.setdefault("_periodic_levels", {})
        if (n, k) not in cache:
            if n >= TILE:  # the tiles inside [0, n)^2 reduced as a field of their own: exact up to k = log2 n
                inside = DirectionField({t: v for t, v in self.tiles.items()
                                         if 0 <= t[0] < n // TILE and 0 <= t[1] < n // TILE})
                cache[(n, k)] = inside.region(k, 0, 0, n >> k, n >> k)
            else:
                a = self.region(0, 0, 0, n, n)
                for _ in range(k):
                    a = None if a is None else reduce_once(a)
                cache[(n, k)] = a
        return cache[(n, k)]

    def region(self, k: int, x0: int, y0: int, w: int, h: int, period: int = 0) -> np.ndarray | None:
        """J reduced k times over [x0, x0+w) x [y0, y0+h) (level pixels), int16
        (h, w, 4); None when no painted tile touches it. With ``period`` n (a
        toroidal tile's size, finest pixels): the field inside [0, n)^2 repeated
        with period n, then reduced (a level pixel larger than the tile takes the
        whole tile's reduction), so what is painted outside the tile never counts."""
        if period:
            n = period
            kk = min(k, n.bit_length() - 1)
            base = self._periodic(n, kk) if self.tiles else None
            if base is None:
                return None
            nl = n >> kk
            ys = np.arange(y0, y0 + h) & (nl - 1)
            xs = np.arange(x0, x0 + w) & (nl - 1)
            return np.ascontiguousarray(base[ys[:, None], xs[None, :]])
        tiles = self._mip_tiles(k) if self.tiles else {}
        return tiles_region(tiles, x0, y0, w, h, IDENTITY) if tiles else None


def reduce_once(a: np.ndarray) -> np.ndarray:
    """One mipmap step of Q12 Jacobians (2h, 2w, 4) -> (h, w, 4): each entry
    floor(sum of the 2 x 2 children / 4); where that mean's determinant falls
    below MIN_DET (directions cancel out), the top-left child."""
    a = a.astype(np.int32)
    s = a[0::2, 0::2] + a[1::2, 0::2] + a[0::2, 1::2] + a[1::2, 1::2]
    red = s >> 2  # floor(sum / 4): >> is a floor on numpy ints
    return np.where((_dets(red) < MIN_DET)[..., None], a[0::2, 0::2], red).astype(np.int16)


def turn_towards(theta: np.ndarray, target, weight: np.ndarray) -> np.ndarray:
    """Angles moved a share ``weight`` of the way to ``target`` along the shorter arc (degrees)."""
    d = (np.asarray(target, np.float64) - theta + 180.0) % 360.0 - 180.0
    return theta + weight * d


def comb(target_deg):
    """An edit (DirectionField.edited) turning the texture towards a direction (array or scalar)."""
    def op(th, sc, asp, J, w):
        return turn_towards(th, target_deg, w), sc, asp
    return op


def grow(factor: float):
    """An edit making the texture ``factor`` times larger where fully weighted (smaller below 1)."""
    def op(th, sc, asp, J, w):
        return th, sc * np.power(float(factor), w), asp
    return op


def erase():
    """An edit back towards the exemplar as it is (direction 0, scale 1, aspect 1)."""
    def op(th, sc, asp, J, w):
        return turn_towards(th, 0.0, w), np.exp(np.log(sc) * (1 - w)), np.exp(np.log(asp) * (1 - w))
    return op


def smooth(size: int):
    """An edit blending each pixel towards the mean direction, scale and aspect
    around it (a box of ``size`` px): combed strokes flow into each other."""
    from scipy import ndimage

    def op(th, sc, asp, J, w):
        r = np.radians(th)
        c = ndimage.uniform_filter(np.cos(r), size, mode="nearest")
        s = ndimage.uniform_filter(np.sin(r), size, mode="nearest")
        mean_th = np.degrees(np.arctan2(s, c))
        ls = ndimage.uniform_filter(np.log(sc), size, mode="nearest")
        la = ndimage.uniform_filter(np.log(asp), size, mode="nearest")
        agree = np.hypot(c, s)  # where directions cancel out, leave them
        w2 = w * np.clip(agree * 2.0 - 0.2, 0.0, 1.0)
        return (turn_towards(th, mean_th, w2), np.exp(np.log(sc) + w * (ls - np.log(sc))),
                np.exp(np.log(asp) + w * (la - np.log(asp))))
    return op


def polyline_frame(points: np.ndarray, x0: int, y0: int, w: int, h: int, reach: float = np.inf):
    """(distance to the polyline, its direction in degrees at the nearest point)
    for the pixel centers of [x0, x0+w) x [y0, y0+h), exact within ``reach``
    of it (farther: inf); the polyline is first resampled as a Catmull-Rom
    spline through ``points`` (N, 2), so the direction turns smoothly at its
    vertices."""
    p = np.asarray(points, np.float64)
    if len(p) > 2:
        ext = np.vstack([2 * p[0] - p[1], p, 2 * p[-1] - p[-2]])
        fine = []
        for i in range(1, len(ext) - 2):
            a, b, c, d = ext[i - 1], ext[i], ext[i + 1], ext[i + 2]
            n = max(2, int(np.hypot(*(c - b)) // 3))
            t = np.linspace(0.0, 1.0, n, endpoint=False)[:, None]
            fine.append(0.5 * (2 * b + (c - a) * t + (2 * a - 5 * b + 4 * c - d) * t ** 2
                               + (3 * b - a - 3 * c + d) * t ** 3))
        fine.append(p[-1:])
        p = np.vstack(fine)
    best = np.full((h, w), np.inf)
    ang = np.zeros((h, w))
    for a, b in zip(p[:-1], p[1:]):
        d = b - a
        L2 = float(d @ d)
        if L2 == 0:
            continue
        # Only the pixels within ``reach`` of the segment can be closer to it than that.
        bx0 = max(x0, int(np.floor(min(a[0], b[0]) - reach)))
        by0 = max(y0, int(np.floor(min(a[1], b[1]) - reach)))
        bx1 = min(x0 + w, int(np.ceil(max(a[0], b[0]) + reach)) + 1)
        by1 = min(y0 + h, int(np.ceil(max(a[1], b[1]) + reach)) + 1)
        if bx0 >= bx1 or by0 >= by1:
            continue
        ys, xs = np.mgrid[by0:by1, bx0:bx1] + 0.5
        t = np.clip(((xs - a[0]) * d[0] + (ys - a[1]) * d[1]) / L2, 0.0, 1.0)
        dist = np.hypot(xs - a[0] - t * d[0], ys - a[1] - t * d[1])
        win = (slice(by0 - y0, by1 - y0), slice(bx0 - x0, bx1 - x0))
        closer = dist < best[win]
        best[win] = np.where(closer, dist, best[win])
        ang[win] = np.where(closer, np.degrees(np.arctan2(d[1], d[0])), ang[win])
    return best, ang


def flow_to_jacobians(rgb: np.ndarray, y_up: bool = True, scale: float = 1.0, aspect: float = 1.0) -> np.ndarray:
    """A flow map (H, W, >=2) with R, G in [0, 1] (0.5 = no flow; within 1.5/255
    of it counts as 0.5, so 8-bit 127 and 128 both do) to Q12 Jacobians:
    the texture's +x runs along the flow vector; pixels whose vector is shorter
    than 1/8 keep the identity. ``y_up``: green points up (OpenGL), else down (DirectX)."""
    vx = 2.0 * rgb[..., 0] - 1.0
    vy = 2.0 * rgb[..., 1] - 1.0
    # 8-bit maps cannot hold 0.5: 127 and 128 both mean "none" along that axis.
    vx = np.where(np.abs(vx) < 1.5 / 255.0, 0.0, vx)
    vy = np.where(np.abs(vy) < 1.5 / 255.0, 0.0, vy)
    if y_up:
        vy = -vy  # canvas y runs down
    theta = np.degrees(np.arctan2(vy, vx))
    j = jacobian(theta, scale, aspect)
    return np.where((np.hypot(vx, vy) >= 0.125)[..., None], j, IDENTITY).astype(np.int16)


def angle_to_jacobians(gray: np.ndarray, scale: float = 1.0, aspect: float = 1.0) -> np.ndarray:
    """An angle map (H, W) in [0, 1] (0 and 1 = along +x, 0.25 = +y, down on screen) to Q12 Jacobians."""
    return jacobian(360.0 * np.asarray(gray, np.float64), scale, aspect)


def max_stretch_ratio(j: np.ndarray) -> float:
    """The largest exemplar step per canvas pixel in a Q12 J array (1 = isometric)."""
    v = np.abs(np.asarray(j, np.float64)) / J_ONE
    return float(max(np.hypot(v[..., 0], v[..., 2]).max(initial=1.0), np.hypot(v[..., 1], v[..., 3]).max(initial=1.0)))


__all__ = ["DirectionField", "IDENTITY", "J_ONE", "MAX_STRETCH", "MIN_STRETCH", "angle_to_jacobians", "comb",
           "decompose", "erase", "flow_to_jacobians", "grow", "jacobian", "max_stretch_ratio", "polyline_frame",
           "smooth", "turn_towards", "valid_jacobians"]
