"""Near-regular textures (LH05 section 4.5; docs/algorithm.md section 5): the
lattice model, its automatic detection, and the rectification of a block of
cells into a square toroidal exemplar.

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

Detection (:func:`.lattice_detect.detect`) uses the autocorrelation of the image (FFT, the
overlap-normalized estimate), its local maxima (``scipy.ndimage``), the two
shortest independent strong peaks reduced to a Gauss-reduced basis, then a
least-squares fit of the basis to every lattice peak found at sub-pixel
precision. Its confidence compares the autocorrelation at lattice points with
that between them; below :data:`MIN_CONFIDENCE` the answer is "no lattice".
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..exemplar import Exemplar

MAX_CELLS = 16           # cells per block side
MIN_VECTOR = 3.0         # px: shorter translation vectors are refused
MIN_SINE = 0.1           # |sin| of the angle between t1 and t2 (about 6 degrees)
MIN_CONFIDENCE = 0.3     # detection: below this, "no lattice"
MIN_REPEATS = 2          # detection: a lattice vector fits at least this many times in the image (half the image)
SURE_REPEATS = 3         # detection: a lattice seen fewer times than this along a vector...
FEW_CONFIDENCE = 0.5     # ...needs at least this confidence (two cells say less than many)
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

    def describe(self) -> str:
        """The cell as people name it, in input pixels: its width along t1 by
        the spacing of its rows ("31 x 11 px"; staggered rows too)."""
        w = math.hypot(*self.t1)
        return f"{w:.0f} x {abs(self.cross) / max(w, 1e-9):.0f} px"

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
        from scipy import ndimage  # imported when used: a cached analysis's window needs none of scipy
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


@dataclass(frozen=True)
class Detection:
    """What the search (:func:`.lattice_detect.detect`) found: a lattice
    (None: no lattice found), the confidence in [0, 1], and the time it took."""

    lattice: Lattice | None
    confidence: float
    seconds: float
    t1: tuple[float, float] | None = None  # the reduced basis, even when rejected
    t2: tuple[float, float] | None = None


def _fmt(v: float) -> str:
    s = f"{v:.3f}".rstrip("0").rstrip(".")
    return "0" if s in ("-0", "") else s


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
    from scipy import ndimage
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


def row_offset(img: np.ndarray, w: float, h: float, margin: float = 0.1) -> tuple[float, float, float] | None:
    """For a hand-marked cell w x h (px): the offset s of the next row that
    makes the image most like itself shifted by (s, h), when it beats
    stacked rows (s = 0) by ``margin`` in correlation: staggered rows
    (running-bond bricks, shingles). (s, its correlation, the stacked rows')
    or None. One FFT autocorrelation of the whole image, overlap-normalized."""
    a = np.asarray(img, dtype=np.float64)
    if a.ndim == 3:
        a = a[:, :, :3].mean(axis=2) if a.shape[2] >= 3 else a[:, :, 0]
    H, W = a.shape
    hy = int(round(h))
    if not 2 <= hy < H // 2 or w < 2 or w >= W // 2:
        return None
    a = a - a.mean()
    size = (2 * H, 2 * W)
    f = np.fft.rfft2(a, s=size)
    ac = np.fft.irfft2(f * np.conj(f), s=size)
    ones = np.fft.rfft2(np.ones((H, W)), s=size)
    overlap = np.fft.irfft2(ones * np.conj(ones), s=size)
    ac = ac / np.maximum(overlap, 1.0) / max(ac[0, 0] / (H * W), 1e-12)
    row = ac[-hy % size[0]]  # shifts (s, h): the image below matches the one above moved by s
    shifts = np.arange(int(np.ceil(w)))
    values = row[-shifts % size[1]]
    best = int(np.argmax(values))
    stacked = float(values[0])
    if best in (0, len(shifts) - 1) or values[best] < stacked + margin:
        return None
    return float(best), float(values[best]), stacked


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
    from scipy import ndimage
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
