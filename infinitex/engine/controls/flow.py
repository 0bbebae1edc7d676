"""A velocity field over the infinite canvas: what makes texture flow
(LH06 section 7, texture advection; the frames are engine/advect.py's).

**Units.** Velocities are canvas pixels per frame, +x right and +y down the
image's rows, held exactly in 1/256 px (``Q``): a uniform velocity, plus a
:class:`VelocityMap` (a map of velocities placed on the canvas like a
direction map, adding to it over its rectangle and nothing outside it).

**Sampling** at a position ``X`` (1/256 px, pixel centers at multiples of 256)
is bilinear between the map's texels in integers, the same on every machine::

    i = X >> 8, f = X & 255 (per axis), texels outside the map count 0
    V = uniform + (v00 (256-fx)(256-fy) + v10 fx (256-fy) + v01 (256-fx) fy + v11 fx fy) >> 16

On a toroidal tile of n px the canvas, and the field, repeat with period n.

**Velocity maps** follow the direction maps' convention: red and green in
[0, 1], 0.5 = still (8-bit 127 and 128 both), scaled so that 0 and 1 are
``-speed`` and ``+speed`` px per frame; green points up (``y_up``, OpenGL)
unless the map is DirectX-style.
"""
from __future__ import annotations

import threading
from collections import OrderedDict
from dataclasses import dataclass
from functools import cached_property

import numpy as np

from ..fixed import FRAC_ONE

Q = FRAC_ONE              # 1/256 px
MAX_SPEED = 32            # px per frame, either axis, everywhere (uniform + map)
MAX_PERIOD = 128          # frames between renewals (engine/advect.py)
MIN_PERIOD = 2
MAX_LOOP = 4096           # frames of a seamless loop
MAX_FRAME = 1 << 20       # frame numbers of an endless animation: 0 .. MAX_FRAME - 1
MAX_MAP_SIDE = 8192
DEFAULT_PERIOD = 16
DEFAULT_DISTORTION = 0.6  # the Frobenius norm of (observed - desired Jacobian) at which a chain gives way early


class FlowError(ValueError):
    """A flow that cannot be made: one sentence for the user."""


TILE = 64                 # a velocity map's tiles (canvas pixels a side), shared between its edits
_DERIVED: OrderedDict = OrderedDict()  # (map key, what) -> dense arrays of the maps lately used
_DERIVED_LOCK = threading.Lock()        # (the editor's autosave thread reads them too)


class VelocityMap:
    """Velocities in 1/256 px per frame over the canvas rectangle of ``w`` x
    ``h`` pixels at (``x``, ``y``), texel (0, 0) at that pixel; zero outside it.

    Held as TILE x TILE tiles on the canvas' grid (int16 pairs; a tile that is
    all still is not kept), so a brush dab makes a map that shares every tile
    it did not touch with the one before (an undo step costs what it changed).
    ``values`` is the dense (h, w, 2) int32 array, made when asked for."""

    def __init__(self, values: np.ndarray | None = None, x: int = 0, y: int = 0, *,
                 tiles: dict | None = None, size: tuple[int, int] | None = None):
        if tiles is None:
            v = np.asarray(values)
            if v.ndim != 3 or v.shape[2] != 2 or not v.shape[0] or not v.shape[1]:
                raise FlowError("A velocity map is an (H, W, 2) array of velocities.")
            if max(v.shape[:2]) > MAX_MAP_SIDE:
                raise FlowError(f"A velocity map is at most {MAX_MAP_SIDE} px a side, not {v.shape[1]}x{v.shape[0]}.")
            if not np.issubdtype(v.dtype, np.integer) or np.abs(v.astype(np.int64)).max() > MAX_SPEED * Q:
                raise FlowError(f"A velocity map holds integers in 1/256 px per frame, at most {MAX_SPEED} px a side.")
            w, h = int(v.shape[1]), int(v.shape[0])
        else:
            w, h = (int(size[0]), int(size[1]))
            if not (0 < w <= MAX_MAP_SIDE and 0 < h <= MAX_MAP_SIDE):
                raise FlowError(f"A velocity map is at most {MAX_MAP_SIDE} px a side, not {w}x{h}.")
        self.x, self.y, self.w, self.h = int(x), int(y), w, h
        limit = 2 ** 31 - 2 ** 24  # where canvas positions end (engine/pyramid.py COORD_LIMIT)
        if not (-limit <= self.x and self.x + w <= limit and -limit <= self.y and self.y + h <= limit):
            raise FlowError(f"A velocity map lies within +-{limit} px of the canvas origin; "
                            f"({self.x}, {self.y}) is outside.")
        self.tiles = _split(v, self.x, self.y) if tiles is None else tiles

    @classmethod
    def from_unit(cls, rgb: np.ndarray, speed: float, y_up: bool = True, x: int = 0, y: int = 0) -> VelocityMap:
        """A map from red and green in [0, 1] (0.5 still), ``speed`` px per frame at 0 and 1."""
        if not 0 < speed <= MAX_SPEED:
            raise FlowError(f"The speed is more than 0 and at most {MAX_SPEED} px per frame, not {speed:g}.")
        v = 2.0 * np.asarray(rgb, np.float64)[..., :2] - 1.0
        v = np.where(np.abs(v) < 1.5 / 255.0, 0.0, v)
        if y_up:
            v[..., 1] = -v[..., 1]  # canvas y runs down
        return cls(np.rint(np.clip(v, -1.0, 1.0) * speed * Q).astype(np.int32), x, y)

    # -- what the engine reads ----------------------------------------------------

    @property
    def values(self) -> np.ndarray:
        """(h, w, 2) int32, 1/256 px per frame (read-only)."""
        return self._derived("values", self._dense)

    @property
    def flat(self) -> tuple[np.ndarray, np.ndarray]:
        """Each component in a border of 2 zero texels, flattened (int32; Flow.sample's lookups)."""
        def make():
            out = []
            for c in (0, 1):
                a = np.zeros((self.h + 4, self.w + 4), np.int32)
                a[2:self.h + 2, 2:self.w + 2] = self.values[..., c]
                out.append(a.ravel())
            return out[0], out[1]
        return self._derived("flat", make)

    @property
    def moving(self) -> np.ndarray:
        """(h, w) bool: texels with a velocity."""
        return self._derived("moving", lambda: np.any(self.values != 0, axis=2))

    def _derived(self, what: str, make):
        k = (self.key, what)
        with _DERIVED_LOCK:
            value = _DERIVED.get(k)
            if value is not None:
                _DERIVED.move_to_end(k)
                return value
        value = make()
        with _DERIVED_LOCK:
            _DERIVED[k] = value
            while len(_DERIVED) > 9:  # the maps of the last few edits (an undo, the player's)
                _DERIVED.popitem(last=False)
        return value

    def _dense(self) -> np.ndarray:
        out = np.zeros((self.h, self.w, 2), np.int32)
        for (tx, ty), t in self.tiles.items():
            x0, y0 = tx * TILE - self.x, ty * TILE - self.y
            a0, b0 = max(0, -x0), max(0, -y0)
            a1, b1 = min(TILE, self.w - x0), min(TILE, self.h - y0)
            out[y0 + b0:y0 + b1, x0 + a0:x0 + a1] = t[b0:b1, a0:a1]
        out.flags.writeable = False
        return out

    @cached_property
    def peak(self) -> int:
        """The largest |component| (1/256 px per frame)."""
        return max((_tile_facts(t)[0] for t in self.tiles.values()), default=0)

    @cached_property
    def key(self) -> bytes:
        """A digest of the rectangle and every tile's (each tile's own digest is
        kept with it: a map made by a dab hashes only the tiles it changed)."""
        import hashlib
        h = hashlib.sha256(np.array([self.w, self.h, self.x, self.y], np.int64).tobytes())
        for k in sorted(self.tiles):
            h.update(np.array(k, np.int64).tobytes())
            h.update(_tile_facts(self.tiles[k])[1])
        return h.digest()

    def nearest(self, qx: np.ndarray, qy: np.ndarray) -> np.ndarray:
        """(N, 2) int32: the velocity of the texel at each canvas pixel (qx, qy), read
        from the tiles (no dense array made: what the Flow tool's arrows draw)."""
        out = np.zeros((len(qx), 2), np.int32)
        inside = (qx >= self.x) & (qx < self.x + self.w) & (qy >= self.y) & (qy < self.y + self.h)
        for i in np.nonzero(inside)[0]:
            t = self.tiles.get((int(qx[i]) // TILE, int(qy[i]) // TILE))
            if t is not None:
                out[i] = t[int(qy[i]) % TILE, int(qx[i]) % TILE]
        return out

    def __eq__(self, other):
        return isinstance(other, VelocityMap) and self.key == other.key

    def __hash__(self):
        return hash(self.key)

    def __repr__(self) -> str:
        return f"VelocityMap({self.w}x{self.h} at ({self.x}, {self.y}), {len(self.tiles)} tiles)"

    # -- edits (the editor's Flow tool) -------------------------------------------

    def _grown(self, x0: int, y0: int, x1: int, y1: int, limit: int) -> tuple[int, int, int, int]:
        nx0, ny0 = min(self.x, x0), min(self.y, y0)
        nx1, ny1 = max(self.x + self.w, x1), max(self.y + self.h, y1)
        if max(nx1 - nx0, ny1 - ny0) > limit:
            raise FlowError(f"A painted flow covers at most {limit} px a side; erase or clear some first.")
        return nx0, ny0, nx1, ny1

    def painted(self, x0: int, y0: int, weights: np.ndarray, target: tuple[int, int],
                limit: int = MAX_MAP_SIDE) -> VelocityMap:
        """The map after a dab: each texel of the rectangle at (x0, y0) the size of
        ``weights`` (coverage in [0, 1]) moved toward ``target`` (1/256 px per
        frame) by its weight; the map grows to hold the dab (at most ``limit``
        px a side)."""
        hh, ww = weights.shape
        nx0, ny0, nx1, ny1 = self._grown(x0, y0, x0 + ww, y0 + hh, limit)
        tiles = dict(self.tiles)
        tgt = np.array(target, np.float64)
        for ty in range(y0 // TILE, -(-(y0 + hh) // TILE)):
            for tx in range(x0 // TILE, -(-(x0 + ww) // TILE)):
                a0, b0 = max(x0, tx * TILE), max(y0, ty * TILE)
                a1, b1 = min(x0 + ww, (tx + 1) * TILE), min(y0 + hh, (ty + 1) * TILE)
                wt = weights[b0 - y0:b1 - y0, a0 - x0:a1 - x0, None]
                if not wt.any():
                    continue
                old = tiles.get((tx, ty))
                t = np.zeros((TILE, TILE, 2), np.int16) if old is None else old.copy()
                sub = t[b0 - ty * TILE:b1 - ty * TILE, a0 - tx * TILE:a1 - tx * TILE]
                sub[...] = np.rint(sub + (tgt - sub) * wt).astype(np.int16)
                _keep(tiles, (tx, ty), t)
        if tiles:  # the rectangle shrinks to what still moves (an erased corner gives its room back)
            xs = [k[0] for k in tiles]
            ys = [k[1] for k in tiles]
            nx0, ny0 = max(nx0, min(xs) * TILE), max(ny0, min(ys) * TILE)
            nx1, ny1 = min(nx1, (max(xs) + 1) * TILE), min(ny1, (max(ys) + 1) * TILE)
        return VelocityMap(tiles=tiles, size=(max(1, nx1 - nx0), max(1, ny1 - ny0)), x=nx0, y=ny0)

    def merged(self, other: VelocityMap, limit: int = MAX_MAP_SIDE) -> VelocityMap:
        """This map with ``other`` laid over it (its rectangle replaced by ``other``'s texels)."""
        nx0, ny0, nx1, ny1 = self._grown(other.x, other.y, other.x + other.w, other.y + other.h, limit)
        tiles = dict(self.tiles)
        dense = other.values
        for ty in range(other.y // TILE, -(-(other.y + other.h) // TILE)):
            for tx in range(other.x // TILE, -(-(other.x + other.w) // TILE)):
                a0, b0 = max(other.x, tx * TILE), max(other.y, ty * TILE)
                a1, b1 = min(other.x + other.w, (tx + 1) * TILE), min(other.y + other.h, (ty + 1) * TILE)
                old = tiles.get((tx, ty))
                t = np.zeros((TILE, TILE, 2), np.int16) if old is None else old.copy()
                t[b0 - ty * TILE:b1 - ty * TILE, a0 - tx * TILE:a1 - tx * TILE] = \
                    dense[b0 - other.y:b1 - other.y, a0 - other.x:a1 - other.x]
                _keep(tiles, (tx, ty), t)
        return VelocityMap(tiles=tiles, size=(nx1 - nx0, ny1 - ny0), x=nx0, y=ny0)


_FACTS: dict = {}  # id of a tile -> (a weak reference to it, its peak, its digest)


def _tile_facts(t: np.ndarray) -> tuple[int, bytes]:
    """A tile's largest |component| and its digest, computed once per tile."""
    got = _FACTS.get(id(t))
    if got is None or got[0]() is not t:
        import hashlib
        import weakref
        got = (weakref.ref(t), int(np.abs(t).max()), hashlib.sha256(t.tobytes()).digest())
        with _DERIVED_LOCK:  # (the autosave thread hashes maps too)
            if len(_FACTS) > 65536:  # the tiles gone are forgotten
                for k in [k for k, v in _FACTS.items() if v[0]() is None]:
                    del _FACTS[k]
            _FACTS[id(t)] = got
    return got[1], got[2]


def _keep(tiles: dict, k: tuple[int, int], t: np.ndarray) -> None:
    if t.any():
        t.flags.writeable = False
        tiles[k] = t
    else:
        tiles.pop(k, None)


def _split(v: np.ndarray, x: int, y: int) -> dict:
    """A dense map's tiles on the canvas grid (all-still tiles left out)."""
    h, w = v.shape[:2]
    tiles: dict = {}
    for ty in range(y // TILE, -(-(y + h) // TILE)):
        for tx in range(x // TILE, -(-(x + w) // TILE)):
            a0, b0 = max(x, tx * TILE), max(y, ty * TILE)
            a1, b1 = min(x + w, (tx + 1) * TILE), min(y + h, (ty + 1) * TILE)
            t = np.zeros((TILE, TILE, 2), np.int16)
            t[b0 - ty * TILE:b1 - ty * TILE, a0 - tx * TILE:a1 - tx * TILE] = v[b0 - y:b1 - y, a0 - x:a1 - x]
            _keep(tiles, (tx, ty), t)
    return tiles


@dataclass(frozen=True)
class Flow:
    """How the texture moves: ``velocity`` (uniform, 1/256 px per frame) plus
    ``map``; ``period``: frames between renewals of the advected texture (a
    frame depends on at most 2 * period frames before it, engine/advect.py);
    ``loop``: frames of a seamless loop (frame ``loop`` is frame 0; a multiple
    of ``period``), 0 for an endless animation; ``distortion``: how far a
    chain of advected texture may stretch before it gives way early."""

    velocity: tuple[int, int] = (0, 0)
    map: VelocityMap | None = None
    period: int = DEFAULT_PERIOD
    loop: int = 0
    distortion: float = DEFAULT_DISTORTION

    @classmethod
    def of(cls, vx: float = 0.0, vy: float = 0.0, **kw) -> Flow:
        """A flow from a uniform velocity in px per frame (rounded to 1/256 px)."""
        for v in (vx, vy):
            if not np.isfinite(v) or abs(v) > MAX_SPEED:
                raise FlowError(f"A velocity is at most {MAX_SPEED} px per frame along each axis, not {v:g}.")
        return cls(velocity=(int(round(vx * Q)), int(round(vy * Q))), **kw)

    def validate(self) -> None:
        vx, vy = self.velocity
        if not isinstance(self.period, (int, np.integer)) or not MIN_PERIOD <= self.period <= MAX_PERIOD:
            raise FlowError(f"The renewal period is {MIN_PERIOD} to {MAX_PERIOD} frames, not {self.period}.")
        if self.loop:
            if not 0 < self.loop <= MAX_LOOP:
                raise FlowError(f"A loop is 1 to {MAX_LOOP} frames, not {self.loop}.")
            if self.loop % self.period:
                raise FlowError(f"A loop of {self.loop} frames needs a renewal period that divides it "
                                f"(not {self.period}).")
        if not 0.05 <= self.distortion <= 4.0:
            raise FlowError(f"The distortion threshold is 0.05 to 4, not {self.distortion:g}.")
        if self.peak > MAX_SPEED * Q:
            raise FlowError(f"The velocity reaches {self.peak / Q:g} px per frame; at most {MAX_SPEED}.")
        if max(abs(vx), abs(vy)) > MAX_SPEED * Q:
            raise FlowError(f"A velocity is at most {MAX_SPEED} px per frame along each axis.")

    @property
    def peak(self) -> int:
        """A bound on |V| along either axis, 1/256 px per frame."""
        return max(abs(self.velocity[0]), abs(self.velocity[1])) + (self.map.peak if self.map is not None else 0)

    @property
    def uniform(self) -> bool:
        """The same velocity everywhere: the texture slides rigidly."""
        return self.map is None or not self.map.peak

    @property
    def still(self) -> bool:
        return self.uniform and self.velocity == (0, 0)

    def suggested_period(self, loop: int = 0) -> int:
        """A renewal period for this field: about the frames in which its shear
        (the velocity gradient's Frobenius norm, 75th percentile over the texels
        that move) stretches a chain by ``distortion`` over its life of two
        periods, 12 to 32 frames (16 for a uniform flow); for a loop of ``loop``
        frames, the divisor of it nearest."""
        want = DEFAULT_PERIOD
        if not self.uniform:
            v = self.map.values.astype(np.float64) / Q
            if min(v.shape[:2]) > 1:
                gx, gy = np.diff(v, axis=1)[:-1], np.diff(v, axis=0)[:, :-1]
                g = np.sqrt((gx ** 2).sum(-1) + (gy ** 2).sum(-1))[self.map.moving[:-1, :-1]]
                shear = float(np.percentile(g, 75)) if g.size else 0.0
                if shear > 0:
                    want = int(np.clip(round(self.distortion / (2 * shear)), 12, 32))
        if not loop:
            return want
        divisors = [d for d in range(MIN_PERIOD, MAX_PERIOD + 1) if loop % d == 0]
        if not divisors:
            raise FlowError(f"A loop of {loop} frames needs a renewal period from {MIN_PERIOD} to {MAX_PERIOD} "
                            "that divides it; use a number of frames with such a divisor (32, 48, 64...).")
        return min(divisors, key=lambda d: (abs(d - want), -d))

    def reach(self, frames: int) -> int:
        """A bound on how far (px, either axis) content travels in ``frames`` frames, plus one."""
        return -(-frames * self.peak // Q) + 1

    def sample(self, X: np.ndarray, Y: np.ndarray, period: int = 0) -> tuple[np.ndarray, np.ndarray]:
        """The velocity (1/256 px per frame, int64) at positions X, Y (1/256 px, int64)."""
        vx = np.full(np.shape(X), self.velocity[0], np.int64)
        vy = np.full(np.shape(X), self.velocity[1], np.int64)
        if self.uniform:
            return vx, vy
        m = self.map
        h, w = m.h, m.w
        X = np.asarray(X, np.int64)
        Y = np.asarray(Y, np.int64)
        if period:
            X = X % (period * Q)
            Y = Y % (period * Q)
        ix, fx = X >> 8, (X & (Q - 1)).astype(np.int32)
        iy, fy = Y >> 8, (Y & (Q - 1)).astype(np.int32)
        vx_map, vy_map = m.flat
        row = w + 4
        if period:  # texel indices wrap: each corner on its own
            out = []
            for dx, dy in ((0, 0), (1, 0), (0, 1), (1, 1)):
                tx = np.clip((ix + dx) % period - m.x + 2, 1, w + 2)
                ty = np.clip((iy + dy) % period - m.y + 2, 1, h + 2)
                out.append((ty * row + tx).astype(np.intp))
        else:  # the map sits in a border of 2 zeros: a clipped corner reads zeros
            tx = np.clip(ix - m.x + 2, 0, w + 2)
            ty = np.clip(iy - m.y + 2, 0, h + 2)
            i00 = (ty * row + tx).astype(np.intp)
            out = [i00, i00 + 1, i00 + row, i00 + row + 1]
        gx, gy = Q - fx, Q - fy
        wgt = (gx * gy, fx * gy, gx * fy, fx * fy)  # int32: |v| <= 2^13, the weights sum to 2^16
        sx = sum(vx_map[i] * k for i, k in zip(out, wgt))
        sy = sum(vy_map[i] * k for i, k in zip(out, wgt))
        return vx + (sx >> 16), vy + (sy >> 16)

    def moving_at(self, qx: np.ndarray, qy: np.ndarray, period: int = 0) -> np.ndarray:
        """bool: the map gives canvas pixels (qx, qy) a velocity (its texel there is not still)."""
        if self.uniform:
            return np.zeros(np.shape(qx), bool)
        m = self.map
        h, w = m.h, m.w
        if period:
            qx, qy = qx % period, qy % period
        tx, ty = np.asarray(qx, np.int64) - m.x, np.asarray(qy, np.int64) - m.y
        inside = (tx >= 0) & (tx < w) & (ty >= 0) & (ty < h)
        return inside & m.moving[np.where(inside, ty, 0), np.where(inside, tx, 0)]
