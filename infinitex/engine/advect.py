"""Texture in motion: the synthesized texture flows along a velocity field
(LH06 section 7, texture advection), frame after frame, with a bounded past.

LH06 advects the previous frame's synthesized coordinates along the velocity
and regenerates only where the texture has become too distorted. Played from
frame 0 that makes frame t depend on every frame before it; here a frame
depends on at most ``2 * period`` frames, so any window of any frame is
computed alone, exactly, with a bounded margin (engine/controls/flow.py has the
field and its units).

**Chains.** Chain ``j`` is born at frame ``t_j = j * period`` from the static
texture ``T`` (the document's synthesis; every map of a material alike) and
lives ``2 * period`` frames. At age ``a`` its content at pixel ``p`` is the
static coordinate found by tracing ``p`` back ``a`` frames along the field
(semi-Lagrangian, in exact integers, 1/256 px)::

    d_0 = 0,  d_{i+1} = d_i - V(p + d_i)          (the trajectory of p)
    X = p + d_a - V0 t_j + R_j [moving]           (where in T the content was)
    S_j(p) = T[round(X)] + J (X - round(X))       (the sub-pixel rest as a remainder)

``V0`` is the uniform velocity: where the field is uniform every chain is the
same rigid slide of ``T`` and renewal changes nothing. ``R_j``, an offset per
chain (8 points on a circle of KEY_RADIUS px, taken in turn: 8 distinct ones,
consecutive chains 236 px apart), applies where the velocity map moves: there
a renewed chain brings new content instead of rewinding the old (the pulse of
flow-map shaders), and one synthesis of the static texture, KEY_RADIUS wider,
serves every chain of a window (no new synthesis when a chain is born). ``J`` is
the direction field's Jacobian at ``round(X)`` (identity without one).

**Renewal, not crossfade.** At frame t two chains are alive: the new one
(age ``a`` in [0, period)) and the old one (age ``a + period``). A pixel shows
the new chain where its blob has come due, ``h < (a + 1) / period``: blobs are
Voronoi cells of about BLOB px in the new chain's own positions (they move
with its content), their edges nudged along the exemplar's elements (a
watershed cell of its color gradient, within one patch), each with a turn
``h``: its cell's rank in a blue-noise table, so about the same share comes
in every frame, spread evenly (renewal_turns). A vote over 5 x 5 pixels keeps single
pixels from showing the other chain, and the finest level's correction mends
the cuts where the two meet. By the end of the period every pixel shows the
new chain, which then becomes the old one. No pixel ever blends two
textures: no ghosting and no loss of contrast; each frame renews about
1/period of the area. (Units of single elements made many short cuts:
neighborhood energy 1.47 of the static texture's on the pebbles vortex,
against 1.25 with blobs; a wide majority vote instead renewed everything at
mid-period, steps 3x the median.)

**Distortion** (LH06: the Frobenius norm of the observed Jacobian minus the
desired one; here ``|| D d_a ||``, the trajectory's stretch) bounds the period:
``Flow.suggested_period`` is about the frames in which the field's shear
stretches a chain to ``distortion`` over its two periods. Renewing stretched
places sooner than others, per pixel, was measured to come in bursts.

**Loops.** With ``loop = N`` (a multiple of the period), frames are taken
modulo N and chain indices modulo N / period: frame N is frame 0 exactly, and
the step N-1 -> N is a renewal step like the others. On a toroidal tile (a
source with a period n) positions, the field and the static texture repeat
with period n: a flipbook that tiles in space and loops in time. A uniform
velocity whose travel over N frames is a multiple of n loops without renewal.

**Cost.** A frame is a gather: two trajectories (one step each when frames are
played in order: the trajectories of the last frame are kept), two lookups in
static windows that are synthesized once per chain, and the choice; composed
in GL by engine/advect_gl.py (this module's numpy composition is its oracle,
and composes alone with a direction field), then corrected at the cuts.
"""
from __future__ import annotations

from functools import cached_property
from typing import Protocol

import numpy as np

from .controls.flow import MAX_FRAME, Q, Flow, FlowError
from .fixed import hash2, lowbias32
from .rect import Rect

SALT = 0x2545F491          # keeps the flow's hashes apart from the synthesis'
ENDLESS_KEYS = 8           # distinct chain offsets R_j of an endless animation
KEY_RADIUS = 128           # px: R_j is a point of KEY_RING, 8 points on a circle of this radius
KEY_RING = ((128, 0), (91, 91), (0, 128), (-91, 91), (-128, 0), (-91, -91), (0, -128), (91, -91))
BLOB = 32                  # px between the points whose Voronoi cells come in together (renewal_turns)
BLUE_NOISE = np.array([
    16, 159, 220, 57, 150, 91, 135, 105, 12, 224, 112, 27, 218, 10, 246, 44,
    232, 133, 26, 117, 248, 2, 192, 215, 58, 180, 146, 203, 95, 59, 151, 85,
    110, 67, 181, 198, 76, 168, 39, 126, 83, 252, 41, 72, 233, 169, 123, 200,
    172, 40, 236, 98, 47, 142, 231, 178, 17, 157, 119, 3, 138, 29, 241, 14,
    222, 147, 8, 161, 210, 25, 92, 66, 204, 99, 219, 176, 196, 107, 77, 54,
    93, 121, 74, 253, 130, 111, 244, 148, 33, 239, 60, 86, 46, 211, 153, 185,
    22, 213, 191, 30, 61, 183, 5, 193, 124, 162, 24, 134, 237, 7, 131, 245,
    170, 50, 101, 165, 141, 82, 221, 51, 75, 216, 104, 189, 164, 97, 37, 68,
    145, 223, 1, 205, 230, 19, 154, 115, 177, 9, 254, 43, 70, 226, 206, 109,
    250, 79, 129, 55, 114, 94, 249, 31, 207, 90, 152, 120, 15, 140, 179, 13,
    42, 197, 158, 242, 35, 173, 195, 65, 136, 228, 53, 199, 240, 87, 56, 118,
    149, 28, 88, 184, 69, 144, 6, 102, 167, 23, 81, 175, 36, 160, 217, 188,
    235, 106, 209, 11, 127, 238, 212, 45, 247, 128, 214, 108, 132, 20, 100, 71,
    171, 49, 137, 225, 52, 84, 155, 116, 73, 187, 0, 62, 251, 194, 227, 4,
    125, 255, 21, 166, 113, 182, 18, 201, 34, 139, 234, 156, 80, 38, 143, 63,
    186, 78, 96, 202, 32, 229, 64, 243, 163, 89, 48, 190, 122, 174, 103, 208,
], np.int64)  # 16 x 16 ranks (void and cluster, Ulichney 1993)
UNIT_NUDGE = 6             # px a unit's pixels are nudged by before their blob is found
J_SHIFT = 12               # Jacobians are Q12
VOTE = 2                   # a pixel shows the chain most of the (2 VOTE + 1)^2 around it show
SEAM = 4                   # the correction mends what lies this close to a cut between chains


class TextureSource(Protocol):
    """The static texture T that flows. A source that can also correct a state
    (``correction_region(rect)``, ``correct(rect, state)``, as SynthSource) has
    the cuts between chains mended."""

    m: int          # exemplar size
    wrap: bool      # the exemplar tiles (coordinates wrap) or not (they clamp)
    period: int     # a toroidal tile's size, or 0 (the infinite canvas)

    def window(self, rect: Rect, slack: int) -> tuple[np.ndarray, np.ndarray]:
        """Over ``rect``: the coordinates (H, W, 4) int32 with remainders, and
        which unit each pixel belongs to, (H, W, 2) int64 (the same over one
        element of the exemplar within one patch). ``slack``: how much more
        around it later calls will likely ask for."""

    def jacobians(self, rect: Rect) -> np.ndarray | None:
        """(H, W, 4) Q12 direction-field Jacobians over ``rect``, or None (identity)."""


class FlowFrames:
    """Frames of ``source``'s texture flowing along ``flow``: ``frame(t, rect)``
    gives the exact coordinates of any window of any frame. Frames asked in
    order over one window reuse the last frame's trajectories (the result is
    the same bit for bit)."""

    def __init__(self, source: TextureSource, flow: Flow, seed: int = 0, correct: bool = True, gl: bool = True):
        flow.validate()
        self.correct = correct and hasattr(source, "correct")
        if source.period and not flow.uniform:
            n = source.period
            h, w = flow.map.h, flow.map.w
            if (flow.map.x, flow.map.y, w, h) != (0, 0, n, n):
                raise FlowError(f"On a toroidal tile of {n} px the velocity map covers the tile: {n}x{n} at (0, 0).")
        self.source = source
        self.flow = flow
        self.seed = int(seed) & 0xFFFFFFFF
        self._rect: Rect | None = None
        self._paths: dict[int, np.ndarray] = {}  # age -> trajectory (H+1, W+1, 2) over the window
        self._base: tuple[np.ndarray, np.ndarray] | None = None
        # Composed in GL (engine/advect_gl.py) on a Synthesizer's context, without a direction
        # field; this module's numpy composition is its oracle (gl=False).
        self._gl = None
        if gl and getattr(source, "synth", None) is not None and not source.synth.controls.directed:
            from .advect_gl import GpuComposer
            self._gl = GpuComposer(self, source, VOTE, SEAM, BLOB, UNIT_NUDGE, KEY_RADIUS)

    def release(self) -> None:
        if self._gl is not None:
            self._gl.release()
            self._gl = None

    # -- which chains --------------------------------------------------------
    def chains(self, t: int) -> tuple[tuple[int, int, int], tuple[int, int, int]]:
        """((key, born, age) of the old chain, the same of the new one) at frame t:
        ``key`` picks R_j and the hashes, ``born`` is t_j (in frames)."""
        P, N = self.flow.period, self.flow.loop
        if N:
            t %= N
        elif not 0 <= t < MAX_FRAME:
            raise FlowError(f"Frames are numbered 0 to {MAX_FRAME - 1}, not {t}.")
        j1 = t // P
        a1 = t - j1 * P
        out = []
        for j, a in ((j1 - 1, a1 + P), (j1, a1)):
            if N:
                k = j % (N // P)
                out.append((k, k * P, a))
            else:
                out.append((j % ENDLESS_KEYS, j * P, a))
        return out[0], out[1]

    def turn_seed(self, key: int) -> int:
        """The seed of chain ``key``'s turns (renewal_turns)."""
        return (self.seed ^ SALT ^ ((key * 0x9E3779B9) & 0xFFFFFFFF)) & 0xFFFFFFFF

    def key_offset(self, key: int) -> tuple[int, int]:
        """R_j in px (0 for a uniform flow): a point of KEY_RING, three eighths of a
        turn from the last chain's (236 px away; any two at least 98 px apart, more
        than the texture's elements), where the seed says the ring starts. All
        within KEY_RADIUS: one synthesis of the static texture serves every chain."""
        if self.flow.uniform:
            return 0, 0
        start = int(hash2(np.int64(0), np.int64(0), 0, self.seed ^ SALT)[0]) & 7
        step = 3 * key
        chains = self.flow.loop // self.flow.period if self.flow.loop else 0
        if chains > 1 and chains % 8 == 1 and key == chains - 1:
            step += 4  # (a loop's last chain runs into its first: never from the same place)
        rx, ry = KEY_RING[(step + start) % 8]
        n = self.source.period
        return (rx % n, ry % n) if n else (rx, ry)

    # -- trajectories --------------------------------------------------------
    def _window(self, rect: Rect) -> None:
        if rect != self._rect:
            self._rect = rect
            self._paths = {}
            ys, xs = np.mgrid[rect.y0:rect.y1 + 1, rect.x0:rect.x1 + 1]
            self._base = (xs.astype(np.int64) * Q, ys.astype(np.int64) * Q)

    def trajectory(self, age: int) -> np.ndarray:
        """d_age over the current window plus one column and row, (H+1, W+1, 2) int64."""
        if age in self._paths:
            return self._paths[age]
        X, Y = self._base
        if self.flow.uniform:  # every step is the same
            d = np.empty(X.shape + (2,), np.int64)
            d[..., 0] = -age * self.flow.velocity[0]
            d[..., 1] = -age * self.flow.velocity[1]
        else:
            start = age - 1 if age - 1 in self._paths else 0
            d = self._paths[start].copy() if start else np.zeros(X.shape + (2,), np.int64)
            for _ in range(start, age):
                vx, vy = self.flow.sample(X + d[..., 0], Y + d[..., 1], self.source.period)
                d[..., 0] -= vx
                d[..., 1] -= vy
        self._paths[age] = d
        return d

    # -- a frame -------------------------------------------------------------
    def frame(self, t: int, rect: Rect) -> np.ndarray:
        """Coordinates (H, W, 4) int32 (exemplar texel x, y, remainders in 1/256 px) of frame t over rect."""
        return self.frame_with_jacobians(t, rect, False)[0]

    def frame_with_jacobians(self, t: int, rect: Rect, jacobians: bool = True):
        """The coordinates and the observed Jacobian of each pixel's texture, (H, W, 4) Q12:
        the direction field's J times the trajectory's ``I + D d`` (what turns a normal map)."""
        if not self.correct:
            return self._frame(t, rect, jacobians)[:2]
        # Where renewal has cut one chain against the other, the composite is corrected
        # on the finest level (LH06: regenerate by correction), as the synthesis mends its
        # own seams; elsewhere each chain's content moves untouched (a correction there
        # would re-decide moving texels at fixed canvas places: shimmer).
        region = self.source.correction_region(rect)
        raw, J, seam = self._frame(t, region, jacobians)
        y, x = slice(rect.y0 - region.y0, rect.y1 - region.y0), slice(rect.x0 - region.x0, rect.x1 - region.x0)
        out, seam = raw[y, x].copy(), seam[y, x]
        if seam.any():
            fixed = self.source.correct(rect, raw)
            c = fixed.shape[2]  # without a direction field, each pixel keeps its sub-pixel rest
            out[..., :c] = np.where(seam[..., None], fixed, out[..., :c])
        return out, (J[y, x] if J is not None else None)

    def draft_rgb(self, t: int, rect: Rect, palette: np.ndarray) -> np.ndarray:
        """Frame t over rect without the correction of its cuts, as RGB8 colors of
        ``palette`` (a map, uint8 (m, m, C)): what the editor plays (twice as
        fast; the colors bilinear in the map's 8 bits, within a level of the
        exports'). Composed and colored in GL when the frames are."""
        if self._gl is not None:
            return self._gl.draft_colors(t, rect, palette)
        from .subpixel import sample
        px = sample(palette, self._frame(t, rect, False)[0], self.source.wrap)
        return np.repeat(px[..., :1], 3, axis=2) if px.shape[2] < 3 else np.ascontiguousarray(px[..., :3])

    def _frame(self, t: int, rect: Rect, jacobians: bool):
        """(coordinates, Jacobians or None, the seams: (H, W) bool, within SEAM px of
        two chains that show different texels side by side) over rect."""
        if self._gl is not None and not jacobians:
            coords, seam = self._gl.frame(t, rect)
            return coords, None, seam
        old, new = self.chains(t)
        v, e = VOTE, SEAM
        self._window(Rect(rect.x0 - v - e, rect.y0 - v - e, rect.x1 + v + e, rect.y1 + v + e))
        keep = {old[2], new[2]}
        c0, _, d0, j0 = self._chain(*old, jacobians, turns=False)  # (the old chain's turns have passed)
        c1, unit, d1, j1 = self._chain(*new, jacobians)
        self._paths = {a: d for a, d in self._paths.items() if a in keep}  # the next frame steps from these
        # Each unit's turn comes at a steady rate, 1/period of them a frame (sooner where
        # the old chain has stretched, measured, came in bursts: jumps of 2.6x the median).
        due = unit < ((new[2] + 1) << 16) // self.flow.period
        # A vote over (2 VOTE + 1)^2 pixels: no pixel alone shows the other chain.
        take_new = _box_count(due, v) * 2 > (2 * v + 1) ** 2
        c0, c1 = c0[v:-v, v:-v], c1[v:-v, v:-v]
        coords = np.where(take_new[..., None], c1, c0).astype(np.int32)
        differ = np.any(c0 != c1, axis=-1)
        cut = np.zeros_like(take_new)
        cut[:, 1:] |= (take_new[:, 1:] != take_new[:, :-1]) & (differ[:, 1:] | differ[:, :-1])
        cut[1:, :] |= (take_new[1:, :] != take_new[:-1, :]) & (differ[1:, :] | differ[:-1, :])
        seam = _box_count(cut, e) > 0
        inner = (slice(e, -e), slice(e, -e))
        if not jacobians:
            return coords[inner], None, seam
        J = np.where(take_new[..., None], self._observed(d1, j1)[v:-v, v:-v], self._observed(d0, j0)[v:-v, v:-v])
        return coords[inner], J[inner], seam

    @staticmethod
    def _observed(d: np.ndarray, J: np.ndarray | None) -> np.ndarray:
        """(H, W, 4) Q12: J (I + D d), D d by forward differences of the trajectory (1/256 px per px)."""
        gx = d[:-1, 1:] - d[:-1, :-1]  # d(p + e_x) - d(p): column x of D d
        gy = d[1:, :-1] - d[:-1, :-1]
        M = np.stack([(Q + gx[..., 0]) << 4, gy[..., 0] << 4, gx[..., 1] << 4, (Q + gy[..., 1]) << 4], -1)
        if J is None:
            return M
        a = J.astype(np.int64)
        return np.stack([(a[..., 0] * M[..., 0] + a[..., 1] * M[..., 2]) >> J_SHIFT,
                         (a[..., 0] * M[..., 1] + a[..., 1] * M[..., 3]) >> J_SHIFT,
                         (a[..., 2] * M[..., 0] + a[..., 3] * M[..., 2]) >> J_SHIFT,
                         (a[..., 2] * M[..., 1] + a[..., 3] * M[..., 3]) >> J_SHIFT], -1)

    def _chain(self, key: int, born: int, age: int, jacobians: bool = False, turns: bool = True):
        """(coordinates (H, W, 4), its blobs' turns (H, W) in [0, 65536) (None without
        ``turns``), the trajectory, the direction field's J at each pixel's content or
        None) of one chain."""
        d = self.trajectory(age)
        X, Y = self._base
        vx, vy = self.flow.velocity
        X = X[:-1, :-1] + d[:-1, :-1, 0] - vx * born
        Y = Y[:-1, :-1] + d[:-1, :-1, 1] - vy * born
        n = self.source.period
        rx, ry = self.key_offset(key)
        moving = None
        if rx or ry:
            q0x, q0y = (X + Q // 2) >> 8, (Y + Q // 2) >> 8
            moving = self.flow.moving_at(q0x, q0y, n)
            X = X + np.where(moving, rx * Q, 0)
            Y = Y + np.where(moving, ry * Q, 0)
        qx, qy = (X + Q // 2) >> 8, (Y + Q // 2) >> 8
        fx, fy = X - qx * Q, Y - qy * Q
        slack = self.flow.reach(2 * self.flow.period) + 32 + (KEY_RADIUS if rx or ry else 0)
        if moving is None or moving.all() or not moving.any():
            T, pid, J = self._lookup(qx, qy, slack)
        else:  # two far-apart places of T: one window each
            T = np.empty(qx.shape + (4,), np.int32)
            pid = np.empty(qx.shape + (2,), np.int64)
            J = None
            for part in (moving, ~moving):
                t_, p_, j_ = self._lookup(qx[part], qy[part], slack)
                T[part], pid[part] = t_, p_
                if j_ is not None:
                    J = np.zeros(qx.shape + (4,), np.int64) if J is None else J
                    J[part] = j_
        m = self.source.m
        if J is not None:  # the rest of the position, turned into exemplar offsets
            J = J.astype(np.int64)
            ex = (J[..., 0] * fx + J[..., 1] * fy) >> J_SHIFT
            ey = (J[..., 2] * fx + J[..., 3] * fy) >> J_SHIFT
        else:
            ex, ey = fx, fy
        Fx = T[..., 0].astype(np.int64) * Q + T[..., 2] + ex
        Fy = T[..., 1].astype(np.int64) * Q + T[..., 3] + ey
        ux, uy = (Fx + Q // 2) >> 8, (Fy + Q // 2) >> 8
        out = np.empty(T.shape[:2] + (4,), np.int64)
        out[..., 2], out[..., 3] = Fx - ux * Q, Fy - uy * Q
        if self.source.wrap:
            out[..., 0], out[..., 1] = ux & (m - 1), uy & (m - 1)
        else:
            out[..., 0], out[..., 1] = np.clip(ux, 0, m - 1), np.clip(uy, 0, m - 1)
        return out, (renewal_turns(qx, qy, pid, self.turn_seed(key), n) if turns else None), d, J

    def _lookup(self, qx: np.ndarray, qy: np.ndarray, slack: int):
        """T, the patch ids and J at canvas pixels (qx, qy)."""
        n = self.source.period
        if n:
            qx, qy = qx % n, qy % n
            box = Rect(0, 0, n, n)
        else:
            box = Rect(int(qx.min()), int(qy.min()), int(qx.max()) + 1, int(qy.max()) + 1)
        T, pid = self.source.window(box, slack)
        J = self.source.jacobians(box)
        iy, ix = qy - box.y0, qx - box.x0
        return T[iy, ix], pid[iy, ix], (J[iy, ix] if J is not None else None)


MAX_STATIC_SIDE = 16384  # what one synthesis and the frame's GL textures cover (GL_MAX_TEXTURE_SIZE here)


def static_side(flow: Flow, w: int, h: int) -> int:
    """The largest side of what a w x h frame's composition reads at once: a
    chain's static window (the frame, the vote's and seams' margins, two periods
    of travel each way) and the GL textures made of it."""
    return max(w, h) + 2 * (VOTE + SEAM + 1) + 2 * (flow.reach(2 * flow.period) + 2) + 64


def _hash(*parts, seed: int) -> np.ndarray:
    """lowbias32 of the integer arrays ``parts`` chained with ``seed`` (uint32)."""
    with np.errstate(over="ignore"):
        h = lowbias32(np.uint32(seed & 0xFFFFFFFF))
        for p in parts:
            h = lowbias32(h ^ np.asarray(p).astype(np.uint32))
    return h


def renewal_turns(qx: np.ndarray, qy: np.ndarray, unit: np.ndarray, s: int, period: int = 0) -> np.ndarray:
    """When each pixel of a chain comes in, in [0, 65536): the value of the blob
    its content lies in. Blobs are the Voronoi cells of one jittered point per
    BLOB x BLOB px of the chain's own positions (qx, qy), so they move with the
    content; each pixel's position is first nudged by up to UNIT_NUDGE px by a
    hash of its unit (``unit``, (H, W, 2): an exemplar element within a patch),
    so a blob's edge runs along the elements' outlines rather than straight.
    A blob's value is its cell's rank in BLUE_NOISE (then a hash): about
    1/period of the area comes in each frame, spread evenly.
    On a toroidal tile of ``period`` px (a multiple of BLOB) the blobs repeat with it.
    ``s``: the chain's seed (FlowFrames.turn_seed)."""
    if period:
        qx, qy = qx % period, qy % period
    u = _hash(unit[..., 0], unit[..., 1], seed=s)
    n = 2 * UNIT_NUDGE + 1
    px = qx + (u % n).astype(np.int64) - UNIT_NUDGE
    py = qy + ((u >> np.uint32(8)) % n).astype(np.int64) - UNIT_NUDGE
    cx, cy = np.floor_divide(px, BLOB), np.floor_divide(py, BLOB)
    best = np.full(px.shape, np.iinfo(np.int64).max, np.int64)
    value = np.zeros(px.shape, np.int64)
    phase = int(lowbias32(np.uint32(s ^ 0x5BD1E995)))
    ox, oy = phase & 15, (phase >> 4) & 15  # where the chain's blue-noise table starts
    for dy in (-1, 0, 1):
        for dx in (-1, 0, 1):
            gx, gy = cx + dx, cy + dy
            if period:
                gx, gy = gx % (period // BLOB), gy % (period // BLOB)
                sx0, sy0 = cx + dx, cy + dy
            else:
                sx0, sy0 = gx, gy
            g = _hash(gx, gy, seed=s ^ 0x5BD1E995)
            sx = sx0 * BLOB + (g % BLOB).astype(np.int64)
            sy = sy0 * BLOB + ((g >> np.uint32(8)) % BLOB).astype(np.int64)
            dist = (px - sx) ** 2 + (py - sy) ** 2
            closer = dist < best
            best = np.where(closer, dist, best)
            # Stratified turns: a cell's turn is its rank in a 16 x 16 blue-noise
            # table (placed by the seed), its low bits a hash, so any window renews
            # about the same number of blobs every frame, spread evenly (uniform
            # turns came in clumps: steps up to 2.2x the median).
            rank = BLUE_NOISE[((gy + oy) & 15) * 16 + ((gx + ox) & 15)]
            value = np.where(closer, (rank << 8) | (g >> np.uint32(24)).astype(np.int64), value)
    return value


def _box_count(a: np.ndarray, r: int) -> np.ndarray:
    """How many of the (2r + 1)^2 values around each pixel are set (the result is 2r smaller a side)."""
    c = np.cumsum(np.cumsum(np.pad(a.astype(np.int32), ((1, 0), (1, 0))), 0), 1)
    k = 2 * r + 1
    return c[k:, k:] - c[:-k, k:] - c[k:, :-k] + c[:-k, :-k]


class SynthSource:
    """The static texture of a :class:`~infinitex.engine.synth.Synthesizer`:
    windows synthesized on demand (with slack, so that a chain's whole life is
    one synthesis) and kept; or a toroidal tile of ``period`` px, made once."""

    def __init__(self, synth, period: int = 0, keep: int = 6):
        self.synth = synth
        self.m = synth.analysis.size
        self.wrap = bool(synth.analysis.toroidal)
        self.period = int(period)
        self.keep = keep
        self._windows: list[tuple[Rect, np.ndarray, np.ndarray]] = []

    def window(self, rect: Rect, slack: int = 0) -> tuple[np.ndarray, np.ndarray]:
        if self.period:
            if not self._windows:
                n = self.period
                self._windows.append((Rect(0, 0, n, n), *self._synthesize(Rect(0, 0, n, n), n)))
            return self._windows[0][1:]
        for i, (r, c, p) in enumerate(self._windows):
            if r.contains(rect):
                self._windows.append(self._windows.pop(i))
                y, x = slice(rect.y0 - r.y0, rect.y1 - r.y0), slice(rect.x0 - r.x0, rect.x1 - r.x0)
                return c[y, x], p[y, x]
        big = Rect(rect.x0 - slack, rect.y0 - slack, rect.x1 + slack, rect.y1 + slack)
        c, p = self._synthesize(big, 0)
        self._windows.append((big, c, p))
        del self._windows[:-self.keep]
        return c[slack:slack + rect.h, slack:slack + rect.w], p[slack:slack + rect.h, slack:slack + rect.w]

    def _synthesize(self, rect: Rect, period: int) -> tuple[np.ndarray, np.ndarray]:
        """The finest level over rect, and each pixel's unit: (its exemplar element, its patch)."""
        s = self.synth
        fine = _with_remainders(s.toroidal(period) if period else s.window(rect, remainder=True))
        # A unit: one element of the exemplar (a pebble, a leaf) within one patch (the
        # coordinate less the position, constant over a coherent patch, to 8 px).
        cells = self.cells[fine[..., 1], fine[..., 0]]
        ys, xs = np.mgrid[rect.y0:rect.y1, rect.x0:rect.x1]
        ox, oy = fine[..., 0].astype(np.int64) - xs, fine[..., 1].astype(np.int64) - ys
        if self.wrap:
            ox, oy = ox & (self.m - 1), oy & (self.m - 1)
        return fine, np.stack([cells, (ox >> 3) * 4096 + (oy >> 3)], -1)

    @cached_property
    def cells(self) -> np.ndarray:
        """(m, m) int64: the exemplar cut into its elements (watershed of the color
        gradient, one seed per 8 x 8 px): what comes in at once."""
        return exemplar_cells(self.synth.analysis.levels[self.synth.L].stack)

    def correction_region(self, rect: Rect) -> Rect:
        """What the finest level's correction of ``rect`` reads."""
        return self._corrector.padded(self.synth.L, rect)

    def correct(self, rect: Rect, state: np.ndarray) -> np.ndarray:
        """The finest level's correction of ``state`` (over correction_region(rect)), over rect."""
        return self._corrector.correct(self.synth.L, rect, state)

    @cached_property
    def _corrector(self):
        from dataclasses import replace

        from .pyramid import Pyramid
        s = self.synth
        params = replace(s.params, period=self.period) if self.period else s.params
        return Pyramid(s.gpu, s.gan, params, scrolling=False, controls=s.controls)

    def release(self) -> None:
        if "_corrector" in self.__dict__:
            self._corrector.release()
            del self.__dict__["_corrector"]

    def jacobians(self, rect: Rect) -> np.ndarray | None:
        ctl = self.synth.controls
        if not ctl.directed:
            return None
        return ctl.direction.region(0, rect.x0, rect.y0, rect.w, rect.h, self.period)


def exemplar_cells(img: np.ndarray, spacing: int = 8) -> np.ndarray:
    """Elements of an exemplar (m, m, C) as labels (m, m) int64: the watershed of
    its smoothed color gradient from the gradient's minimum in each spacing^2 cell."""
    from scipy import ndimage
    a = ndimage.gaussian_filter(np.asarray(img, np.float64)[..., :3], (1.0, 1.0, 0), mode="wrap")
    g = sum(np.hypot(ndimage.sobel(a[..., c], 0, mode="wrap"), ndimage.sobel(a[..., c], 1, mode="wrap"))
            for c in range(a.shape[2]))
    g = np.rint(g / max(g.max(), 1e-9) * 65535).astype(np.uint16)
    m = g.shape[0]
    markers = np.zeros(g.shape, np.int32)
    label = 1
    for y in range(0, m, spacing):
        for x in range(0, m, spacing):
            block = g[y:y + spacing, x:x + spacing]
            i = int(np.argmin(block))
            markers[y + i // block.shape[1], x + i % block.shape[1]] = label
            label += 1
    return ndimage.watershed_ift(g, markers).astype(np.int64)


def _with_remainders(c: np.ndarray) -> np.ndarray:
    if c.shape[-1] == 4:
        return c.astype(np.int32, copy=False)
    out = np.zeros(c.shape[:2] + (4,), np.int32)
    out[..., :2] = c
    return out
