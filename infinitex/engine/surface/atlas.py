"""The atlas domain (LH06 section 6): synthesis directly in a mesh's texture
atlas, continuous across its UV seams.

The pyramid synthesizes the whole atlas as one window per level: level l holds
the atlas at ``size >> k`` texels (k = L - l). This class gives the passes,
per level and region (:class:`~infinitex.engine.controls.Controls` ``surface``):

**J per texel** (Q12, as engine/controls/direction.py): the map from an atlas
offset (finest texels) to the exemplar offset that shows there. On a triangle
with parameterization derivatives ``Pu = dP/du``, ``Pv = dP/dv`` and a
tangent frame (R, U) (the exemplar's +x along R, its up along U):
``J = sigma / size * [[R.Pu, -R.Pv], [-U.Pu, U.Pv]]`` (atlas and exemplar y
point down), sigma = exemplar px per world unit. The frame comes from
``frame``: "up" (U is the world's up projected on the surface: bricks stay
level on walls; near horizontal faces a second axis takes over) or "uv" (R
along the model's u direction). A chart mirrored against its frame mirrors the
texture (det J > 0 always); stretches are clamped to direction.py's range.
J is constant per triangle; a texel takes its covering triangle's J.

**The indirection map**: per texel (own chart or -1, the chart its link serves
or -1, the link's target texel). A texel within GUTTER + 1 of a chart's border
edge, outside that chart, links to the texel of the same surface point in the
chart across the edge: the triangle across the edge (welded by position) is
unfolded into the chart's plane and the affine map between the two charts'
coordinates sends the texel's centre over. The correction's, fidelity stage's
and upsampling's reads go through it (shaders/common.glsl ``atlas_texel``), so
neighborhoods continue across seams. A texel near two charts serves the nearer
one. Along open borders (no triangle across), a link goes to the chart's own
nearest texel.

**Coverage**: a texel belongs to the triangle whose interior holds its centre
(exact integer edge functions, positions in 1/256 finest texels, a top-left
rule on shared edges; overlapping triangles: the lowest index wins). All of it
is computed on the CPU from the model's arrays only (float64 geometry, then
integers), so the same model and settings give the same maps on any machine.
"""
from __future__ import annotations

import hashlib
import numpy as np

from ..controls.direction import J_ONE, MAX_STRETCH, MIN_DET, MIN_STRETCH, clamp_stretch
from ..controls.fields import TILE
from .mesh import Model

GUTTER = 4  # texels, at every level, that a chart's pixels may read beyond its border (the passes read <= 3)
SUB = 8  # bits below a finest texel of rasterized positions
MIN_SIZE, MAX_SIZE = 64, 4096
CHUNK = 1 << 21  # candidate texels rasterized at once
MAX_COVERAGE = 16  # triangles' bounding boxes may cover the atlas this many times over (overlapping UVs)
FRAMES = ("up", "uv")
MAX_CHARTS = 32000  # chart ids fit the int16 indirection texture


class AtlasError(ValueError):
    """An atlas that cannot be synthesized (one line)."""


def _edges(faces: np.ndarray):
    """Half-edges (F*3): (triangle, corner i -> i+1)."""
    t = np.repeat(np.arange(len(faces)), 3)
    i = np.tile(np.arange(3), len(faces))
    return t, faces[t, i], faces[t, (i + 1) % 3], faces[t, (i + 2) % 3]


def _match(key_a: np.ndarray, key_b: np.ndarray) -> np.ndarray:
    """For each half-edge with unordered key (a, b), another half-edge with the
    same key (the next one of its group, in index order, cyclically), or -1."""
    lo, hi = np.minimum(key_a, key_b), np.maximum(key_a, key_b)
    order = np.lexsort((np.arange(len(lo)), hi, lo))
    ls, hs = lo[order], hi[order]
    start = np.r_[True, (ls[1:] != ls[:-1]) | (hs[1:] != hs[:-1])]
    gid = np.cumsum(start) - 1
    gstart = np.flatnonzero(start)
    gsize = np.diff(np.r_[gstart, len(order)])
    pos = np.arange(len(order)) - gstart[gid]
    nxt = gstart[gid] + (pos + 1) % gsize[gid]
    res = np.empty(len(lo), np.int64)
    res[order] = np.where(gsize[gid] > 1, order[nxt], -1)
    return res


def _box_texels(ids: np.ndarray, x0: np.ndarray, y0: np.ndarray, w: np.ndarray, h: np.ndarray):
    """Every texel (id, x, y) of boxes [x0, x0 + w) x [y0, y0 + h), a chunk of
    about CHUNK texels at a time (a box larger than that is one chunk)."""
    cnt = np.maximum(w, 0) * np.maximum(h, 0)
    ends = np.cumsum(cnt)
    start = 0
    while start < len(ids):
        base = ends[start - 1] if start else 0
        stop = max(start + 1, int(np.searchsorted(ends, base + CHUNK, side="right")))
        c = cnt[start:stop]
        rep = np.repeat(np.arange(start, stop), c)
        off = np.arange(int(c.sum())) - np.repeat(np.cumsum(c) - c, c)
        bw = np.maximum(w[rep], 1)
        yield ids[rep], x0[rep] + off % bw, y0[rep] + off // bw
        start = stop


def triangle_jacobians(model: Model, uvpx: np.ndarray, sigma: float, frame: str,
                       up: np.ndarray) -> tuple[np.ndarray, float]:
    """J (Q12 int16, (F, 4)) per triangle (module docstring), and the share of
    triangles whose stretch was held within range."""
    P, X, f = model.positions, uvpx, model.faces
    e1, e2 = P[f[:, 1]] - P[f[:, 0]], P[f[:, 2]] - P[f[:, 0]]
    d1, d2 = X[f[:, 1]] - X[f[:, 0]], X[f[:, 2]] - X[f[:, 0]]
    dd = d1[:, 0] * d2[:, 1] - d2[:, 0] * d1[:, 1]  # the pixel edges' determinant
    ok = np.abs(dd) > 1e-12
    dd = np.where(ok, dd, 1.0)
    # G = [e1 e2] [d1 d2]^-1: dP per finest px (x, y down), elementwise.
    Gx = (e1 * d2[:, 1:2] - e2 * d1[:, 1:2]) / dd[:, None]
    Gy = (e2 * d1[:, 0:1] - e1 * d2[:, 0:1]) / dd[:, None]
    nrm = np.cross(e1, e2)
    nl = np.linalg.norm(nrm, axis=-1, keepdims=True)
    ok &= nl[:, 0] > 0
    N = nrm / np.maximum(nl, 1e-300)
    if frame == "up":
        Rr = np.cross(up_field(model, N, up), N)
    else:
        Rr = Gx - (Gx * N).sum(-1, keepdims=True) * N
    Rr = Rr / np.maximum(np.linalg.norm(Rr, axis=-1, keepdims=True), 1e-300)
    U = np.cross(N, Rr)
    s = sigma
    J = np.stack([s * (Rr * Gx).sum(-1), s * (Rr * Gy).sum(-1), -s * (U * Gx).sum(-1), -s * (U * Gy).sum(-1)],
                 axis=-1)  # (F, 4): j00, j01, j10, j11
    flip = J[:, 0] * J[:, 3] - J[:, 1] * J[:, 2] < 0  # mirrored against the frame: mirror the texture
    J[flip, 0:2] *= -1  # left-right (upside down would show more)
    J, clamped = clamp_stretch(J, 1.0 / MAX_STRETCH, 1.0 / MIN_STRETCH)
    # Share of the triangles whose texture had to be held within the stretch range (reported by the CLI).
    stretch_clamped = float(np.mean(clamped & ok))
    q = np.round(J * J_ONE).astype(np.int64)
    det = q[:, 0] * q[:, 3] - q[:, 1] * q[:, 2]
    q[(det < MIN_DET) | ~ok] = [J_ONE, 0, 0, J_ONE]
    return q.astype(np.int16), stretch_clamped

def unit_up(up) -> np.ndarray:
    """The up direction as a unit vector (AtlasError unless three finite numbers,
    not all zero), scaled first so that no magnitude overflows or vanishes."""
    u = np.asarray(up, np.float64)
    if u.shape != (3,) or not np.isfinite(u).all() or not np.any(u):
        raise AtlasError("The up direction must be three finite numbers, not all zero.")
    u = u / np.abs(u).max()
    return u / np.linalg.norm(u)


def up_field(model: Model, N: np.ndarray, up: np.ndarray) -> np.ndarray:
    """Per triangle, where the exemplar's up points ("up" frame): the world's
    up projected on the surface; on faces turned towards up or down (where
    that vanishes) it blends into the up folded over the model's rims, so
    across a rim the texture runs on: inwards (towards the vertical axis
    through the model's centre) on top, outwards underneath. The field is
    continuous but at the axis (hairy ball: some point must be singular)."""
    P, f = model.positions, model.faces
    centre = 0.5 * (P.min(axis=0) + P.max(axis=0))
    tc = P[f].mean(axis=1)
    radial = centre - tc
    radial -= (radial * up).sum(-1)[:, None] * up  # elementwise (no BLAS: the same bits everywhere)
    radial *= np.sign((N * up).sum(-1) + 1e-300)[:, None]

    def tangent(v):
        t = v - (v * N).sum(-1, keepdims=True) * N
        return t, np.linalg.norm(t, axis=-1, keepdims=True)
    pu, lu = tangent(np.broadcast_to(up, N.shape))
    pr, lr = tangent(radial)
    side = np.clip((lu - 0.1) / 0.4, 0.0, 1.0)  # 1 on walls, 0 on faces within 25 degrees of flat
    u = side * pu / np.maximum(lu, 1e-300) + (1 - side) * pr / np.maximum(lr, 1e-300)
    # At the axis itself (no radial direction) and where the two cancel: any fixed tangent.
    alt, _ = tangent(np.broadcast_to(np.cross(up, [1.0, 0.0, 0.0]) if abs(up[0]) < 0.9
                                     else np.cross(up, [0.0, 0.0, 1.0]), N.shape))
    lu2 = np.linalg.norm(u, axis=-1, keepdims=True)
    return np.where(lu2 > 1e-6, u, alt)


def compose(field: np.ndarray | None, jac: np.ndarray) -> np.ndarray:
    """Q12 J_comb J_frame per texel (field None: J_frame), in integers (round
    half up), then held within the stretch range (clamp_stretch) where the two
    stretches add up beyond it; where the product degenerates, J_frame."""
    if field is None:
        return jac
    f = field.reshape(-1, 4).astype(np.int64)
    j = jac.reshape(-1, 4).astype(np.int64)
    sel = np.flatnonzero(np.any(f != [J_ONE, 0, 0, J_ONE], axis=1))
    if not len(sel):
        return jac
    a, b = f[sel], j[sel]
    q = np.stack([a[:, 0] * b[:, 0] + a[:, 1] * b[:, 2], a[:, 0] * b[:, 1] + a[:, 1] * b[:, 3],
                  a[:, 2] * b[:, 0] + a[:, 3] * b[:, 2], a[:, 2] * b[:, 1] + a[:, 3] * b[:, 3]], -1)
    q = (q + (J_ONE >> 1)) >> 12
    held, changed = clamp_stretch(q.astype(np.float64) / J_ONE, 1.0 / MAX_STRETCH, 1.0 / MIN_STRETCH)
    q[changed] = np.round(held[changed] * J_ONE).astype(np.int64)  # (the rest exactly as they were)
    det = q[:, 0] * q[:, 3] - q[:, 1] * q[:, 2]
    out = j.copy()
    keep = det >= MIN_DET
    out[sel[keep]] = q[keep]
    return out.reshape(jac.shape).astype(np.int16)


class AtlasDomain:
    """A model's atlas at ``size`` finest texels, textured at ``sigma`` exemplar
    px per world unit with tangent frames from ``frame``; ``seams=False`` gives
    every chart no links (the naive per-chart synthesis, for comparison)."""

    def __init__(self, model: Model, size: int, sigma: float, frame: str = "up", up=(0.0, 1.0, 0.0),
                 seams: bool = True):
        if size & (size - 1) or not MIN_SIZE <= size <= MAX_SIZE:
            raise AtlasError(f"The atlas size must be a power of two from {MIN_SIZE} to {MAX_SIZE}.")
        if frame not in FRAMES:
            raise AtlasError(f"The tangent frame must be one of {', '.join(FRAMES)}.")
        if not (np.isfinite(sigma) and sigma > 0):
            raise AtlasError("The texture scale must be a positive number.")
        up = unit_up(up)
        self.model = model
        self.size = int(size)
        self.sigma = float(sigma)
        self.frame = frame
        self.up = up
        self.seams = bool(seams)
        self.comb = None  # a direction field combed over the model (combed)
        self._levels: dict[int, dict] = {}  # geometry per level (shared by reframed copies)
        self._jac_levels: dict[int, np.ndarray] = {}
        self._topology()
        self.key = self._make_key()

    # -- topology, frames and maps across edges (once) -------------------------

    def _topology(self) -> None:
        from scipy.sparse import coo_matrix  # scipy imported when a model is opened, not by every command
        from scipy.sparse.csgraph import connected_components
        m = self.model
        f = m.faces
        self.uvpx = np.stack([m.uvs[:, 0] * self.size, (1.0 - m.uvs[:, 1]) * self.size], axis=-1)  # finest px, y down
        # Welded by position (to 2^-24 of the model's size: exporters may round split vertices differently).
        _, pid = np.unique(np.round(m.positions / (m.extent * 2.0 ** -24)), axis=0, return_inverse=True)
        pid = pid.reshape(-1)
        self._pid = pid
        _, uvid = np.unique(np.c_[pid, np.round(m.uvs * 2 ** 30)], axis=0, return_inverse=True)
        uvid = uvid.reshape(-1)
        t, a, b, c = _edges(f)
        across_uv = _match(uvid[a], uvid[b])  # the same edge in the same chart
        across_3d = _match(pid[a], pid[b])  # the same edge on the surface
        same = across_uv >= 0
        g = coo_matrix((np.ones(int(same.sum())), (t[same], t[across_uv[same]])), shape=(len(f), len(f)))
        n, chart = connected_components(g, directed=False)
        if n > MAX_CHARTS:
            raise AtlasError(f"{m.name} has {n:,} UV charts; at most {MAX_CHARTS:,} are supported.")
        self.charts = n
        self.chart = chart.astype(np.int32)
        # Border half-edges: no neighbor in the same chart.
        border = ~same
        self.b_tri = t[border]
        self.b_a, self.b_b, self.b_c = a[border], b[border], c[border]
        other = across_3d[border]
        self.b_other = np.where(other >= 0, t[np.maximum(other, 0)], -1)
        self.b_map = self._maps(other, t, a, b, c, border)
        self.jac, self.stretch_clamped = triangle_jacobians(self.model, self.uvpx, self.sigma, self.frame, self.up)

    def _maps(self, other, t, a, b, c, border) -> np.ndarray:
        """Per border half-edge, the affine map (2 x 3) from this chart's finest
        px to those of the triangle across it (unfolded into this triangle's plane)."""
        P, X = self.model.positions, self.uvpx
        n = int(border.sum())
        maps = np.zeros((n, 2, 3))
        ok = other >= 0
        if not ok.any():
            return maps
        o = np.maximum(other, 0)
        oa, ob, oc = a[o], b[o], c[o]  # the other half-edge runs the shared edge the other way (or not)
        pa, pb, pc = self.b_a, self.b_b, self.b_c
        # The other triangle's vertices matching this edge's ends, by position.
        pos = P
        same_dir = self._pid[oa] == self._pid[pa]  # welded, like the seams themselves
        q0 = np.where(same_dir, oa, ob)
        q1 = np.where(same_dir, ob, oa)
        q2 = oc
        P0, P1, P2, Q2 = pos[pa], pos[pb], pos[pc], pos[q2]
        e = P1 - P0
        el = np.linalg.norm(e, axis=-1, keepdims=True)
        eh = e / np.maximum(el, 1e-300)
        inner = (P2 - P0) - ((P2 - P0) * eh).sum(-1, keepdims=True) * eh
        inn = inner / np.maximum(np.linalg.norm(inner, axis=-1, keepdims=True), 1e-300)
        rel = Q2 - P0
        along = (rel * eh).sum(-1, keepdims=True)
        height = np.linalg.norm(rel - along * eh, axis=-1, keepdims=True)
        unfolded = P0 + along * eh - height * inn  # Q2 turned about the edge into this triangle's plane
        # Its coordinates in this triangle's parameterization (finest px, affine on the plane).
        E1, E2, R = P1 - P0, P2 - P0, unfolded - P0
        g11, g12, g22 = (E1 * E1).sum(-1), (E1 * E2).sum(-1), (E2 * E2).sum(-1)
        r1, r2 = (R * E1).sum(-1), (R * E2).sum(-1)
        det = g11 * g22 - g12 * g12
        good = ok & (np.abs(det) > 1e-300)
        det = np.where(good, det, 1.0)
        al, be = (g22 * r1 - g12 * r2) / det, (g11 * r2 - g12 * r1) / det
        A0, A1, A2 = X[pa], X[pb], X[pc]
        A2u = A0 + al[:, None] * (A1 - A0) + be[:, None] * (A2 - A0)
        B0, B1, B2 = X[q0], X[q1], X[q2]
        # The affine map sending (A0, A1, A2u) to (B0, B1, B2): linear part L = [B1-B0, B2-B0] [A1-A0, A2u-A0]^-1,
        # written out elementwise (IEEE operations only: the same bits on every machine, no LAPACK).
        u1, u2 = A1 - A0, A2u - A0
        v1, v2 = B1 - B0, B2 - B0
        dets = u1[:, 0] * u2[:, 1] - u2[:, 0] * u1[:, 1]
        good &= np.abs(dets) > 1e-12
        dets = np.where(good, dets, 1.0)
        i00, i01, i10, i11 = u2[:, 1] / dets, -u2[:, 0] / dets, -u1[:, 1] / dets, u1[:, 0] / dets
        maps = np.zeros((n, 2, 3))
        for r in range(2):
            maps[:, r, 0] = v1[:, r] * i00 + v2[:, r] * i10
            maps[:, r, 1] = v1[:, r] * i01 + v2[:, r] * i11
            maps[:, r, 2] = B0[:, r] - maps[:, r, 0] * A0[:, 0] - maps[:, r, 1] * A0[:, 1]
        maps[~good] = 0
        self.b_other = np.where(good, self.b_other, -1)
        return maps

    # -- per level ------------------------------------------------------------

    def level_size(self, k: int) -> int:
        return max(1, self.size >> k)

    def _level(self, k: int) -> dict:
        if k not in self._levels:
            self._levels[k] = self._build_level(k)
        return self._levels[k]

    def _rasterize(self, k: int) -> np.ndarray:
        """(n, n) int32: the triangle covering each texel centre of level k, or -1."""
        n = self.level_size(k)
        f = self.model.faces
        Xq = np.round(self.uvpx * (1 << SUB)).astype(np.int64)
        A, B, C = Xq[f[:, 0]], Xq[f[:, 1]], Xq[f[:, 2]]
        area = (B[:, 0] - A[:, 0]) * (C[:, 1] - A[:, 1]) - (B[:, 1] - A[:, 1]) * (C[:, 0] - A[:, 0])
        swap = area < 0
        B, C = np.where(swap[:, None], C, B), np.where(swap[:, None], B, C)
        tris = np.flatnonzero(area != 0)
        step = 1 << (k + SUB)
        half = step >> 1
        V = np.stack([A, B, C], axis=1)[tris]  # (T, 3, 2)
        lo = V.min(axis=1)
        hi = V.max(axis=1)
        x0 = np.clip(-((half - lo) // step), 0, n)  # ceil((lo - half) / step)
        x1 = np.clip((hi - half) // step + 1, 0, n)
        w = np.maximum(x1[:, 0] - x0[:, 0], 0)
        h = np.maximum(x1[:, 1] - x0[:, 1], 0)
        if int((w * h).sum()) > MAX_COVERAGE * n * n + CHUNK:
            raise AtlasError(f"{self.model.name}: its triangles cover the atlas {int((w * h).sum()) / (n * n):.0f} "
                             "times over; its UVs overlap heavily or lie far outside [0, 1].")
        # Pieces of at most about CHUNK candidates: large triangles in bands of rows.
        rows = np.maximum(1, CHUNK // np.maximum(w, 1))
        bands = np.where(w > 0, -(-h // rows), 0)
        piece = np.repeat(np.arange(len(tris)), bands)
        k_in = np.arange(int(bands.sum())) - np.repeat(np.cumsum(bands) - bands, bands)
        py0 = x0[piece, 1] + k_in * rows[piece]
        py1 = np.minimum(py0 + rows[piece], x1[piece, 1])
        best = np.full(n * n, np.iinfo(np.int32).max, np.int64)
        for ti, tx, ty in _box_texels(piece, x0[piece, 0], py0, w[piece], py1 - py0):
            px, py = tx * step + half, ty * step + half
            inside = np.ones(len(ti), bool)
            for i in range(3):
                P0, P1 = V[ti, i], V[ti, (i + 1) % 3]
                ex, ey = P1[:, 0] - P0[:, 0], P1[:, 1] - P0[:, 1]
                E = ex * (py - P0[:, 1]) - ey * (px - P0[:, 0])
                topleft = (ey < 0) | ((ey == 0) & (ex > 0))
                inside &= (E > 0) | ((E == 0) & topleft)
            idx = ty[inside] * n + tx[inside]
            np.minimum.at(best, idx, tris[ti[inside]])
        out = np.where(best == np.iinfo(np.int32).max, -1, best).astype(np.int32)
        return out.reshape(n, n)

    def _build_level(self, k: int) -> dict:
        from scipy import ndimage
        n = self.level_size(k)
        tri = self._rasterize(k)
        covered = tri >= 0
        own = np.where(covered, self.chart[np.maximum(tri, 0)], -1).astype(np.int32)
        # The nearest covered texel of every texel (fills J off the charts; open borders; landings).
        if covered.any():
            near = ndimage.distance_transform_edt(~covered, return_distances=False, return_indices=True)
        else:
            near = np.indices((n, n))
        near_tri = tri[near[0], near[1]] if covered.any() else tri  # whose J a texel takes (-1: none)
        link_chart = np.full((n, n), -1, np.int32)
        link_to = np.zeros((n, n, 2), np.int32)
        if self.seams and len(self.b_tri):
            self._links(k, n, own, near, link_chart, link_to)
        return dict(own=own.astype(np.int16), near_tri=near_tri.astype(np.int32),
                    link_chart=link_chart.astype(np.int16), link_to=link_to.astype(np.int16))

    def _level_jac(self, k: int) -> np.ndarray:
        """J per texel of level k (its covering triangle's, off the charts the
        nearest texel's), after the combed field's (``combed``) where there is one."""
        if k not in self._jac_levels:
            if self.comb is not None:  # the frame's (kept by the atlas combed), composed over the painted tiles
                jac = self._frame._level_jac(k).copy()
                n = self.level_size(k)
                for x, y in self.comb.painted_tiles(k):
                    if 0 <= x < n and 0 <= y < n:  # (tiles are aligned: one beyond the atlas is wholly out)
                        w, h = min(n - x, TILE), min(n - y, TILE)
                        jac[y:y + h, x:x + w] = compose(self.comb.region(k, x, y, w, h), jac[y:y + h, x:x + w])
            else:
                t = self._level(k)["near_tri"]
                jac = self.jac[np.maximum(t, 0)]
                jac[t < 0] = [J_ONE, 0, 0, J_ONE]
            self._jac_levels[k] = np.ascontiguousarray(jac, np.int16)
        return self._jac_levels[k]

    def combed(self, field) -> AtlasDomain:
        """The same atlas with a direction field combed over the model (a
        DirectionField in this atlas' finest texels, or None): where painted,
        the texture turns, grows and stretches from its frame's (J = J_comb J_frame)."""
        if field is not None and field.identity:
            field = None
        if field is self.comb or (field is not None and field == self.comb):
            return self
        if field is None:
            return self._frame
        import copy
        out = copy.copy(self)
        out._frame = self if self.comb is None else self._frame  # the atlas uncombed: its J levels are kept
        out.comb = field
        out._jac_levels = {}
        out._feature_copies = {}
        out.key = out._make_key()
        return out

    def reframed(self, sigma: float, frame: str | None = None, up=None) -> AtlasDomain:
        """The same atlas (coverage, charts, indirection maps: shared, not computed
        again) with another scale, frame or up: only the Jacobians change (a
        combed field stays, over the new frame)."""
        if self.comb is not None:
            return self._frame.reframed(sigma, frame, up).combed(self.comb)
        import copy
        out = copy.copy(self)
        out.sigma = float(sigma)
        out.frame = self.frame if frame is None else frame
        if out.frame not in FRAMES or not (np.isfinite(out.sigma) and out.sigma > 0):
            raise AtlasError("The tangent frame or the texture scale is not valid.")
        if up is not None:
            out.up = unit_up(up)
        out._jac_levels = {}
        out._feature_copies = {}  # their J follows the frame and scale
        out.jac, out.stretch_clamped = triangle_jacobians(out.model, out.uvpx, out.sigma, out.frame, out.up)
        out.key = out._make_key()
        return out

    def _make_key(self) -> str:
        return hashlib.sha256(repr((self.model.key, self.size, self.sigma, self.frame, self.up.tolist(),
                                    self.seams, None if self.comb is None else self.comb.key)).encode()).hexdigest()

    def _links(self, k: int, n: int, own, near, link_chart, link_to) -> None:
        """Fill the level's indirection map (module docstring)."""
        scale = float(1 << k)
        X = self.uvpx / scale  # level-k px
        a, b = X[self.b_a], X[self.b_b]
        reach = GUTTER + 1.0
        # Each edge's band, box by box along it (pieces of at most 32 px: a long diagonal edge's
        # bounding box would be mostly far from it).
        pieces = np.maximum(1, np.ceil(np.linalg.norm(b - a, axis=-1) / 32.0)).astype(np.int64)
        pe = np.repeat(np.arange(len(a)), pieces)
        j = np.arange(int(pieces.sum())) - np.repeat(np.cumsum(pieces) - pieces, pieces)
        sa = a[pe] + (j / pieces[pe])[:, None] * (b - a)[pe]
        sb = a[pe] + ((j + 1) / pieces[pe])[:, None] * (b - a)[pe]
        lo = np.floor(np.minimum(sa, sb) - reach - 0.5).astype(np.int64)
        hi = np.ceil(np.maximum(sa, sb) + reach - 0.5).astype(np.int64)
        lo, hi = np.clip(lo, 0, n), np.clip(hi + 1, 0, n)
        e_chart = self.chart[self.b_tri]
        best_d = np.full(n * n, np.inf)
        best_e = np.full(n * n, -1, np.int64)
        for ei, tx, ty in _box_texels(pe, lo[:, 0], lo[:, 1], hi[:, 0] - lo[:, 0], hi[:, 1] - lo[:, 1]):
            keep = own[ty, tx] != e_chart[ei]
            ei, tx, ty = ei[keep], tx[keep], ty[keep]
            pa, pb = a[ei], b[ei]
            d = pb - pa
            pc = np.stack([tx + 0.5, ty + 0.5], axis=-1)
            tt = np.clip(((pc - pa) * d).sum(-1) / np.maximum((d * d).sum(-1), 1e-300), 0.0, 1.0)
            dist = np.linalg.norm(pc - (pa + tt[:, None] * d), axis=-1)
            near_enough = dist <= reach
            ei, tx, ty, dist = ei[near_enough], tx[near_enough], ty[near_enough], dist[near_enough]
            idx = ty * n + tx
            if not len(idx):
                continue
            # Per texel, the nearest edge (ties: the lower edge index): sort, take firsts, merge.
            order = np.lexsort((ei, dist, idx))
            idx, ei, dist = idx[order], ei[order], dist[order]
            first = np.r_[True, idx[1:] != idx[:-1]]
            idx, ei, dist = idx[first], ei[first], dist[first]
            better = (dist < best_d[idx]) | ((dist == best_d[idx]) & (ei < best_e[idx]))
            best_d[idx[better]] = dist[better]
            best_e[idx[better]] = ei[better]
        hit = np.flatnonzero(best_e >= 0)
        if not len(hit):
            return
        e = best_e[hit]
        ty, tx = hit // n, hit % n
        chart_a = e_chart[e]
        other = self.b_other[e]
        # Across the edge: the texel centre through the edge's map (finest px), then to level k.
        cx, cy = (tx + 0.5) * scale, (ty + 0.5) * scale
        M = self.b_map[e]
        gx = M[:, 0, 0] * cx + M[:, 0, 1] * cy + M[:, 0, 2]
        gy = M[:, 1, 0] * cx + M[:, 1, 1] * cy + M[:, 1, 2]
        ux = np.clip(np.floor(gx / scale).astype(np.int64), 0, n - 1)
        uy = np.clip(np.floor(gy / scale).astype(np.int64), 0, n - 1)
        want = np.where(other >= 0, self.chart[np.maximum(other, 0)], chart_a)
        open_edge = other < 0
        # Open borders: the chart's own nearest texel.
        ux = np.where(open_edge, near[1][ty, tx], ux)
        uy = np.where(open_edge, near[0][ty, tx], uy)
        # A landing off the wanted chart (a border texel whose centre it does not cover): its nearest covered texel.
        miss = own[uy, ux] != want
        nx, ny = near[1][uy, ux], near[0][uy, ux]
        fix = miss & (own[ny, nx] == want)
        ux, uy = np.where(fix, nx, ux), np.where(fix, ny, uy)
        good = own[uy, ux] == want
        link_chart[ty[good], tx[good]] = chart_a[good]
        link_to[ty[good], tx[good]] = np.stack([ux[good], uy[good]], axis=-1)

    # -- what the passes read -------------------------------------------------------

    @staticmethod
    def _crop(arr: np.ndarray, fill, x0: int, y0: int, w: int, h: int) -> np.ndarray:
        n = arr.shape[0]
        out = np.empty((h, w) + arr.shape[2:], arr.dtype)
        out[...] = fill
        ax0, ay0, ax1, ay1 = max(x0, 0), max(y0, 0), min(x0 + w, n), min(y0 + h, n)
        if ax0 < ax1 and ay0 < ay1:
            out[ay0 - y0:ay1 - y0, ax0 - x0:ax1 - x0] = arr[ay0:ay1, ax0:ax1]
        return out

    def jacobians(self, k: int, x0: int, y0: int, w: int, h: int) -> np.ndarray:
        """J (Q12 int16, (h, w, 4)) over a region of level k (outside the atlas: its nearest edge's)."""
        jac = self._level_jac(k)
        n = self.level_size(k)
        ys = np.clip(np.arange(y0, y0 + h), 0, n - 1)
        xs = np.clip(np.arange(x0, x0 + w), 0, n - 1)
        return np.ascontiguousarray(jac[ys[:, None], xs[None, :]])

    def links(self, k: int, x0: int, y0: int, w: int, h: int) -> np.ndarray:
        """The indirection map over a region of level k: (h, w, 4) int16 (own
        chart, the chart its link serves, target x, target y); -1 where none."""
        L = self._level(k)
        packed = np.concatenate([L["own"][..., None], L["link_chart"][..., None], L["link_to"]], axis=-1)
        return self._crop(packed, np.array([-1, -1, 0, 0], np.int16), x0, y0, w, h)

    def mask(self, k: int = 0) -> np.ndarray:
        """(n, n) bool: texels covered by a chart at level k (0: finest)."""
        return self._level(k)["own"] >= 0

    def owner(self, k: int = 0) -> np.ndarray:
        return self._level(k)["own"]

    def texel_jacobians(self, xs: np.ndarray, ys: np.ndarray) -> np.ndarray:
        """J (Q12 int16, (N, 4)) of finest texels (xs, ys) inside the atlas (a combed field's included)."""
        return self._level_jac(0)[ys, xs]

    def nearest_triangle(self, k: int = 0) -> np.ndarray:
        """(n, n) int32: the triangle covering each texel of level k, off the charts the nearest one's (-1: none)."""
        return self._level(k)["near_tri"]

    def feature_copies(self, features_key: str, feats: np.ndarray) -> np.ndarray:
        """Features placed on the model as per-chart copies (surface/features.py), kept per feature list."""
        from .features import feature_copies
        cache = self.__dict__.setdefault("_feature_copies", {})
        if features_key not in cache:
            if len(cache) > 8:
                cache.clear()
            cache[features_key] = feature_copies(self, feats)
        return cache[features_key]

    def feature_table(self, features_key: str, feats: np.ndarray, level: int, L: int, m: int, toroidal: bool,
                      x0: int, y0: int, x1: int, y1: int) -> np.ndarray | None:
        """The passes' table of the features placed on the model (their per-chart
        copies) over a level-texel rectangle (surface/features.py feature_table)."""
        from .features import feature_table
        return feature_table(self.feature_copies(features_key, feats), feats, level, L, m, toroidal, x0, y0, x1, y1)

    @staticmethod
    def table_reach(table: np.ndarray, level: int, L: int) -> tuple[np.ndarray, np.ndarray]:
        """Each row's centre level texel and reach (surface/features.py table_reach)."""
        from .features import table_reach
        return table_reach(table, level, L)

    def link_map(self, k: int = 0) -> tuple[np.ndarray, np.ndarray]:
        """(chart served, target (n, n, 2)) of level k's links."""
        L = self._level(k)
        return L["link_chart"], L["link_to"]
