"""Which block of lattice cells becomes the exemplar: the most cells (powers of
two per side) that fit in the input image, for detected vectors
(:func:`choose_block`) or for a cell the artist marked or moved
(:func:`fit_block`, which keeps the lattice's phase)."""
from __future__ import annotations

import math

import numpy as np

from .lattice import MAX_CELLS, Lattice

COUNTS = (1, 2, 4, 8, 16)
MAX_SHIFT = 256  # whole cells a block may move to fit (cells of 3 px in a 768 px image)


def choose_block(t1, t2, width: int, height: int) -> Lattice | None:
    """The block for vectors t1, t2 in a width x height image: the most cells
    (powers of two per side) whose parallelogram fits, with the rectified
    aspect nx|t1| : ny|t2| within 2:1 (closest to square on ties), centred."""
    l1, l2 = math.hypot(*t1), math.hypot(*t2)
    best = None
    for nx in (1, 2, 4, 8, 16):
        for ny in (1, 2, 4, 8, 16):
            bw = abs(nx * t1[0]) + abs(ny * t2[0])
            bh = abs(nx * t1[1]) + abs(ny * t2[1])
            if bw > width - 1 or bh > height - 1:
                continue
            ratio = (nx * l1) / (ny * l2)
            if not 0.5 <= ratio <= 2.0:
                continue
            key = (nx * ny, -abs(math.log(ratio)))
            if best is None or key > best[0]:
                best = (key, nx, ny)
    if best is None:
        return None
    _, nx, ny = best
    cx = (width - (nx * t1[0] + ny * t2[0])) / 2.0
    cy = (height - (nx * t1[1] + ny * t2[1])) / 2.0
    return Lattice((round(cx, 3), round(cy, 3)), (round(t1[0], 3), round(t1[1], 3)),
                   (round(t2[0], 3), round(t2[1], 3)), nx, ny)


def fit_block(origin, t1, t2, width: int, height: int, most: tuple[int, int] = (MAX_CELLS, MAX_CELLS),
              levels: int | None = None, keep_origin: bool = False) -> Lattice | None:
    """The lattice of cell vectors t1, t2 through ``origin`` whose block fits a
    width x height image with the most cells (powers of two per side, at most
    ``most``; the rectified aspect nx|t1| : ny|t2| within 2:1 when one fits so).
    The block starts at origin + i t1 + j t2 for whole i, j, so the cells stay
    where they were put: at ``origin`` itself when that fits, else as near the
    image's centre as it can (``keep_origin``: a block at ``origin`` with fewer
    cells comes first, so a handle stays where it was dropped). None when not
    even one cell fits."""
    o, a, b = (np.asarray(v, dtype=np.float64) for v in (origin, t1, t2))
    l1, l2 = math.hypot(*a), math.hypot(*b)
    if min(l1, l2) <= 0:
        return None
    if abs(a[0] * b[1] - a[1] * b[0]) < 1e-9:
        return None
    # Whole-cell shifts around the one that brings the origin nearest the image's centre.
    ci, cj = np.rint(np.linalg.solve(np.array([a, b]).T, np.array([width, height]) / 2.0 - o)).astype(int)
    r = min(MAX_SHIFT, int(max(width, height) / max(1e-9, min(l1, l2))) + 2)
    ii, jj = np.meshgrid(np.arange(ci - r, ci + r + 1), np.arange(cj - r, cj + r + 1))
    starts = o + ii[..., None] * a + jj[..., None] * b          # (2r+1, 2r+1, 2)
    home = (ii == 0) & (jj == 0)
    tol = 0.5
    best = None
    for nx in (n for n in COUNTS if n <= most[0]):
        for ny in (n for n in COUNTS if n <= most[1]):
            corners = np.array([[0, 0], nx * a, ny * b, nx * a + ny * b])
            lo, hi = corners.min(axis=0), corners.max(axis=0)
            ok = ((starts + lo >= -tol) & (starts + hi <= np.array([width, height]) + tol)).all(axis=-1)
            if not ok.any():
                continue
            centre = starts + (nx * a + ny * b) / 2.0
            off = np.hypot(centre[..., 0] - width / 2.0, centre[..., 1] - height / 2.0)
            off = np.where(ok, off, np.inf)
            at_origin = bool((ok & home).any())
            y, x = np.argwhere(home)[0] if at_origin else np.unravel_index(np.argmin(off), off.shape)
            aspect = abs(math.log((nx * l1) / (ny * l2)))
            key = (aspect <= math.log(2.0) + 1e-9, nx * ny, at_origin, -aspect, -float(off[y, x]))
            if keep_origin:
                key = (at_origin,) + key
            if best is None or key > best[0]:
                best = (key, nx, ny, starts[y, x])
    if best is None:
        return None
    _, nx, ny, start = best
    return Lattice((round(float(start[0]), 3), round(float(start[1]), 3)),
                   (round(float(a[0]), 3), round(float(a[1]), 3)), (round(float(b[0]), 3), round(float(b[1]), 3)),
                   nx, ny, levels)


EXACT_TOLERANCE = 0.05  # px: vectors this close to whole pixels are taken as whole
MAX_INDEX = 4           # a supercell of at most this many cells


def exact_block(lat: Lattice, width: int, height: int) -> Lattice:
    """``lat`` described so that its rectification copies pixels exactly,
    where the image allows: vectors within EXACT_TOLERANCE of whole pixels
    (a game texture's or a drawn pattern's), an axis-aligned cell of w x h
    whole pixels spanned by small combinations of them (a staggered or
    diagonal lattice's rectangular supercell, at most MAX_INDEX cells), and
    nx w = ny h a power of two: the block is then the image's own pixels at
    a whole-pixel origin, with no shear and no resampling (a slanted block is
    resampled twice, into the exemplar and back, which softens it). The
    block is the largest such that fits, if it holds at least as many of the
    detected cells as ``lat``'s; ``lat`` itself otherwise."""
    t1, t2 = np.asarray(lat.t1, float), np.asarray(lat.t2, float)
    r1, r2 = np.rint(t1), np.rint(t2)
    if np.abs(t1 - r1).max() > EXACT_TOLERANCE or np.abs(t2 - r2).max() > EXACT_TOLERANCE:
        return lat
    best = None
    span = range(-MAX_INDEX, MAX_INDEX + 1)
    for i in span:
        for j in span:
            a = i * r1 + j * r2
            if a[1] != 0 or a[0] <= 0:
                continue
            for k in span:
                for m in span:
                    b = k * r1 + m * r2
                    if b[0] != 0 or b[1] <= 0:
                        continue
                    index = abs(i * m - j * k)
                    if 1 <= index <= MAX_INDEX and (best is None or index < best[0]):
                        best = (index, int(a[0]), int(b[1]))
    if best is None:
        return lat
    index, w, h = best
    for side in (512, 256, 128, 64, 32):
        nx, ny = side // w, side // h
        if nx * w != side or ny * h != side or nx & (nx - 1) or ny & (ny - 1) or max(nx, ny) > MAX_CELLS:
            continue
        if nx * ny * index < lat.nx * lat.ny:
            break  # fewer of the detected cells than the resampled block holds: less variety
        if side > width or side > height:
            continue
        # The cells where the detected ones are (their phase), at a whole
        # pixel, the block as near the image's centre as fits.
        o = np.rint(np.asarray(lat.origin, float))
        start = []
        for c, cell, room in ((o[0], w, width - side), (o[1], h, height - side)):
            lo, hi = math.ceil(-c / cell), math.floor((room - c) / cell)
            if lo > hi:
                break
            start.append(c + cell * min(hi, max(lo, round((room / 2 - c) / cell))))
        if len(start) < 2:
            continue
        x0, y0 = start
        return Lattice((float(x0), float(y0)), (float(w), 0.0), (0.0, float(h)), nx, ny, lat.levels)
    return lat
