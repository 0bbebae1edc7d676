"""Randomness fields (LH05 4.2): over the exemplar (:class:`ExemplarField`,
m x m, min-mipmapped) and over the infinite canvas (:class:`CanvasField`,
sparse tiles, mipmapped toward neutral), the brush dabs that paint them, and
:class:`ExemplarArray`, the content-compared m x m base that the exemplar
field and the avoid mask share. The formulas are in the package docstring."""
from __future__ import annotations

from dataclasses import dataclass, field
from functools import cached_property

import numpy as np

from ..exemplar import ExemplarError

NEUTRAL = 32768
TILE = 64  # canvas field tile side, finest-level pixels
MAX_FIELD_TILES = 65536  # tiles a canvas map may cover (a 16384 x 16384 px area); as the project loader's cap


class FieldTooLarge(ExemplarError):
    """A canvas randomness map that would cover more than MAX_FIELD_TILES tiles; one sentence."""


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
    xs = np.arange(x0, x0 + w, dtype=np.int64) + 0.5 - cx  # (broadcast: no full grids of indices)
    ys = np.arange(y0, y0 + h, dtype=np.int64) + 0.5 - cy
    d = np.hypot(xs[None, :], ys[:, None]) / max(radius, 1e-6)
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


def tile_changes(a_tiles: dict, b_tiles: dict, blank: np.ndarray) -> list:
    """(x0, y0, x1, y1) per TILE x TILE tile: the box of the pixels that differ
    between two sparse tile maps (an absent tile is ``blank``)."""
    out = []
    for k in set(a_tiles) | set(b_tiles):
        a, b = a_tiles.get(k), b_tiles.get(k)
        if a is b:
            continue
        ys, xs = np.nonzero((a if a is not None else blank) != (b if b is not None else blank))
        if len(xs):  # the bounding box of the pixels that differ
            x0, y0 = k[0] * TILE, k[1] * TILE
            out.append((x0 + int(xs.min()), y0 + int(ys.min()), x0 + int(xs.max()) + 1, y0 + int(ys.max()) + 1))
    return out


def tiles_region(tiles: dict, x0: int, y0: int, w: int, h: int, blank) -> np.ndarray | None:
    """The pixels of [x0, x0+w) x [y0, y0+h) from sparse TILE x TILE tiles
    (absent tiles are ``blank``: a value, or one pixel's channels); None when
    no tile touches the rectangle."""
    out = None
    for ty in range(y0 // TILE, (y0 + h - 1) // TILE + 1):
        for tx in range(x0 // TILE, (x0 + w - 1) // TILE + 1):
            t = tiles.get((tx, ty))
            if t is None:
                continue
            if out is None:
                out = np.empty((h, w) + t.shape[2:], t.dtype)
                out[:] = blank
            ix0, iy0 = max(tx * TILE, x0), max(ty * TILE, y0)
            ix1, iy1 = min((tx + 1) * TILE, x0 + w), min((ty + 1) * TILE, y0 + h)
            out[iy0 - y0:iy1 - y0, ix0 - x0:ix1 - x0] = t[iy0 - ty * TILE:iy1 - ty * TILE, ix0 - tx * TILE:ix1 - tx * TILE]
    return out


def tiles_within(tiles: dict, size: int) -> dict:
    """The tiles that lie over [0, size)^2 (a model's texture: the rest is never read)."""
    return {t: v for t, v in tiles.items() if 0 <= t[0] * TILE < size and 0 <= t[1] * TILE < size}


def rescaled_pixels(tiles: dict, factor: float, blank) -> tuple[np.ndarray, int, int]:
    """The pixels of sparse tiles (absent: ``blank``) on a canvas ``factor``
    times larger, each new pixel the one it came from: (array, x, y of its top left)."""
    xs = [tx for tx, _ in tiles]
    ys = [ty for _, ty in tiles]
    x0, y0 = min(xs) * TILE, min(ys) * TILE
    w, h = (max(xs) + 1) * TILE - x0, (max(ys) + 1) * TILE - y0
    dense = tiles_region(tiles, x0, y0, w, h, blank)
    nx0, ny0 = int(np.floor(x0 * factor)), int(np.floor(y0 * factor))
    nw, nh = max(1, int(np.ceil((x0 + w) * factor)) - nx0), max(1, int(np.ceil((y0 + h) * factor)) - ny0)
    sx = np.clip(np.floor((np.arange(nx0, nx0 + nw) + 0.5) / factor).astype(np.int64) - x0, 0, w - 1)
    sy = np.clip(np.floor((np.arange(ny0, ny0 + nh) + 0.5) / factor).astype(np.int64) - y0, 0, h - 1)
    return np.ascontiguousarray(dense[sy[:, None], sx[None, :]]), nx0, ny0


def mip_parents(finer: dict, blank, reduce) -> dict:
    """One mipmap step of sparse tiles: each parent tile is ``reduce`` of its
    four children put together (2 TILE x 2 TILE; absent ones ``blank``)."""
    out: dict = {}
    for px, py in {(tx >> 1, ty >> 1) for tx, ty in finer}:
        some = next(iter(finer.values()))
        big = np.empty((2 * TILE, 2 * TILE) + some.shape[2:], some.dtype)
        for dy in (0, 1):
            for dx in (0, 1):
                t = finer.get((2 * px + dx, 2 * py + dy))
                big[dy * TILE:(dy + 1) * TILE, dx * TILE:(dx + 1) * TILE] = blank if t is None else t
        out[(px, py)] = reduce(big)
    return out


def tiles_key(tiles: dict, salt: bytes = b"") -> str:
    """A content hash of sparse tiles (in tile order)."""
    import hashlib
    hsh = hashlib.sha256(salt)
    for k in sorted(tiles):
        hsh.update(repr(k).encode())
        hsh.update(tiles[k].tobytes())
    return hsh.hexdigest()


class ExemplarArray:
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
class ExemplarField(ExemplarArray):
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
        """A painted region (uint16 H x W) placed with its top-left at canvas (x, y).
        FieldTooLarge, before any tile is made, if it would cover more than MAX_FIELD_TILES tiles."""
        values = _u16(values)
        h, w = values.shape
        count = ((x + w - 1) // TILE - x // TILE + 1) * ((y + h - 1) // TILE - y // TILE + 1)
        if count > MAX_FIELD_TILES:
            raise FieldTooLarge(f"The canvas randomness map ({w}x{h} px) would cover {count} tiles of {TILE}x{TILE} "
                                f"px; at most {MAX_FIELD_TILES} are allowed (about 16384 x 16384 px).")
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
                hardness: float = 0.5, bounds: tuple[int, int, int, int] | None = None
                ) -> tuple[CanvasField, "tuple[int, int, int, int]"]:
        """A dab (finest-level canvas pixels): the new field, sharing every
        untouched tile with this one, and the rectangle (x0, y0, x1, y1) it
        changed; ``bounds`` (x0, y0, x1, y1): painted only inside it (a model's atlas)."""
        x0, y0, x1, y1 = dab_rect(cx, cy, radius)
        if bounds is not None:
            x0, y0 = max(x0, bounds[0]), max(y0, bounds[1])
            x1, y1 = min(x1, bounds[2]), min(y1, bounds[3])
            if x0 >= x1 or y0 >= y1:
                return self, (x0, y0, x0, y0)
        tiles = dict(self.tiles)
        # The weights over the dab's whole tile span at once (one numpy pass, not one a tile).
        tx0, ty0, tx1, ty1 = x0 // TILE, y0 // TILE, (x1 - 1) // TILE + 1, (y1 - 1) // TILE + 1
        ox, oy = tx0 * TILE, ty0 * TILE
        wts = dab_weights(cx, cy, radius, hardness, ox, oy, (tx1 - tx0) * TILE, (ty1 - ty0) * TILE)
        if bounds is not None:  # nothing outside them
            wts[:, :max(0, x0 - ox)] = 0
            wts[:, max(0, x1 - ox):] = 0
            wts[:max(0, y0 - oy)] = 0
            wts[max(0, y1 - oy):] = 0
        touched = wts.reshape(ty1 - ty0, TILE, tx1 - tx0, TILE).any(axis=(1, 3))
        for j, i in zip(*np.nonzero(touched)):
            key = (tx0 + int(i), ty0 + int(j))
            old = tiles.get(key)
            base = old if old is not None else np.full((TILE, TILE), NEUTRAL, np.uint16)
            w = wts[j * TILE:(j + 1) * TILE, i * TILE:(i + 1) * TILE]
            tiles[key] = apply_dab(base, w, value, strength)
        return CanvasField(tiles), (x0, y0, x1, y1)

    def rescaled(self, factor: float, size: int) -> CanvasField:
        """The field over a model's texture of ``size`` texels (its tiles beyond
        it dropped: they are never read) on one ``factor`` times larger: each new
        pixel takes the value of the one it came from."""
        inside = tiles_within(self.tiles, size)
        if not inside or factor == 1:
            return CanvasField(inside) if len(inside) != len(self.tiles) else self
        return CanvasField.from_image(*rescaled_pixels(inside, factor, NEUTRAL))

    def changed_rects(self, other: CanvasField) -> list:
        """(x0, y0, x1, y1) per tile: the box of the pixels that differ between two fields."""
        return tile_changes(self.tiles, other.tiles, np.full((TILE, TILE), NEUTRAL, np.uint16))

    @cached_property
    def key(self) -> str:
        return tiles_key(self.tiles)

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
        cache[k] = mip_parents(self._mip_tiles(k - 1), NEUTRAL, reduce_toward_neutral)
        return cache[k]

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
        return tiles_region(tiles, x0, y0, w, h, NEUTRAL)
