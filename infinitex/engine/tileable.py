"""Make tileable: turn a photo that does not wrap into a toroidal exemplar.

A photo's borders do not continue into each other, so a toroidal synthesis of
it shows its border every exemplar width (the wood checkerboard). Two steps,
both on the CPU:

1. **Periodic component** (Moisan, "Periodic plus smooth image
   decomposition", 2011): the image minus the smooth image whose Laplacian is
   the jump across its wrap-around borders. It keeps every detail of the
   interior and removes the brightness steps (shading, vignetting) between
   opposite borders; no parameter.
2. **Border cut** (Efros & Freeman 2001's minimum-error boundary cut, made
   cyclic): the last ``band`` columns are laid over the first ones and each row
   switches from one to the other where the two agree best (a shortest path
   from top to bottom through the overlap's squared differences that closes on
   itself, so the rows wrap too); then the same for rows. Elements cut by the
   border are replaced by whole ones from the other side. The result is ``band``
   pixels smaller each way.

A material's maps are cut along the same seams (the cost sums every map, each
weighted by its contrast), so they stay aligned; normal maps are renormalized.
"""
from __future__ import annotations

from dataclasses import replace

import numpy as np

from .exemplar import Exemplar
from .wrap import guess_toroidal
from .material import Material, MaterialMap, renormalize

DEFAULT_BAND = 1 / 8  # of the side
# Make tileable is recommended for an exemplar that fails the seam test when its
# large-scale shading (luminance blurred by 1/8 of its side, wrapped) varies by
# at least this fraction of its contrast: there it removes the blotches a
# plain synthesis repeats every exemplar width (wood, caustics, a text page),
# while on evenly lit stochastic photos (gravel, pebbles, granite, grass) a
# blind judgement preferred the plain synthesis (docs/formats.md#make-tileable).
SHADING_OFFER = 0.18


def periodic_component(img: np.ndarray) -> np.ndarray:
    """Moisan's periodic component of an (H, W, C) float image."""
    u = np.asarray(img, np.float64)
    h, w = u.shape[:2]
    v = np.zeros_like(u)
    dy = u[-1] - u[0]
    v[0] += dy
    v[-1] -= dy
    dx = u[:, -1] - u[:, 0]
    v[:, 0] += dx
    v[:, -1] -= dx
    q = np.cos(2 * np.pi * np.arange(h) / h)[:, None]
    r = np.cos(2 * np.pi * np.arange(w) / w)[None, :]
    den = 2 * q + 2 * r - 4
    den[0, 0] = 1.0
    s_hat = np.fft.fft2(v, axes=(0, 1)) / den[:, :, None]
    s_hat[0, 0] = 0.0
    s = np.real(np.fft.ifft2(s_hat, axes=(0, 1)))
    return u - s


def _cyclic_cut(cost: np.ndarray, starts: int = 16) -> np.ndarray:
    """Per row of ``cost`` (H, B), the column where the cut crosses it: the
    cheapest path from the first row to the last moving at most one column per
    row that ends within one column of where it started (so it wraps), over
    up to ``starts`` start columns (spread over the band, and the cheapest
    one of the first row), all followed at once."""
    h, b = cost.shape
    s0 = np.unique(np.concatenate([np.linspace(0, b - 1, min(starts, b)).round().astype(np.int64),
                                   [int(np.argmin(cost[0]))]]))
    n = len(s0)
    acc = np.full((n, b), np.inf)
    acc[np.arange(n), s0] = cost[0, s0]
    back = np.zeros((h, n, b), np.int8)
    pad = np.full((n, 1), np.inf)
    rows = np.arange(n)[:, None]
    cols = np.arange(b)[None, :]
    for y in range(1, h):
        stack = np.stack([np.concatenate([pad, acc[:, :-1]], axis=1), acc,
                          np.concatenate([acc[:, 1:], pad], axis=1)])
        k = np.argmin(stack, axis=0)
        back[y] = k - 1
        acc = stack[k, rows, cols] + cost[y][None, :]
    # Close each path: it must end within one column of its start.
    near = np.abs(cols - s0[:, None]) <= 1
    end_cost = np.where(near, acc, np.inf)
    i, end = np.unravel_index(int(np.argmin(end_cost)), end_cost.shape)
    path = np.empty(h, np.int64)
    path[-1] = end
    for y in range(h - 1, 0, -1):
        path[y - 1] = path[y] + back[y, i, path[y]]
    return path


def _column_cut(guide: np.ndarray, band: int) -> np.ndarray:
    """Where each row of ``guide`` (H, W, C) switches from its last ``band``
    columns (laid over the first ones) back to the first ones (_cyclic_cut)."""
    w = guide.shape[1]
    right, left = guide[:, w - band:], guide[:, :band]  # right continues the image past its end; left starts it
    return _cyclic_cut(((right - left) ** 2).sum(axis=2))


def _wrap_columns(img: np.ndarray, band: int, cut: np.ndarray) -> np.ndarray:
    """``img`` (H, W, C) made to wrap left-right along ``cut``: W - band columns."""
    w = img.shape[1]
    right, left = img[:, w - band:], img[:, :band]
    take_right = np.arange(band)[None, :] < cut[:, None]  # before the cut: what follows the last kept column
    strip = np.where(take_right[:, :, None], right, left)
    return np.concatenate([strip, img[:, band:w - band]], axis=1)


def make_tileable_maps(images: list[np.ndarray], band: int | None = None) -> list[np.ndarray]:
    """Toroidal versions of aligned images (a material's maps), each (H, W) or
    (H, W, C) in [0, 1], all cut along the same seams: (H - band, W - band),
    float32. The seams follow all maps at once, each weighted by its own
    contrast (a flat map has no say). ``band`` defaults to 1/8 of the shorter side."""
    arrays = [np.asarray(img, np.float64) for img in images]
    flat = [a.ndim == 2 for a in arrays]
    arrays = [a[:, :, None] if f else a for a, f in zip(arrays, flat)]
    h, w = arrays[0].shape[:2]
    if any(a.shape[:2] != (h, w) for a in arrays):
        raise ValueError("The maps made tileable together must have one size.")
    if band is None:
        band = max(2, int(round(min(h, w) * DEFAULT_BAND)))
    if not 2 <= band <= min(h, w) // 3:
        raise ValueError(f"The border band must be 2 to {min(h, w) // 3} px for a {w}x{h} image.")
    parts = [periodic_component(a) for a in arrays]
    if len(parts) == 1:
        weights = [1.0]
    else:
        sd = [float(p.std()) for p in parts]
        weights = [1.0 / v if v > 1e-6 else 0.0 for v in sd]
        if not any(weights):
            weights = [1.0] * len(parts)

    def guide(ps):
        return ps[0] if len(ps) == 1 else np.concatenate([p * wt for p, wt in zip(ps, weights)], axis=2)

    cut = _column_cut(guide(parts), band)
    parts = [_wrap_columns(p, band, cut).transpose(1, 0, 2) for p in parts]
    cut = _column_cut(guide(parts), band)
    parts = [_wrap_columns(p, band, cut).transpose(1, 0, 2) for p in parts]
    out = [np.clip(p, 0.0, 1.0).astype(np.float32) for p in parts]
    return [o[:, :, 0] if f else o for o, f in zip(out, flat)]


def make_tileable(img: np.ndarray, band: int | None = None) -> np.ndarray:
    """A toroidal version of ``img`` (H, W) or (H, W, C) in [0, 1]:
    (H - band, W - band), float32. ``band`` defaults to 1/8 of the shorter side."""
    return make_tileable_maps([img], band)[0]


def _periodic_resize(a: np.ndarray, side: int) -> np.ndarray:
    """A toroidal (H, W, C) image resampled to (side, side, C), still toroidal
    (scipy's cubic spline with wrap-around boundaries; a Gaussian prefilter,
    wrapped too, when it shrinks)."""
    from scipy import ndimage  # imported when an exemplar is made tileable, not by every command
    h, w = a.shape[:2]
    out = []
    for c in range(a.shape[2]):
        plane = np.asarray(a[:, :, c], np.float64)
        sig = (0.5 * max(0.0, h / side - 1.0), 0.5 * max(0.0, w / side - 1.0))
        if max(sig) > 0:
            plane = ndimage.gaussian_filter(plane, sig, mode="wrap")
        out.append(ndimage.zoom(plane, (side / h, side / w), order=3, mode="grid-wrap", grid_mode=True))
    return np.clip(np.stack(out, axis=2), 0.0, 1.0).astype(np.float32)


def tileable_exemplar(ex: Exemplar) -> Exemplar:
    """The exemplar ``ex`` made tileable (:func:`make_tileable`) at the same
    size, toroidal. With a high-resolution copy, the cut is made on it and
    the exemplar is resampled from the result, so both hold the same seams."""
    return _tileable_exemplars([ex])[0]


def _tileable_exemplars(exs: list[Exemplar], normals: tuple[bool, ...] = ()) -> list[Exemplar]:
    """Aligned exemplars made tileable together (one cut); ``normals[i]``:
    exemplar i is a normal map, renormalized after the cut and the resampling."""
    m = exs[0].size
    hires = all(ex.hires is not None for ex in exs)
    cut = make_tileable_maps([ex.hires if hires else ex.pixels for ex in exs])
    out = []
    for i, (ex, c) in enumerate(zip(exs, cut)):
        normal = i < len(normals) and normals[i]
        if normal:
            c = renormalize(c)
        pixels = _periodic_resize(c, m)
        if normal:
            pixels = renormalize(pixels)
        out.append(replace(ex, pixels=pixels, hires=c if hires else None, toroidal=True,
                           toroidal_guess=guess_toroidal(pixels)))
    return out


def tileable_material(material: Material) -> Material:
    """A material whose maps are made tileable together: one cut for all of
    them, so they stay aligned; normal maps stay unit length."""
    roles = material.roles
    exs = _tileable_exemplars([material.maps[r].exemplar for r in roles], tuple(r == "normal" for r in roles))
    return Material({r: MaterialMap(r, ex) for r, ex in zip(roles, exs)}, True)


def shading_strength(pixels: np.ndarray) -> float:
    """How much an (m, m, C) image's large-scale shading varies: the standard
    deviation of its luminance blurred by m/8 (wrapped) over that of its
    luminance. The blur is a product in the Fourier domain (numpy's FFT: the
    wrapped Gaussian exactly, and no scipy to import before a command's first
    line of output)."""
    lum = np.asarray(pixels, np.float64).mean(axis=2)
    sd = float(lum.std())
    if sd < 1e-9:
        return 0.0
    sigma = lum.shape[0] / 8.0
    fy, fx = np.fft.fftfreq(lum.shape[0])[:, None], np.fft.rfftfreq(lum.shape[1])[None, :]
    gain = np.exp(-2.0 * (np.pi * sigma) ** 2 * (fx * fx + fy * fy))
    return float(np.fft.irfft2(np.fft.rfft2(lum) * gain, s=lum.shape).std()) / sd


def recommended(ex: Exemplar) -> bool:
    """Whether to offer Make tileable for ``ex``: it does not tile by the seam
    test and its shading varies enough to show as blotches (SHADING_OFFER).
    Remembered on the exemplar."""
    if ex.toroidal_guess:
        return False
    got = getattr(ex, "_tileable_offer", None)
    if got is None:
        got = shading_strength(ex.pixels) >= SHADING_OFFER
        ex._tileable_offer = got
    return got
