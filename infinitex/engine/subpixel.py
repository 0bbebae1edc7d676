"""Colors of coordinates that carry sub-pixel remainders (a direction field,
engine/controls/direction.py): a state is (texel x, texel y, remainder x,
remainder y) in 1/256 px, and a map is sampled bilinearly at
``texel + remainder / 256`` (wrapped on a toroidal exemplar, clamped
otherwise), so a turned or scaled texture is drawn smoothly instead of with
the nearest texel's stair steps. Without remainders (2 channels, or all 0) the
lookup is the plain ``map[S]``, bit for bit. Normal maps turn with the texture.
"""
from __future__ import annotations

import numpy as np

from .fixed import FRAC_ONE


def has_remainders(coords: np.ndarray) -> bool:
    return coords.shape[-1] == 4 and bool(np.any(coords[..., 2:]))


def sample(arr: np.ndarray, coords: np.ndarray, wrap: bool) -> np.ndarray:
    """arr[S] (arr (n, n, C)) for coordinates (..., 2), or (..., 4) with remainders:
    bilinear at texel + remainder / 256, in arr's dtype (rounded for integers)."""
    if not has_remainders(coords):
        return arr[coords[..., 1], coords[..., 0]]
    n = arr.shape[0]
    x = coords[..., 0] * FRAC_ONE + coords[..., 2].astype(np.int64)
    y = coords[..., 1] * FRAC_ONE + coords[..., 3].astype(np.int64)
    x0, y0 = x >> 8, y >> 8  # floor
    fx = ((x & (FRAC_ONE - 1)) / FRAC_ONE)[..., None]
    fy = ((y & (FRAC_ONE - 1)) / FRAC_ONE)[..., None]

    def idx(v):
        return np.mod(v, n) if wrap else np.clip(v, 0, n - 1)
    xa, xb, ya, yb = idx(x0), idx(x0 + 1), idx(y0), idx(y0 + 1)
    a = arr.astype(np.float32)
    out = ((1 - fx) * (1 - fy) * a[ya, xa] + fx * (1 - fy) * a[ya, xb]
           + (1 - fx) * fy * a[yb, xa] + fx * fy * a[yb, xb])
    if np.issubdtype(arr.dtype, np.integer):
        return np.clip(np.rint(out), np.iinfo(arr.dtype).min, np.iinfo(arr.dtype).max).astype(arr.dtype)
    return out.astype(arr.dtype)


def turn_normals(normals: np.ndarray, jac: np.ndarray) -> np.ndarray:
    """Tangent-space normals (H, W, >=3) in [0, 1] encoding, sampled from the
    exemplar, turned with the texture at each pixel: the output's height is
    h(J p), so slopes transform by J^T; with J scaled to unit determinant
    (a turn alone turns the normal, a uniform scale leaves it), then
    renormalized. The maps are OpenGL-style (+Y up, against the image's rows).
    ``jac``: Q12 (H, W, 4)."""
    j = jac.astype(np.float64) / 4096.0
    det = np.sqrt(np.maximum(j[..., 0] * j[..., 3] - j[..., 1] * j[..., 2], 1e-12))
    nx = normals[..., 0].astype(np.float64) * 2.0 - 1.0
    ny = 1.0 - normals[..., 1].astype(np.float64) * 2.0  # +Y up: image rows run down
    nz = normals[..., 2].astype(np.float64) * 2.0 - 1.0
    tx = (j[..., 0] * nx + j[..., 2] * ny) / det  # J^T (nx, ny)
    ty = (j[..., 1] * nx + j[..., 3] * ny) / det
    length = np.sqrt(tx * tx + ty * ty + nz * nz)
    length = np.where(length > 0, length, 1.0)
    out = normals.astype(np.float64).copy()
    out[..., 0] = (tx / length + 1.0) * 0.5
    out[..., 1] = (1.0 - ty / length) * 0.5
    out[..., 2] = (nz / length + 1.0) * 0.5
    return np.clip(out, 0.0, 1.0).astype(normals.dtype)


def shear_pull(pred: list[np.ndarray], wgt: list[np.ndarray], c: int, m: int, toroidal: bool, h: int) -> np.ndarray:
    """How far corner c's extrapolated position moves towards the others that
    nearly agree with it (at most one texel, h exemplar pixels, apart): the
    weighted sum of their differences. Where two patches meet with a 1 px shear
    (fine-level jitter), the magnified image then warps smoothly from one to the
    other instead of blending two copies 1 px apart (the comb or zipper lines
    along edges at 800%); coherent corners (no difference) and real seams (far
    apart) are drawn as LH05 section 5 does. Continuous across texels; exact at
    texel centers. The canvas shader does the same (canvas.frag)."""
    pull = np.zeros_like(pred[c])
    for o in range(4):
        if o == c:
            continue
        d = pred[o] - pred[c]  # an integer per corner pair: (u_o - u_c) - h (o - c)
        if toroidal:
            d -= m * np.floor(d / m + 0.5)
        near = (np.abs(d).max(axis=-1) <= h)[..., None]
        pull += wgt[o][..., None] * np.where(near, d, 0.0)
    return pull


def bilinear(src: np.ndarray, x: np.ndarray, y: np.ndarray, wrap: bool) -> np.ndarray:
    """Bilinear samples of src (n, n, C) at pixel positions (x, y) (centers at
    integers): wrapped (toroidal) or clamped to the edge, as the canvas' texture."""
    n = src.shape[0]
    x0, y0 = np.floor(x).astype(np.int64), np.floor(y).astype(np.int64)
    fx, fy = (x - x0)[..., None], (y - y0)[..., None]

    def idx(v):
        return np.mod(v, n) if wrap else np.clip(v, 0, n - 1)
    xa, xb, ya, yb = idx(x0), idx(x0 + 1), idx(y0), idx(y0 + 1)
    return ((1 - fx) * (1 - fy) * src[ya, xa] + fx * (1 - fy) * src[ya, xb]
            + (1 - fx) * fy * src[yb, xa] + fx * fy * src[yb, xb])
