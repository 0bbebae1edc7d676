"""Features placed on a model (LH05 4.4 in a mesh's atlas, engine/surface/atlas.py).

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

from ..controls.direction import J_ONE, MAX_STRETCH, MIN_DET, MIN_STRETCH, clamp_stretch
from ..controls.features import level_values

Q = 3  # bits below a finest texel of a copy's centre
COLUMNS = 10  # a copy: feature index, p x, p y, chart, J (4), reach x, reach y (finest texels per exemplar px)


def _inverse_rows(J: np.ndarray) -> np.ndarray:
    """Per Q12 J (n, 4): the lengths of the rows of J^-1 (finest texels per exemplar px along x, y)."""
    a, b, c, d = (J[:, i].astype(np.float64) / J_ONE for i in range(4))
    det = np.abs(a * d - b * c)
    return np.stack([np.sqrt(d * d + b * b), np.sqrt(c * c + a * a)], axis=-1) / det[:, None]


def _nearest_seams(atlas, chart: np.ndarray, centre: np.ndarray, ext: np.ndarray):
    """Per feature and chart across a seam of its chart: the border edge
    nearest its centre (ties: the lower index), when within ``ext``: (feature,
    edge, distance) arrays. The edges are sampled every texel at most, one k-d
    tree per pair of charts; a feature measures exactly the edges of its 8
    nearest samples: the cost follows the features and the seams' length, not
    their product."""
    from scipy.spatial import cKDTree
    X = atlas.uvpx
    e = np.flatnonzero(atlas.b_other >= 0)
    out_f, out_e, out_d = [np.zeros(0, np.int64)], [np.zeros(0, np.int64)], [np.zeros(0)]
    if not len(e) or not len(chart):
        return out_f[0], out_e[0], out_d[0]
    a, b = X[atlas.b_a[e]], X[atlas.b_b[e]]
    d = b - a
    steps = np.maximum(1, np.ceil(np.sqrt((d * d).sum(-1)))).astype(np.int64) + 1  # samples per edge
    se = np.repeat(np.arange(len(e)), steps)
    t = (np.arange(int(steps.sum())) - np.repeat(np.cumsum(steps) - steps, steps)) / (steps[se] - 1)
    pts = a[se] + t[:, None] * d[se]
    own = atlas.chart[atlas.b_tri[e]].astype(np.int64)[se]
    across = atlas.chart[atlas.b_other[e]].astype(np.int64)[se]
    group = own * atlas.charts + across
    order = np.argsort(group, kind="stable")
    group, pts, se = group[order], pts[order], se[order]
    starts = np.flatnonzero(np.r_[True, group[1:] != group[:-1]])
    bounds = np.r_[starts, len(group)]
    by_chart = {}
    for gi in range(len(starts)):
        by_chart.setdefault(int(group[starts[gi]] // atlas.charts), []).append(gi)
    for c in np.unique(chart):
        fs = np.flatnonzero(chart == c)
        for gi in by_chart.get(int(c), []):
            lo, hi = bounds[gi], bounds[gi + 1]
            kk = min(8, hi - lo)
            _, k = cKDTree(pts[lo:hi]).query(centre[fs], k=kk)
            cand = se[lo + k.reshape(len(fs), kk)]  # the edges of the nearest samples: measured exactly
            pa, pd = a[cand], d[cand]
            pc = centre[fs][:, None, :]
            tt = np.clip(((pc - pa) * pd).sum(-1) / np.maximum((pd * pd).sum(-1), 1e-300), 0.0, 1.0)
            r = pc - (pa + tt[..., None] * pd)
            dist = np.sqrt((r * r).sum(-1))
            rows = np.repeat(np.arange(len(fs)), kk)
            order = np.lexsort((cand.ravel(), dist.ravel(), rows))  # per feature: the nearest, ties the lowest edge
            pick = order[np.r_[0:len(order):kk]] if len(order) else order
            cd, dd = cand.ravel()[pick], dist.ravel()[pick]
            close = dd <= ext[fs]
            out_f.append(fs[close])
            out_e.append(e[cd[close]])
            out_d.append(dd[close])
    return np.concatenate(out_f), np.concatenate(out_e), np.concatenate(out_d)


def feature_copies(atlas, feats: np.ndarray) -> np.ndarray:
    """Per feature (rows of controls.feature_arrays), its copy in the chart
    under its centre and one in each chart across a seam its outer disc
    reaches (across the edge of that seam nearest its centre): float64 (C,
    COLUMNS), by feature, its own copy first, then by chart across (module docstring)."""
    n = atlas.size
    feats = np.asarray(feats, np.int64).reshape(-1, 9)
    px, py, outer = feats[:, 0], feats[:, 1], feats[:, 3]
    inside = (px >= 0) & (px < n) & (py >= 0) & (py < n)
    idx = np.flatnonzero(inside)
    tri = atlas.nearest_triangle(0)[py[idx], px[idx]]
    idx, tri = idx[tri >= 0], tri[tri >= 0]  # off the atlas: it covers nothing
    px, py, outer = px[idx], py[idx], outer[idx]
    chart = atlas.chart[tri].astype(np.int64)
    J = atlas.texel_jacobians(px, py).astype(np.int64)  # the texels' (a combed field's too)
    reach = _inverse_rows(J)
    centre = np.stack([px + 0.5, py + 0.5], axis=-1)
    own = np.column_stack([idx, (px << Q) + (1 << (Q - 1)), (py << Q) + (1 << (Q - 1)), chart, J, reach])
    # Seams the outer discs reach: per feature and chart across, the nearest edge.
    f, e, _ = _nearest_seams(atlas, chart, centre, outer * reach.max(axis=1) + 2.0)
    across = atlas.chart[atlas.b_other[e]].astype(np.int64)
    M = atlas.b_map[e]
    cx, cy = centre[f, 0], centre[f, 1]
    p2x = M[:, 0, 0] * cx + M[:, 0, 1] * cy + M[:, 0, 2]  # elementwise (no BLAS)
    p2y = M[:, 1, 0] * cx + M[:, 1, 1] * cy + M[:, 1, 2]
    a00, a01, a10, a11 = M[:, 0, 0], M[:, 0, 1], M[:, 1, 0], M[:, 1, 1]
    det = a00 * a11 - a01 * a10
    good = np.abs(det) > 1e-12
    det = np.where(good, det, 1.0)
    i00, i01, i10, i11 = a11 / det, -a01 / det, -a10 / det, a00 / det
    j = J[f].astype(np.float64) / J_ONE
    J2 = np.stack([j[:, 0] * i00 + j[:, 1] * i10, j[:, 0] * i01 + j[:, 1] * i11,
                   j[:, 2] * i00 + j[:, 3] * i10, j[:, 2] * i01 + j[:, 3] * i11], axis=-1)
    J2, _ = clamp_stretch(J2, 1.0 / MAX_STRETCH, 1.0 / MIN_STRETCH)
    q = np.round(J2 * J_ONE).astype(np.int64)
    # (A seam to a mirrored chart turns det J' negative: the disc goes on there, mirrored.)
    good &= np.abs(q[:, 0] * q[:, 3] - q[:, 1] * q[:, 2]) >= MIN_DET
    f, q, across = f[good], q[good], across[good]
    other = np.column_stack([idx[f], np.round(p2x[good] * (1 << Q)), np.round(p2y[good] * (1 << Q)), across, q,
                             _inverse_rows(q)]) if len(f) else np.zeros((0, COLUMNS))
    rows = np.concatenate([own.astype(np.float64), other.astype(np.float64)]).reshape(-1, COLUMNS)
    kind = np.r_[np.zeros(len(own)), np.ones(len(other))]
    return rows[np.lexsort((rows[:, 3], kind, rows[:, 0]))] if len(rows) else rows


def feature_table(copies: np.ndarray, feats: np.ndarray, level: int, L: int, m: int, toroidal: bool,
                  x0: int, y0: int, x1: int, y1: int) -> np.ndarray | None:
    """The copies active at ``level`` whose reach meets the level-texel
    rectangle [x0, x1) x [y0, y1), as the int32 (N, 3, 4) table the passes
    read (module docstring); None when there are none."""
    if not len(copies):
        return None
    k = L - level
    active, radius, u = level_values(feats[copies[:, 0].astype(np.int64)], level, L, m, toroidal)
    P = copies[:, 1:3].astype(np.int64)
    p = P >> (k + Q)
    lim = np.ceil(radius * copies[:, 8:10].max(axis=1) / (1 << k)).astype(np.int64) + 2
    active &= (p[:, 0] - lim < x1) & (x0 <= p[:, 0] + lim) & (p[:, 1] - lim < y1) & (y0 <= p[:, 1] + lim)
    if not active.any():
        return None
    table = np.zeros((int(active.sum()), 3, 4), np.int32)
    table[:, 0] = np.stack([P[:, 0], P[:, 1], lim, radius], axis=-1)[active]
    table[:, 1, :2] = u[active]
    table[:, 1, 2] = copies[active, 3]
    table[:, 2] = copies[active, 4:8]
    return table


def table_reach(table: np.ndarray, level: int, L: int) -> tuple[np.ndarray, np.ndarray]:
    """The level texel of each row's centre and its reach (features.feature_bins' inputs)."""
    return table[:, 0, :2].astype(np.int64) >> (L - level + Q), table[:, 0, 2].astype(np.int64)


def across_seams(atlas, x: float, y: float, radius: float) -> list[tuple[float, float, float]]:
    """A disc of ``radius`` finest texels at atlas point (x, y), continued
    over the seams it reaches: per chart across (the nearest edge of each
    seam), the disc's centre through that seam's map and its radius times the
    map's scale. What a brush dab near a chart's border also paints, so that
    painting runs on over the seam like the texture does."""
    n = atlas.size
    xi, yi = min(n - 1, max(0, int(x))), min(n - 1, max(0, int(y)))
    t = int(atlas.nearest_triangle(0)[yi, xi])
    if t < 0 or atlas.owner(0)[yi, xi] < 0:
        return []
    chart = np.array([int(atlas.chart[t])], np.int64)
    _, edges, _ = _nearest_seams(atlas, chart, np.array([[x, y]], np.float64), np.array([radius]))
    out = []
    for e in edges:
        M = atlas.b_map[e]
        det = abs(M[0, 0] * M[1, 1] - M[0, 1] * M[1, 0])
        if det > 1e-12:
            out.append((float(M[0, 0] * x + M[0, 1] * y + M[0, 2]), float(M[1, 0] * x + M[1, 1] * y + M[1, 2]),
                        float(radius * np.sqrt(det))))
    return out
