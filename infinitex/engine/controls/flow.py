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


@dataclass(frozen=True, eq=False)
class VelocityMap:
    """Velocities (H, W, 2) int32 in 1/256 px per frame; texel (0, 0) is the
    canvas pixel (x, y)."""

    values: np.ndarray
    x: int = 0
    y: int = 0

    def __post_init__(self):
        v = np.asarray(self.values)
        if v.ndim != 3 or v.shape[2] != 2 or not v.shape[0] or not v.shape[1]:
            raise FlowError("A velocity map is an (H, W, 2) array of velocities.")
        if max(v.shape[:2]) > MAX_MAP_SIDE:
            raise FlowError(f"A velocity map is at most {MAX_MAP_SIDE} px a side, not {v.shape[1]}x{v.shape[0]}.")
        if not np.issubdtype(v.dtype, np.integer) or np.abs(v.astype(np.int64)).max() > MAX_SPEED * Q:
            raise FlowError(f"A velocity map holds integers in 1/256 px per frame, at most {MAX_SPEED} px a side.")
        object.__setattr__(self, "values", np.ascontiguousarray(v, np.int32))
        object.__setattr__(self, "x", int(self.x))
        object.__setattr__(self, "y", int(self.y))
        limit = 2 ** 31 - 2 ** 24  # where canvas positions end (engine/pyramid.py COORD_LIMIT)
        if not (-limit <= self.x and self.x + v.shape[1] <= limit and -limit <= self.y and self.y + v.shape[0] <= limit):
            raise FlowError(f"A velocity map lies within +-{limit} px of the canvas origin; "
                            f"({self.x}, {self.y}) is outside.")

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

    @cached_property
    def peak(self) -> int:
        """The largest |component| (1/256 px per frame)."""
        return int(np.abs(self.values).max())

    @cached_property
    def flat(self) -> tuple[np.ndarray, np.ndarray]:
        """Each component in a border of 2 zero texels, flattened (int32; Flow.sample's lookups)."""
        h, w = self.values.shape[:2]
        out = []
        for c in (0, 1):
            a = np.zeros((h + 4, w + 4), np.int32)
            a[2:h + 2, 2:w + 2] = self.values[..., c]
            out.append(a.ravel())
        return out[0], out[1]

    @cached_property
    def moving(self) -> np.ndarray:
        """(H, W) bool: texels with a velocity."""
        return np.any(self.values != 0, axis=2)

    @cached_property
    def key(self) -> bytes:
        import hashlib
        h = hashlib.sha256(self.values.tobytes())
        h.update(np.array([*self.values.shape, self.x, self.y], np.int64).tobytes())
        return h.digest()

    def __eq__(self, other):
        return isinstance(other, VelocityMap) and self.key == other.key

    def __hash__(self):
        return hash(self.key)


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
        h, w = m.values.shape[:2]
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
        h, w = m.values.shape[:2]
        if period:
            qx, qy = qx % period, qy % period
        tx, ty = np.asarray(qx, np.int64) - m.x, np.asarray(qy, np.int64) - m.y
        inside = (tx >= 0) & (tx < w) & (ty >= 0) & (ty < h)
        return inside & m.moving[np.where(inside, ty, 0), np.where(inside, tx, 0)]
