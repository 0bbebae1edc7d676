"""Texture quality measures (numpy + scipy, no downloaded weights).

All images are float arrays in [0, 1], (H, W) or (H, W, C); coordinate maps
are int (H, W, 2) exemplar (x, y). Read the figures together: neighborhood
energy alone rewards copying (a tiled exemplar scores 0), so it comes with
coverage, verbatim-copy size and repetition.
"""
from __future__ import annotations

import numpy as np
from scipy import ndimage, sparse, stats
from scipy.sparse import csgraph
from scipy.spatial import cKDTree

PATCH = 5
PCA_DIMS = 10


def _chan(img: np.ndarray) -> np.ndarray:
    img = np.asarray(img, dtype=np.float64)
    return img[:, :, None] if img.ndim == 2 else img


def _patches(img: np.ndarray, step: int = 1) -> np.ndarray:
    """All PATCH x PATCH neighborhoods (valid positions, every ``step`` px) as rows."""
    w = np.lib.stride_tricks.sliding_window_view(img, (PATCH, PATCH), axis=(0, 1))
    w = w[::step, ::step]
    return w.reshape(w.shape[0] * w.shape[1], -1)


def _phases(img: np.ndarray, s: int, mode: str, every: bool = True) -> list[np.ndarray]:
    """The image Gaussian-filtered for scale ``s`` and subsampled by ``s`` at
    each of the s^2 phases (``every``; else at phase 0 only): together they
    hold every neighborhood of taps ``s`` apart, so an image and a copy of it
    shifted by any pixel offset have the same neighborhoods at every scale."""
    if s == 1:
        return [img]
    blurred = ndimage.gaussian_filter(img, sigma=(s / 2, s / 2, 0), mode=mode)
    n = s if every else 1
    return [blurred[i::s, j::s] for i in range(n) for j in range(n)]


def neighborhood_energy(exemplar: np.ndarray, output: np.ndarray, scales=(1, 2, 4),
                        samples: int = 4000, seed: int = 0, periodic: bool = False,
                        every_phase: bool = True) -> tuple[float, float]:
    """(energy, completeness): mean squared distance per value of output
    neighborhoods to their nearest exemplar neighborhood, and of exemplar
    neighborhoods to their nearest output neighborhood, averaged over scales
    (Gaussian-filtered, taps 1, 2, 4 px apart); 5x5 neighborhoods, matched
    in their 10 leading PCA dimensions (outputs over 300^2 use every other
    neighborhood as match candidates for completeness).

    At scales over 1 the neighborhoods of both images are taken at every
    position (all s^2 subsampling phases): an output that copies the exemplar
    shifted by an odd number of pixels scores 0 like one copied in phase.
    (Until December 2026 only phase 0 was read: an exact copy of a sharp,
    fine-grained exemplar at another phase scored like a poor match, by
    chance of where its copies fell; figures before then used that reading,
    which ``every_phase=False`` gives.)"""
    ex, out = _chan(exemplar), _chan(output)
    rng = np.random.default_rng(seed)
    energy, complete = [], []
    mode = "wrap" if periodic else "reflect"  # how images are extended for the blur
    big = out.shape[0] * out.shape[1] > 300 ** 2
    for s in scales:
        es, os_ = _phases(ex, s, mode, every_phase), _phases(out, s, mode, every_phase)
        if periodic:  # the exemplar's neighborhoods include those across its wrap
            es = [np.pad(e, ((0, PATCH - 1), (0, PATCH - 1), (0, 0)), mode="wrap") for e in es]
        if min(es[0].shape[:2]) < PATCH + 2 or min(os_[0].shape[:2]) < PATCH + 2:
            continue
        pe = np.concatenate([_patches(e) for e in es])
        po = np.concatenate([_patches(o, step=2 if big else 1) for o in os_])
        d = pe.shape[1]
        # Search in the exemplar patches' leading PCA dimensions (kd-trees are
        # slow in 75-D), then measure the true distance to the match found.
        mean = pe.mean(axis=0)
        _, _, vt = np.linalg.svd(pe - mean, full_matrices=False)
        basis = vt[:PCA_DIMS].T
        ze, zo = (pe - mean) @ basis, (po - mean) @ basis
        so = rng.choice(len(po), min(samples, len(po)), replace=False)
        _, j = cKDTree(ze).query(zo[so], workers=-1)
        energy.append(np.mean(np.sum((po[so] - pe[j]) ** 2, axis=1)) / d)
        se = rng.choice(len(pe), min(samples, len(pe)), replace=False)
        _, j = cKDTree(zo).query(ze[se], workers=-1)
        complete.append(np.mean(np.sum((pe[se] - po[j]) ** 2, axis=1)) / d)
    return float(np.mean(energy)), float(np.mean(complete))


def copied_windows(exemplar: np.ndarray, output: np.ndarray, periodic: bool = False, tolerance: int = 2) -> float:
    """Fraction of the output's 5x5 windows found in the exemplar, every value
    within ``tolerance``/255 (8-bit values; across its wrap when ``periodic``):
    how much of an image is copied, read from the pixels alone, so it applies
    to the peer too, whose copies are off by a level here and there (a tiling
    scores about 1 but at its seams, noise 0)."""
    ex = np.rint(_chan(exemplar) * 255)
    out = np.rint(_chan(output) * 255)
    if periodic:
        ex = np.pad(ex, ((0, PATCH - 1), (0, PATCH - 1), (0, 0)), mode="wrap")
    # Nearest exemplar window in the max norm, searched only within the tolerance.
    d, _ = cKDTree(_patches(ex)).query(_patches(out), p=np.inf, distance_upper_bound=tolerance + 0.5, workers=-1)
    return float(np.mean(d <= tolerance + 0.25))


def coverage(coords: np.ndarray, m: int) -> tuple[float, float]:
    """(evenness, used): normalized entropy of how often each exemplar pixel is
    used (1 = perfectly even), and the fraction of exemplar pixels used at all."""
    idx = (coords[..., 1].astype(np.int64) % m) * m + (coords[..., 0] % m)
    counts = np.bincount(idx.ravel(), minlength=m * m).astype(np.float64)
    p = counts / counts.sum()
    nz = p[p > 0]
    evenness = float(-(nz * np.log(nz)).sum() / np.log(m * m))
    return evenness, float((counts > 0).mean())


def sheared_seams(coords: np.ndarray, m: int) -> float:
    """Fraction of neighbor pairs (horizontal and vertical) whose coordinates
    continue each other but for one exemplar pixel (S[p + e] - S[p] - e has
    components in {-1, 0, 1}, not all 0): seams that magnification shows as
    zipper lines (a strip repeated or skipped). Coordinates compare mod m."""
    c = coords.astype(np.int64)
    fractions = []
    for a, b, e in ((c[:, :-1], c[:, 1:], np.array([1, 0])), (c[:-1], c[1:], np.array([0, 1]))):
        d = (b - a - e) % m
        d = np.where(d > m // 2, d - m, d)
        cheb = np.abs(d).max(axis=-1)
        fractions.append(float((cheb == 1).mean()))
    return float(np.mean(fractions))


def seam_pairs(coords: np.ndarray, m: int) -> tuple[np.ndarray, np.ndarray]:
    """The seams of a coordinate map, neighbors whose coordinates do not
    continue each other (mod m): (between x and x + 1: (H, W - 1), between y
    and y + 1: (H - 1, W)), booleans."""
    c = coords[..., :2].astype(np.int64)
    cols = ((c[:, 1:] - c[:, :-1] - np.array([1, 0])) % m != 0).any(-1)
    rows = ((c[1:] - c[:-1] - np.array([0, 1])) % m != 0).any(-1)
    return cols, rows


def _column_runs(b: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Runs of True down each column of b: (column, first row, length)."""
    p = np.zeros((b.shape[0] + 2, b.shape[1]), np.int8)
    p[1:-1] = b
    d = np.diff(p, axis=0).T  # column-major, so runs come sorted by column then row
    sc, sr = np.nonzero(d == 1)
    _, er = np.nonzero(d == -1)
    return sc, sr, er - sr


def straight_seam_runs(coords: np.ndarray, m: int, length: int = 12,
                       origin: tuple[int, int] = (0, 0)) -> tuple[float, float]:
    """(runs, on_borders): the seams of a coordinate map (neighbors whose
    coordinates do not continue each other, mod m) that run straight, down one
    column boundary or along one row boundary for ``length`` px or more, per
    1000 neighbor pairs; and the fraction of those runs whose line lies on the
    texel borders of a level 2 or more levels coarser (its canvas position,
    ``origin`` being the map's top left: 0.25 by chance, more
    where the pyramid's blocks come down as straight seams)."""
    cols, rows = seam_pairs(coords, m)
    vc, _, vl = _column_runs(cols)
    hc, _, hl = _column_runs(rows.T)
    long_v, long_h = vl >= length, hl >= length
    pairs = cols.size + rows.size
    runs = 1000.0 * (vl[long_v].sum() + hl[long_h].sum()) / pairs
    lines = np.concatenate([origin[0] + vc[long_v] + 1, origin[1] + hc[long_h] + 1])
    on_borders = float(np.mean(lines % 4 == 0)) if lines.size else 0.0
    return float(runs), on_borders


def usage_peak(coords: np.ndarray, m: int, block: int = 16) -> float:
    """How unevenly the exemplar is used, by blocks of ``block`` px: the most
    used block's share over the mean share (1 = even; a block that recurs
    everywhere, like gravel's dark band behind its zoomed-out streaks, scores high)."""
    b = max(1, m // block)
    idx = ((coords[..., 1].astype(np.int64) % m) * b // m) * b + ((coords[..., 0].astype(np.int64) % m) * b // m)
    counts = np.bincount(idx.ravel(), minlength=b * b).astype(np.float64)
    return float(counts.max() / counts.mean())


def verbatim_regions(coords: np.ndarray, m: int, toroidal: bool = False,
                     mask: np.ndarray | None = None) -> tuple[float, int]:
    """(mean, max) size in pixels of verbatim-copied regions: connected pixels
    whose coordinates continue each other (S[p + e] = S[p] + e, mod m for a
    toroidal exemplar). The mean is area-weighted: the region size a random
    output pixel belongs to (a random pixel of ``mask``, when given)."""
    h, w = coords.shape[:2]
    c = coords.astype(np.int64)
    ids = np.arange(h * w).reshape(h, w)
    rows, cols = [], []
    for axis, e in ((1, np.array([1, 0])), (0, np.array([0, 1]))):
        a = c[:, :-1] if axis == 1 else c[:-1]
        b = c[:, 1:] if axis == 1 else c[1:]
        d = b - a - e
        if toroidal:
            d %= m
        same = np.all(d == 0, axis=-1)
        ia = ids[:, :-1] if axis == 1 else ids[:-1]
        ib = ids[:, 1:] if axis == 1 else ids[1:]
        rows.append(ia[same])
        cols.append(ib[same])
    r, q = np.concatenate(rows), np.concatenate(cols)
    g = sparse.coo_matrix((np.ones(len(r), dtype=np.int8), (r, q)), shape=(h * w, h * w))
    _, labels = csgraph.connected_components(g, directed=False)
    sizes = np.bincount(labels)
    if mask is not None:
        return float(sizes[labels[np.asarray(mask).ravel()]].mean()), int(sizes.max())
    return float((sizes.astype(np.float64) ** 2).sum() / sizes.sum()), int(sizes.max())


def autocorrelation(y: np.ndarray, periodic: bool = False) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Normalized autocorrelation (1 at shift 0) of a 2-D array, mean removed,
    and its shifts dy (a column) and dx (a row): circular when ``periodic``,
    else over twice the size with each shift divided by its overlap."""
    h, w = y.shape
    y = y - y.mean()
    if periodic:
        f = np.fft.fft2(y)
        ac = np.real(np.fft.ifft2(f * np.conj(f)))
        size = (h, w)
    else:
        size = (2 * h, 2 * w)
        f = np.fft.rfft2(y, s=size)
        ac = np.fft.irfft2(f * np.conj(f), s=size)
        ones = np.fft.rfft2(np.ones((h, w)), s=size)
        overlap = np.fft.irfft2(ones * np.conj(ones), s=size)
        ac = ac / np.maximum(overlap, 1.0)
    ac /= max(ac[0, 0], 1e-12)
    dy = np.fft.fftfreq(size[0], 1.0 / size[0])[:, None]
    dx = np.fft.fftfreq(size[1], 1.0 / size[1])[None, :]
    return ac, dy, dx


def repetition(output: np.ndarray, exclude: int = 8) -> float:
    """Highest normalized autocorrelation peak away from the origin (shifts of
    ``exclude`` px or more, up to half the image): about 1 for a tiled image,
    about 0 for noise."""
    img = _chan(output).mean(axis=2)
    h, w = img.shape
    ac, dy, dx = autocorrelation(img)
    mask = (np.maximum(np.abs(dx), np.abs(dy)) >= exclude) & (np.abs(dx) <= w // 2) & (np.abs(dy) <= h // 2)
    return float(ac[mask].max())


def histogram_distance(exemplar: np.ndarray, output: np.ndarray) -> float:
    """Mean over channels of the 1-D Wasserstein distance between value
    distributions (0 = same histogram; values in [0, 1])."""
    ex, out = _chan(exemplar), _chan(output)
    return float(np.mean([stats.wasserstein_distance(ex[..., c].ravel(), out[..., c].ravel())
                          for c in range(ex.shape[2])]))


PS_SCALES = 4  # steerable pyramid scales of the Portilla-Simoncelli statistics


def _ps_luma(img: np.ndarray) -> np.ndarray:
    """Luminance (Rec. 709) of an image, cropped to a multiple of 2^(PS_SCALES + 1) a side."""
    x = _chan(np.asarray(img, dtype=np.float64))
    if x.shape[2] >= 3:
        y = x[..., :3] @ np.array([0.2126, 0.7152, 0.0722])
    else:
        y = x[..., 0]
    q = 1 << (PS_SCALES + 1)
    h, w = (y.shape[0] // q) * q, (y.shape[1] // q) * q
    if h < 2 * q or w < 2 * q:
        raise ValueError(f"An image for the Portilla-Simoncelli statistics needs at least {2 * q} px a side.")
    return y[:h, :w]


_PS_MODELS: dict = {}


def ps_statistics(img: np.ndarray) -> dict:
    """The Portilla-Simoncelli (2000) texture statistics of an image's luminance,
    by group (plenoptic's ``PortillaSimoncelli``, 4 scales, 4 orientations, on
    CPU torch): {group name: float64 array of its finite values}."""
    import torch
    from plenoptic.models import PortillaSimoncelli
    y = _ps_luma(img)
    model = _PS_MODELS.get(y.shape)
    if model is None:
        model = _PS_MODELS[y.shape] = PortillaSimoncelli(y.shape, n_scales=PS_SCALES, n_orientations=4)
    with torch.no_grad():
        stats_ = model(torch.tensor(y, dtype=torch.float64)[None, None])
        groups = model.convert_to_dict(stats_)
    return {k: v.detach().cpu().numpy().astype(np.float64).ravel() for k, v in groups.items()}


def ps_distance(exemplar: np.ndarray, output: np.ndarray) -> float:
    """Portilla-Simoncelli texture-statistics distance: for each group of
    statistics (pixel moments, auto-correlations, magnitude and cross-scale
    correlations...), the relative L2 difference ||s_out - s_ex|| / ||s_ex||,
    averaged over the groups (so no group's units dominate). 0 for the same
    statistics; an image of another texture (or noise) scores around 1 or more."""
    a, b = ps_statistics(exemplar), ps_statistics(output)
    rel = []
    for k, sa in a.items():
        sb = b[k]
        ok = np.isfinite(sa) & np.isfinite(sb)
        if not ok.any():
            continue
        rel.append(np.linalg.norm(sb[ok] - sa[ok]) / max(np.linalg.norm(sa[ok]), 1e-12))
    return float(np.mean(rel))


def all_measures(exemplar, output, coords=None, m=None, toroidal=False, ps: bool = False) -> dict:
    energy, complete = neighborhood_energy(exemplar, output)
    d = {"energy": energy, "completeness": complete, "repetition": repetition(output),
         "histogram": histogram_distance(exemplar, output), "copied": copied_windows(exemplar, output, toroidal)}
    if ps:
        d["ps"] = ps_distance(exemplar, output)
    if coords is not None:
        d["coverage"], d["used"] = coverage(coords, m)
        d["verbatim_mean_px"], d["verbatim_max_px"] = verbatim_regions(coords, m, toroidal)
        d["sheared"] = sheared_seams(coords, m)
        d["usage_peak"] = usage_peak(coords, m)
        d["straight_runs"], _ = straight_seam_runs(coords, m)
    return d
