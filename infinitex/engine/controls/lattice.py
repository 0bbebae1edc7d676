"""Near-regular textures (LH05 section 4.5; ALGORITHM.md section 5): the lattice
model, its automatic detection, and the rectification of a block of cells into
a square toroidal exemplar.

A :class:`Lattice` is an origin and two translation vectors ``t1``, ``t2`` in
input-image pixels (any angle, any aspect, not orthogonal), and a block of
``nx x ny`` cells: the parallelogram ``origin + a nx t1 + b ny t2``, a, b in
[0, 1), which is mapped affinely onto an ``m x m`` square exemplar. In that
exemplar a cell is ``m / nx x m / ny`` pixels. ``nx`` and ``ny`` are powers of
two (1 to 16), so that the cell is a whole number of exemplar pixels and
divides the spacing ``h_l`` of every level coarser than it: the synthesis can
then quantize jitter to whole cells exactly, in integers.

The synthesis runs on the rectified exemplar. On the *lattice levels* (by
default those whose spacing is at least a quarter of the smaller cell side) the jitter is
quantized to whole cells and the similarity sets are restricted to
lattice-equivalent positions (``u + (i m/nx, j m/ny)``), so coarse structure
moves by whole cells only and rows stay rows; finer levels jitter and correct
freely. The result is shown rectified, or mapped back to the input's geometry
through :meth:`Lattice.canvas_matrix`.

Detection (:func:`detect`) uses the autocorrelation of the image (FFT, the
overlap-normalized estimate), its local maxima (``scipy.ndimage``), the two
shortest independent strong peaks reduced to a Gauss-reduced basis, then a
least-squares fit of the basis to every lattice peak found at sub-pixel
precision. Its confidence compares the autocorrelation at lattice points with
that between them; below :data:`MIN_CONFIDENCE` the answer is "no lattice".
"""
from __future__ import annotations

import math
import time
from dataclasses import dataclass, replace

import numpy as np
from scipy import ndimage

from ..exemplar import Exemplar

MAX_CELLS = 16           # cells per block side
MIN_VECTOR = 3.0         # px: shorter translation vectors are refused
MIN_SINE = 0.1           # |sin| of the angle between t1 and t2 (about 6 degrees)
MIN_CONFIDENCE = 0.3     # detection: below this, "no lattice"
MIN_REPEATS = 3          # detection: a lattice vector fits at least this many times in the image
DETECT_SIDE = 512        # detection works on images at most this size (box-reduced)
EXEMPLAR_MAX = 512       # side of the rectified exemplar
EXEMPLAR_MIN = 32
HIRES_MAX = 2048         # side of the rectified copy kept for magnification


def lattice_level_limit(m: int, nx: int, ny: int) -> int:
    """The finest level that can be a lattice level of an m x m exemplar with
    nx x ny cells: spacing at least a sixteenth of the smaller cell side (the
    default stops at a quarter). The analysis prepares restricted similarity
    sets down to it."""
    c = min(m // nx, m // ny)
    L = m.bit_length() - 1
    return max(0, min(L, L - (c.bit_length() - 1) + 4))


class LatticeError(ValueError):
    """A lattice that cannot be used; the message is one sentence for the user."""


def _pow2(n: int) -> bool:
    return n >= 1 and n & (n - 1) == 0


@dataclass(frozen=True)
class Lattice:
    """Origin, translation vectors (input-image pixels) and block of cells.

    ``levels`` is the number of lattice levels (the coarsest ones); None means
    the default, :meth:`default_levels`."""

    origin: tuple[float, float]
    t1: tuple[float, float]
    t2: tuple[float, float]
    nx: int = 2
    ny: int = 2
    levels: int | None = None

    # -- text form (CLI, project files) ---------------------------------------

    def to_text(self) -> str:
        """``OX,OY,T1X,T1Y,T2X,T2Y,NX,NY`` in input-image pixels (what --lattice reads)."""
        nums = [*self.origin, *self.t1, *self.t2]
        return ",".join(_fmt(v) for v in nums) + f",{self.nx},{self.ny}"

    @classmethod
    def parse(cls, text: str) -> Lattice:
        parts = [p.strip() for p in text.split(",")]
        if len(parts) != 8:
            raise LatticeError("A lattice is 8 numbers OX,OY,T1X,T1Y,T2X,T2Y,NX,NY "
                               f"(got {len(parts)}).")
        try:
            vals = [float(p) for p in parts[:6]]
            nx, ny = int(parts[6]), int(parts[7])
        except ValueError:
            raise LatticeError("A lattice is 8 numbers OX,OY,T1X,T1Y,T2X,T2Y,NX,NY; "
                               "NX and NY are whole numbers.") from None
        lat = cls((vals[0], vals[1]), (vals[2], vals[3]), (vals[4], vals[5]), nx, ny)
        lat.check_shape()
        return lat

    # -- validity --------------------------------------------------------------

    def check_shape(self) -> None:
        """Raise LatticeError unless the vectors and cell counts are usable."""
        vals = [*self.origin, *self.t1, *self.t2]
        if not all(math.isfinite(v) and abs(v) < 1e6 for v in vals):
            raise LatticeError("Lattice numbers must be finite and below 10^6 px.")
        for name, n in (("NX", self.nx), ("NY", self.ny)):
            if not (_pow2(n) and n <= MAX_CELLS):
                raise LatticeError(f"{name} = {n}: cell counts must be 1, 2, 4, 8 or 16 (a power of two, "
                                   "so a cell is a whole number of exemplar pixels).")
        l1, l2 = math.hypot(*self.t1), math.hypot(*self.t2)
        if min(l1, l2) < MIN_VECTOR:
            raise LatticeError(f"A lattice vector is {min(l1, l2):.2f} px long; vectors must be at least "
                               f"{MIN_VECTOR:g} px.")
        if abs(self.cross) < MIN_SINE * l1 * l2:
            raise LatticeError("The lattice vectors are (nearly) collinear; they must span a cell "
                               "(at least 6 degrees apart).")
        if self.levels is not None and not 0 <= self.levels <= 10:
            raise LatticeError(f"Lattice levels = {self.levels}: use 0 to 10.")

    def validate(self, width: int, height: int) -> None:
        """check_shape, and the block of cells must lie inside a width x height image."""
        self.check_shape()
        xs, ys = zip(*self.corners())
        tol = 0.5
        if min(xs) < -tol or min(ys) < -tol or max(xs) > width + tol or max(ys) > height + tol:
            raise LatticeError(f"The {self.nx}x{self.ny} block of cells (x {min(xs):.0f} to {max(xs):.0f}, "
                               f"y {min(ys):.0f} to {max(ys):.0f}) does not fit in the {width}x{height} image; "
                               "use fewer cells or move the origin.")

    @property
    def cross(self) -> float:
        return self.t1[0] * self.t2[1] - self.t1[1] * self.t2[0]

    def corners(self) -> list[tuple[float, float]]:
        """The block parallelogram: origin, +nx t1, +nx t1 + ny t2, +ny t2."""
        ox, oy = self.origin
        ax, ay = self.nx * self.t1[0], self.nx * self.t1[1]
        bx, by = self.ny * self.t2[0], self.ny * self.t2[1]
        return [(ox, oy), (ox + ax, oy + ay), (ox + ax + bx, oy + ay + by), (ox + bx, oy + by)]

    def block_matrix(self) -> np.ndarray:
        """B (2x2): image offset = B @ (a, b) for block coordinates a, b in [0, 1)."""
        return np.array([[self.nx * self.t1[0], self.ny * self.t2[0]],
                         [self.nx * self.t1[1], self.ny * self.t2[1]]], dtype=np.float64)

    # -- exemplar geometry -------------------------------------------------------

    def exemplar_size(self) -> int:
        """m: the power of two nearest (in log scale) to the block's longer side, 32..512."""
        side = max(self.nx * math.hypot(*self.t1), self.ny * math.hypot(*self.t2))
        m = 1 << max(0, int(round(math.log2(max(1.0, side)))))
        return int(min(EXEMPLAR_MAX, max(EXEMPLAR_MIN, m, 4 * max(self.nx, self.ny))))

    def hires_size(self) -> int:
        """Side of the rectified copy kept for magnification: the block's own resolution."""
        side = max(self.nx * math.hypot(*self.t1), self.ny * math.hypot(*self.t2))
        return int(min(HIRES_MAX, 1 << max(0, math.ceil(math.log2(max(1.0, side))))))

    def cell(self, m: int) -> tuple[int, int]:
        """Cell size (cx, cy) in exemplar pixels of an m x m rectified exemplar."""
        return m // self.nx, m // self.ny

    def default_levels(self, m: int) -> int:
        """Levels whose spacing h_l = m >> l is at least a quarter of the
        smaller cell side. (LH05 stops at the cell; then the free correction
        of the next levels lets rows drift: the generated bricks keep 71% of
        their regularity stopping at half a cell, 90% at a quarter.)"""
        c = min(self.cell(m))
        return min(self.max_levels(m), max(1, int(math.log2(m)) - int(math.log2(max(1, c))) + 3))

    def max_levels(self, m: int) -> int:
        """The most lattice levels this block allows on an m x m exemplar."""
        return lattice_level_limit(m, self.nx, self.ny) + 1

    def level_count(self, m: int) -> int:
        """Number of lattice levels (the coarsest ones) actually used."""
        return min(self.max_levels(m), self.default_levels(m) if self.levels is None else self.levels)

    def quant_shift(self, m: int, level: int) -> tuple[int, int] | None:
        """(log2 cx, log2 cy) on a lattice level, None on the others."""
        if level >= self.level_count(m):
            return None
        cx, cy = self.cell(m)
        return int(math.log2(cx)), int(math.log2(cy))

    def canvas_matrix(self, m: int) -> np.ndarray:
        """G (2x2): rectified canvas position p = G @ q for a position q in the
        input's geometry (input-image pixels). The block (nx t1, ny t2) covers
        m x m canvas pixels, as it covers the m x m exemplar."""
        return m * np.linalg.inv(self.block_matrix())

    # -- rectification -----------------------------------------------------------

    def rectify(self, image: np.ndarray, side: int) -> np.ndarray:
        """The block resampled to ``side x side`` (float32, channels kept):
        pixel (i, j) samples the image at ``origin + ((i+1/2)/side) nx t1 +
        ((j+1/2)/side) ny t2`` with scipy's cubic spline, after a Gaussian
        prefilter when the block is reduced (no aliasing)."""
        img = np.asarray(image, dtype=np.float32)
        if img.ndim == 2:
            img = img[:, :, None]
        B = self.block_matrix()
        scale = np.linalg.svd(B / side, compute_uv=False)  # source px per output px, per axis
        sigma = 0.5 * math.sqrt(max(0.0, float(scale.max()) ** 2 - 1.0))
        a = (np.arange(side, dtype=np.float64) + 0.5) / side
        A, Bb = np.meshgrid(a, a)  # A: along x (t1), Bb: along y (t2)
        qx = self.origin[0] + B[0, 0] * A + B[0, 1] * Bb - 0.5
        qy = self.origin[1] + B[1, 0] * A + B[1, 1] * Bb - 0.5
        out = np.empty((side, side, img.shape[2]), dtype=np.float32)
        for c in range(img.shape[2]):
            plane = img[:, :, c].astype(np.float64)
            if sigma > 0.3:
                plane = ndimage.gaussian_filter(plane, sigma, mode="nearest")
            out[:, :, c] = ndimage.map_coordinates(plane, [qy, qx], order=3, mode="nearest")
        return np.clip(out, 0.0, 1.0)


def _fmt(v: float) -> str:
    s = f"{v:.3f}".rstrip("0").rstrip(".")
    return "0" if s in ("-0", "") else s


# -- detection -----------------------------------------------------------------


@dataclass(frozen=True)
class Detection:
    """What :func:`detect` found: a lattice (None: no lattice found), the
    confidence in [0, 1], and the time it took."""

    lattice: Lattice | None
    confidence: float
    seconds: float
    t1: tuple[float, float] | None = None  # the reduced basis, even when rejected
    t2: tuple[float, float] | None = None


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


def _autocorrelation(gray: np.ndarray) -> np.ndarray:
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


def _subpixel(ac: np.ndarray, y: int, x: int) -> tuple[float, float]:
    """Parabolic sub-pixel offset of the peak at (y, x) per axis."""
    def off(a, b, c):
        d = a - 2 * b + c
        return 0.0 if d >= 0 else float(np.clip(0.5 * (a - c) / d, -0.5, 0.5))
    return (off(ac[y - 1, x], ac[y, x], ac[y + 1, x]), off(ac[y, x - 1], ac[y, x], ac[y, x + 1]))


def _sample(ac: np.ndarray, pts: np.ndarray, center: tuple[int, int]) -> np.ndarray:
    return ndimage.map_coordinates(ac, [pts[:, 1] + center[0], pts[:, 0] + center[1]], order=1, mode="constant")


def detect(pixels: np.ndarray) -> Detection:
    """Find the lattice of a near-regular image (H, W) or (H, W, C) in [0, 1].

    Returns a Detection whose ``lattice`` is None when the image shows no
    lattice (confidence below MIN_CONFIDENCE, or fewer than two independent
    peaks): an answer, not an error. The block is the largest power-of-two
    count of cells per side that fits in the image with a rectified aspect
    within 2:1, centred in the image."""
    t0 = time.perf_counter()
    img = np.asarray(pixels, dtype=np.float64)
    if img.ndim == 3:
        img = img[:, :, :3].mean(axis=2) if img.shape[2] >= 3 else img[:, :, 0]
    H, W = img.shape
    f = max(1, math.ceil(max(H, W) / DETECT_SIDE))
    gray = img
    if f > 1:  # box reduction by an integer factor (exact scale for the vectors)
        h2, w2 = H // f, W // f
        gray = img[:h2 * f, :w2 * f].reshape(h2, f, w2, f).mean(axis=(1, 3))
    none = Detection(None, 0.0, 0.0)
    if min(gray.shape) < 16:
        return replace(none, seconds=time.perf_counter() - t0)
    ac = _autocorrelation(gray)
    hy, hx = ac.shape[0] // 2, ac.shape[1] // 2
    lobe = _lobe_radius(ac)
    # A lattice must repeat at least MIN_REPEATS times across the image.
    reach = min(gray.shape) / MIN_REPEATS
    grid = _grid(ac, (hy, hx), lobe, reach, f)
    rows = _rows(ac, (hy, hx), reach)
    if grid is None and rows is None:
        return replace(none, seconds=time.perf_counter() - t0)
    # Rows win when the grid only cuts them into arbitrary cells (and they are
    # confident), or when there is no confident grid.
    if rows is not None and (grid is None or (_along(ac, (hy, hx), rows[3], grid[0], grid[1])
                                              and rows[2] >= MIN_CONFIDENCE) or grid[2] < min(MIN_CONFIDENCE, rows[2])):
        t1, t2, conf = rows[:3]
    else:
        t1, t2, conf = grid
    t1, t2 = t1 * f, t2 * f
    b1, b2 = (float(t1[0]), float(t1[1])), (float(t2[0]), float(t2[1]))
    lat = None
    if conf >= MIN_CONFIDENCE:
        from .lattice_block import choose_block  # it builds Lattices: defined after this module
        lat = choose_block(b1, b2, W, H)
    return Detection(lat, conf, time.perf_counter() - t0, b1, b2)


def _grid(ac: np.ndarray, center: tuple[int, int], lobe: float, reach: float, f: int):
    """A two-dimensional lattice from the autocorrelation's peaks: (t1, t2, the
    confidence) or None."""
    hy, hx = center
    peaks = (ac == ndimage.maximum_filter(ac, size=3, mode="constant", cval=np.inf)) & (ac > 0.05)
    peaks[hy, hx] = False
    peaks[[0, -1], :] = False
    peaks[:, [0, -1]] = False
    ys, xs = np.nonzero(peaks)
    if ys.size < 2:
        return None
    vals = ac[ys, xs]
    vec = np.stack([xs - hx, ys - hy], axis=1).astype(np.float64)
    length = np.hypot(vec[:, 0], vec[:, 1])
    keep = (length >= max(MIN_VECTOR / f, lobe)) & (length <= reach)
    vec, vals, length = vec[keep], vals[keep], length[keep]
    if vals.size < 2:
        return None
    # Candidate bases: pairs among the shortest strong peaks, reduced. A basis
    # with a peak inside the motif has lattice points that miss (low median
    # correlation there); a basis of a coarser sub-lattice scores as high as
    # the true one but spans a larger cell: keep the smallest cell among those
    # scoring near the best.
    strong = vals >= 0.3 * vals.max()
    vec, vals, length = vec[strong], vals[strong], length[strong]
    shortest = np.argsort(length - 1e-6 * vals, kind="stable")[:12]
    highest = np.argsort(-vals + 1e-6 * length, kind="stable")[:12]
    cand = vec[np.unique(np.concatenate([shortest, highest]))]
    cand = cand[np.argsort(np.hypot(cand[:, 0], cand[:, 1]), kind="stable")]
    scored = []
    for i in range(len(cand)):
        for j in range(i + 1, len(cand)):
            a, b = cand[i], cand[j]
            if abs(a[0] * b[1] - a[1] * b[0]) < MIN_SINE * math.hypot(*a) * math.hypot(*b):
                continue
            a, b = gauss_reduce(a, b)
            _, P = _lattice_points(a, b, hy, hx, limit=3)
            P = P[np.hypot(P[:, 0], P[:, 1]) >= lobe]
            if len(P) >= 2:
                scored.append((float(np.median(_sample(ac, P, (hy, hx)))), abs(a[0] * b[1] - a[1] * b[0]), a, b))
    if not scored:
        return None
    top = max(s[0] for s in scored)
    _, _, t1, t2 = min((s for s in scored if s[0] >= top - 0.2 * abs(top)), key=lambda s: s[1])
    t1, t2 = _refine(ac, t1, t2, (hy, hx))
    t1, t2 = canonical_basis(t1, t2)
    return t1, t2, _confidence(ac, t1, t2, (hy, hx), lobe)


RIDGE_MIN = 0.5  # rows: the median correlation along their direction


def _rows(ac: np.ndarray, center: tuple[int, int], reach: float):
    """A one-dimensional lattice (rows, stripes, planks, slightly curved rows):
    the autocorrelation stays high along one direction (a ridge through lag 0)
    and repeats across it. Returns (t1 along the rows, t2 across them, the
    confidence, the direction along the rows) or None."""
    hy, hx = center
    rmax = min(hy, hx) - 2
    if rmax < 8:
        return None
    th = np.deg2rad(np.arange(0.0, 180.0, 0.5))
    r = np.arange(2.0, rmax / 2.0)  # the near half: curved rows stay on the ridge there
    pts = (r[None, :, None] * np.stack([np.cos(th), np.sin(th)], axis=1)[:, None, :]).reshape(-1, 2)
    along = _sample(ac, pts, center).reshape(len(th), len(r))
    score = np.median(along, axis=1)
    k = int(np.argmax(score))
    if score[k] < RIDGE_MIN or np.percentile(along[k], 10) < 0.3:
        return None
    d = np.array([math.cos(th[k]), math.sin(th[k])])
    n = np.array([-d[1], d[0]])
    # The period across the rows (up to half the image): the shortest lag whose
    # multiples correlate, on average, within 80% of the best lag's (a multiple
    # of the period scores as well but is longer; half of it scores about
    # nothing, as the rows fall between), each multiple read as the profile's
    # highest value within half a pixel (thin joints make thin peaks).
    step = 0.25
    s = np.arange(0.0, rmax + 1.0, step)
    prof = _sample(ac, s[:, None] * n[None, :], center)
    local = ndimage.maximum_filter1d(prof, size=5, mode="nearest")  # +-0.5 px
    periods = np.arange(MIN_VECTOR, rmax, step)
    if periods.size == 0:
        return None
    comb = np.array([local[np.rint(np.arange(P, s[-1], P) / step).astype(int)].mean() for P in periods])
    twice = periods <= s[-1] / 2  # seen at least twice: far lags alone are noisy (few pixels overlap)
    if comb[twice].max(initial=-1.0) > 0.3:
        comb = np.where(twice, comb, -1.0)
    if comb.max() <= 0.3:
        return None
    i = int(np.nonzero(comb >= 0.8 * comb.max())[0][0])
    while i + 1 < len(comb) and comb[i + 1] >= comb[i]:  # the top of that peak of the comb
        i += 1
    period = float(periods[i])
    j = int(round(period / step))
    j = j - 2 + int(np.argmax(prof[j - 2:j + 3]))  # the peak itself, then sub-pixel
    if not 1 <= j < len(prof) - 1:
        return None
    a, b, c = prof[j - 1], prof[j], prof[j + 1]
    den = a - 2 * b + c
    period = (j + (0.0 if den >= 0 else float(np.clip(0.5 * (a - c) / den, -0.5, 0.5)))) * step
    if period < MIN_VECTOR:
        return None
    # Confidence: the correlation at the period's multiples against half-way
    # between them (as for a grid), times how well the rows hold along.
    ks = np.arange(1, max(1, int(s[-1] // period)) + 1)
    on = float(local[np.minimum(np.rint(ks * period / step).astype(int), len(local) - 1)].mean())
    half = float(_sample(ac, ((ks - 0.5) * period)[:, None] * n[None, :], center).mean())
    conf = float(np.clip((on - half) / max(1e-6, 1.0 - half), 0.0, 1.0)) * min(1.0, float(score[k]) / 0.7)
    t1, t2 = canonical_basis(d * max(period, 8.0), n * period)
    return t1, t2, conf, d


def _along(ac: np.ndarray, center, d, t1, t2) -> bool:
    """Whether the 2-D basis (t1, t2) has a vector along the rows (direction d)
    whose half-way point correlates as much as its end: then it only cuts the
    rows into arbitrary cells and the rows' own lattice is the answer."""
    d = np.asarray(d, float)
    for v in (np.asarray(t1, float), np.asarray(t2, float)):
        if abs(v[0] * d[1] - v[1] * d[0]) <= 0.1 * math.hypot(*v):
            end, mid = _sample(ac, np.stack([v, 0.5 * v]), center)
            if mid >= 0.8 * end:
                return True
    return False


def _lattice_points(t1, t2, hy: int, hx: int, limit: int = 12) -> tuple[np.ndarray, np.ndarray]:
    """Integer pairs (n1, n2) != 0 and their lattice points inside the lag window."""
    n = np.arange(-limit, limit + 1)
    N1, N2 = np.meshgrid(n, n)
    N = np.stack([N1.ravel(), N2.ravel()], axis=1)
    N = N[(N != 0).any(axis=1)]
    P = N @ np.stack([t1, t2])
    inside = (np.abs(P[:, 0]) <= hx - 2) & (np.abs(P[:, 1]) <= hy - 2)
    return N[inside], P[inside]


def _refine(ac: np.ndarray, t1, t2, center) -> tuple[np.ndarray, np.ndarray]:
    """Least-squares fit of (t1, t2) to the sub-pixel peaks found near every
    lattice point in the window, weighted by how far they are (far peaks pin
    the vectors down most)."""
    hy, hx = center
    for _ in range(2):
        N, P = _lattice_points(t1, t2, hy, hx)
        if len(N) < 2:
            break
        floor = 0.4 * float(_sample(ac, np.stack([t1, t2]), center).min())
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
            oy, ox = _subpixel(ac, y, x)
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


def _lobe_radius(ac: np.ndarray) -> float:
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


def _confidence(ac: np.ndarray, t1, t2, center, lobe: float = 0.0) -> float:
    """How much more the image correlates with itself at lattice points than
    half-way between them, in [0, 1] (points inside the central lobe left out)."""
    hy, hx = center
    N, P = _lattice_points(t1, t2, hy, hx, limit=2)
    P = P[np.hypot(P[:, 0], P[:, 1]) >= lobe]
    if len(P) < 2:
        return 0.0
    on = float(np.median(_sample(ac, P, center)))
    t1, t2 = np.asarray(t1, float), np.asarray(t2, float)
    mids = np.concatenate([np.concatenate([P + half, half[None]])
                           for half in (0.5 * t1, 0.5 * t2, 0.5 * (t1 + t2))])  # half-way points
    mids = mids[(np.abs(mids[:, 0]) <= hx - 1) & (np.abs(mids[:, 1]) <= hy - 1)
                & (np.hypot(mids[:, 0], mids[:, 1]) >= lobe)]
    off = float(np.median(_sample(ac, mids, center))) if len(mids) else 0.0
    return float(np.clip((on - off) / max(1e-6, 1.0 - off), 0.0, 1.0))


# -- the rectified exemplar ---------------------------------------------------------


def rectified_exemplar(image: np.ndarray, lattice: Lattice, source: str = "") -> Exemplar:
    """The lattice's block of cells as a toroidal m x m exemplar (m from
    :meth:`Lattice.exemplar_size`), with the block at its own resolution kept
    as ``hires`` for magnification. ``image`` is float32 (H, W, C) in [0, 1]."""
    H, W = image.shape[:2]
    lattice.validate(W, H)
    m = lattice.exemplar_size()
    px = lattice.rectify(image, m)
    hs = lattice.hires_size()
    hires = lattice.rectify(image, hs) if hs > m else None
    return Exemplar(pixels=px, toroidal=True, toroidal_guess=True, source=source, fit="lattice",
                    original_size=(W, H), hires=hires)


def autocorrelation_at(img: np.ndarray, v) -> float:
    """Pearson correlation of an image (H, W[, C]) with itself shifted by the
    vector v (px, sub-pixel by linear interpolation) over their overlap: the
    lattice-regularity measure of the tests and benchmarks."""
    a = np.asarray(img, dtype=np.float64)
    if a.ndim == 3:
        a = a[:, :, :3].mean(axis=2) if a.shape[2] >= 3 else a[:, :, 0]
    H, W = a.shape
    vx, vy = float(v[0]), float(v[1])
    x0, x1 = max(0, math.ceil(-vx)), min(W, math.floor(W - 1 - vx))
    y0, y1 = max(0, math.ceil(-vy)), min(H, math.floor(H - 1 - vy))
    if x1 - x0 < 4 or y1 - y0 < 4:
        return 0.0
    ys, xs = np.mgrid[y0:y1, x0:x1].astype(np.float64)
    b = ndimage.map_coordinates(a, [ys + vy, xs + vx], order=1, mode="nearest")
    p = a[y0:y1, x0:x1]
    p, b = p - p.mean(), b - b.mean()
    den = math.sqrt(float((p * p).sum() * (b * b).sum()))
    return float((p * b).sum() / den) if den > 1e-12 else 0.0


# -- back to the input's geometry ------------------------------------------------


def original_geometry_box(lattice: Lattice, m: int, x: int, y: int, w: int, h: int) -> tuple[int, int, int, int]:
    """The rectified canvas texels (x0, y0, x1, y1) that rendering the
    input-geometry rectangle (x, y, w, h) reads (with the 4-texel blend)."""
    G = lattice.canvas_matrix(m)
    corners = np.array([[x, y], [x + w, y], [x, y + h], [x + w, y + h]], dtype=np.float64)
    p = corners @ G.T
    return (math.floor(p[:, 0].min()) - 2, math.floor(p[:, 1].min()) - 2,
            math.ceil(p[:, 0].max()) + 2, math.ceil(p[:, 1].max()) + 2)


def render_original(coords: np.ndarray, box: tuple[int, int, int, int], lattice: Lattice, m: int,
                    source: np.ndarray, x: int, y: int, w: int, h: int) -> np.ndarray:
    """The texture in the input's geometry (float32 (h, w, C)): pixel q of the
    rectangle (x, y, w, h) (input-image pixels) is the rectified canvas point
    p = G q, shown by synthesis magnification (LH05 section 5): each of the 4
    texels nearest p extrapolates its exemplar coordinate to p, the rectified
    exemplar ``source`` (m x m, or its hi-res copy) is sampled there
    (bilinear, wrapping), and the 4 colors are blended bilinearly. ``coords``
    are the synthesized coordinates of the rectified texels ``box`` (from
    :func:`original_geometry_box`)."""
    G = lattice.canvas_matrix(m)
    ys, xs = np.mgrid[y:y + h, x:x + w].astype(np.float64) + 0.5
    px = G[0, 0] * xs + G[0, 1] * ys
    py = G[1, 0] * xs + G[1, 1] * ys
    fx, fy = px - 0.5, py - 0.5
    ix, iy = np.floor(fx).astype(np.int64), np.floor(fy).astype(np.int64)
    ax, ay = fx - ix, fy - iy
    s = source.shape[0]
    scale = s / m
    planes = [np.asarray(source[:, :, c], dtype=np.float64) for c in range(source.shape[2])]
    out = np.zeros((h, w, source.shape[2]), dtype=np.float64)
    x0, y0 = box[0], box[1]
    for dy in (0, 1):
        for dx in (0, 1):
            tx, ty = ix + dx, iy + dy
            u = coords[ty - y0, tx - x0].astype(np.float64)
            ux = (u[..., 0] + (px - (tx + 0.5)) + 0.5) * scale - 0.5  # extrapolated, in source pixels
            uy = (u[..., 1] + (py - (ty + 0.5)) + 0.5) * scale - 0.5
            wgt = (ax if dx else 1 - ax) * (ay if dy else 1 - ay)
            for c, plane in enumerate(planes):
                out[:, :, c] += wgt * ndimage.map_coordinates(plane, [uy, ux], order=1, mode="grid-wrap")
    return np.clip(out, 0.0, 1.0).astype(np.float32)
