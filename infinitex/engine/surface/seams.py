"""How visible a model's UV seams are in a baked atlas (bench/surface.py, tests).

Along every seam edge (a chart border with a triangle of another chart, or of
the same chart elsewhere, across it), points about one texel apart are taken
on the surface; each is looked up half a texel inside each of the two charts
(the texels of both sides, one texel apart on the surface). The seam error is
the mean colour difference between the two sides, against the mean difference
between adjacent texels inside charts: 1.0 means a seam is as continuous as
the texture itself.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .atlas import AtlasDomain


@dataclass(frozen=True)
class SeamError:
    seam: float  # mean |difference| across seams (per channel, the image's units)
    interior: float  # the same between adjacent texels inside charts
    samples: int  # seam point pairs measured

    @property
    def ratio(self) -> float:
        return self.seam / max(self.interior, 1e-12)


def seam_pairs(atlas: AtlasDomain) -> tuple[np.ndarray, np.ndarray]:
    """Texel pairs (each (n, 2) as x, y, finest level) facing each other across the model's seams."""
    X = atlas.uvpx
    keep = atlas.b_other >= 0
    a, b, c = X[atlas.b_a[keep]], X[atlas.b_b[keep]], X[atlas.b_c[keep]]
    M = atlas.b_map[keep]
    chart_a = atlas.chart[atlas.b_tri[keep]]
    chart_b = atlas.chart[atlas.b_other[keep]]
    d = b - a
    length = np.linalg.norm(d, axis=-1)
    count = np.maximum(1, np.ceil(length)).astype(np.int64)
    e = np.repeat(np.arange(len(a)), count)
    t = (np.arange(int(count.sum())) - np.repeat(np.cumsum(count) - count, count) + 0.5) / np.repeat(count, count)
    p = a[e] + t[:, None] * d[e]
    normal = np.stack([-d[:, 1], d[:, 0]], -1) / np.maximum(length, 1e-300)[:, None]
    inward = np.where(((c - a) * normal).sum(-1, keepdims=True) >= 0, normal, -normal)
    qa = p + 0.5 * inward[e]
    lin = M[e][:, :, :2]
    pb = (lin @ p[:, :, None])[:, :, 0] + M[e][:, :, 2]
    out_b = (lin @ (-inward[e])[:, :, None])[:, :, 0]
    qb = pb + 0.5 * out_b / np.maximum(np.linalg.norm(out_b, axis=-1, keepdims=True), 1e-300)
    n = atlas.size
    ta = np.clip(np.floor(qa).astype(np.int64), 0, n - 1)
    tb = np.clip(np.floor(qb).astype(np.int64), 0, n - 1)
    own = atlas.owner(0)
    ok = (own[ta[:, 1], ta[:, 0]] == chart_a[e]) & (own[tb[:, 1], tb[:, 0]] == chart_b[e])
    return ta[ok], tb[ok]


def seam_error(image: np.ndarray, atlas: AtlasDomain) -> SeamError:
    """The seam error of a baked atlas image (float or integer (N, N[, C]))."""
    img = image.astype(np.float64)
    if img.ndim == 2:
        img = img[..., None]
    ta, tb = seam_pairs(atlas)
    seam = np.abs(img[ta[:, 1], ta[:, 0]] - img[tb[:, 1], tb[:, 0]]).mean() if len(ta) else 0.0
    own = atlas.owner(0)
    diffs = []
    for sl_a, sl_b in (((slice(None), slice(None, -1)), (slice(None), slice(1, None))),
                       ((slice(None, -1), slice(None)), (slice(1, None), slice(None)))):
        same = (own[sl_a] == own[sl_b]) & (own[sl_a] >= 0)
        diffs.append(np.abs(img[sl_a][same] - img[sl_b][same]))
    interior = float(np.concatenate(diffs).mean())
    return SeamError(float(seam), interior, len(ta))
