"""Whether an exemplar tiles (toroidal): its wrap-around seams against its
interior, at the pixel scale and in blocks of a few pixels; and, for small
patterns, whether a seam looks like one of their own edges."""
from __future__ import annotations

import numpy as np

# Whether an exemplar tiles, from its wrap-around seams at several scales: the
# mean difference of k x k block means across the seam, over that across the
# interior boundaries k to SEAM_NEAR k from it. A photo cut from a larger one
# passes at the pixel scale when its detail is fine (grass, dirt: neighboring
# pixels differ about as much as distant ones) while its shading and larger
# elements jump at the seam, which a synthesis then copies as long straight
# lines (docs/benchmarks.md, "Straight seams"). On 67 game textures, 536 cuts of
# them and 67 cuts made tileable (bench/tiling_guess.py), the pixel test alone
# takes 115 cuts for tiling, this one 35; it keeps 45 of the 57 made tileable
# that the pixel test keeps, and the bundled cobbles. An exemplar taken for not
# tiling when it does loses only a band at its border to the synthesis, and the
# Toroidal setting overrides the guess. The nearest boundaries alone compare
# best: farther ones see other content (a grout line running beside the seam).
SEAM_SCALES = (1, 2, 4, 8)
SEAM_NEAR = 1
SEAM_MEAN_TOLERANCE = 1.25  # geometric mean of the ratios over the scales
SEAM_MAX_TOLERANCE = 1.8    # any one scale
SEAM_FLOOR = 0.3            # interior differences counted as at least this much of the pixel scale's


def seam_ratios(pixels: np.ndarray, scales: tuple[int, ...] = SEAM_SCALES) -> list[float]:
    """Per scale k (up to a quarter of the exemplar): the largest over the two
    wrap-around seams of the mean difference of the k x k block means on either
    side of the seam, over that of the interior boundaries k to SEAM_NEAR k away
    (at least SEAM_FLOOR times the pixel scale's, so that a smooth image's
    tiny block differences do not make any seam stand out)."""
    p = pixels.astype(np.float64).reshape(pixels.shape[0], pixels.shape[1], -1)
    out = []
    pixel_scale = {}
    for k in scales:
        worst = None
        for axis, q in enumerate((p, p.transpose(1, 0, 2))):
            H, W = q.shape[:2]
            if 4 * k > min(H, W):
                continue
            # The columns near the seam, which then lies between columns half - 1 and half.
            half = min(W // 2, (SEAM_NEAR + 1) * k)
            Hk = H - H % k
            strip = np.concatenate([q[:Hk, W - half:], q[:Hk, :half]], axis=1)
            strip = strip.reshape(Hk // k, k, 2 * half, -1).mean(axis=1)
            c = np.concatenate([np.zeros_like(strip[:, :1]), np.cumsum(strip, axis=1)], axis=1)
            blocks = (c[:, k:] - c[:, :-k]) / k  # the k x k block means starting at column i
            d = np.abs(blocks[:, k:] - blocks[:, :-k]).mean(axis=(0, 2))  # across column i + k
            b = np.arange(d.size) + k
            near = (np.abs(b - half) >= k) & (np.abs(b - half) <= SEAM_NEAR * k)
            inner = d[near].mean()
            pixel_scale.setdefault(axis, inner)
            r = d[half - k] / (max(inner, SEAM_FLOOR * pixel_scale[axis]) + 1e-9)
            worst = r if worst is None else max(worst, r)
        if worst is not None:
            out.append(float(worst))
    return out


def seams_match_at_pixel_scale(pixels: np.ndarray, tolerance: float = 1.6) -> bool:
    """The mean absolute difference across the left/right and top/bottom seams
    at most ``tolerance`` times that between adjacent interior columns/rows."""
    p = pixels.astype(np.float64)
    inner_x = np.abs(np.diff(p, axis=1)).mean()
    inner_y = np.abs(np.diff(p, axis=0)).mean()
    seam_x = np.abs(p[:, 0] - p[:, -1]).mean()
    seam_y = np.abs(p[0, :] - p[-1, :]).mean()
    eps = 1e-6
    return bool(seam_x <= tolerance * inner_x + eps and seam_y <= tolerance * inner_y + eps)


def guess_toroidal(pixels: np.ndarray, tolerance: float = 1.6) -> bool:
    """True when the wrap-around seams differ no more than interior neighbors:
    at the pixel scale (:func:`seams_match_at_pixel_scale`) and at every scale
    of :func:`seam_ratios` (their geometric mean at most SEAM_MEAN_TOLERANCE,
    none above SEAM_MAX_TOLERANCE)."""
    if not seams_match_at_pixel_scale(pixels, tolerance):
        return False
    r = np.maximum(np.array(seam_ratios(pixels)), 1e-6)
    return bool(r.size == 0 or (np.exp(np.log(r).mean()) <= SEAM_MEAN_TOLERANCE and r.max() <= SEAM_MAX_TOLERANCE))


def seams_like_an_edge(pixels: np.ndarray, tolerance: float = 1.05) -> bool:
    """True when each wrap-around seam differs no more than the most different
    pair of adjacent interior columns (rows): for small patterns, whose seam may
    fall on one of their own edges (a grid line at the border), which the
    mean-based :func:`guess_toroidal` refuses; a cut photo's seam stands out."""
    p = pixels.astype(np.float64).reshape(pixels.shape[0], pixels.shape[1], -1)
    if min(p.shape[:2]) < 2:
        return False
    cols, rows = np.abs(np.diff(p, axis=1)).mean(axis=(0, 2)), np.abs(np.diff(p, axis=0)).mean(axis=(1, 2))
    seam_x, seam_y = np.abs(p[:, 0] - p[:, -1]).mean(), np.abs(p[0, :] - p[-1, :]).mean()
    return bool(seam_x <= tolerance * cols.max() + 1e-6 and seam_y <= tolerance * rows.max() + 1e-6)
