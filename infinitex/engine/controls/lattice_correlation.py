"""The autocorrelation a lattice is read from and the measures taken on it
(for :mod:`.lattice_detect`): the normalized autocorrelation, sub-pixel
peaks, lattice points in the lag window, the basis fitted to them, the
confidence, the central lobe, and the bases people read (Gauss-reduced, rows
along the axes)."""
from __future__ import annotations

import math

import numpy as np
from scipy import ndimage


def gauss_reduce(t1: np.ndarray, t2: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Lagrange-Gauss reduction: the two shortest vectors spanning the same lattice."""
    a, b = np.asarray(t1, float), np.asarray(t2, float)
    if a @ a > b @ b:
        a, b = b, a
    for _ in range(64):
        mu = round(float(a @ b) / float(a @ a))
        b = b - mu * a
        if b @ b >= a @ a:
            break
        a, b = b, a
    return a, b


def canonical_basis(t1, t2) -> tuple[np.ndarray, np.ndarray]:
    """A basis oriented for people: the reduced basis, except that a short
    lattice vector within 3 degrees of the x (or y) axis becomes t1 (or t2),
    so rows of running-bond bricks stay rows; t1 points right, t2 to +y."""
    a, b = gauss_reduce(np.asarray(t1, float), np.asarray(t2, float))
    det = abs(a[0] * b[1] - a[1] * b[0])
    vecs = [a, b, a + b, a - b]
    limit = 2.5 * math.hypot(*b)
    tol = math.sin(math.radians(3))

    def pair(first, axis):
        rest = [v for v in vecs if v is not first
                and abs(abs(first[0] * v[1] - first[1] * v[0]) - det) <= 1e-6 * det]
        return min(rest, key=lambda v: math.hypot(*v)) if rest else None

    for axis in (0, 1):
        aligned = [v for v in vecs if abs(v[1 - axis]) <= tol * math.hypot(*v) and math.hypot(*v) <= limit]
        if aligned:
            first = min(aligned, key=lambda v: math.hypot(*v))
            other = pair(first, axis)
            if other is not None:
                a, b = (first, other) if axis == 0 else (other, first)
                break
    else:
        if abs(b[0]) * math.hypot(*a) > abs(a[0]) * math.hypot(*b):  # b is more horizontal
            a, b = b, a
    if a[0] < 0 or (a[0] == 0 and a[1] < 0):
        a = -a
    if a[0] * b[1] - a[1] * b[0] < 0:
        b = -b
    return a, b


def autocorrelation(gray: np.ndarray) -> np.ndarray:
    """Normalized autocorrelation (each lag divided by its overlap), centred:
    index (H // 2, W // 2) holds lag 0; lags up to half the image each way."""
    H, W = gray.shape
    g = gray - ndimage.gaussian_filter(gray, max(H, W) / 8.0, mode="reflect")  # drop slow shading
    g = g - g.mean()
    sh = (2 * H, 2 * W)
    F = np.fft.rfft2(g, s=sh)
    ac = np.fft.irfft2(F * np.conj(F), s=sh)
    ones = np.fft.rfft2(np.ones_like(g), s=sh)
    count = np.fft.irfft2(ones * np.conj(ones), s=sh)
    ac = np.fft.fftshift(ac / np.maximum(count, 1.0))
    cy, cx = H, W
    hy, hx = H // 2, W // 2
    ac = ac[cy - hy:cy + hy + 1, cx - hx:cx + hx + 1]
    zero = ac[hy, hx]
    return ac / zero if zero > 1e-12 else np.zeros_like(ac)


def subpixel(ac: np.ndarray, y: int, x: int) -> tuple[float, float]:
    """Parabolic sub-pixel offset of the peak at (y, x) per axis."""
    def off(a, b, c):
        d = a - 2 * b + c
        return 0.0 if d >= 0 else float(np.clip(0.5 * (a - c) / d, -0.5, 0.5))
    return (off(ac[y - 1, x], ac[y, x], ac[y + 1, x]), off(ac[y, x - 1], ac[y, x], ac[y, x + 1]))


def sample(ac: np.ndarray, pts: np.ndarray, center: tuple[int, int], mode: str = "constant") -> np.ndarray:
    """The correlation at lags ``pts`` (N, 2: x, y), bilinear; ``center`` is
    lag 0's (row, column)."""
    return ndimage.map_coordinates(ac, [pts[:, 1] + center[0], pts[:, 0] + center[1]], order=1, mode=mode)


def lattice_points(t1, t2, hy: int, hx: int, limit: int = 12) -> tuple[np.ndarray, np.ndarray]:
    """Integer pairs (n1, n2) != 0 and their lattice points inside the lag window."""
    n = np.arange(-limit, limit + 1)
    N1, N2 = np.meshgrid(n, n)
    N = np.stack([N1.ravel(), N2.ravel()], axis=1)
    N = N[(N != 0).any(axis=1)]
    P = N @ np.stack([t1, t2])
    inside = (np.abs(P[:, 0]) <= hx - 2) & (np.abs(P[:, 1]) <= hy - 2)
    return N[inside], P[inside]


def refine(ac: np.ndarray, t1, t2, center) -> tuple[np.ndarray, np.ndarray]:
    """Least-squares fit of (t1, t2) to the sub-pixel peaks found near every
    lattice point in the window (far peaks pin the vectors down most: a
    pixel's error there is a small fraction of a vector)."""
    hy, hx = center
    for _ in range(2):
        N, P = lattice_points(t1, t2, hy, hx)
        if len(N) < 2:
            break
        floor = 0.4 * float(sample(ac, np.stack([t1, t2]), center).min())
        rows, obs = [], []
        for n, p in zip(N, P):
            x, y = int(round(p[0])) + hx, int(round(p[1])) + hy
            win = ac[y - 1:y + 2, x - 1:x + 2]
            if win.shape != (3, 3):
                continue
            dy, dx = np.unravel_index(int(np.argmax(win)), (3, 3))
            y, x = y + dy - 1, x + dx - 1
            if not (1 <= y < ac.shape[0] - 1 and 1 <= x < ac.shape[1] - 1):
                continue
            if ac[y, x] < floor or ac[y, x] < ac[y - 1:y + 2, x - 1:x + 2].max():
                continue  # weak, or not a local maximum
            oy, ox = subpixel(ac, y, x)
            rows.append(n)
            obs.append((x - hx + ox, y - hy + oy))
        if len(rows) < 2:
            break
        A = np.asarray(rows, float)
        Y = np.asarray(obs, float)
        if np.linalg.matrix_rank(A) < 2:
            break
        T, *_ = np.linalg.lstsq(A, Y, rcond=None)
        t1, t2 = T[0], T[1]
    return np.asarray(t1, float), np.asarray(t2, float)


def polish(ac: np.ndarray, t1, t2, center, lobe: float) -> tuple[np.ndarray, np.ndarray]:
    """The basis near (t1, t2) under which the image agrees best with itself:
    the mean correlation at the lattice points n1 t1 + n2 t2, |n1|, |n2| <= 2,
    maximized from where the peaks put the basis (each peak's own position is
    only good to about a pixel; together they pin the vectors down to a small
    fraction of one). The correlation is lightly smoothed and read through a
    cubic spline: a bilinear reading peaks at whole pixels, and would pull
    the vectors there. Moves of more than 1.5 px are not taken."""
    from scipy.optimize import minimize
    hy, hx = center
    # The spline coefficients of the smoothed correlation, once.
    x0 = np.concatenate([t1, t2]).astype(float)
    n = np.array([(i, j) for i in range(-2, 3) for j in range(-2, 3) if (i, j) != (0, 0)], float)
    coef = ndimage.spline_filter(ndimage.gaussian_filter(ac, 0.8), order=3)

    def points(x):
        P = n @ x.reshape(2, 2)
        keep = (np.abs(P[:, 0]) <= hx - 3) & (np.abs(P[:, 1]) <= hy - 3) & (np.hypot(P[:, 0], P[:, 1]) >= lobe)
        return P[keep]

    if len(points(x0)) < 4:
        return np.asarray(t1, float), np.asarray(t2, float)

    def cost(x):
        P = points(x)
        if not len(P):
            return 0.0
        v = ndimage.map_coordinates(coef, [P[:, 1] + hy, P[:, 0] + hx], order=3, prefilter=False)
        return -float(v.mean())

    res = minimize(cost, x0, method="Nelder-Mead",
                   options={"xatol": 0.01, "fatol": 1e-6, "initial_simplex": x0 + np.vstack([np.zeros(4), 0.5 * np.eye(4)])})
    x = res.x
    moved = max(math.hypot(*(x[:2] - x0[:2])), math.hypot(*(x[2:] - x0[2:])))
    if not res.success or moved > 1.5 or len(points(x)) < len(points(x0)):
        return np.asarray(t1, float), np.asarray(t2, float)
    return x[:2], x[2:]


def lobe_radius(ac: np.ndarray) -> float:
    """Radius of the autocorrelation's central lobe: the first radius at which
    the correlation has dropped below 0.3 in some direction (lags inside it
    say nothing about a lattice)."""
    hy, hx = ac.shape[0] // 2, ac.shape[1] // 2
    ys, xs = np.mgrid[-hy:ac.shape[0] - hy, -hx:ac.shape[1] - hx]
    r = np.rint(np.hypot(xs, ys)).astype(np.int64).ravel()
    n = min(hy, hx)
    low = np.full(n + 1, np.inf)
    sel = r <= n
    np.minimum.at(low, r[sel], ac.ravel()[sel])
    below = np.nonzero(low < 0.3)[0]
    return float(below[0]) if below.size else float(n)


def confidence(ac: np.ndarray, t1, t2, center, lobe: float = 0.0) -> float:
    """How much more the image correlates with itself at lattice points than
    half-way between them, in [0, 1] (points inside the central lobe left out)."""
    hy, hx = center
    N, P = lattice_points(t1, t2, hy, hx, limit=2)
    P = P[np.hypot(P[:, 0], P[:, 1]) >= lobe]
    if len(P) < 2:
        return 0.0
    on = float(np.median(sample(ac, P, center)))
    t1, t2 = np.asarray(t1, float), np.asarray(t2, float)
    mids = np.concatenate([np.concatenate([P + half, half[None]])
                           for half in (0.5 * t1, 0.5 * t2, 0.5 * (t1 + t2))])  # half-way points
    mids = mids[(np.abs(mids[:, 0]) <= hx - 1) & (np.abs(mids[:, 1]) <= hy - 1)
                & (np.hypot(mids[:, 0], mids[:, 1]) >= lobe)]
    off = float(np.median(sample(ac, mids, center))) if len(mids) else 0.0
    return float(np.clip((on - off) / max(1e-6, 1.0 - off), 0.0, 1.0))
