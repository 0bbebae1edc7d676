"""k-coherence similarity sets (LH05 3.3; docs/algorithm.md sections 2 and 3):
for every exemplar texel, the k texels whose neighborhoods are most alike, found
by approximate nearest-neighbor search; and the band near a non-toroidal
exemplar's border that no candidate may use."""
from __future__ import annotations

import numpy as np

# Approximate nearest neighbors, as LH05 (Arya et al. 1998): each match is
# within (1 + eps) of the exact one; 4x faster than exact search at 512^2.
ANN_EPS = 1.0
# At most this many texels with one same neighborhood descriptor go into the
# search tree. Identical points cannot be split by a k-d tree: a flat area
# (a logo, a clean graphic, a painted-out half) made one leaf of 10^5 points
# that every query scanned (a 512^2 flat image never finished). Equal
# neighborhoods are interchangeable matches, so keeping a spread of them
# loses no match, only copies; images without such runs are unchanged.
MAX_EQUAL = 64


def border_margin(m: int, h: int) -> int:
    """Width of the band near a non-toroidal exemplar's border that no candidate
    may use at a level with spacing h: the pixel's descendants (h/2) plus the
    finest neighborhood (2), at most m/8 so coarse levels keep an interior."""
    return int(min(h // 2 + 2, m // 8))


def spread_equal(desc: np.ndarray, pool: np.ndarray, most: int) -> np.ndarray:
    """``pool`` (ascending texel indices) with at most ``most`` texels of any
    one descriptor value: of a larger group of equal descriptors, ``most``
    spread evenly through it in raster order (a deterministic rule)."""
    rows = np.ascontiguousarray(desc[pool])
    keys = rows.view(np.dtype((np.void, rows.dtype.itemsize * rows.shape[1]))).ravel()
    _, group, counts = np.unique(keys, return_inverse=True, return_counts=True)
    if counts.max() <= most:
        return pool
    order = np.argsort(group, kind="stable")             # members of a group in raster order
    rank = np.empty(pool.size, np.int64)
    starts = np.concatenate([[0], np.cumsum(counts)[:-1]])
    rank[order] = np.arange(pool.size) - np.repeat(starts, counts)
    n = counts[group]
    stride = np.maximum(1, -(-n // most))                 # every stride-th member, at most ``most``
    keep = (rank % stride == 0) & (rank // stride < most)
    return pool[keep]


def squared_apart(spacing: float) -> int:
    """The least integer d2 with sqrt(d2) >= ``spacing``: integer squared
    distances are ``spacing`` apart exactly when at least this."""
    apart = int(np.ceil(spacing * spacing))
    while apart > 0 and np.sqrt(apart - 1) >= spacing:
        apart -= 1
    while np.sqrt(apart) < spacing:
        apart += 1
    return apart


def similarity_sets(desc: np.ndarray, m: int, h: int, k: int, toroidal: bool,
                    spacing_frac: float) -> np.ndarray:
    """C^1..C^k for every texel, int16 (m, m, k, 2) as (x, y).

    C^1(u) = u, except near a non-toroidal border where it is the best interior
    match. The others are the best matches at least ``spacing`` px from u, from
    C^1 and from each other; missing entries repeat C^1.
    """
    ys, xs = np.mgrid[0:m, 0:m]
    pos = np.stack([xs.ravel(), ys.ravel()], axis=1).astype(np.int32)  # (int32: half the memory traffic)
    desc = desc.reshape(m * m, -1).astype(np.float32)
    if toroidal:
        usable = np.ones(m * m, dtype=bool)
    else:
        b = border_margin(m, h)
        usable = ((pos >= b) & (pos < m - b)).all(axis=1)
    # Coarse levels are smooth: texels a few pixels apart look alike, so the
    # tree holds a lattice of them (step <= h/4, so coordinates keep sub-h
    # precision) and the nearest matches are not all next to u.
    step = max(1, min(h // 4, int(spacing_frac * m) // 2))
    lattice = ((pos % step) == 0).all(axis=1)
    pool = np.nonzero(usable & lattice)[0]
    if pool.size == 0:
        pool = np.nonzero(usable)[0]
    pool = spread_equal(desc, pool, MAX_EQUAL)
    from scipy.spatial import cKDTree  # imported when used: a cached analysis needs none of scipy
    tree = cKDTree(desc[pool])
    apart = squared_apart(max(1.0, spacing_frac * m))

    def far(a: np.ndarray, b: np.ndarray) -> np.ndarray:
        """Whether positions a and b (..., 2) are at least ``spacing`` apart (wrapped on a torus)."""
        d = np.abs(a - b)
        if toroidal:
            d = np.minimum(d, m - d)
        dx, dy = d[..., 0], d[..., 1]
        return dx * dx + dy * dy >= apart

    out = np.empty((m * m, k, 2), dtype=np.int32)
    out[:, 0] = pos
    if not toroidal:
        bad = np.nonzero(~usable)[0]
        if bad.size:
            _, nn = tree.query(desc[bad], k=1, eps=ANN_EPS, workers=-1)
            out[bad, 0] = pos[pool[nn]]
    if k == 1:
        return out.reshape(m, m, 1, 2).astype(np.int16)

    todo = np.arange(m * m)
    chosen = np.repeat(out[:, :1], k - 1, axis=1)  # default: repeat C^1
    for kq in (16, 64, 256):
        if todo.size == 0:
            break
        kq = min(kq, pool.size)
        _, nn = tree.query(desc[todo], k=kq, eps=ANN_EPS, workers=-1)
        nn = nn.reshape(todo.size, kq)
        cand = pos[pool[nn]]                                   # (n, kq, 2)
        ok = far(cand, pos[todo, None])
        if not toroidal:  # (on a torus C^1 is u itself)
            ok &= far(cand, out[todo, None, 0])
        filled = np.zeros(todo.size, dtype=bool)
        picks = []
        for slot in range(k - 1):
            first = np.argmax(ok, axis=1)
            has = ok[np.arange(todo.size), first]
            pick = cand[np.arange(todo.size), first]
            picks.append((pick, has))
            ok &= far(cand, pick[:, None])
            if slot == 0:
                filled = has
        for slot, (pick, has) in enumerate(picks):
            rows = todo[has]
            chosen[rows, slot] = pick[has]
        todo = todo[~filled]
    out[:, 1:] = chosen
    return out.reshape(m, m, k, 2).astype(np.int16)


def lattice_similarity_sets(desc: np.ndarray, k: int, nx: int, ny: int) -> np.ndarray:
    """C^1..C^k restricted to the lattice (LH05 4.5), int16 (m, m, k, 2).

    C^1(u) = u; the others are the best-matching of the nx*ny - 1 positions
    ``u + (i m/nx, j m/ny) mod m`` (exact integer distances between the
    projected neighborhoods; ties go to the first offset in (j, i) order);
    missing entries (a 1x1 block) repeat u. The rectified exemplar is
    toroidal by construction, so every such position is usable.

    The positions u + cells form classes of nx*ny texels; the distances within
    a class come from one Gram matrix (BLAS, exact: integers below 2^53), a
    batch of classes at a time, so 16 x 16 cells cost a matrix product instead
    of 255 passes over the exemplar."""
    m = desc.shape[0]
    cx, cy = m // nx, m // ny
    ys, xs = np.mgrid[0:m, 0:m]
    ident = np.stack([xs, ys], axis=-1).astype(np.int64)
    out = np.repeat(ident[:, :, None, :], k, axis=2)
    offsets = np.array([(i * cx, j * cy) for j in range(ny) for i in range(nx) if i or j], dtype=np.int64)
    if k == 1 or len(offsets) == 0:
        return out.astype(np.int16)
    P, D = nx * ny, desc.shape[2]
    K = min(k - 1, len(offsets))
    # Class c = (y mod cy) * cx + x mod cx; member a = (y // cy) * nx + x // cx.
    X = desc.astype(np.float64).reshape(ny, cy, nx, cx, D).transpose(1, 3, 0, 2, 4).reshape(cy * cx, P, D)
    jm, im = np.divmod(np.arange(P), nx)
    # Per class, key[a, b] = P (|x_b|^2 - 2 x_a.x_b) + (the offset from a to b in
    # (j, i) order): |x_a - x_b|^2 less |x_a|^2 (the same for all b), scaled so
    # the offset breaks ties. One matrix product of integers below 2^53: exact.
    order = (((jm[None, :] - jm[:, None]) % ny) * nx + (im[None, :] - im[:, None]) % nx).astype(np.float64)
    order[np.arange(P), np.arange(P)] = np.inf  # a itself is C^1
    rows = np.concatenate([-2.0 * P * X, np.ones((*X.shape[:2], 1))], axis=2)
    cols = np.ascontiguousarray(np.concatenate([X, P * (X * X).sum(axis=-1, keepdims=True)], axis=2).transpose(0, 2, 1))
    bo = np.empty((cy * cx, P, K), dtype=np.int64)
    step = max(1, (1 << 22) // (P * P))
    for c0 in range(0, cy * cx, step):
        key = np.matmul(rows[c0:c0 + step], cols[c0:c0 + step])
        key += order
        for slot in range(K):  # the K smallest: distinct keys, so ties go to the first offset
            best = np.argmin(key, axis=2)
            bo[c0:c0 + step, :, slot] = order[np.arange(P)[None, :], best] - 1
            if slot + 1 < K:
                np.put_along_axis(key, best[:, :, None], np.inf, axis=2)
    bo = bo.reshape(cy, cx, ny, nx, K).transpose(2, 0, 3, 1, 4).reshape(m, m, K)
    out[:, :, 1:1 + K] = (ident[:, :, None, :] + offsets[bo]) % m
    return out.astype(np.int16)
