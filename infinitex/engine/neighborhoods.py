"""An exemplar level's filtered colors and neighborhood features
(docs/algorithm.md section 2): the Gaussian stack, LH06's appearance vectors
(or LH05's colors), the runtime neighborhood's integer projection and every
texel's projected neighborhood. Used by :mod:`engine.analysis`, which caches
the results.

Each texel's neighborhood taps are copied a band of rows at a time (by
slices, see :func:`runs`) and projected with one BLAS product per band, so a
2048^2 exemplar takes seconds and little memory. Whatever is rounded to
integers is computed so that another machine's BLAS gives the same integers.
"""
from __future__ import annotations

import numpy as np

from . import fixed

NDIM = fixed.NDIM
# PCA axes come from the statistics of at most PCA_SAMPLES^2 texels (a regular grid).
PCA_SAMPLES = 256


# ----------------------------------------------------------------------------
# Gaussian stack


def augmented_period(pixels: np.ndarray, toroidal: bool) -> np.ndarray:
    """The periodic image that extends the exemplar (LH05 3.2).

    Toroidal: the exemplar itself (period m). Otherwise the 2m x 2m mirror
    augmentation [E, flipx E; flipy E, flipxy E], whose periodic extension
    reflects the exemplar at every border.
    """
    if toroidal:
        return pixels
    top = np.concatenate([pixels, pixels[:, ::-1]], axis=1)
    return np.concatenate([top, top[::-1]], axis=0)


def gaussian_stack(pixels: np.ndarray, toroidal: bool) -> list[np.ndarray]:
    """E_0..E_L, each m x m: E_L = E, E_l blurred with sigma = h_l / 2, E_0 = mean.

    Filtering is done on the periodic augmentation, so borders see the wrapped
    or mirrored texture, never a zero pad: by FFT of the exemplar when it is
    toroidal, else by DCT-II, whose basis is exactly the mirrored 2m period
    (a quarter of the work of filtering the 2m x 2m augmentation).
    """
    from scipy import fft as sfft  # imported when used: a cached analysis needs none of scipy
    m, C = pixels.shape[0], pixels.shape[2]
    L = m.bit_length() - 1
    if toroidal:
        fy, fx = np.fft.fftfreq(m)[:, None], np.fft.rfftfreq(m)[None, :]
    else:
        fy, fx = (np.arange(m) / (2.0 * m))[:, None], (np.arange(m) / (2.0 * m))[None, :]
    f2 = fx * fx + fy * fy
    out = [np.empty_like(pixels, dtype=np.float32) for _ in range(1, L)]
    for c in range(C):  # one channel at a time: a fraction of the memory
        plane = pixels[:, :, c].astype(np.float64)
        if toroidal:
            spectrum = sfft.rfft2(plane, workers=-1)
        else:
            spectrum = sfft.dctn(plane, type=2, norm="ortho", workers=-1)
        for level in range(1, L):
            gain = np.exp(-2.0 * (np.pi ** 2) * ((1 << (L - level)) / 2.0) ** 2 * f2)
            if toroidal:
                out[level - 1][:, :, c] = sfft.irfft2(spectrum * gain, s=(m, m), workers=-1)
            else:
                out[level - 1][:, :, c] = sfft.idctn(spectrum * gain, type=2, norm="ortho", workers=-1)
    # E_0 is the mean (a read-only broadcast: no memory), E_L the exemplar itself.
    mean = np.broadcast_to(pixels.mean(axis=(0, 1), dtype=np.float64).astype(np.float32), pixels.shape)
    return [mean] + out + [np.asarray(pixels, dtype=np.float32)]


def tap_index(n: int, offset: int, m: int, mirror: bool, sample: int = 1) -> np.ndarray:
    """Indices (into an m-wide axis) of positions ``0, sample, ... < n`` moved by
    ``offset`` in the periodic augmentation: wrapped mod m, or mirrored (period 2m)."""
    i = (np.arange(0, n, sample) + offset) % (2 * m if mirror else m)
    return np.where(i < m, i, 2 * m - 1 - i) if mirror else i


def tap(img: np.ndarray, dx: int, dy: int, mirror: bool, sample: int = 1) -> np.ndarray:
    """img'[y, x] = img_aug[y + dy, x + dx] on the (sampled) grid (a gather)."""
    m = img.shape[0]
    # One axis at a time: whole rows are copied first (6x faster than np.ix_).
    return img.take(tap_index(m, dy, m, mirror, sample), axis=0).take(tap_index(m, dx, m, mirror, sample), axis=1)


def runs(idx: np.ndarray) -> list[tuple[int, int, slice]]:
    """``idx`` as runs (a, b, source slice) with idx[a:b] == range(...)[source]:
    tap indices are a few stretches of step +1 or -1 (wrapped or mirrored), so
    a tap is copied by slices instead of a gather, 4x faster."""
    d = np.diff(idx)
    starts = [0] + [j + 1 for j in np.nonzero(np.abs(d) != 1)[0]] + \
        [j + 2 for j in np.nonzero(d[1:] != d[:-1])[0]] + [len(idx)]
    starts = sorted(set(starts))
    out = []
    for a, b in zip(starts[:-1], starts[1:]):
        i0 = int(idx[a])
        step = int(idx[a + 1] - i0) if b - a > 1 else 1
        stop = i0 + step * (b - a)
        out.append((a, b, slice(i0, stop if stop >= 0 else None, step)))
    return out


def _row_chunks(m: int, texels: int):
    """Row ranges of about ``texels`` texels: a tap matrix of that many rows fits
    the CPU caches' neighborhood and keeps the analysis' peak memory small."""
    step = max(1, texels // m)
    for y0 in range(0, m, step):
        yield y0, min(m, y0 + step)


def projected(img: np.ndarray, taps, weights: np.ndarray, mirror: bool, out: np.ndarray,
               finish=lambda band: band, dtype=np.float32) -> np.ndarray:
    """out[u] = finish(sum_t img_aug[u + taps[t]] @ weights[t*C:(t+1)*C]) for
    every texel u; ``out`` is (m*m, D). Built a band of rows at a time in
    ``dtype``: the band's taps side by side (copied by slices, see :func:`runs`),
    one matrix product (BLAS) each."""
    m, C = img.shape[0], img.shape[2]
    planes = np.ascontiguousarray(np.moveaxis(img, 2, 0))   # (C, m, m): every tap copy is whole rows
    wt = np.ascontiguousarray(weights.T, dtype=dtype)       # (D, T*C)
    plan = [(runs(tap_index(m, dy, m, mirror)), runs(tap_index(m, dx, m, mirror))) for dx, dy in taps]
    for y0, y1 in _row_chunks(m, (1 << 19) // np.dtype(dtype).itemsize):
        x = np.empty((len(taps) * C, y1 - y0, m), dtype=dtype)
        for t, (rows, cols) in enumerate(plan):
            for ra, rb, rs in rows:
                a, b = max(ra, y0), min(rb, y1)
                if a >= b:
                    continue
                r0 = rs.start + rs.step * (a - ra)
                r1 = r0 + rs.step * (b - a)
                rsl = slice(r0, r1 if r1 >= 0 else None, rs.step)
                for ca, cb, cs in cols:
                    x[t * C:(t + 1) * C, a - y0:b - y0, ca:cb] = planes[:, rsl, cs]
        out[y0 * m:y1 * m] = finish((wt @ x.reshape(len(taps) * C, -1)).T)
    return out


def sample_step(m: int) -> int:
    """Grid step of the texels whose statistics give the PCA axes: every texel
    up to PCA_SAMPLES a side, a regular subgrid of PCA_SAMPLES^2 of them above
    (plenty for a 75 x 75 covariance, and a small fraction of the time and memory)."""
    return max(1, m // PCA_SAMPLES)


# ----------------------------------------------------------------------------
# Neighborhood features


def _pca(x: np.ndarray, dims: int) -> np.ndarray:
    """Top principal axes of the rows of x (columns of the result), sign-fixed."""
    xc = x - x.mean(axis=0, keepdims=True)
    cov = (xc.T @ xc) / max(1, xc.shape[0])
    w, v = np.linalg.eigh(cov)
    order = np.argsort(w)[::-1][:dims]
    v = v[:, order]
    if v.shape[1] < dims:
        v = np.concatenate([v, np.zeros((v.shape[0], dims - v.shape[1]))], axis=1)
    # Deterministic signs: largest-magnitude entry of each axis positive.
    idx = np.argmax(np.abs(v), axis=0)
    signs = np.sign(v[idx, np.arange(v.shape[1])])
    signs[signs == 0] = 1
    return v * signs


def appearance_features(stack: np.ndarray, h: int, sigma: float, toroidal: bool) -> np.ndarray:
    """LH06 appearance vectors of one level, quantized to int8 in [-127, 127].

    Taps are ``E_l[u + h*d]`` of the level's periodic augmentation, d in
    [-2, 2]^2, weighted by exp(-|d|^2 / 2 sigma^2); the PCA axes come from the
    taps on the :func:`sample_step` grid, and every texel is projected on them
    a band of rows at a time, so the 25 * C-wide matrix never exists at full size.
    """
    m, C = stack.shape[0], stack.shape[2]
    mirror = not toroidal
    offsets = [(dx * h, dy * h) for dy in range(-2, 3) for dx in range(-2, 3)]
    wgt = np.repeat([np.exp(-(dx * dx + dy * dy) / (2.0 * sigma * sigma * h * h)) for dx, dy in offsets], C)
    st = sample_step(m)
    n = len(tap_index(m, 0, m, mirror, st))
    x = np.empty((n, n, len(offsets) * C))
    for t, (dx, dy) in enumerate(offsets):
        x[:, :, t * C:(t + 1) * C] = tap(stack, dx, dy, mirror, st)
    x = x.reshape(-1, len(offsets) * C)
    x *= wgt
    axes = _pca(x, NDIM)
    offset = x.mean(axis=0) @ axes
    # The scale comes from the sampled texels (all of them up to PCA_SAMPLES a
    # side); on a larger exemplar the rare vector beyond their peak is clipped.
    # A flat level (E_0, a uniform exemplar) has no appearance: all zero.
    peak = float(np.abs(x @ axes - offset).max())
    flat = peak <= 1e-9 * max(1.0, float(np.abs(x).max()))
    del x
    scale = 0.0 if flat else fixed.FEAT_MAX / peak

    def quantized(band: np.ndarray) -> np.ndarray:
        band -= offset
        band *= scale
        return np.clip(np.rint(band, out=band), -fixed.FEAT_MAX, fixed.FEAT_MAX).astype(np.int8)

    # In float64: each vector is rounded to integers, and float32's error
    # (about 1e-5 here) would round some texels differently with another BLAS
    # kernel or thread count, i.e. another texture on another machine.
    out = np.empty((m * m, NDIM), np.int8)
    return projected(stack, offsets, wgt[:, None] * axes, mirror, out, quantized, np.float64).reshape(m, m, NDIM)


def otsu_threshold(values: np.ndarray, bins: int = 256) -> float:
    """The threshold that maximizes the between-class variance (Otsu 1979)."""
    lo, hi = float(values.min()), float(values.max())
    if hi - lo < 1e-9:
        return lo
    hist, edges = np.histogram(values, bins=bins, range=(lo, hi))
    p = hist / hist.sum()
    centers = (edges[:-1] + edges[1:]) / 2
    w0 = np.cumsum(p)
    mu = np.cumsum(p * centers)
    with np.errstate(divide="ignore", invalid="ignore"):
        between = (mu[-1] * w0 - mu) ** 2 / (w0 * (1.0 - w0))
    between[~np.isfinite(between)] = -1.0
    return float(edges[int(np.argmax(between)) + 1])


def feature_distance(pixels: np.ndarray, toroidal: bool) -> np.ndarray:
    """LH06's feature-distance channel from the exemplar's own features, (m, m, 1) in [0, 1].

    The feature mask is the exemplar's brightness (mean of its channels, lightly
    blurred) above its Otsu threshold: the elements against their background
    (stones against mortar, spots, glyphs, cells against their walls). Its
    signed distance (positive inside), clamped to D = m/32 px (at least 4) so
    the medial axes carry no singularity, is mapped to [0, 1]. Distances see the
    periodic augmentation (wrapped or mirrored), which the clamp makes a pad of D.
    """
    from scipy.ndimage import distance_transform_edt, gaussian_filter

    m = pixels.shape[0]
    mode = "wrap" if toroidal else "mirror"
    lum = gaussian_filter(pixels.astype(np.float64).mean(axis=2), 1.0, mode=mode)
    mask = lum > otsu_threshold(lum)
    D = max(4, m // 32)
    padded = np.pad(mask, D + 1, mode="wrap" if toroidal else "symmetric")
    inside = distance_transform_edt(padded)
    outside = distance_transform_edt(~padded)
    signed = (inside - outside)[D + 1:D + 1 + m, D + 1:D + 1 + m]
    return ((np.clip(signed, -D, D) / D + 1.0) / 2.0).astype(np.float32)[:, :, None]


def color_features(stack: np.ndarray) -> np.ndarray:
    """LH05 color model: colors quantized to int8 in [0, 127]."""
    return np.rint(np.clip(stack, 0.0, 1.0) * fixed.FEAT_MAX).astype(np.int8)


def gather_exemplar_neighborhood(feat: np.ndarray, h: int, model: str, sample: int = 1) -> np.ndarray:
    """The unprojected runtime neighborhood of every (sampled) exemplar texel, int64 (n, T*F):
    3 * A[u + h*d] for the 4 diagonals (the synthesized side sums 3 predictions),
    or E[u + h*d] for d in [-2, 2]^2. Reads wrap mod m, as the shader's do."""
    mult = fixed.APPEARANCE_PREDICTIONS if model == "appearance" else 1
    return np.concatenate([mult * tap(feat, dx * h, dy * h, False, sample).reshape(-1, feat.shape[2]).astype(np.int64)
                           for dx, dy in fixed.taps(model)], axis=1)


def exemplar_neighborhoods(feat: np.ndarray, h: int, model: str, proj: np.ndarray, shift: int) -> np.ndarray:
    """N_E(u) for every texel, int16 (m, m, 8): exactly fixed.project of the
    gathered neighborhood. Every product and partial sum is an integer below
    2^24 in magnitude (features <= 3 * 127, projection entries <= PROJ_ONE, at
    most 100 terms), so float32 BLAS computes it exactly, in any order."""
    m = feat.shape[0]
    mult = fixed.APPEARANCE_PREDICTIONS if model == "appearance" else 1
    offsets = [(dx * h, dy * h) for dx, dy in fixed.taps(model)]
    p = proj.astype(np.int64)
    assert mult * fixed.FEAT_MAX * int(np.abs(p).sum(axis=0).max()) < 1 << 24
    out = np.empty((m * m, NDIM), np.int16)
    projected(feat, offsets, mult * p, False, out,
               lambda band: np.right_shift(band.astype(np.int64), shift).astype(np.int16))
    return out.reshape(m, m, NDIM)


def runtime_projection(n_raw: np.ndarray, feat_max_abs: int, model: str) -> tuple[np.ndarray, int]:
    """Integer PCA matrix (T*F x 8) for the runtime neighborhood and its shift."""
    axes = _pca(n_raw.astype(np.float64), NDIM)
    proj = np.rint(axes * fixed.PROJ_ONE).astype(np.int64)
    count = n_raw.shape[1]
    mult = fixed.APPEARANCE_PREDICTIONS if model == "appearance" else 1
    bound_n = mult * max(1, feat_max_abs) * np.sqrt(count)
    return proj.astype(np.int32), fixed.choose_shift(proj, bound_n)
