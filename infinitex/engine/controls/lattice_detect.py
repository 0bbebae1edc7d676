"""Finding the lattice of a near-regular image (LH05 section 4.5;
docs/algorithm.md section 5): the autocorrelation's peaks give a grid (two
vectors), its ridges give rows (planks, stripes, lines); the confidence says how
sure; the block of cells comes from :mod:`.lattice_block`. The lattice is
looked for in the image's shades and in its outlines (cells shaded apart
repeat only in their outlines), the more confident answer kept, its vectors
polished to where the image agrees with itself best
(:mod:`.lattice_correlation`)."""
from __future__ import annotations

import math
import time
from dataclasses import replace

import numpy as np
from scipy import ndimage

from .lattice import (
    DETECT_SIDE,
    FEW_CONFIDENCE,
    MIN_CONFIDENCE,
    MIN_REPEATS,
    MIN_SINE,
    MIN_VECTOR,
    SURE_REPEATS,
    Detection,
)
from .lattice_block import choose_block, exact_block
from .lattice_correlation import (
    autocorrelation,
    canonical_basis,
    confidence,
    gauss_reduce,
    lattice_points,
    lobe_radius,
    polish,
    refine,
    sample,
)


def detect(pixels: np.ndarray) -> Detection:
    """Find the lattice of a near-regular image (H, W) or (H, W, C) in [0, 1].

    Returns a Detection whose ``lattice`` is None when the image shows no
    lattice (confidence below MIN_CONFIDENCE, or fewer than two independent
    peaks): an answer, not an error. The block is the largest power-of-two
    count of cells per side that fits in the image with a rectified aspect
    within 2:1, centred in the image (a whole-pixel lattice's as its
    axis-aligned supercell at a whole-pixel origin: lattice_block.exact_block)."""
    t0 = time.perf_counter()
    img = np.asarray(pixels, dtype=np.float64)
    if img.ndim == 3:
        img = img[:, :, :3].mean(axis=2) if img.shape[2] >= 3 else img[:, :, 0]
    H, W = img.shape
    f = max(1, math.ceil(max(H, W) / DETECT_SIDE))
    gray = img
    if f > 1:  # box reduction by an integer factor (exact scale for the vectors)
        h2, w2 = H // f, W // f
        gray = img[:h2 * f, :w2 * f].reshape(h2, f, w2, f).mean(axis=(1, 3))
    none = Detection(None, 0.0, 0.0)
    if min(gray.shape) < 16:
        return replace(none, seconds=time.perf_counter() - t0)
    # The most confident of what the shades and the outlines show.
    shade, edges = _feature_correlations(gray)
    found = [r for r in (_lattice_of(shade, gray, f), _lattice_of(edges, gray, f, rows_too=False))
             if r is not None]
    if not found:
        return replace(none, seconds=time.perf_counter() - t0)
    t1, t2, conf = max(found, key=lambda r: r[2])
    t1, t2 = t1 * f, t2 * f
    b1, b2 = (float(t1[0]), float(t1[1])), (float(t2[0]), float(t2[1]))
    lat = None
    # A lattice repeating fewer than SURE_REPEATS times along a vector (rows:
    # across them; their vector along is as long) is taken only when clearly there.
    longest = max(math.hypot(*v) for v in gauss_reduce(t1, t2))  # (a brick's row is no reduced vector)
    needed = MIN_CONFIDENCE if longest <= min(H, W) / SURE_REPEATS + 0.5 else max(MIN_CONFIDENCE, FEW_CONFIDENCE)
    if conf >= needed:
        lat = choose_block(b1, b2, W, H)
        if lat is not None:
            lat = exact_block(lat, W, H)
    return Detection(lat, conf, time.perf_counter() - t0, b1, b2)


def _feature_correlations(gray: np.ndarray):
    """The autocorrelations a lattice is looked for in: of the image's shades,
    and of its edges (the gradient's magnitude). Cells whose colours vary one
    from the next (tiles, bricks, cells shaded apart) hardly correlate in shade
    at the lattice's vectors, but their outlines do; a smooth periodic motif
    (woven strands, a photo repeated) shows best in shade."""
    gy, gx = np.gradient(ndimage.gaussian_filter(gray, 1.0))
    return autocorrelation(gray), autocorrelation(np.hypot(gx, gy))


def _lattice_of(ac: np.ndarray, gray: np.ndarray, f: int, rows_too: bool = True):
    """The lattice one autocorrelation shows: (t1, t2, confidence) at the
    reduced image's scale, or None. Without ``rows_too``, grids only (a grid
    that only cuts rows is none): outlines of letters or of strokes repeat at
    half their pitch and along lines of text, where no rows are."""
    hy, hx = ac.shape[0] // 2, ac.shape[1] // 2
    lobe = lobe_radius(ac)
    # A lattice must repeat at least MIN_REPEATS times across the image.
    reach = min(gray.shape) / MIN_REPEATS + 0.5
    grid = _grid(ac, (hy, hx), lobe, reach, f)
    rows = None
    if rows_too:
        rows = _rows(ac, (hy, hx))
        if rows is None and grid is not None:
            rows = _rows_of_grid(ac, (hy, hx), grid)
            if rows is not None:
                grid = None  # it only cut these rows
        if rows is not None and min(math.hypot(*rows[0]), math.hypot(*rows[1])) > reach:
            rows = None  # rows seen fewer than MIN_REPEATS times
    elif grid is not None and _rows_of_grid(ac, (hy, hx), grid) is not None:
        return None
    # (A vector at the largest lag lies on the array's edge: read there.)
    if grid is not None and sample(ac, np.stack(grid[:2]), (hy, hx), "nearest").min() < GRID_MIN_CORRELATION:
        grid = None  # the image hardly repeats at its vectors: strokes of text, not cells
    if not rows_too:
        return grid
    if grid is None and rows is None:
        return None
    # Rows win when the grid only cuts them into arbitrary cells (and they are
    # confident), or when there is no confident grid; rows whose cells repeat
    # along them too (bricks, shingles, staggered or not) are that grid.
    if rows is not None and (grid is None or (_along(ac, (hy, hx), rows[3], grid[0], grid[1])
                                              and rows[2] >= MIN_CONFIDENCE) or grid[2] < min(MIN_CONFIDENCE, rows[2])):
        return _cells_along(gray, (hy, hx), rows, reach, lobe) or rows[:3]
    return grid


def _grid(ac: np.ndarray, center: tuple[int, int], lobe: float, reach: float, f: int):
    """A two-dimensional lattice from the autocorrelation's peaks: (t1, t2, the
    confidence) or None."""
    hy, hx = center
    peaks = (ac == ndimage.maximum_filter(ac, size=3, mode="constant", cval=np.inf)) & (ac > 0.05)
    peaks[hy, hx] = False
    peaks[[0, -1], :] = False
    peaks[:, [0, -1]] = False
    ys, xs = np.nonzero(peaks)
    if ys.size < 2:
        return None
    vals = ac[ys, xs]
    vec = np.stack([xs - hx, ys - hy], axis=1).astype(np.float64)
    length = np.hypot(vec[:, 0], vec[:, 1])
    keep = (length >= max(MIN_VECTOR / f, lobe)) & (length <= reach)
    vec, vals, length = vec[keep], vals[keep], length[keep]
    if vals.size < 2:
        return None
    # Candidate bases: pairs among the shortest strong peaks, reduced. A basis
    # with a peak inside the motif has lattice points that miss (low median
    # correlation there); a basis of a coarser sub-lattice scores as high as
    # the true one but spans a larger cell: keep the smallest cell among those
    # scoring near the best.
    vec, vals, length = _candidate_peaks(vec, vals, length)
    if vals.size < 2:
        return None
    shortest = np.argsort(length - 1e-6 * vals, kind="stable")[:12]
    highest = np.argsort(-vals + 1e-6 * length, kind="stable")[:12]
    cand = vec[np.unique(np.concatenate([shortest, highest]))]
    cand = cand[np.argsort(np.hypot(cand[:, 0], cand[:, 1]), kind="stable")]
    # The candidates are whole-pixel peaks, so their sums and multiples miss
    # the true lattice points by a pixel or so, where sharp peaks (thin
    # outlines) read low: bases are scored on the highest correlation within
    # a pixel.
    loose = ndimage.maximum_filter(ac, size=3, mode="nearest")
    scored = []
    for i in range(len(cand)):
        for j in range(i + 1, len(cand)):
            a, b = cand[i], cand[j]
            if abs(a[0] * b[1] - a[1] * b[0]) < MIN_SINE * math.hypot(*a) * math.hypot(*b):
                continue
            a, b = gauss_reduce(a, b)
            _, P = lattice_points(a, b, hy, hx, limit=3)
            P = P[np.hypot(P[:, 0], P[:, 1]) >= lobe]
            if len(P) >= 2:
                near = float(sample(loose, np.stack([a, b, a + b, a - b]), (hy, hx)).min())
                scored.append((float(np.median(sample(loose, P, (hy, hx)))), abs(a[0] * b[1] - a[1] * b[0]), a, b, near))
    if not scored:
        return None
    # Near the best median, the smallest cell whose own shortest vectors
    # correlate about as much as the best basis's: a cell half as large whose
    # every other point misses (a basket weave's straight neighbours, where
    # the diagonal ones repeat) scores a good median but weak short vectors.
    top = max(s[0] for s in scored)
    good = [s for s in scored if s[0] >= top - 0.2 * abs(top)]
    best_near = max(s[4] for s in good)
    _, _, t1, t2, _ = min((s for s in good if s[4] >= best_near - 0.2 * abs(best_near)), key=lambda s: s[1])
    t1, t2 = _primitive(ac, (hy, hx), t1, t2, lobe)
    t1, t2 = refine(ac, t1, t2, (hy, hx))
    t1, t2 = polish(ac, t1, t2, (hy, hx), lobe)
    t1, t2 = canonical_basis(t1, t2)
    if min(math.hypot(*t1), math.hypot(*t2)) < MIN_VECTOR / f:
        return None  # fitted below the shortest vector a lattice may have
    return t1, t2, confidence(ac, t1, t2, (hy, hx), lobe)


def _candidate_peaks(vec: np.ndarray, vals: np.ndarray, length: np.ndarray):
    """The peaks worth pairing into bases: one of each +-v pair, the strong
    ones (at least 0.3 of the highest; if they all lie in one direction, the
    best of the other directions too), and no multiple of a shorter peak about
    as strong (the rows of a far-reaching grid would crowd out its other
    direction)."""
    half = (vec[:, 1] > 0) | ((vec[:, 1] == 0) & (vec[:, 0] > 0))
    vec, vals, length = vec[half], vals[half], length[half]
    if vals.size == 0:
        return vec, vals, length
    strong = vals >= 0.3 * vals.max()
    a = vec[np.argmax(vals)]
    off = np.abs(vec[:, 0] * a[1] - vec[:, 1] * a[0]) >= MIN_SINE * length * math.hypot(*a)
    forced = None
    if not (strong & off).any() and off.any():
        forced = int(np.argmax(np.where(off, vals, -np.inf)))
        strong[forced] = True
        forced = int(np.count_nonzero(strong[:forced]))  # its place among the strong ones
    vec, vals, length = vec[strong], vals[strong], length[strong]
    # (Outlines can hold thousands of small peaks: the 256 shortest and the 64
    # highest are more than the bases are drawn from.)
    order = np.argsort(length, kind="stable")
    if order.size > 320:
        top = np.argsort(-vals, kind="stable")[:64]
        if forced is not None:
            top = np.append(top, forced)
        order = np.concatenate([order[:256], np.setdiff1d(top, order[:256])])
        order = order[np.argsort(length[order], kind="stable")]
    kept: list[int] = []
    for i in order:
        if kept:
            K = vec[kept]
            k = np.rint((K @ vec[i]) / np.einsum("ij,ij->i", K, K))
            rest = np.hypot(*(vec[i][None, :] - k[:, None] * K).T)
            if np.any((k >= 2) & (vals[kept] >= 0.85 * vals[i]) & (rest <= 1.5)):
                continue  # a multiple of a shorter peak about as strong
        kept.append(int(i))
    return vec[kept], vals[kept], length[kept]


def _primitive(ac: np.ndarray, center, t1, t2, lobe: float):
    """The finest lattice the basis is a coarser version of: while a fraction
    of a lattice vector (t/k for k up to 8) or of the cell ((i t1 + j t2)/k with
    i or j = 1, k up to 4: the half-way point of a centred cell, the third of a
    hexagonal one) and all its multiples up to the lattice correlate as much as
    the basis itself, that fraction is a lattice vector too (a grid of thin
    lines otherwise comes out as cells of several grid cells, a hexagonal
    pattern as a cell three times too large). A whole-pixel basis's fractions
    fall between pixels, where a sharp peak reads low: each is read as the
    highest correlation within half a pixel (:func:`_near`)."""
    a, b = np.asarray(t1, float), np.asarray(t2, float)
    floor = max(lobe, MIN_VECTOR)
    for _ in range(6):
        found = _fraction(ac, center, a, b, floor)
        if found is None:
            break
        a, b = gauss_reduce(*found)
    return a, b


_HALF_PIXEL = np.array([(0.0, 0.0), (0.5, 0.0), (-0.5, 0.0), (0.0, 0.5), (0.0, -0.5)])


def _near(ac: np.ndarray, pts: np.ndarray, center) -> np.ndarray:
    """The correlation at each point, the highest within half a pixel."""
    pts = np.asarray(pts, float).reshape(-1, 2)
    return np.max([sample(ac, pts + o, center) for o in _HALF_PIXEL], axis=0)


def _fraction(ac: np.ndarray, center, a, b, floor: float):
    """(h, w): a fraction h of a basis vector (t/k, k up to 8) all of whose
    multiples correlate at least 85% as much as the basis, or of the cell
    (:func:`_cell_fraction`), and w the vector that spans the finer lattice
    with it; None if there is none."""
    level = 0.85 * float(sample(ac, np.stack([a, b]), center).min())
    for v, keep in ((a, b), (b, a)):
        for k in range(2, 9):
            h = v / k
            if math.hypot(*h) < floor:
                break
            if float(_near(ac, np.outer(np.arange(1, k), h), center).min()) >= level:
                return h, keep
    return _cell_fraction(ac, center, a, b, level, floor)


def _cell_fraction(ac: np.ndarray, center, a, b, level: float, floor: float):
    """(h, w): a fraction h = (i a + j b)/k of the cell (i or j = 1, k <= 4)
    whose multiples, each taken to its shortest copy modulo the lattice,
    correlate at least ``level``; w the basis vector that spans the finer
    lattice with it. None if there is none."""
    B = np.stack([a, b], axis=1)
    for k in (2, 3, 4):
        for i in range(k):
            for j in range(k):
                if (i != 1 and j != 1) or math.gcd(math.gcd(i, j), k) != 1:
                    continue
                h = (i * a + j * b) / k
                pts = []
                for m in range(1, k):
                    p = m * h
                    p = p - B @ np.rint(np.linalg.solve(B, p))  # its shortest copy, about
                    copies = [p + B @ np.array(n) for n in ((0, 0), (1, 0), (-1, 0), (0, 1), (0, -1))]
                    pts.append(min(copies, key=lambda q: math.hypot(*q)))
                if min(math.hypot(*q) for q in pts) < floor:
                    continue
                if float(_near(ac, np.stack(pts), center).min()) >= level:
                    return h, (b if i == 1 else a)
    return None


def _cells_along(gray: np.ndarray, center, rows, reach: float, lobe: float):
    """Rows whose cells also repeat along them (bricks in running bond,
    shingles, tiles in courses): the period w along the rows and the shift o
    from one row to the next give the grid t1 = w d, t2 = P n + o d. Found when
    the correlation along the rows (lags k w d) and along the next row (lags
    P n + (o + k w) d) each stand clearly above its value half-way between (a
    random bond's rows correlate about evenly all along). The correlation is
    that of the change along the rows (the joints between cells; the lines
    between rows, which correlate at any lag along them, drop out). Returns
    (t1, t2, confidence) or None."""
    t1r, t2r, conf, d = rows
    d = np.asarray(d, float)
    gy, gx = np.gradient(ndimage.gaussian_filter(gray, 1.0))
    ac = autocorrelation(np.abs(gx * d[0] + gy * d[1]))
    across = np.asarray(t2r, float) if abs(float(np.asarray(t2r, float) @ d)) < abs(float(np.asarray(t1r, float) @ d)) \
        else np.asarray(t1r, float)
    step = 0.25
    smax = reach
    s = np.arange(0.0, smax + 1.0, step)
    on_row = ndimage.maximum_filter1d(sample(ac, s[:, None] * d[None, :], center), size=5, mode="nearest")
    periods = np.arange(max(2.0 * lobe, MIN_VECTOR, 0.75 * math.hypot(*across)), smax - 1.0, step)
    if periods.size == 0:
        return None
    def at(prof, x):
        return prof[np.minimum(np.rint(np.asarray(x) / step).astype(int), len(prof) - 1)]
    score = at(on_row, periods) - at(on_row, 0.5 * periods)  # a multiple of the period scores about nothing
    if score.max() <= 0.05:
        return None
    i = int(np.nonzero(score >= 0.8 * score.max())[0][0])
    while i + 1 < len(score) and score[i + 1] >= score[i]:
        i += 1
    w = float(periods[i])
    half = float(at(on_row, 0.5 * w))
    contrast_row = (float(at(on_row, w)) - half) / max(1e-6, 1.0 - half)
    # The next row: its best shift within one period.
    o = np.arange(0.0, w, step)
    nxt = sample(ac, across[None, :] + o[:, None] * d[None, :], center)
    k = int(np.argmax(nxt))
    opposite = float(sample(ac, (across + ((o[k] + 0.5 * w) % w) * d)[None, :], center)[0])
    contrast_next = (float(nxt[k]) - opposite) / max(1e-6, 1.0 - opposite)
    if min(contrast_row, contrast_next) < CELLS_ALONG_MIN or max(contrast_row, contrast_next) < CELLS_ALONG_CLEAR:
        return None
    t1, t2 = refine(ac, w * d, across + float(o[k]) * d, center)
    if abs(t1[1]) <= math.sin(math.radians(3)) * math.hypot(*t1):
        # Rows along x: t1 along them (a long brick's row is no reduced vector), t2 to the next row.
        t1 = t1 if t1[0] > 0 else -t1
        t2 = t2 if t1[0] * t2[1] - t1[1] * t2[0] > 0 else -t2
        t2 = t2 - round(float(t2 @ t1) / float(t1 @ t1)) * t1
    else:
        t1, t2 = canonical_basis(t1, t2)
    return t1, t2, min(conf, max(contrast_row, contrast_next))


# Rows are a grid when the contrast along them and along the next row are both
# at least CELLS_ALONG_MIN and one at least CELLS_ALONG_CLEAR (chosen on the
# tuned halves and the generated rows: aliased joints of turned planks reach 0.35).
CELLS_ALONG_MIN = 0.25
CELLS_ALONG_CLEAR = 0.45


RIDGE_MIN = 0.5  # rows: the median correlation along their direction
# A grid's image correlates with itself at its two vectors at least this much.
# Every lattice of the real and photo-like development sets found right does at
# 0.40 or more (two weak generated ones, confidence 0.33 and 0.36, at 0.26 and
# 0.34: lost); lines of text, their letter strokes 3-4 px apart, make a grid
# of that pitch at 0.26-0.31 whose confidence (0.39-0.42) passes, and lattice
# mode then garbles the letters (neighborhood energy 3x that without).
GRID_MIN_CORRELATION = 0.35


def _rows(ac: np.ndarray, center: tuple[int, int]):
    """A one-dimensional lattice (rows, stripes, planks, slightly curved rows):
    the autocorrelation stays high along one direction (a ridge through lag 0)
    and repeats across it. Returns (t1 along the rows, t2 across them, the
    confidence, the direction along the rows) or None."""
    hy, hx = center
    rmax = min(hy, hx) - 2
    if rmax < 8:
        return None
    th = np.deg2rad(np.arange(0.0, 180.0, 0.5))
    # The ridge over the near half of the lags, else over the nearest fifth
    # (rows that bend stay on it only that far).
    for far in (rmax / 2.0, rmax / 5.0):
        r = np.arange(2.0, far)
        pts = (r[None, :, None] * np.stack([np.cos(th), np.sin(th)], axis=1)[:, None, :]).reshape(-1, 2)
        along = sample(ac, pts, center).reshape(len(th), len(r))
        score = np.median(along, axis=1)
        k = int(np.argmax(score))
        if score[k] >= RIDGE_MIN and np.percentile(along[k], 10) >= 0.3:
            break
    else:
        return None
    d = np.array([math.cos(th[k]), math.sin(th[k])])
    n = np.array([-d[1], d[0]])
    # The period across the rows (up to half the image): the shortest lag whose
    # multiples correlate, on average, within 80% of the best lag's (a multiple
    # of the period scores as well but is longer; half of it scores about
    # nothing, as the rows fall between), each multiple read as the profile's
    # highest value within half a pixel (thin joints make thin peaks).
    step = 0.25
    s = np.arange(0.0, rmax + 1.0, step)
    prof = sample(ac, s[:, None] * n[None, :], center)
    local = ndimage.maximum_filter1d(prof, size=5, mode="nearest")  # +-0.5 px
    periods = np.arange(MIN_VECTOR, rmax, step)
    if periods.size == 0:
        return None
    comb = np.array([local[np.rint(np.arange(P, s[-1], P) / step).astype(int)].mean() for P in periods])
    twice = periods <= s[-1] / 2  # seen at least twice: far lags alone are noisy (few pixels overlap)
    if comb[twice].max(initial=-1.0) > 0.3:
        comb = np.where(twice, comb, -1.0)
    if comb.max() <= 0.3:
        return None
    i = int(np.nonzero(comb >= 0.8 * comb.max())[0][0])
    while i + 1 < len(comb) and comb[i + 1] >= comb[i]:  # the top of that peak of the comb
        i += 1
    period = float(periods[i])
    j = int(round(period / step))
    j = j - 2 + int(np.argmax(prof[j - 2:j + 3]))  # the peak itself, then sub-pixel
    if not 1 <= j < len(prof) - 1:
        return None
    a, b, c = prof[j - 1], prof[j], prof[j + 1]
    den = a - 2 * b + c
    period = (j + (0.0 if den >= 0 else float(np.clip(0.5 * (a - c) / den, -0.5, 0.5)))) * step
    if period < MIN_VECTOR:
        return None
    # Confidence: the correlation at the period's multiples against half-way
    # between them (as for a grid), times how well the rows hold along.
    ks = np.arange(1, max(1, int(s[-1] // period)) + 1)
    on = float(local[np.minimum(np.rint(ks * period / step).astype(int), len(local) - 1)].mean())
    half = float(sample(ac, ((ks - 0.5) * period)[:, None] * n[None, :], center).mean())
    conf = float(np.clip((on - half) / max(1e-6, 1.0 - half), 0.0, 1.0)) * min(1.0, float(score[k]) / 0.7)
    t1, t2 = canonical_basis(d * max(period, 8.0), n * period)
    return t1, t2, conf, d


def _rows_of_grid(ac: np.ndarray, center, grid):
    """Rows a grid's basis reveals (bent rows, whose ridge does not hold far):
    one of its vectors is short and correlates half-way as much as at its end,
    so it only cuts the rows; the other gives the period across them. The same
    (t1, t2, confidence, direction) as :func:`_rows`, or None."""
    t1, t2, conf = grid
    for v, w in ((t1, t2), (t2, t1)):
        end, mid = sample(ac, np.stack([v, 0.5 * v]), center)
        length = math.hypot(*v)
        if length < 8.0 and mid >= 0.8 * end:
            d = np.asarray(v, float) / length
            n = np.array([-d[1], d[0]])
            period = abs(float(np.asarray(w, float) @ n))
            if period >= MIN_VECTOR:
                a, b = canonical_basis(d * max(period, 8.0), n * period)
                # The grid's confidence depends on where its short vector
                # cuts the rows: unless the rows hold across at least half as
                # well on their own, their own confidence it is.
                own = _across(ac, center, n, period)
                return a, b, (conf if own >= 0.5 * conf else own), d
    return None


def _across(ac: np.ndarray, center, n, period: float) -> float:
    """How much more the image correlates with itself at whole periods across
    rows (direction n) than half-way between, in [0, 1]."""
    hy, hx = center
    ks = np.arange(1, max(1, int(min(hy, hx) // period)) + 1)
    on = float(sample(ac, (ks * period)[:, None] * n[None, :], center).mean())
    off = float(sample(ac, ((ks - 0.5) * period)[:, None] * n[None, :], center).mean())
    return float(np.clip((on - off) / max(1e-6, 1.0 - off), 0.0, 1.0))


def _along(ac: np.ndarray, center, d, t1, t2) -> bool:
    """Whether the 2-D basis (t1, t2) has a vector along the rows (direction d)
    whose half-way point correlates as much as its end: then it only cuts the
    rows into arbitrary cells and the rows' own lattice is the answer."""
    d = np.asarray(d, float)
    for v in (np.asarray(t1, float), np.asarray(t2, float)):
        if abs(v[0] * d[1] - v[1] * d[0]) <= 0.18 * math.hypot(*v):  # within about 10 degrees
            end, mid = sample(ac, np.stack([v, 0.5 * v]), center)
            if mid >= 0.8 * end:
                return True
    return False

