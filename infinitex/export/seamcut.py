"""Least-cost seams between two overlapping images in a band (the minimum
error boundary cut of image quilting, Efros and Freeman 2001), for the tile
sets (``wang.py``).

A band is (L, W): L positions along it, W across. A seam gives each position
i a column c(i) in [0, W) with |c(i) - c(i - 1)| <= 1; the pixels before it
take image A, the others image B. The seam minimizes the sum of the pixel
costs on it, found by dynamic programming in O(L W). Deterministic: the same
colours give the same seam on every machine (float64, ties to the lower
column)."""
from __future__ import annotations

import numpy as np

def seam_cost(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """(H, W) cost of a seam through each pixel between colour images
    (H, W, C): their squared difference there (image quilting's; on this
    project's tile sets it hid cuts better than Kwatra's gradient-weighted
    difference: bench/tileset.py)."""
    return ((a.astype(np.float64) - b.astype(np.float64)) ** 2).sum(axis=-1)


def seam(cost: np.ndarray) -> np.ndarray:
    """(L,) columns of the least-cost 8-connected path through ``cost`` (L, W)."""
    return seam_and_cost(cost)[0]


def seam_and_cost(cost: np.ndarray) -> tuple[np.ndarray, float]:
    """The least-cost path's columns (L,) and its total cost."""
    length, width = cost.shape
    acc = cost.astype(np.float64).copy()
    back = np.zeros((length, width), np.int8)
    pad = np.full(width + 2, np.inf)
    left, mid, right = pad[:-2], pad[1:-1], pad[2:]
    best = np.empty(width)
    for i in range(1, length):
        mid[:] = acc[i - 1]
        # the first of the three smallest (argmin's order: left, here, right)
        here = mid < left
        np.minimum(left, mid, out=best)
        go_right = right < best
        np.minimum(best, right, out=best)
        acc[i] += best
        back[i] = np.where(go_right, 1, here.view(np.int8) - 1)
    c = np.empty(length, np.int64)
    c[-1] = int(np.argmin(acc[-1]))
    for i in range(length - 1, 0, -1):
        c[i - 1] = c[i] + back[i, c[i]]
    return c, float(acc[-1, c[-1]])


def before_seam(cost: np.ndarray) -> np.ndarray:
    """Boolean (L, W): the pixels before the least-cost seam (image A's)."""
    return before_seam_and_cost(cost)[0]


def before_seam_and_cost(cost: np.ndarray) -> tuple[np.ndarray, float]:
    """The pixels before the least-cost seam and the seam's total cost."""
    c, total = seam_and_cost(cost)
    return np.arange(cost.shape[1])[None, :] < c[:, None], total
