"""Least-cost seams between two overlapping images in a band (the minimum
error boundary cut of image quilting, Efros and Freeman 2001, with the
gradient weighting of Kwatra et al. 2003), for the tile sets (``wang.py``).

A band is (L, W): L positions along it, W across. A seam gives each position
i a column c(i) in [0, W) with |c(i) - c(i - 1)| <= 1; the pixels before it
take image A, the others image B. The seam minimizes the sum of the pixel
costs on it, found by dynamic programming in O(L W). Deterministic: the same
colours give the same seam on every machine (float64, ties to the lower
column)."""
from __future__ import annotations

import numpy as np

GRADIENT = 0.1  # a colour step (summed norm, [0, 1] units) that halves a seam pixel's cost


def _norm(x: np.ndarray) -> np.ndarray:
    return np.sqrt((x.astype(np.float64) ** 2).sum(axis=-1))


def _step(img: np.ndarray) -> np.ndarray:
    """How much a pixel differs from its neighbours (H, W): the largest of
    the four differences (what a seam beside it would hide among)."""
    out = np.zeros(img.shape[:2])
    dx = _norm(img[:, 1:] - img[:, :-1])
    dy = _norm(img[1:] - img[:-1])
    out[:, 1:] = np.maximum(out[:, 1:], dx)
    out[:, :-1] = np.maximum(out[:, :-1], dx)
    out[1:] = np.maximum(out[1:], dy)
    out[:-1] = np.maximum(out[:-1], dy)
    return out


def seam_cost(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """(H, W) cost of a seam through each pixel between colour images
    (H, W, C): their mismatch there, lowered where either image has an edge
    (a seam along the border of an element shows least)."""
    return _norm(a - b) / (1.0 + (_step(a) + _step(b)) / GRADIENT)


def seam(cost: np.ndarray) -> np.ndarray:
    """(L,) columns of the least-cost 8-connected path through ``cost`` (L, W)."""
    length, width = cost.shape
    acc = cost.astype(np.float64).copy()
    back = np.zeros((length, width), np.int8)
    cols = np.arange(width)
    for i in range(1, length):
        prev = acc[i - 1]
        options = np.stack([np.r_[np.inf, prev[:-1]], prev, np.r_[prev[1:], np.inf]])
        k = np.argmin(options, axis=0)
        acc[i] += options[k, cols]
        back[i] = k - 1
    c = np.empty(length, np.int64)
    c[-1] = int(np.argmin(acc[-1]))
    for i in range(length - 1, 0, -1):
        c[i - 1] = c[i] + back[i, c[i]]
    return c


def before_seam(cost: np.ndarray) -> np.ndarray:
    """Boolean (L, W): the pixels before the least-cost seam (image A's)."""
    c = seam(cost)
    return np.arange(cost.shape[1])[None, :] < c[:, None]
