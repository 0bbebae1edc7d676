"""Texture by numbers (TBN10, docs/algorithm.md section 7): a label map over the
exemplar says what each of its regions is (stones, grass, mortar...), a label
map painted over the infinite canvas says which label each place should get,
and the synthesis follows it, with transitions taken from the exemplar's own.

Labels are small integers 0..15 over the exemplar (:class:`ExemplarLabels`);
over the canvas (:class:`CanvasLabels`, sparse TILE x TILE tiles of the
finest-level pixels) 0 is *free* (no constraint) and 1..16 mean labels 0..15.

**What the passes compare.** Both sides become, per level-l pixel, a mix of at
most two labels with integer weights summing to 255, packed in one uint32:

- exemplar texel u: the labels' shares in the level's Gaussian stack of the
  one-hot label channels (the blur the colors get, sigma h_l / 2), the two
  largest kept (ties: the lower label), renormalized:
  ``e1 | e2 << 4 | v1 << 8 | v2 << 16`` (v2 = 0 and e2 = e1 for one label);
- canvas pixel p (:meth:`CanvasLabels.features`): the canvas labels sampled
  over the pixel's footprint (s x s samples, s = min(2^k, 4), k = L - l, at
  ``p 2^k + i 2^k/s + 2^k/(2s)``; every pixel for k <= 2), counted per label,
  blurred by the 3 x 3 binomial filter in level pixels (a transition as wide
  as a level pixel), then the two largest painted labels renormalized, and
  the painted share of the footprint: ``t1 | t2 << 4 | w1 << 8 | w2 << 16 | share << 24``;
  a pixel less than half painted (share < SHARE_MIN) is free, and on the
  levels of pixels of 4 px and more (k >= ERODE_FROM) so is one whose 3 x 3
  neighbors are not all painted enough too, as the painted randomness acts
  only on the features that fit inside the painted area: a thin stroke steers
  the fine scales along it, a large painted area the coarse ones too, and no
  stroke re-rolls the large features around it. (Without the neighbors, a
  32 px wide stroke steered the 16 px level, whose changes the fidelity stage
  carries about 20 of its pixels on: a 100 px stroke re-rolled 44% of a
  1024 x 768 view, up to 480 px away; now 4%, 170 px.)

The label distance of two mixes is ``D = |a|^2 + |b|^2 - 2 a.b`` (in 255ths,
at most 2 * 255^2), and a candidate u at pixel p costs, on top of its
neighborhood (or patch) cost, ``(((D * share) >> 8) * W_l) >> 4``: a painted
share of the footprint asks for its labels in proportion, a free pixel asks
nothing. ``W_l`` (:func:`label_weight`) makes a full mismatch cost
``s_l`` times a typical distance between unrelated exemplar neighborhoods of
the level (the median over fixed pairs), with ``s_l = strength * (1 + (L -
l) / 2)``: labels weigh more at coarse levels, where textures are hardly
discernible yet (TBN10 4.3). A pixel with a painted share also tries one
exemplar texel of its main label (:meth:`ExemplarLabels.seed_table`, picked by
hash), and the random walk runs, so synthesis can cross into another label's
region and find its transitions.
"""
from __future__ import annotations

import threading
from collections import OrderedDict
from dataclasses import dataclass, field
from functools import cached_property, lru_cache

import numpy as np

from .. import fixed
from .fields import MAX_FIELD_TILES, TILE, ExemplarArray, FieldTooLarge, dab_rect, dab_weights, tile_changes, tiles_key

MAX_LABELS = 16
FREE = 0               # a canvas pixel without a label
SEED_COUNT = 64        # exemplar texels per label the seed candidate picks from
SEED_SALT = 0x6C62272E
STRENGTH_MAX = 8.0
BINOMIAL = np.array([1, 2, 1], np.int64)
# Sasha Trubetskoy's 16 distinct colors: new labels (proposed, painted, a palette's) get them in order.
LABEL_COLORS = ((230, 25, 75), (60, 180, 75), (255, 225, 25), (0, 130, 200), (245, 130, 48), (145, 30, 180),
                (70, 240, 240), (240, 50, 230), (210, 245, 60), (250, 190, 212), (0, 128, 128), (220, 190, 255),
                (170, 110, 40), (255, 250, 200), (128, 0, 0), (170, 255, 195))
# Random-walk steps of a labeled pixel (TBN10's search across labels) when the
# analysis has similarity sets: off. Measured (bench.labels --walk) it lowered
# the transition energy a little at Variety (median 1.09 against 1.13) and not
# at Balanced, but two blind judges, with the order swapped, preferred the
# outputs without it in 4 of 6 cases (1 with it, 1 tie): it scatters stray
# fragments of the other texture near boundaries. Without similarity sets
# (k = 0) the walk is the search itself and stays on.
LABEL_WALK = 0
SHARE_MIN = 128        # of 255: a canvas pixel less painted than this is free
ERODE_FROM = 2         # levels this far above the finest (pixels of 4 px and more) need the share over
#                        their 3 x 3 neighbours too: a level is steered only where its features fit
#                        inside the painted area, so a thin stroke leaves the coarse scales (whose
#                        changes carry farthest) alone; see erosion()


def erosion(k: int) -> int:
    """Level pixels around a level pixel of a level k above the finest that must be painted
    enough too for it to count as painted (0 at the finest levels: strokes keep their edges)."""
    return 1 if k >= ERODE_FROM else 0
# Canvas mixes are kept in tiles of MIX_TILE x MIX_TILE level pixels (CanvasLabels.features),
# at most MIX_CACHE_TILES of them (4 KB each), shared by every label map of the process.
MIX_TILE = 32
MIX_CACHE_TILES = 4096
_MIX_CACHE: OrderedDict = OrderedDict()
_MIX_LOCK = threading.Lock()


def pack_mix(i1, i2, w1, w2, share=None) -> np.ndarray:
    """The packed uint32 of a two-label mix (see the module docstring)."""
    v = (np.asarray(i1, np.uint32) | (np.asarray(i2, np.uint32) << np.uint32(4))
         | (np.asarray(w1, np.uint32) << np.uint32(8)) | (np.asarray(w2, np.uint32) << np.uint32(16)))
    if share is not None:
        v = v | (np.asarray(share, np.uint32) << np.uint32(24))
    return v.astype(np.uint32)


def top_two(weights: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Per pixel of ``weights`` (..., N) (non-negative integers or floats; at
    least one positive), the two largest labels (ties: the lower one first)
    and their weights renormalized to 255 (round half up; w2 = 255 - w1, or
    0 with i2 = i1 when only one label is present)."""
    n = weights.shape[-1]
    if n <= 2:  # one or two labels (the common case): no sort
        w0 = weights[..., 0]
        w1 = weights[..., 1] if n == 2 else np.zeros_like(w0)
        i1 = (w1 > w0).astype(np.int64)  # ties keep the lower label first
        i2 = 1 - i1 if n == 2 else i1
        a = np.where(i1 == 1, w1, w0).astype(np.float64)
        b = np.where(i1 == 1, w0, w1).astype(np.float64)
    else:
        order = np.argsort(-weights, axis=-1, kind="stable")
        i1, i2 = order[..., 0], order[..., 1]
        a = np.take_along_axis(weights, i1[..., None], -1)[..., 0].astype(np.float64)
        b = np.take_along_axis(weights, i2[..., None], -1)[..., 0].astype(np.float64)
    two = b > 0
    w1 = np.where(two, np.floor((510.0 * a + (a + b)) / np.maximum(2.0 * (a + b), 1e-300)), 255).astype(np.int64)
    w1 = np.minimum(w1, 255)
    w2 = np.where(two, 255 - w1, 0)
    i2 = np.where(two, i2, i1)
    return i1.astype(np.int64), i2.astype(np.int64), w1, w2


def mix_distance(t: np.ndarray, e: np.ndarray) -> np.ndarray:
    """D between packed mixes (int64 arrays), as the shaders compute it."""
    t, e = t.astype(np.int64), e.astype(np.int64)
    t1, t2, w1, w2 = t & 15, (t >> 4) & 15, (t >> 8) & 255, (t >> 16) & 255
    e1, e2, v1, v2 = e & 15, (e >> 4) & 15, (e >> 8) & 255, (e >> 16) & 255

    def weight_of(i):
        return np.where(e1 == i, v1, np.where(e2 == i, v2, 0))
    dot = w1 * weight_of(t1) + np.where(t2 != t1, w2 * weight_of(t2), 0)
    return w1 * w1 + w2 * w2 + v1 * v1 + v2 * v2 - 2 * dot


def label_cost(t: np.ndarray, e: np.ndarray, weight: int) -> np.ndarray:
    """The label cost of exemplar mixes ``e`` at canvas mixes ``t`` (packed)."""
    share = (t.astype(np.int64) >> 24) & 255
    return (((mix_distance(t, e) * share) >> 8) * int(weight)) >> 4


@dataclass(frozen=True, eq=False)
class ExemplarLabels(ExemplarArray):
    """The exemplar's label map: uint8 (m, m), labels 0..15."""

    values: np.ndarray
    _salt = b"labels"

    def __post_init__(self):
        v = np.ascontiguousarray(self.values)
        if v.dtype != np.uint8:
            raise ValueError("an exemplar label map is uint8")
        if v.ndim != 2 or v.shape[0] != v.shape[1] or v.shape[0] & (v.shape[0] - 1):
            raise ValueError(f"an exemplar label map is a power-of-two square, not {v.shape}")
        if int(v.max(initial=0)) >= MAX_LABELS:
            raise ValueError(f"exemplar labels are 0 to {MAX_LABELS - 1}")
        object.__setattr__(self, "values", v)

    @cached_property
    def present(self) -> tuple[int, ...]:
        """The labels the map uses, ascending."""
        return tuple(int(i) for i in np.flatnonzero(np.bincount(self.values.ravel(), minlength=MAX_LABELS)))

    def features(self, level: int, toroidal: bool) -> np.ndarray:
        """The packed mix of every exemplar texel at ``level`` (uint32 (m, m))."""
        return _exemplar_mixes(self, toroidal)[level]

    def painted(self, cx: float, cy: float, radius: float, label: int) -> ExemplarLabels:
        """A hard round dab of ``label`` (exemplar pixels; clipped at its border)."""
        m = self.size
        x0, y0, x1, y1 = dab_rect(cx, cy, radius)
        x0, y0, x1, y1 = max(0, x0), max(0, y0), min(m, x1), min(m, y1)
        if x0 >= x1 or y0 >= y1:
            return self
        v = self.values.copy()
        inside = dab_weights(cx, cy, radius, 0.999, x0, y0, x1 - x0, y1 - y0) > 0.5
        v[y0:y1, x0:x1][inside] = label
        return ExemplarLabels(v)

    def seed_table(self, level: int, toroidal: bool) -> np.ndarray:
        """int32 (MAX_LABELS, SEED_COUNT, 2): per label, exemplar texels (x, y)
        mostly of that label at ``level`` (its main label, weight >= 192 when
        any texel has it), spread by a fixed hash; a label the map lacks: zeros."""
        return _seed_table(self, level, toroidal)


@lru_cache(maxsize=2)
def _exemplar_mixes(labels: ExemplarLabels, toroidal: bool) -> tuple[np.ndarray, ...]:
    """Every level's packed exemplar mixes (a few label maps are kept: the
    documents on the undo stack hold their maps, not these)."""
    from ..neighborhoods import gaussian_stack
    ids = np.array(labels.present, np.int64)
    onehot = np.stack([(labels.values == i).astype(np.float32) for i in labels.present], axis=2)
    out = []
    for shares in gaussian_stack(onehot, toroidal):
        i1, i2, w1, w2 = top_two(np.clip(shares, 0.0, None))
        out.append(pack_mix(ids[i1], ids[i2], w1, w2))
    return tuple(out)


@lru_cache(maxsize=32)
def _seed_table(labels: ExemplarLabels, level: int, toroidal: bool) -> np.ndarray:
    f = labels.features(level, toroidal).astype(np.int64)
    m = labels.size
    table = np.zeros((MAX_LABELS, SEED_COUNT, 2), np.int32)
    idx = np.arange(m * m, dtype=np.int64)
    main, strong = f.ravel() & 15, ((f.ravel() >> 8) & 255) >= 192
    for lab in labels.present:
        pick = idx[(main == lab) & strong]
        if not len(pick):
            pick = idx[main == lab]
        if not len(pick):
            pick = idx[labels.values.ravel() == lab]
        with np.errstate(over="ignore"):
            order = np.argsort(fixed.lowbias32(pick.astype(np.uint32) ^ np.uint32(SEED_SALT + lab)),
                               kind="stable")
        chosen = pick[order[np.arange(SEED_COUNT) % len(pick)]]
        table[lab, :, 0], table[lab, :, 1] = chosen % m, chosen // m
    return table


def typical_distance(nbhd: np.ndarray, samples: int = 4096) -> int:
    """The median squared distance between the projected neighborhoods of
    fixed pseudo-random pairs of exemplar texels (clamped like the shader's)."""
    m = nbhd.shape[0]
    rng = np.random.default_rng(0x7B1)
    a = rng.integers(0, m * m, samples)
    b = rng.integers(0, m * m, samples)
    flat = nbhd.reshape(m * m, -1).astype(np.int64)
    d = np.minimum(((flat[a] - flat[b]) ** 2).sum(axis=1), fixed.DIST_CLAMP)
    return int(np.sort(d)[samples // 2])


def typical_patch_cost(colors: np.ndarray, h: int, radius: int, toroidal: bool, samples: int = 1024) -> int:
    """The median fidelity-stage patch cost between fixed pseudo-random pairs of
    exemplar texels (the level's quantized colors, taps h apart)."""
    m = colors.shape[0]
    rng = np.random.default_rng(0x7B2)
    a = rng.integers(0, m, (samples, 2))
    b = rng.integers(0, m, (samples, 2))
    cost = np.zeros(samples, np.int64)
    for dy in range(-radius, radius + 1):
        for dx in range(-radius, radius + 1):
            if dx == 0 and dy == 0:
                continue
            d = np.array([dx * h, dy * h])
            pa, pb = a + d, b + d
            pa, pb = ((pa & (m - 1)), (pb & (m - 1))) if toroidal else (np.clip(pa, 0, m - 1), np.clip(pb, 0, m - 1))
            e = colors[pa[:, 1], pa[:, 0]].astype(np.int64) - colors[pb[:, 1], pb[:, 0]]
            cost += (e * e).sum(axis=1)
    return int(np.sort(cost)[samples // 2])


def label_weight(typical: int, strength: float, level: int, L: int) -> int:
    """W_l: a full label mismatch (D = 2 * 255^2, all painted) costs about
    ``strength * (1 + (L - level) / 2)`` times ``typical``; at most 32767 (so
    that the products stay below 2^32)."""
    s = float(strength) * (1.0 + 0.5 * (L - level))
    return int(min(32767, max(0, round(s * typical * 16.0 / (2 * 255 * 255)))))


def _canvas_u8(a: np.ndarray) -> np.ndarray:
    a = np.asarray(a)
    if a.dtype != np.uint8:
        raise ValueError("canvas labels are uint8 (0 free, 1..16 a label)")
    if int(a.max(initial=0)) > MAX_LABELS:
        raise ValueError(f"canvas labels are 0 (free) to {MAX_LABELS}")
    return np.ascontiguousarray(a)


@dataclass(frozen=True, eq=False)
class CanvasLabels:
    """Labels over the canvas: sparse uint8 TILE x TILE tiles keyed by tile
    index (tx, ty) (pixels [tx*TILE, (tx+1)*TILE)), 0 = unpainted, 1..16 =
    label + 1; absent tiles are unpainted. Unpainted pixels are free, or with
    a ``background`` (1..16, label + 1) that label: a palette's first
    exemplar, which the others are painted into (a palette with nothing
    painted shows its first exemplar, not a patchwork of all of them)."""

    tiles: dict = field(default_factory=dict)
    background: int = FREE

    def __post_init__(self):
        if not 0 <= int(self.background) <= MAX_LABELS:
            raise ValueError(f"a canvas label background is 0 (free) to {MAX_LABELS}")
        object.__setattr__(self, "background", int(self.background))
        clean = {}
        for (tx, ty), t in self.tiles.items():
            t = _canvas_u8(t)
            if t.shape != (TILE, TILE):
                raise ValueError(f"canvas label tiles are {TILE}x{TILE}, not {t.shape}")
            if t.any():
                clean[(int(tx), int(ty))] = t
        object.__setattr__(self, "tiles", clean)

    @classmethod
    def from_image(cls, values: np.ndarray, x: int, y: int) -> CanvasLabels:
        """A label map (uint8 H x W, 0 free) placed with its top-left at canvas (x, y).
        FieldTooLarge, before any tile is made, if it would cover more than MAX_FIELD_TILES tiles."""
        return cls().replaced(values, x, y)

    def replaced(self, values: np.ndarray, x: int, y: int, keep_free: bool = False) -> CanvasLabels:
        """These labels with the block ``values`` (uint8, 0 free) written at
        canvas (x, y); ``keep_free``: its free pixels leave what is there.
        FieldTooLarge, before any tile is made, if the block would cover more
        than MAX_FIELD_TILES tiles."""
        values = _canvas_u8(values)
        h, w = values.shape
        count = ((x + w - 1) // TILE - x // TILE + 1) * ((y + h - 1) // TILE - y // TILE + 1)
        if count > MAX_FIELD_TILES:
            raise FieldTooLarge(f"The canvas label map ({w}x{h} px) would cover {count} tiles of {TILE}x{TILE} "
                                f"px; at most {MAX_FIELD_TILES} are allowed (about 16384 x 16384 px).")
        tiles = dict(self.tiles)
        for ty in range(y // TILE, (y + h - 1) // TILE + 1):
            for tx in range(x // TILE, (x + w - 1) // TILE + 1):
                old = tiles.get((tx, ty))
                t = old.copy() if old is not None else np.zeros((TILE, TILE), np.uint8)
                x0, y0 = tx * TILE, ty * TILE
                ix0, iy0 = max(x0, x), max(y0, y)
                ix1, iy1 = min(x0 + TILE, x + w), min(y0 + TILE, y + h)
                new = values[iy0 - y:iy1 - y, ix0 - x:ix1 - x]
                part = t[iy0 - y0:iy1 - y0, ix0 - x0:ix1 - x0]
                part[...] = np.where(new == 0, part, new) if keep_free else new
                tiles[(tx, ty)] = t
        return CanvasLabels(tiles, self.background)

    def painted(self, cx: float, cy: float, radius: float, value: int, hardness: float = 0.8,
                seed: int = 0) -> tuple[CanvasLabels, tuple[int, int, int, int]]:
        """A label dab (``value`` 0 erases to free, 1..16 a label + 1): inside
        ``hardness * radius`` every pixel takes it, in the soft edge a fraction
        of them that falls to 0 at ``radius`` (chosen by a fixed hash of the
        pixel and ``seed``), which the blur of the labels turns into a wider
        transition. Returns the new labels, sharing untouched tiles, and the
        rectangle (x0, y0, x1, y1) it changed."""
        if not 0 <= int(value) <= MAX_LABELS:
            raise ValueError(f"a canvas label is 0 (free) to {MAX_LABELS}")
        x0, y0, x1, y1 = dab_rect(cx, cy, radius)
        tiles = dict(self.tiles)
        for ty in range(y0 // TILE, (y1 - 1) // TILE + 1):
            for tx in range(x0 // TILE, (x1 - 1) // TILE + 1):
                wts = dab_weights(cx, cy, radius, hardness, tx * TILE, ty * TILE, TILE, TILE)
                if not wts.any():
                    continue
                ys, xs = np.mgrid[ty * TILE:(ty + 1) * TILE, tx * TILE:(tx + 1) * TILE]
                with np.errstate(over="ignore"):
                    hv = fixed.lowbias32(fixed.lowbias32(ys.astype(np.uint32) ^ np.uint32(seed & 0xFFFFFFFF))
                                         ^ xs.astype(np.uint32))
                take = (hv & np.uint32(0xFFFF)).astype(np.float64) < wts * 65536.0
                old = tiles.get((tx, ty))
                base = old.copy() if old is not None else np.zeros((TILE, TILE), np.uint8)
                base[take] = value
                tiles[(tx, ty)] = base
        return CanvasLabels(tiles, self.background), (x0, y0, x1, y1)

    def changed_rects(self, other: CanvasLabels) -> list:
        """(x0, y0, x1, y1) per tile: the box of the pixels that differ between two label maps."""
        return tile_changes(self.tiles, other.tiles, np.zeros((TILE, TILE), np.uint8))

    @cached_property
    def key(self) -> str:
        return tiles_key(self.tiles, b"labels") + (f"/{self.background}" if self.background else "")

    def __eq__(self, other):
        return isinstance(other, CanvasLabels) and self.key == other.key

    def __hash__(self):
        return hash(self.key)

    @property
    def empty(self) -> bool:
        """Nothing constrains the synthesis (nothing painted, no background)."""
        return not self.tiles and not self.background

    @cached_property
    def used(self) -> tuple[int, ...]:
        """The labels (0..15) painted anywhere or in the background, ascending."""
        seen = np.zeros(MAX_LABELS + 1, bool)
        for t in self.tiles.values():
            seen[np.unique(t)] = True
        seen[self.background] = True
        return tuple(int(i) - 1 for i in np.flatnonzero(seen[1:]) + 1)

    def sample(self, xs: np.ndarray, ys: np.ndarray) -> np.ndarray:
        """The canvas labels at the grid of finest pixels xs x ys (uint8 (len(ys), len(xs)))."""
        bg = self.background
        out = np.full((len(ys), len(xs)), bg, np.uint8)
        if not self.tiles:
            return out
        txs, tys = xs // TILE, ys // TILE
        ux, uy = np.unique(txs), np.unique(tys)
        if len(ux) * len(uy) <= len(self.tiles):
            keys = ((int(a), int(b)) for b in uy for a in ux)
        else:
            sx, sy = set(ux.tolist()), set(uy.tolist())
            keys = (k for k in self.tiles if k[0] in sx and k[1] in sy)
        for tx, ty in keys:
            t = self.tiles.get((tx, ty))
            if t is None:
                continue
            cols, rows = np.flatnonzero(txs == tx), np.flatnonzero(tys == ty)
            v = t[np.ix_(ys[rows] - ty * TILE, xs[cols] - tx * TILE)]
            out[np.ix_(rows, cols)] = np.where(v == FREE, np.uint8(bg), v) if bg else v
        return out

    def features(self, k: int, x0: int, y0: int, w: int, h: int, period: int = 0) -> np.ndarray | None:
        """The packed canvas mixes of the level pixels [x0, x0+w) x [y0, y0+h)
        of a level k levels above the finest (uint32 (h, w)); None when no
        painted pixel reaches them (or none is painted enough to count).
        ``period``: a toroidal tile's period n in finest pixels (the canvas is
        read at finest positions mod n).

        On the infinite canvas they come from tiles of MIX_TILE level pixels
        kept between calls and between label maps (a dab's map shares the
        untouched label tiles of the one before): a tile is computed again
        only when a label tile it reads changed, so a dab costs the tiles
        around it, not every level's whole region (each level pixel's mix
        depends on its own samples and its neighbors' alone)."""
        if self.empty:
            return None
        if period:
            return self._features(k, x0, y0, w, h, period)
        T = MIX_TILE
        out = None
        for ty in range(y0 // T, (y0 + h - 1) // T + 1):
            for tx in range(x0 // T, (x0 + w - 1) // T + 1):
                mix = self._tile_mixes(k, tx, ty)
                if mix is None:
                    continue
                if out is None:
                    out = np.zeros((h, w), np.uint32)
                ix0, iy0 = max(x0, tx * T), max(y0, ty * T)
                ix1, iy1 = min(x0 + w, (tx + 1) * T), min(y0 + h, (ty + 1) * T)
                out[iy0 - y0:iy1 - y0, ix0 - x0:ix1 - x0] = mix[iy0 - ty * T:iy1 - ty * T, ix0 - tx * T:ix1 - tx * T]
        return out if out is not None and out.any() else None

    def _tile_mixes(self, k: int, tx: int, ty: int) -> np.ndarray | None:
        """The mixes of level-k tile (tx, ty) (MIX_TILE^2 level pixels), from the
        cache when the label tiles they read are the same arrays as then."""
        T, f, b = MIX_TILE, 1 << k, 1 + erosion(k)
        lx0, lx1 = ((tx * T - b) * f) // TILE, (((tx + 1) * T + b) * f - 1) // TILE
        ly0, ly1 = ((ty * T - b) * f) // TILE, (((ty + 1) * T + b) * f - 1) // TILE
        if (lx1 - lx0 + 1) * (ly1 - ly0 + 1) <= len(self.tiles):
            reads = [(key, self.tiles[key]) for key in ((a, b) for b in range(ly0, ly1 + 1)
                                                         for a in range(lx0, lx1 + 1)) if key in self.tiles]
        else:
            reads = sorted((key, t) for key, t in self.tiles.items()
                           if lx0 <= key[0] <= lx1 and ly0 <= key[1] <= ly1)
        if not reads and not self.background:
            return None
        key = (k, tx, ty, self.background)
        with _MIX_LOCK:
            hit = _MIX_CACHE.get(key)
            if hit is not None and len(hit[0]) == len(reads) and all(
                    a[0] == b[0] and a[1] is b[1] for a, b in zip(hit[0], reads)):
                _MIX_CACHE.move_to_end(key)
                return hit[1]
        mix = self._features(k, tx * T, ty * T, T, T, 0)
        with _MIX_LOCK:
            _MIX_CACHE[key] = (reads, mix)  # (holding the arrays keeps their identity unique)
            _MIX_CACHE.move_to_end(key)
            while len(_MIX_CACHE) > MIX_CACHE_TILES:
                _MIX_CACHE.popitem(last=False)
        return mix

    def _features(self, k: int, x0: int, y0: int, w: int, h: int, period: int) -> np.ndarray | None:
        """features computed from the label samples themselves."""
        f = 1 << k
        s = min(f, 4)
        e = erosion(k)
        step, off = f // s, (f // s) // 2
        sub = np.arange(s) * step + off
        xs = ((np.arange(x0 - 1 - e, x0 + w + 1 + e) * f)[:, None] + sub[None, :]).ravel()
        ys = ((np.arange(y0 - 1 - e, y0 + h + 1 + e) * f)[:, None] + sub[None, :]).ravel()
        if period:
            xs, ys = xs & (period - 1), ys & (period - 1)
        lab = self.sample(xs, ys)
        if not lab.any():
            return None
        mix = _mix_features(lab, s, h + 2 * e, w + 2 * e)
        if e:  # painted only where the 3 x 3 neighbours are painted enough too
            painted = mix != 0
            held = painted[e:-e, e:-e].copy()
            for dy in range(-e, e + 1):
                for dx in range(-e, e + 1):
                    held &= painted[e + dy:e + dy + h, e + dx:e + dx + w]
            mix = np.where(held, mix[e:-e, e:-e], np.uint32(0)).astype(np.uint32)
        return mix


def _mix_features(lab: np.ndarray, s: int, h: int, w: int) -> np.ndarray:
    """Packed canvas mixes from (h + 2) s x (w + 2) s label samples (a border
    of one level pixel for the blur): counts per level pixel, the 3 x 3
    binomial blur, the two largest painted labels and the painted share."""
    # Counts of the values present only (one bincount), free first.
    values = np.union1d([FREE], np.unique(lab))
    lut = np.zeros(MAX_LABELS + 1, np.int64)
    lut[values] = np.arange(len(values))
    cell = (np.arange(h + 2)[:, None, None, None] * (w + 2) + np.arange(w + 2)[None, None, :, None])
    idx = (cell * len(values) + lut[lab.reshape(h + 2, s, w + 2, s)]).ravel()
    counts = np.bincount(idx, minlength=(h + 2) * (w + 2) * len(values)).reshape(h + 2, w + 2, len(values))
    blur = counts[:-2] * BINOMIAL[0] + counts[1:-1] * BINOMIAL[1] + counts[2:] * BINOMIAL[2]
    blur = blur[:, :-2] * BINOMIAL[0] + blur[:, 1:-1] * BINOMIAL[1] + blur[:, 2:] * BINOMIAL[2]
    total = 16 * s * s
    painted = total - blur[:, :, 0]
    share = (255 * painted) // total
    if len(values) == 1:
        return np.zeros((h, w), np.uint32)
    i1, i2, w1, w2 = top_two(blur[:, :, 1:])  # the painted values, ascending: ties keep the lower label
    ids = values[1:] - 1
    packed = pack_mix(ids[i1], ids[i2], w1, w2, share)
    return np.where(share >= SHARE_MIN, packed, np.uint32(0)).astype(np.uint32)


def propose_labels(an, n: int) -> np.ndarray:
    """Labels (uint8 (m, m), 0..n-1) proposed for an analyzed exemplar: its
    appearance vectors two levels above the finest (a region's look rather
    than a pixel's) clustered by k-means (scipy, fixed seed), then smoothed by
    a majority over a small window; ordered by mean brightness, darkest first."""
    from scipy import ndimage
    from scipy.cluster.vq import kmeans2, vq
    m = an.size
    level = max(0, an.L - 2)
    feat = an.levels[level].feat.reshape(m * m, -1).astype(np.float32)
    n = int(min(max(2, n), MAX_LABELS))
    step = max(1, (m * m) // 16384)
    centers, _ = kmeans2(feat[::step], n, seed=np.random.default_rng(7), minit="++")
    ids = vq(feat, centers.astype(np.float32))[0].reshape(m, m)
    sigma = max(1.0, m / 128.0)
    votes = np.stack([ndimage.gaussian_filter((ids == i).astype(np.float32), sigma, mode="wrap" if an.toroidal
                                              else "reflect") for i in range(n)], axis=2)
    ids = np.argmax(votes, axis=2)
    lum = an.levels[-1].stack.mean(axis=2)
    used = [i for i in range(n) if (ids == i).any()]
    order = sorted(used, key=lambda i: float(lum[ids == i].mean()))
    remap = np.zeros(n, np.uint8)
    remap[order] = np.arange(len(order), dtype=np.uint8)
    return remap[ids]
