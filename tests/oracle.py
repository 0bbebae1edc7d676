"""A small numpy oracle of the synthesis passes (docs/algorithm.md section 3).

Written independently of the GL pyramid: one padded window per level with the
naive padding c * s^2 * radius (larger than the engine's exact margins), plain
row-major arrays, clamped reads at the window border. Its exact interior must
equal the GL result bit for bit. With a surface (a mesh's texture atlas,
Controls.surface), every state read goes through the level's indirection map
(state_texel, and the parent texel in upsample), J comes from the surface,
and placed features follow the atlas rule (per-chart copies, _atlas_features).
"""
from __future__ import annotations

import numpy as np

from infinitex.engine import fixed
from infinitex.engine.analysis import Analysis
from infinitex.engine.controls import NEUTRAL, NO_CONTROLS, Controls, modulated_rq
from infinitex.engine.similarity import border_margin
from infinitex.engine.params import FIDELITY_SEARCH, SynthParams, subpass_order


def field_values(controls: Controls, an: Analysis, params: SynthParams, level: int,
                 ux: np.ndarray, uy: np.ndarray, gx: np.ndarray, gy: np.ndarray):
    """(E, C): the randomness field values at each pixel, read the documented way
    (written without the engine's tile and region code: a pixel at a time)."""
    m, L = an.size, an.L
    E = np.full(ux.shape, NEUTRAL, np.int64)
    C = np.full(ux.shape, NEUTRAL, np.int64)
    e, c = controls.randomness_exemplar, controls.randomness_canvas
    if e is not None:
        k = L - level
        # Min over the h_l x h_l exemplar block of each upsampled coordinate.
        bx, by = (ux & (m - 1)) >> k, (uy & (m - 1)) >> k
        blocks = e.values.reshape(m >> k, 1 << k, m >> k, 1 << k).min(axis=(1, 3)).astype(np.int64)
        E = blocks[by, bx]
    if c is not None and c.tiles:
        k = L - level
        n = params.level_period(level)
        px, py = (gx & (n - 1), gy & (n - 1)) if n else (gx, gy)
        x0, y0 = int(px.min()), int(py.min())
        dense = _dense_canvas(c, x0 << k, y0 << k, (int(px.max()) + 1 - x0) << k, (int(py.max()) + 1 - y0) << k)
        # A level-k pixel: the value closest to neutral its whole 2^k x 2^k footprint
        # agrees on (written per footprint, not as repeated 2x2 steps).
        f = 1 << k
        blocks = dense.reshape(dense.shape[0] // f, f, dense.shape[1] // f, f)
        lo, hi = blocks.min(axis=(1, 3)), blocks.max(axis=(1, 3))
        red = np.where(hi < NEUTRAL, hi, np.where(lo > NEUTRAL, lo, NEUTRAL))
        C = red[py - y0, px - x0].astype(np.int64)
    return E, C


def canvas_mixes(controls: Controls, an: Analysis, params: SynthParams, level: int,
                 gx: np.ndarray, gy: np.ndarray) -> np.ndarray:
    """The packed canvas label mix of each level pixel (gx, gy), from the
    definition (engine/controls/labels.py): its own mix (_pixel_mixes), kept
    only where every level pixel within erosion(k) of it is painted enough too."""
    from infinitex.engine.controls.labels import erosion
    e = erosion(an.L - level)
    offsets = [(dx, dy) for dy in range(-e, e + 1) for dx in range(-e, e + 1)]
    gx, gy = np.asarray(gx), np.asarray(gy)
    # Every neighbour's own mix in one call (the pixels side by side).
    mixes = _pixel_mixes(controls, an, params, level, np.stack([gx + dx for dx, _ in offsets]),
                         np.stack([gy + dy for _, dy in offsets]))
    out = mixes[offsets.index((0, 0))]
    return np.where(np.all(mixes != 0, axis=0), out, 0)


def _pixel_mixes(controls: Controls, an: Analysis, params: SynthParams, level: int,
                 gx: np.ndarray, gy: np.ndarray) -> np.ndarray:
    """A level pixel's own mix: the 3 x 3 binomial sum over its neighbors q
    of the labels sampled s x s over q's footprint, free when less than half painted."""
    from infinitex.engine.controls import TILE
    from infinitex.engine.controls.labels import MAX_LABELS, pack_mix, top_two
    lc = controls.labels_canvas
    k = an.L - level
    f = 1 << k
    s = min(f, 4)
    step = f // s
    n = params.period
    counts = np.zeros(gx.shape + (MAX_LABELS + 1,), np.int64)

    def label_at(X, Y):  # unpainted: the background (free, or a palette's first label)
        if n:
            X, Y = X & (n - 1), Y & (n - 1)
        out = np.zeros(X.shape, np.int64)
        for (tx, ty), t in lc.tiles.items():
            sel = (X // TILE == tx) & (Y // TILE == ty)
            out[sel] = t[Y[sel] - ty * TILE, X[sel] - tx * TILE]
        return np.where(out == 0, lc.background, out)

    rows = np.arange(gx.size)
    for dy, by in ((-1, 1), (0, 2), (1, 1)):
        for dx, bx in ((-1, 1), (0, 2), (1, 1)):
            for j in range(s):
                for i in range(s):
                    X = (gx + dx) * f + i * step + step // 2
                    Y = (gy + dy) * f + j * step + step // 2
                    lab = label_at(X.ravel(), Y.ravel())
                    np.add.at(counts.reshape(-1, MAX_LABELS + 1), (rows, lab), bx * by)
    total = 16 * s * s
    painted = total - counts[..., 0]
    i1, i2, w1, w2 = top_two(counts[..., 1:])
    share = (255 * painted) // total
    packed = pack_mix(i1, i2, w1, w2, share).astype(np.int64)
    return np.where(share >= 128, packed, 0)  # less than half painted: free


def label_terms(controls: Controls, an: Analysis, params: SynthParams, level: int, xs, ys, origin, patch: bool):
    """(canvas mixes t at the pixels, the exemplar mixes, W_l) or None without labels."""
    from infinitex.engine.controls.labels import label_weight, typical_distance, typical_patch_cost
    if not controls.labels_active:
        return None
    t = canvas_mixes(controls, an, params, level, xs + origin[0], ys + origin[1])
    ex = controls.labels_exemplar.features(level, an.toroidal).astype(np.int64)
    if patch:
        typ = typical_patch_cost(fixed.quantized_colors(an.levels[level].stack), an.h(level),
                                 params.fidelity_radius, an.toroidal)
    else:
        typ = typical_distance(an.levels[level].nbhd) * fixed.PSI_ONE
    return t, ex, label_weight(typ, controls.label_strength, level, an.L)


def _dense_canvas(c, x0: int, y0: int, w: int, h: int) -> np.ndarray:
    """The finest canvas field over a rectangle, pixel by pixel from the tiles."""
    from infinitex.engine.controls import TILE
    ys, xs = np.mgrid[y0:y0 + h, x0:x0 + w]
    out = np.full((h, w), NEUTRAL, np.int64)
    for (tx, ty), t in c.tiles.items():
        sel = (xs // TILE == tx) & (ys // TILE == ty)
        out[sel] = t[ys[sel] % TILE, xs[sel] % TILE]
    return out


# -- direction fields (anisometric synthesis, LH06 5) --------------------------
# Written from engine/controls/direction.py's docstring and the shaders' DIRECTION
# headers, with Python integers and floor divisions (no shared helpers): a
# coordinate F is in 1/256 exemplar px, a state texel (nearest texel wrapped,
# remainder in [-128, 128)), J in Q12 (j00, j01, j10, j11).

Q8 = 256
J_IDENTITY = (4096, 0, 0, 4096)


def directed(controls: Controls) -> bool:
    """Coordinates carry 1/256 px remainders: a painted direction field, or a mesh's atlas."""
    if getattr(controls, "surface", None) is not None:
        return True
    d = controls.direction
    return d is not None and bool(d.tiles)


def _dense_direction(d, x0: int, y0: int, w: int, h: int) -> np.ndarray:
    """The finest direction field (h, w, 4) int64 over a rectangle (identity where unpainted)."""
    from infinitex.engine.controls import TILE
    out = np.empty((h, w, 4), np.int64)
    out[:] = J_IDENTITY
    for (tx, ty), t in d.tiles.items():
        ax0, ay0 = max(x0, tx * TILE), max(y0, ty * TILE)
        ax1, ay1 = min(x0 + w, (tx + 1) * TILE), min(y0 + h, (ty + 1) * TILE)
        if ax0 < ax1 and ay0 < ay1:
            out[ay0 - y0:ay1 - y0, ax0 - x0:ax1 - x0] = t[ay0 - ty * TILE:ay1 - ty * TILE,
                                                          ax0 - tx * TILE:ax1 - tx * TILE]
    return out


def _direction_mean(a: np.ndarray) -> np.ndarray:
    """One mipmap step: each entry floor(sum of the 2 x 2 children / 4); where that
    mean's determinant is below MIN_DET, the top-left child."""
    from infinitex.engine.controls.direction import MIN_DET
    tl = a[0::2, 0::2]
    mean = np.floor_divide(tl + a[0::2, 1::2] + a[1::2, 0::2] + a[1::2, 1::2], 4)
    det = mean[..., 0] * mean[..., 3] - mean[..., 1] * mean[..., 2]
    return np.where((det < MIN_DET)[..., None], tl, mean)


def direction_values(controls: Controls, an: Analysis, params: SynthParams, level: int,
                     gx: np.ndarray, gy: np.ndarray) -> np.ndarray:
    """J_l (..., 4) int64 at the level pixels (gx, gy): the finest field over each
    pixel's 2^k x 2^k footprint reduced k times. With a period n (a toroidal
    tile), the finest field inside [0, n)^2 repeated with period n: the tile
    reduced min(k, log2 n) times (further steps reduce equal values), read at
    p mod n_l. Only the level pixels whose footprint meets a painted tile are
    reduced (the reduction of identities is the identity)."""
    from infinitex.engine.controls import TILE
    d = controls.direction
    k = an.L - level
    n = params.level_period(level)
    px, py = (gx & (n - 1), gy & (n - 1)) if n else (gx, gy)
    out = np.empty(px.shape + (4,), np.int64)
    out[:] = J_IDENTITY
    if not directed(controls) or px.size == 0:
        return out
    surface = getattr(controls, "surface", None)
    if surface is not None:  # a mesh's atlas: J_l per level pixel, as the domain gives it (no period)
        x0, y0 = int(gx.min()), int(gy.min())
        J = np.asarray(surface.jacobians(k, x0, y0, int(gx.max()) + 1 - x0, int(gy.max()) + 1 - y0), np.int64)
        return J[gy - y0, gx - x0]
    if n:
        tile = params.period
        red = _dense_direction(d, 0, 0, tile, tile)
        for _ in range(min(k, tile.bit_length() - 1)):
            red = _direction_mean(red)
        return red[py, px].astype(np.int64)
    txs = [t[0] for t in d.tiles]
    tys = [t[1] for t in d.tiles]
    # Level pixels whose footprints meet the painted tiles' bounding box, within this window.
    lx0 = max(int(px.min()), (min(txs) * TILE) >> k)
    ly0 = max(int(py.min()), (min(tys) * TILE) >> k)
    lx1 = min(int(px.max()) + 1, (((max(txs) + 1) * TILE - 1) >> k) + 1)
    ly1 = min(int(py.max()) + 1, (((max(tys) + 1) * TILE - 1) >> k) + 1)
    if lx0 >= lx1 or ly0 >= ly1:
        return out
    red = _dense_direction(d, lx0 << k, ly0 << k, (lx1 - lx0) << k, (ly1 - ly0) << k)
    for _ in range(k):
        red = _direction_mean(red)
    sel = (px >= lx0) & (px < lx1) & (py >= ly0) & (py < ly1)
    out[sel] = red[py[sel] - ly0, px[sel] - lx0]
    return out


def _q8_split(F: np.ndarray, m: int) -> tuple[np.ndarray, np.ndarray]:
    """(nearest texel wrapped to [0, m), remainder in [-128, 128)) of F in 1/256 px."""
    F = np.mod(F, Q8 * m)
    t = np.floor_divide(F + Q8 // 2, Q8)
    return np.mod(t, m), F - Q8 * t


def _q8_nearest(F: np.ndarray) -> np.ndarray:
    """The nearest texel of F (1/256 px), not wrapped: floor(F / 256 + 1/2)."""
    return np.floor_divide(F + Q8 // 2, Q8)


def _jd(J: np.ndarray, dx, dy, h: int) -> tuple[np.ndarray, np.ndarray]:
    """h J d in 1/256 px, floored: floor(h (J d) 256 / 4096)."""
    return (np.floor_divide(h * (J[..., 0] * dx + J[..., 1] * dy), 16),
            np.floor_divide(h * (J[..., 2] * dx + J[..., 3] * dy), 16))


def _full(S: np.ndarray) -> np.ndarray:
    """F (..., 2) in 1/256 px of state texels (..., 4)."""
    return S[..., :2].astype(np.int64) * Q8 + S[..., 2:4]


# -- a mesh's texture atlas (LH06 6) --------------------------------------------
# Written from shaders/common.glsl (atlas_texel, STATE_TEXEL) and upsample.frag
# (parent_texel): per texel of a level, links = (own chart or -1, the chart its
# link serves or -1, link target x, y, level-global). A pixel of chart c (its own
# links' first entry; the reader) reading texel q (window-local, clamped) reads
# q when q's own chart is c, else q's target (window-local, clamped) when q's
# link serves c, else q; a reader < 0 always reads q. The upsample applies the
# same rule to the parent texel q (fixed.parent_step) with the parent level's links, the
# target read as a level-global position.

def atlas_links(controls: Controls, an: Analysis, level: int, x0: int, y0: int, w: int, h: int) -> np.ndarray | None:
    """The surface's links (h, w, 4) int64 over a rectangle of ``level``, or None without a surface."""
    surface = getattr(controls, "surface", None)
    if surface is None:
        return None
    out = np.asarray(surface.links(an.L - level, x0, y0, w, h)).astype(np.int64)
    assert out.shape == (h, w, 4)
    return out


def _follow(reader: np.ndarray, lk: np.ndarray) -> np.ndarray:
    """Where the readers take a linked texel's target instead of the texel (links ``lk``)."""
    return (reader >= 0) & (lk[..., 0] != reader) & (lk[..., 1] == reader)


def state_texel(ys: np.ndarray, xs: np.ndarray, dx, dy, H: int, W: int,
                links: np.ndarray | None = None, origin: tuple[int, int] = (0, 0)):
    """(rows, cols) of the window texel that pixels (ys, xs) read for their
    neighbor (dx, dy) (scalars or per pixel): clamped to the window; with the
    window's ``links``, redirected through the indirection map."""
    qy, qx = np.clip(ys + dy, 0, H - 1), np.clip(xs + dx, 0, W - 1)
    if links is None:
        return qy, qx
    lk = links[qy, qx]
    go = _follow(links[ys, xs, 0], lk)
    ty, tx = np.clip(lk[..., 3] - origin[1], 0, H - 1), np.clip(lk[..., 2] - origin[0], 0, W - 1)
    return np.where(go, ty, qy), np.where(go, tx, qx)


def upsample(parent: np.ndarray | None, parent_origin: tuple[int, int], origin: tuple[int, int],
             shape: tuple[int, int], an: Analysis, params: SynthParams, level: int,
             controls: Controls = NO_CONTROLS) -> np.ndarray:
    h, m = an.h(level), an.size
    H, W = shape
    gy, gx = np.mgrid[origin[1]:origin[1] + H, origin[0]:origin[0] + W].astype(np.int64)
    n = params.level_period(level)
    gmx, gmy = (gx & (n - 1), gy & (n - 1)) if n else (gx, gy)
    direct = directed(controls)
    J = direction_values(controls, an, params, level, gx, gy) if direct else None
    if parent is None:
        ux = np.full(gx.shape, m // 2, dtype=np.int64)
        uy = ux.copy()
        if direct:
            Fx, Fy = ux * Q8, uy * Q8
    else:
        ex, ey = fixed.parent_step(gmx, gmy, level, params.seed, controls.dithered_upsampling)
        beyond = _beyond_exemplar(J, h) if direct else None
        if beyond is not None:  # grown past the exemplar: magnified alone, each texel's children from it
            ex, ey = np.where(beyond, 0, ex), np.where(beyond, 0, ey)
        qx, qy = (gx >> 1) + ex, (gy >> 1) + ey
        dx, dy = (gmx & 1) - 2 * ex, (gmy & 1) - 2 * ey  # the child's place from its parent: {-1, 0, 1, 2}
        links = atlas_links(controls, an, level, origin[0], origin[1], W, H)
        if links is not None:  # the parent texel through the parent level's links, for the pixel's chart
            bx, by = int(qx.min()), int(qy.min())
            plinks = atlas_links(controls, an, level - 1, bx, by, int(qx.max()) + 1 - bx, int(qy.max()) + 1 - by)
            pl = plinks[qy - by, qx - bx]
            go = _follow(links[..., 0], pl)
            qx, qy = np.where(go, pl[..., 2], qx), np.where(go, pl[..., 3], qy)
        px, py = qx - parent_origin[0], qy - parent_origin[1]
        assert px.min() >= 0 and py.min() >= 0 and px.max() < parent.shape[1] and py.max() < parent.shape[0]
        if direct:  # F_{l-1}[q] + floor(J_l(p) h (2D - 1) / 32), less 128 at h = 1
            vx, vy = h * (2 * dx - 1), h * (2 * dy - 1)
            half = Q8 // 2 if h == 1 else 0
            Fp = _full(parent[py, px].astype(np.int64))
            Fx = Fp[..., 0] + np.floor_divide(J[..., 0] * vx + J[..., 1] * vy, 32) - half
            Fy = Fp[..., 1] + np.floor_divide(J[..., 2] * vx + J[..., 3] * vy, 32) - half
            ux, uy = np.mod(_q8_nearest(Fx), m), np.mod(_q8_nearest(Fy), m)
        else:
            ux = parent[py, px, 0] + fixed.child_offset(dx, h)
            uy = parent[py, px, 1] + fixed.child_offset(dy, h)
    rq = fixed.jitter_q(controls.jitter_at(params, m, level))
    if controls.randomness_exemplar is not None or controls.randomness_canvas is not None:
        E, C = field_values(controls, an, params, level, ux, uy, gx, gy)
        rq = modulated_rq(rq, E, C)
    jx, jy = fixed.jitter(gmx, gmy, level, params.seed, h, rq)
    shift = controls.lattice_shift(m, level)
    if shift is not None:  # lattice level: J' = c floor(J / c + 1/2), exactly (Python integers)
        cx, cy = 1 << shift[0], 1 << shift[1]
        jx = np.vectorize(lambda j: cx * ((2 * j + cx) // (2 * cx)))(jx) if cx > 1 else jx
        jy = np.vectorize(lambda j: cy * ((2 * j + cy) // (2 * cy)))(jy) if cy > 1 else jy
    if direct:  # + the jitter scaled with the texture (common.glsl jitter_q8; none grown past the exemplar's pixels)
        Jl = J.astype(np.int64)
        det = Jl[..., 0] * Jl[..., 3] - Jl[..., 1] * Jl[..., 2]
        conds = [det < 2097152, det < 8388608, det > 134217728, det > 33554432]  # the first that holds wins

        def scaled(q):
            q = Q8 * np.asarray(q, np.int64)
            return np.select(conds, [q >> 2, q >> 1, q * 4, q * 2], q)
        ox, oy = scaled(jx), scaled(jy)
        beyond = _beyond_exemplar(J, h)
        if beyond is not None:
            ox, oy = np.where(beyond, 0, ox), np.where(beyond, 0, oy)
        tx, rx = _q8_split(Fx + ox, m)
        ty, ry = _q8_split(Fy + oy, m)
        S = np.stack([tx, ty, rx, ry], axis=-1)
    else:
        S = np.stack([(ux + jx) & (m - 1), (uy + jy) & (m - 1)], axis=-1)
    return apply_features(S, origin, an, params, level, controls)


def apply_features(S: np.ndarray, origin: tuple[int, int], an: Analysis, params: SynthParams, level: int,
                   controls: Controls) -> np.ndarray:
    """Override the coordinates inside placed features (written from the
    definition: every feature tested at every pixel, exact rationals). With a
    direction field (4 channels) a feature sets a whole texel: remainder 0.
    With a surface (a mesh's atlas), the atlas rule (_atlas_features)."""
    if not controls.features:
        return S
    if getattr(controls, "surface", None) is not None:  # placed on a model: the atlas rule
        return _atlas_features(S, origin, an, level, controls)
    if S.shape[-1] == 4:
        out = S.copy()
        hit = np.zeros(S.shape[:2], bool)
        out[..., :2] = _features(S[..., :2], origin, an, params, level, controls, hit)
        out[hit, 2:] = 0
        return out
    return _features(S, origin, an, params, level, controls, None)


def _features(S: np.ndarray, origin: tuple[int, int], an: Analysis, params: SynthParams, level: int,
              controls: Controls, hit: np.ndarray | None) -> np.ndarray:
    """Every feature tested at every pixel of the window, in exact rationals
    written as integers in 1/16 level pixels (the common denominator of the
    floored radius and centre, 1/16, and of a pixel centre, 1/2): a pixel is
    inside when |e|^2 <= r^2, e = pixel centre - feature centre."""
    L, m, h = an.L, an.size, an.h(level)
    k = L - level
    n = params.level_period(level)
    H, W = S.shape[:2]
    gy, gx = np.mgrid[origin[1]:origin[1] + H, origin[0]:origin[0] + W].astype(np.int64)
    out = S.copy()
    for f in controls.features:
        a, b = f.level_range(L)
        if not a <= level <= b:
            continue
        f = f.clamped(m, an.toroidal)
        r16 = f.radius_at(level, L) * 16 // (1 << k)  # the radius in 1/16 level pixels, floored
        cx16, cy16 = f.canvas[0] * 16 // (1 << k), f.canvas[1] * 16 // (1 << k)
        pfx, pfy = f.canvas[0] >> k, f.canvas[1] >> k
        dx, dy = gx - pfx, gy - pfy
        ex, ey = 8 * (2 * gx + 1) - cx16, 8 * (2 * gy + 1) - cy16
        if n:
            wx, wy = ((dx + n // 2) % n) - n // 2, ((dy + n // 2) % n) - n // 2
            ex, ey = ex - 16 * (dx - wx), ey - 16 * (dy - wy)
            dx, dy = wx, wy
        # |e| > r on one axis is outside: clamp there so the squares stay small (exact).
        ex, ey = np.clip(ex, -r16 - 1, r16 + 1), np.clip(ey, -r16 - 1, r16 + 1)
        inside = ex * ex + ey * ey <= r16 * r16
        out[inside, 0] = np.mod(f.exemplar[0] + h * dx[inside], m)
        out[inside, 1] = np.mod(f.exemplar[1] + h * dy[inside], m)
        if hit is not None:
            hit |= inside
    return out


# -- features placed on a model (engine/surface/features.py) ----------------------
# Written from that module's docstring and shaders/common.glsl's
# apply_features_atlas, with numpy int64 and floor divisions. The per-chart
# copies (the centre, its chart and J of each copy) are the engine's CPU-side
# data, read from the surface; the level range, radius and exemplar point come
# from each Feature's own methods. Per copy, at a level-k texel g of the copy's
# chart (its own chart in the indirection map, never -1), with x its centre:
#   D = clamp((2g + 1) 4h - P, +-65535)   x - p in 1/8 finest texels (h = 2^k)
#   e = J D                               2^-15 exemplar px (J in Q12)
#   outside when |e.x| or |e.y| > r << 15, else inside iff
#   e4 = floor(e / 2^11) (1/16 px) has e4.x^2 + e4.y^2 <= (16 r)^2;
#   inside: F = u 256 + floor(e / 2^7) (1/256 px), stored as (nearest texel
#   wrapped mod m, remainder) as everywhere else. Later copies win.

ATLAS_D_MAX = 65535  # |x - p| in 1/8 finest texels per axis (features.py D_MAX; written here again)
FEATURE_CHARTS = True  # False: a copy applies to texels of every chart (a test shows this matters)


def atlas_feature_rows(controls: Controls, an: Analysis, level: int) -> list[tuple]:
    """The copies active at ``level``, in table order: (P x, P y (1/8 finest
    texels), chart, (j00, j01, j10, j11), (u x, u y), r_l) per row."""
    L, m = an.L, an.size
    copies = controls.surface.feature_copies(controls.features_key, controls._features)
    rows = []
    for c in np.asarray(copies):
        f = controls.features[int(c[0])]
        a, b = f.level_range(L)
        if not a <= level <= b:
            continue
        u = f.clamped(m, an.toroidal).exemplar
        rows.append((int(c[1]), int(c[2]), int(c[3]), tuple(int(v) for v in c[4:8]), u, f.radius_at(level, L)))
    return rows


def atlas_feature_hit(row: tuple, gx: np.ndarray, gy: np.ndarray, h: int, m: int):
    """One copy (a row of atlas_feature_rows) at level texels (gx, gy) of spacing
    h: (inside its disc, whatever the texels' charts; the state texels it sets (..., 4))."""
    px, py, _, (j00, j01, j10, j11), (ux, uy), r = row
    Dx = np.clip((2 * gx + 1) * (4 * h) - px, -ATLAS_D_MAX, ATLAS_D_MAX)
    Dy = np.clip((2 * gy + 1) * (4 * h) - py, -ATLAS_D_MAX, ATLAS_D_MAX)
    ex, ey = j00 * Dx + j01 * Dy, j10 * Dx + j11 * Dy
    R = r << 15
    e4x, e4y = np.floor_divide(ex, 1 << 11), np.floor_divide(ey, 1 << 11)
    inside = (np.abs(ex) <= R) & (np.abs(ey) <= R) & (e4x * e4x + e4y * e4y <= (16 * r) ** 2)
    tx, rx = _q8_split(ux * Q8 + np.floor_divide(ex, 1 << 7), m)
    ty, ry = _q8_split(uy * Q8 + np.floor_divide(ey, 1 << 7), m)
    return inside, np.stack([tx, ty, rx, ry], axis=-1)


def _atlas_features(S: np.ndarray, origin: tuple[int, int], an: Analysis, level: int,
                    controls: Controls) -> np.ndarray:
    """Features placed on a model (the rule above) over a window of state texels (h, w, 4)."""
    assert S.shape[-1] == 4
    H, W = S.shape[:2]
    rows = atlas_feature_rows(controls, an, level)
    if not rows:
        return S
    chart = atlas_links(controls, an, level, origin[0], origin[1], W, H)[..., 0]  # the texels' own charts
    gy, gx = np.mgrid[origin[1]:origin[1] + H, origin[0]:origin[0] + W].astype(np.int64)
    out = S.copy()
    for row in rows:
        inside, v = atlas_feature_hit(row, gx, gy, an.h(level), an.size)
        inside &= (chart == row[2]) if FEATURE_CHARTS else (chart >= 0)
        out[inside] = v[inside]
    return out


def synthesized_neighborhood(S: np.ndarray, ys: np.ndarray, xs: np.ndarray, an: Analysis,
                             level: int, J: np.ndarray | None = None, links: np.ndarray | None = None,
                             origin: tuple[int, int] = (0, 0)) -> np.ndarray:
    """Projected N_S(p) for the pixels (ys, xs) of S (reads clamped to S); with
    ``J`` (N, 4), the Jacobians at those pixels, the anisometric neighborhood;
    with ``links`` (S's window's indirection map, window at ``origin``), reads
    through it (a mesh's atlas)."""
    lv = an.levels[level]
    h, m = an.h(level), an.size
    H, W = S.shape[:2]

    def at(dx, dy):
        return S[state_texel(ys, xs, dx, dy, H, W, links, origin)].astype(np.int64)

    feat = lv.feat
    parts = []
    if J is not None:
        return fixed.project(np.concatenate(_directed_taps(S, ys, xs, an, level, J, links, origin), axis=1),
                             lv.proj, lv.shift)
    if an.model == "appearance":
        for dx, dy in fixed.DIAGONALS:
            acc = 0
            for (ddx, ddy) in ((dx, dy), (dx, 0), (0, dy)):
                u = at(ddx, ddy)
                ux = (u[:, 0] + h * (dx - ddx)) & (m - 1)
                uy = (u[:, 1] + h * (dy - ddy)) & (m - 1)
                acc = acc + feat[uy, ux].astype(np.int64)
            parts.append(acc)
    else:
        for dx, dy in fixed.COLOR_TAPS:
            u = at(dx, dy) & (m - 1)
            parts.append(feat[u[:, 1], u[:, 0]].astype(np.int64))
    return fixed.project(np.concatenate(parts, axis=1), lv.proj, lv.shift)


def _directed_taps(S: np.ndarray, ys: np.ndarray, xs: np.ndarray, an: Analysis, level: int,
                   J: np.ndarray, links: np.ndarray | None = None, origin: tuple[int, int] = (0, 0)) -> list:
    """The raw neighborhood parts of N_S(p) with a direction field (correct.frag's
    DIRECTION header): a sample for exemplar offset d comes from an immediate
    neighbor d' of p as the nearest texel of F[p + d'] - h J d' + 256 h d."""
    h, m = an.h(level), an.size
    H, W = S.shape[:2]
    feat = an.levels[level].feat
    j00, j01, j10, j11 = (J[:, i] for i in range(4))

    def sample(dpx, dpy, dx, dy):  # dpx, dpy: per pixel arrays
        F = _full(S[state_texel(ys, xs, dpx, dpy, H, W, links, origin)].astype(np.int64))
        ox, oy = _jd(J, dpx, dpy, h)
        ux = np.mod(_q8_nearest(F[:, 0] + Q8 * h * dx - ox), m)
        uy = np.mod(_q8_nearest(F[:, 1] + Q8 * h * dy - oy), m)
        return feat[uy, ux].astype(np.int64)

    parts = []
    if an.model == "appearance":
        for dx, dy in fixed.DIAGONALS:
            # The signs of J^-1 d = adj(J) d / det J (det > 0), 0 counting as +1.
            sx = np.where(j11 * dx - j01 * dy >= 0, 1, -1)
            sy = np.where(j00 * dy - j10 * dx >= 0, 1, -1)
            zero = np.zeros_like(sx)
            parts.append(sample(sx, sy, dx, dy) + sample(sx, zero, dx, dy) + sample(zero, sy, dx, dy))
    else:
        det = j00 * j11 - j01 * j10
        for dx, dy in fixed.COLOR_TAPS:
            # d' = round(J^-1 d) = floor(J^-1 d + 1/2), clamped to [-2, 2].
            npx, npy = 4096 * (j11 * dx - j01 * dy), 4096 * (j00 * dy - j10 * dx)
            dpx = np.clip(np.floor_divide(2 * npx + det, 2 * det), -2, 2)
            dpy = np.clip(np.floor_divide(2 * npy + det, 2 * det), -2, 2)
            parts.append(sample(dpx, dpy, dx, dy))
    return parts


def _phase_pixels(S: np.ndarray, phase, origin, an: Analysis, params: SynthParams, level: int, controls: Controls):
    """The pixels (ys, xs) of S that a subpass of ``phase`` rewrites, whether a
    direction field applies, its J there (or None) and the window's atlas links."""
    s = params.subgrid
    H, W = S.shape[:2]
    ys, xs = np.mgrid[0:H, 0:W]
    sel = (((xs + origin[0]) % s) == phase[0]) & (((ys + origin[1]) % s) == phase[1])
    ys, xs = ys[sel], xs[sel]
    direct = directed(controls)
    J = direction_values(controls, an, params, level, xs + origin[0], ys + origin[1]) if direct else None
    return ys, xs, direct, J, atlas_links(controls, an, level, origin[0], origin[1], W, H)


def _beyond_exemplar(J: np.ndarray | None, h: int) -> np.ndarray | None:
    """Where a level is grown past the exemplar's pixels (common.glsl
    beyond_exemplar): both axes' steps h J e under one pixel. None: nowhere."""
    if J is None or h > 2:
        return None
    J = J.astype(np.int64)
    c = np.maximum(J[..., 0] ** 2 + J[..., 2] ** 2, J[..., 1] ** 2 + J[..., 3] ** 2)
    return c < (1 << 24) // (h * h)


def _keep_beyond(S: np.ndarray, out: np.ndarray, ys, xs, J, h: int) -> np.ndarray:
    """``out`` with the pixels of a level grown past the exemplar kept as in ``S`` (upsampling alone)."""
    keep = _beyond_exemplar(J, h)
    if keep is not None and keep.any():
        out[ys[keep], xs[keep]] = S[ys[keep], xs[keep]]
    return out


def correct_subpass(S: np.ndarray, phase: tuple[int, int], origin: tuple[int, int], an: Analysis,
                    params: SynthParams, level: int, controls: Controls = NO_CONTROLS, subpass: int = 0) -> np.ndarray:
    lv = an.levels[level]
    h, m = an.h(level), an.size
    H, W = S.shape[:2]
    ys, xs, direct, J, links = _phase_pixels(S, phase, origin, an, params, level, controls)
    ns = synthesized_neighborhood(S, ys, xs, an, level, J, links, origin)
    nbhd = lv.nbhd
    best = np.full(len(ys), np.iinfo(np.int64).max)
    best_u = S[ys, xs, :2].astype(np.int64)
    best_r = np.zeros_like(best_u)  # with a direction field: the remainder of the best
    psi = fixed.psi_q(params.kappa)
    avoid = None if controls.avoid is None else controls.avoid.values
    from infinitex.engine.controls.labels import SEED_SALT, label_cost
    labels = label_terms(controls, an, params, level, xs, ys, origin, False)

    def lab(u):
        return 0 if labels is None else label_cost(labels[0], labels[1][u[:, 1], u[:, 0]], labels[2])
    for dx, dy in fixed.CANDIDATE_OFFSETS:
        nb = S[state_texel(ys, xs, dx, dy, H, W, links, origin)].astype(np.int64)
        if direct:  # F[p + d] - h J d: its nearest texel, and its remainder for every candidate
            F = _full(nb)
            ox, oy = _jd(J, dx, dy, h)
            bx, rx = _q8_split(F[:, 0] - ox, m)
            by, ry = _q8_split(F[:, 1] - oy, m)
            rem = np.stack([rx, ry], axis=1)
        else:
            bx, by = (nb[:, 0] - h * dx) & (m - 1), (nb[:, 1] - h * dy) & (m - 1)
            rem = 0
        for i in range(max(an.k, 1)):
            if an.k == 0:  # no similarity sets: the coherent candidate, off the border band
                u = np.stack([bx, by], axis=1)
                if not an.toroidal:
                    u = np.clip(u, border_margin(m, h), m - 1 - border_margin(m, h))
            else:
                sims = lv.lattice_simset if controls.lattice_shift(m, level) is not None else lv.simset
                u = sims[by, bx, i].astype(np.int64)
            e = nbhd[u[:, 1], u[:, 0]].astype(np.int64) - ns
            dist = np.minimum((e * e).sum(axis=1), fixed.DIST_CLAMP)
            cost = dist * (fixed.PSI_ONE if i == 0 else psi) + lab(u)
            if avoid is not None:
                cost = np.where(avoid[u[:, 1], u[:, 0]] != 0, fixed.AVOIDED, cost)
            better = cost < best
            best = np.where(better, cost, best)
            best_u = np.where(better[:, None], u, best_u)
            best_r = np.where(better[:, None], rem, best_r)
    steps = np.full(len(ys), params.walk_steps(an.k, avoid is not None))
    gx, gy = xs + origin[0], ys + origin[1]
    period = params.level_period(level)
    if period:
        gx, gy = gx & (period - 1), gy & (period - 1)
    wseed = fixed.walk_seed(params.seed, subpass)
    border = None if an.toroidal else border_margin(m, h)
    if labels is not None:  # a labeled pixel tries a texel of its main label (and walks LABEL_WALK steps)
        labeled = (labels[0] >> 24) != 0
        hx, _ = fixed.hash2(gx, gy, level, (wseed ^ SEED_SALT) & 0xFFFFFFFF)
        seeds = controls.labels_exemplar.seed_table(level, an.toroidal)
        u = seeds[labels[0] & 15, (hx + 1024) & 63].astype(np.int64)
        u = (u & (m - 1)) if border is None else np.clip(u, border, m - 1 - border)
        e = nbhd[u[:, 1], u[:, 0]].astype(np.int64) - ns
        cost = np.minimum((e * e).sum(axis=1), fixed.DIST_CLAMP) * psi + lab(u)
        if avoid is not None:
            cost = np.where(avoid[u[:, 1], u[:, 0]] != 0, fixed.AVOIDED, cost)
        better = labeled & (cost < best)
        best = np.where(better, cost, best)
        best_u = np.where(better[:, None], u, best_u)
        best_r = np.where(better[:, None], 0, best_r)  # a seed texel: whole
        from infinitex.engine.controls import labels as labels_module
        steps = np.where(labeled, np.maximum(steps, labels_module.LABEL_WALK), steps)
    if steps.max(initial=0) and controls.lattice_shift(m, level) is None:  # TBN10 random walk around the best
        R = m >> 1
        for t in range(int(steps.max())):
            if R < 2:
                break
            ox, oy = fixed.walk_offsets(gx, gy, level, wseed, t, R)
            u = best_u + np.stack([ox, oy], axis=1)
            u = (u & (m - 1)) if border is None else np.clip(u, border, m - 1 - border)
            e = nbhd[u[:, 1], u[:, 0]].astype(np.int64) - ns
            cost = np.minimum((e * e).sum(axis=1), fixed.DIST_CLAMP) * psi + lab(u)
            if avoid is not None:
                cost = np.where(avoid[u[:, 1], u[:, 0]] != 0, fixed.AVOIDED, cost)
            better = (cost < best) & (t < steps)
            best = np.where(better, cost, best)
            best_u = np.where(better[:, None], u, best_u)
            R >>= 1  # (the walk keeps the best's remainder)
    out = S.copy()
    out[ys, xs] = np.concatenate([best_u, best_r], axis=1) if direct else best_u
    return _keep_beyond(S, out, ys, xs, J, h)


def _fidelity_space(an: Analysis, level: int, direct: bool):
    """The fidelity stage's candidates: (one exemplar pixel in their unit, the
    border (-1: toroidal), keep-inside, nearest texel)."""
    m = an.size
    border = -1 if an.toroidal else border_margin(m, an.h(level))
    one = Q8 if direct else 1

    def inside(u):
        return np.mod(u, one * m) if border < 0 else np.clip(u, one * border, one * (m - 1 - border))

    def texel(u):
        return np.mod(_q8_nearest(u), m) if direct else u

    return one, border, inside, texel


def _with_fidelity_result(S: np.ndarray, ys, xs, best_u, direct: bool, m: int) -> np.ndarray:
    """S with the chosen candidates written at (ys, xs) (split into texel and remainder with a direction field)."""
    out = S.copy()
    if direct:
        tx, rx = _q8_split(best_u[:, 0], m)
        ty, ry = _q8_split(best_u[:, 1], m)
        out[ys, xs] = np.stack([tx, ty, rx, ry], axis=1)
    else:
        out[ys, xs] = best_u
    return out


def fidelity_subpass(S: np.ndarray, phase: tuple[int, int], origin: tuple[int, int], an: Analysis,
                     params: SynthParams, level: int, controls: Controls = NO_CONTROLS,
                     subpass: int = 0) -> np.ndarray:
    """One subpass of the fidelity stage, from its definition (fidelity.frag's
    header): every candidate's whole patch cost, no early exit, no deduplication.
    With a direction field, candidates are coordinates F in 1/256 px: u's patch
    reads the nearest texels of F + h J d, predictions are F[p + d] - h J d,
    random samples move the best by whole pixels, candidates are kept inside in
    1/256 px, and avoid and labels are read at the nearest texel."""
    R = params.fidelity_radius
    h, m = an.h(level), an.size
    H, W = S.shape[:2]
    E = fixed.quantized_colors(an.levels[level].stack)
    ys, xs, direct, J, links = _phase_pixels(S, phase, origin, an, params, level, controls)

    def s_at(dx, dy):
        return S[state_texel(ys, xs, dx, dy, H, W, links, origin)].astype(np.int64)

    patch = [(dx, dy) for dy in range(-R, R + 1) for dx in range(-R, R + 1) if (dx, dy) != (0, 0)]
    # The patch's colors around p, (N, taps, channels): a candidate's cost is the
    # sum over every tap (integers: the order of the sum does not matter).
    nb = np.stack([E[u[:, 1], u[:, 0]] for u in (s_at(*d) for d in patch)], axis=1).astype(np.int32)
    one, border, inside, texel = _fidelity_space(an, level, direct)

    def offset(dx, dy):  # h d, or h J d in 1/256 px (floored)
        if direct:
            return np.stack(_jd(J, dx, dy, h), axis=1)
        return h * np.array([dx, dy])

    Eflat = E.reshape(m * m, -1).astype(np.int32)  # colors in [0, 255]: a patch's sum fits 32 bits
    offsets = np.stack([np.broadcast_to(offset(*d), (len(ys), 2)) for d in patch], axis=1)  # (N, taps, 2)
    labels = label_terms(controls, an, params, level, xs, ys, origin, True)

    def cost(u):
        from infinitex.engine.controls.labels import label_cost
        c = np.zeros(len(u), np.int64)
        ut = texel(u)
        if labels is not None:
            c += label_cost(labels[0], labels[1][ut[:, 1], ut[:, 0]], labels[2])
        t = u[:, None, :] + offsets
        if direct:
            t = _q8_nearest(t)
        t = (t & (m - 1)) if border < 0 else np.clip(t, 0, m - 1)
        e = nb - Eflat[t[..., 1] * m + t[..., 0]]
        c += (e * e).sum(axis=(1, 2), dtype=np.int64)
        if controls.avoid is not None:
            c = np.where(controls.avoid.values[ut[:, 1], ut[:, 0]] != 0, fixed.AVOIDED, c)
        return c

    here = S[ys, xs].astype(np.int64)
    best_u = _full(here) if direct else here
    best = cost(best_u)

    def consider(u):
        nonlocal best, best_u
        c = cost(u)
        better = c < best
        best = np.where(better, c, best)
        best_u = np.where(better[:, None], u, best_u)

    for dx, dy in fixed.CANDIDATE_OFFSETS:
        if (dx, dy) != (0, 0):
            nbr = s_at(dx, dy)
            consider(inside((_full(nbr) if direct else nbr) - offset(dx, dy)))
    if controls.lattice_shift(m, level) is None:
        gx, gy = xs + origin[0], ys + origin[1]
        period = params.level_period(level)
        if period:
            gx, gy = gx & (period - 1), gy & (period - 1)
        fseed = fixed.fidelity_seed(params.seed, subpass)
        for t in range(FIDELITY_SEARCH):
            radius = (m >> 2) >> t
            if radius < 2:
                break
            ox, oy = fixed.walk_offsets(gx, gy, level, fseed, t, radius)
            consider(inside(best_u + one * np.stack([ox, oy], axis=1)))
    return _keep_beyond(S, _with_fidelity_result(S, ys, xs, best_u, direct, m), ys, xs, J, h)


def fidelity_vote_subpass(S: np.ndarray, phase: tuple[int, int], origin: tuple[int, int], an: Analysis,
                          params: SynthParams, level: int, controls: Controls = NO_CONTROLS) -> np.ndarray:
    """One vote subpass of the fidelity stage, from its definition (fidelity.frag's
    header, VOTE): among S[p], then its 8 neighbors' predictions, the first that
    the most of the (2R+1)^2 predictions equal; never into the avoid mask nor
    (labels) to a higher label cost than S[p]'s; on a non-toroidal exemplar a
    prediction that clamping would move neither votes nor is a candidate."""
    R = params.fidelity_radius
    h, m = an.h(level), an.size
    H, W = S.shape[:2]
    ys, xs, direct, J, links = _phase_pixels(S, phase, origin, an, params, level, controls)
    _, border, inside, texel = _fidelity_space(an, level, direct)

    def prediction(dx, dy):  # kept inside; -1 - (index in the window) where clamping moved it
        u = S[state_texel(ys, xs, dx, dy, H, W, links, origin)].astype(np.int64)
        raw = _full(u) - np.stack(_jd(J, dx, dy, h), axis=1) if direct else u - h * np.array([dx, dy])
        kept = inside(raw)
        if border < 0:
            return kept
        t = (dy + R) * (2 * R + 1) + dx + R
        return np.where(np.all(kept == raw, axis=1)[:, None], kept, -1 - t)

    here = S[ys, xs].astype(np.int64)
    self_u = _full(here) if direct else here
    if direct and border < 0:
        self_u = inside(self_u)  # wrapped like the predictions
    window = [(dx, dy) for dy in range(-R, R + 1) for dx in range(-R, R + 1)]
    P = {d: (self_u if d == (0, 0) else prediction(*d)) for d in window}
    labels = label_terms(controls, an, params, level, xs, ys, origin, True)

    def label_of(u):
        from infinitex.engine.controls.labels import label_cost
        ut = texel(u)
        return label_cost(labels[0], labels[1][ut[:, 1], ut[:, 0]], labels[2])

    base = label_of(self_u) if labels is not None else None

    def key(u):  # one integer per prediction (x, y): y and x are under 2^31 in magnitude
        return (u[..., 0] << 32) + u[..., 1]
    PW = np.stack([key(P[e]) for e in window])  # (window, N): the predictions that vote
    most = np.full(len(ys), -1, np.int64)
    best_u = self_u.copy()
    for d in [(0, 0)] + [(dx, dy) for dy in (-1, 0, 1) for dx in (-1, 0, 1) if (dx, dy) != (0, 0)]:
        u = P[d]
        ok = u[:, 0] >= 0  # not clamped
        safe = np.where(ok[:, None], u, self_u)  # (what is read for a clamped one does not matter)
        if controls.avoid is not None:
            ut = texel(safe)
            ok &= controls.avoid.values[ut[:, 1], ut[:, 0]] == 0
        if labels is not None:
            ok &= label_of(safe) <= base
        votes = (PW == key(u)).sum(axis=0)
        better = ok & (votes > most)
        most = np.where(better, votes, most)
        best_u = np.where(better[:, None], u, best_u)
    return _keep_beyond(S, _with_fidelity_result(S, ys, xs, best_u, direct, m), ys, xs, J, h)


def fidelity_stage(S: np.ndarray, origin: tuple[int, int], an: Analysis, params: SynthParams, level: int,
                   controls: Controls = NO_CONTROLS) -> np.ndarray:
    """All the fidelity stage's subpasses on ``level``: the search on even passes
    (numbered over the searches alone) and, with the vote, the vote on odd ones."""
    s = params.subgrid
    for c, order in enumerate(subpass_order(s, params.fidelity_passes(level))):
        for k, phase in enumerate(order):
            if params.fidelity_vote and c % 2:
                S = fidelity_vote_subpass(S, phase, origin, an, params, level, controls)
            else:
                n = (c // 2 if params.fidelity_vote else c) * s * s + k
                S = fidelity_subpass(S, phase, origin, an, params, level, controls, n)
    return S


def synthesize(an: Analysis, params: SynthParams, x: int, y: int, w: int, h: int,
               level: int | None = None, uncorrected_level: int | None = None,
               controls: Controls = NO_CONTROLS) -> np.ndarray:
    """Exact coordinates (h, w, 2) of the window at ``level`` (default finest);
    with a direction field (h, w, 4): the nearest texels and their remainders in 1/256 px.

    ``uncorrected_level`` skips correction on that one level (to measure what
    correction does there)."""
    level = an.L if level is None else level
    s = params.subgrid
    # Window needed at each level, fine to coarse; origins aligned to 2s.
    wins = {}
    x0, y0, x1, y1 = x, y, x + w, y + h
    for l in range(level, -1, -1):
        p = (params.passes_at(l) * fixed.read_radius(an.model) + params.fidelity_passes(l) * params.fidelity_radius) * s * s
        a = 2 * s
        wx0, wy0 = ((x0 - p) // a) * a, ((y0 - p) // a) * a
        wx1, wy1 = -((-(x1 + p)) // a) * a, -((-(y1 + p)) // a) * a
        wins[l] = (wx0, wy0, wx1, wy1)
        x0, y0, x1, y1 = (wx0 - 1) // 2, (wy0 - 1) // 2, wx1 // 2 + 1, wy1 // 2 + 1  # Rect.parents
    parent, porigin = None, (0, 0)
    for l in range(0, level + 1):
        wx0, wy0, wx1, wy1 = wins[l]
        S = upsample(parent, porigin, (wx0, wy0), (wy1 - wy0, wx1 - wx0), an, params, l, controls)
        if l != uncorrected_level and l in params.correcting_levels():
            n_sub = 0
            for order in subpass_order(s, params.passes_at(l)):
                for phase in order:
                    S = correct_subpass(S, phase, (wx0, wy0), an, params, l, controls, n_sub)
                    n_sub += 1
        if l != uncorrected_level and params.fidelity_at(l):
            S = fidelity_stage(S, (wx0, wy0), an, params, l, controls)
        S = apply_features(S, (wx0, wy0), an, params, l, controls)  # features hold through correction (writeback)
        parent, porigin = S, (wx0, wy0)
    wx0, wy0 = wins[level][:2]
    return parent[y - wy0:y - wy0 + h, x - wx0:x - wx0 + w].astype(np.int32)


def neighborhood_error(an: Analysis, level: int, S: np.ndarray) -> float:
    """Mean ||N_S(p) - N_E(S[p])||^2 over the pixels whose reads stay inside S:
    how far each synthesized neighborhood is from the exemplar neighborhood of
    the coordinate it claims."""
    r = fixed.read_radius(an.model)
    H, W = S.shape[:2]
    ys, xs = np.mgrid[r:H - r, r:W - r]
    ys, xs = ys.ravel(), xs.ravel()
    ns = synthesized_neighborhood(S, ys, xs, an, level)
    u = S[ys, xs].astype(np.int64)
    ne = an.levels[level].nbhd.astype(np.int64)[u[:, 1], u[:, 0]]
    return float(((ns - ne) ** 2).sum(axis=1).mean())


def reach_bound(pyr, r):
    """A finest-level bound of what a change of the controls inside rectangle
    ``r`` can alter in pyramid ``pyr`` (its levels' correction margins, doubled
    from each level to the next): outside it, local updates must change nothing."""
    from infinitex.engine.pyramid import Rect
    L = pyr.an.L
    cur = None
    for level in range(L + 1):
        k = L - level
        d = Rect(r.x0 >> k, r.y0 >> k, -((-r.x1) >> k), -((-r.y1) >> k))
        if cur is not None:
            d = Rect(min(d.x0, 2 * cur.x0), min(d.y0, 2 * cur.y0), max(d.x1, 2 * cur.x1), max(d.y1, 2 * cur.y1))
        g = max(pyr.margins[level])
        cur = d.pad(g, g, g, g)
    return cur
