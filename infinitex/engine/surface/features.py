"""Features placed on a model (LH05 4.3 in a mesh's atlas, engine/surface/atlas.py).

A feature on a model has its centre at an atlas texel (``Feature.canvas``:
finest texels of the atlas) and its radii in exemplar pixels: the disc of the
exemplar around ``u_F`` is laid on the surface with the texture's own scale
and orientation there. In the chart that holds the centre, at a texel whose
centre is ``x`` (finest texels),

    F(x) = u_F + J_F (x - p_F),  applied where |J_F (x - p_F)| <= r_l,

with J_F the Jacobian of the triangle under the centre (the atlas' J, module
atlas.py). A disc that reaches across a UV seam goes on in the chart across:
that chart gets a copy of the feature with the centre and J carried over by
the seam's affine map M (x' = A x + t): ``p' = M p_F``, ``J' = J_F A^-1``, so
both sides give the same exemplar point for the same surface point. A copy
applies to its own chart's texels only. Copies reach the charts adjacent to
the centre's chart (one seam away).

The passes read a table of int32 rows of three texels: (p x, p y in 1/8
finest texels, reach in level texels, r_l), (u_F x, u_F y, chart, 0), J
(Q12): shaders/common.glsl ``apply_features_atlas``; tests/oracle.py has the
same arithmetic. Everything here is elementwise float64 rounded to integers,
so the same model and features give the same table on any machine.
"""
from __future__ import annotations

import numpy as np

from ..controls.direction import J_ONE, MAX_STRETCH, MIN_DET, MIN_STRETCH

Q = 3  # bits below a finest texel of a copy's centre
D_MAX = 65535  # |x - p| in 1/8 finest texels the shader computes (farther: outside any feature)
COLUMNS = 10  # a copy: feature index, p x, p y, chart, J (4), reach x, reach y (finest texels per exemplar px)


def _inverse_rows(J: np.ndarray) -> np.ndarray:
    """Per Q12 J (n, 4): the lengths of the rows of J^-1 (finest texels per exemplar px along x, y)."""
    a, b, c, d = (J[:, i].astype(np.float64) / J_ONE for i in range(4))
    det = a * d - b * c
    return np.stack([np.hypot(d, b), np.hypot(c, a)], axis=-1) / np.abs(det)[:, None]


def feature_copies(atlas, feats: np.ndarray) -> np.ndarray:
    """Per feature (rows of controls.feature_arrays), its copy in the chart
    under its centre and one in each chart across a seam its outer disc
    reaches: float64 (C, COLUMNS) in feature order (module docstring)."""
    from .atlas import clamp_stretch
    n = atlas.size
    near = atlas.nearest_triangle(0)
    rows = []
    e_chart = atlas.chart[atlas.b_tri]
    X = atlas.uvpx
    for i, f in enumerate(feats):
        px, py, outer = int(f[0]), int(f[1]), int(f[3])
        if not (0 <= px < n and 0 <= py < n) or near[py, px] < 0:
            continue  # off the atlas: it covers nothing
        tri = int(near[py, px])
        c = int(atlas.chart[tri])
        J = atlas.jacobians(0, px, py, 1, 1)[0, 0].astype(np.int64)  # the texel's (a combed field's too)
        centre = np.array([px + 0.5, py + 0.5])
        reach = _inverse_rows(J[None])[0]
        rows.append([i, (px << Q) + (1 << (Q - 1)), (py << Q) + (1 << (Q - 1)), c, *J, *reach])
        # Seams the outer disc reaches: the nearest border edge of this chart per chart across.
        sel = np.flatnonzero((e_chart == c) & (atlas.b_other >= 0))
        if not len(sel):
            continue
        a, b = X[atlas.b_a[sel]], X[atlas.b_b[sel]]
        d = b - a
        t = np.clip(((centre - a) * d).sum(-1) / np.maximum((d * d).sum(-1), 1e-300), 0.0, 1.0)
        dist = np.hypot(*(centre - (a + t[:, None] * d)).T)
        ext = outer * float(reach.max()) + 2.0
        close = dist <= ext
        sel, dist = sel[close], dist[close]
        across = atlas.chart[atlas.b_other[sel]]
        order = np.lexsort((sel, dist, across))
        first = np.r_[True, across[order][1:] != across[order][:-1]] if len(order) else np.zeros(0, bool)
        for e in sel[order][first]:
            M = atlas.b_map[e]
            p2 = (M[0, 0] * centre[0] + M[0, 1] * centre[1] + M[0, 2],
                  M[1, 0] * centre[0] + M[1, 1] * centre[1] + M[1, 2])  # elementwise (no BLAS)
            a00, a01, a10, a11 = M[0, 0], M[0, 1], M[1, 0], M[1, 1]
            det = a00 * a11 - a01 * a10
            if not abs(det) > 1e-12:
                continue
            i00, i01, i10, i11 = a11 / det, -a01 / det, -a10 / det, a00 / det
            j = J.astype(np.float64) / J_ONE
            J2 = np.array([[j[0] * i00 + j[1] * i10, j[0] * i01 + j[1] * i11,
                            j[2] * i00 + j[3] * i10, j[2] * i01 + j[3] * i11]])
            J2, _ = clamp_stretch(J2, 1.0 / MAX_STRETCH, 1.0 / MIN_STRETCH)
            q = np.round(J2[0] * J_ONE).astype(np.int64)
            if abs(q[0] * q[3] - q[1] * q[2]) < MIN_DET:
                continue  # (a seam to a mirrored chart turns det J' negative: the disc goes on there, mirrored)
            rows.append([i, int(np.round(p2[0] * (1 << Q))), int(np.round(p2[1] * (1 << Q))),
                         int(atlas.chart[atlas.b_other[e]]), *q, *_inverse_rows(q[None])[0]])
    return np.array(rows, np.float64).reshape(-1, COLUMNS)


def feature_table(copies: np.ndarray, feats: np.ndarray, level: int, L: int, m: int, toroidal: bool,
                  x0: int, y0: int, x1: int, y1: int) -> np.ndarray | None:
    """The copies active at ``level`` whose reach meets the level-texel
    rectangle [x0, x1) x [y0, y1), as the int32 (N, 3, 4) table the passes
    read (module docstring); None when there are none."""
    if not len(copies):
        return None
    k = L - level
    f = feats[copies[:, 0].astype(np.int64)]
    first = np.where(f[:, 8] == 1, f[:, 4], 0)  # Feature.level_range
    last = np.where(f[:, 8] == 1, f[:, 5], max(0, L - 2))
    inner, outer = f[:, 2], f[:, 3]
    radius = outer - ((outer - inner) * (level - first)) // np.maximum(1, last - first)
    P = copies[:, 1:3].astype(np.int64)
    p = P >> (k + Q)
    lim = np.ceil(radius * copies[:, 8:10].max(axis=1) / (1 << k)).astype(np.int64) + 2
    active = (first <= level) & (level <= last) & (p[:, 0] - lim < x1) & (x0 <= p[:, 0] + lim) \
        & (p[:, 1] - lim < y1) & (y0 <= p[:, 1] + lim)
    if not active.any():
        return None
    u = f[:, 6:8]
    if not toroidal:  # Feature.clamped: the copied disc does not wrap across the exemplar's border
        r = outer[:, None]
        u = np.where(2 * r + 1 >= m, m // 2, np.minimum(np.maximum(u, r), m - 1 - r))
    table = np.zeros((int(active.sum()), 3, 4), np.int32)
    table[:, 0] = np.stack([P[:, 0], P[:, 1], lim, radius], axis=-1)[active]
    table[:, 1, :2] = u[active]
    table[:, 1, 2] = copies[active, 3]
    table[:, 2] = copies[active, 4:8]
    return table


def table_reach(table: np.ndarray, level: int, L: int) -> tuple[np.ndarray, np.ndarray]:
    """The level texel of each row's centre and its reach (features.feature_bins' inputs)."""
    return table[:, 0, :2].astype(np.int64) >> (L - level + Q), table[:, 0, 2].astype(np.int64)
