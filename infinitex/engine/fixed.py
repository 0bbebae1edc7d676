"""The integer conventions shared by the analysis, the GLSL passes and the oracle.

Everything the correction compares is an integer with a proven bound, so the
GPU result does not depend on float rounding, fused multiply-adds or the
driver: the same document gives the same texture on every machine.

- Features (appearance vectors or colors) are in [-FEAT_MAX, FEAT_MAX].
- A runtime neighborhood is the concatenation of T taps of F features; it is
  projected to NDIM dims by an integer matrix scaled by PROJ_ONE, then shifted
  right (floor) by a per-level ``shift`` chosen so every projected value lies
  in [-NBHD_MAX, NBHD_MAX] (Cauchy-Schwarz bound).
- A squared distance is at most 8 * (2 * NBHD_MAX)^2 < 2^29; it is clamped to
  DIST_CLAMP and multiplied by psi in sixteenths (at most 80), < 2^32 unsigned.
- Jitter: the hash gives H in [-1024, 1023] / 1024 per axis; r_l is stored in
  1024ths; J = floor((h * H * r + 2^19) / 2^20), |h * H * r| <= 2^29.
"""
from __future__ import annotations

import numpy as np

NDIM = 8
FEAT_MAX = 127
PROJ_ONE = 256
NBHD_MAX = 4095
APPEARANCE_PREDICTIONS = 3
DIST_CLAMP = 1 << 25
PSI_ONE = 16
AVOIDED = 0xFFFFFFFE  # the cost of a candidate inside the avoid mask: above every real cost
KAPPA_MAX = 4.0
JITTER_ONE = 1024
JITTER_SHIFT = 20
SHIFT_BIAS = 1 << 30

DIAGONALS = ((-1, -1), (1, -1), (-1, 1), (1, 1))
COLOR_TAPS = tuple((dx, dy) for dy in range(-2, 3) for dx in range(-2, 3))
# Candidate order of k-coherence (also the tie-break order): the 3x3 neighbors
# in row-major order, then i = 1..k for each.
CANDIDATE_OFFSETS = tuple((dx, dy) for dy in range(-1, 2) for dx in range(-1, 2))


def taps(model: str) -> tuple[tuple[int, int], ...]:
    return DIAGONALS if model == "appearance" else COLOR_TAPS


def read_radius(model: str) -> int:
    """How far (in level pixels) one correction reads around the pixel it writes."""
    return 1 if model == "appearance" else 2


def exact_in_float(proj: np.ndarray, value_max: int) -> bool:
    """Whether projecting values of magnitude <= ``value_max`` by ``proj`` (rows
    x dims) is exact in float32 in any order of summation: every product and
    every partial sum is then an integer below 2^24."""
    bound = int(np.abs(proj.astype(np.int64)).sum(axis=0).max()) * int(value_max)
    return bound < 1 << 24


def choose_shift(proj: np.ndarray, bound_n: float) -> int:
    """Smallest right shift that keeps projected values within NBHD_MAX."""
    col_norm = float(np.sqrt((proj.astype(np.float64) ** 2).sum(axis=0)).max())
    bound = col_norm * bound_n
    if bound >= SHIFT_BIAS // 2:
        raise ValueError("neighborhood projection would overflow 32-bit integers")
    shift = 0
    while bound / (1 << shift) > NBHD_MAX:
        shift += 1
    return shift


def project(n_raw: np.ndarray, proj: np.ndarray, shift: int) -> np.ndarray:
    """floor((n_raw @ proj) / 2^shift) in int64, as the shaders compute it."""
    return (n_raw.astype(np.int64) @ proj.astype(np.int64)) >> shift


def psi_q(kappa: float) -> int:
    """psi(i > 1) = 1 + kappa in sixteenths."""
    kappa = float(kappa)
    if not 0.0 <= kappa <= KAPPA_MAX:
        raise ValueError(f"kappa must be in [0, {KAPPA_MAX}], not {kappa}.")
    return int(round(PSI_ONE * (1.0 + kappa)))


def jitter_q(r: float) -> int:
    r = float(r)
    if not 0.0 <= r <= 1.0:
        raise ValueError(f"randomness must be in [0, 1], not {r}.")
    return int(round(r * JITTER_ONE))


def lowbias32(x: np.ndarray) -> np.ndarray:
    """Chris Wellons' lowbias32 integer hash, on uint32 arrays."""
    x = np.asarray(x, dtype=np.uint32).copy()
    x ^= x >> np.uint32(16)
    x *= np.uint32(0x7FEB352D)
    x ^= x >> np.uint32(15)
    x *= np.uint32(0x846CA68B)
    x ^= x >> np.uint32(16)
    return x


def hash_bits(gx: np.ndarray, gy: np.ndarray, level: int, seed: int) -> np.ndarray:
    """The 32 hash bits (uint32) of pixels (gx, gy) of a level (common.glsl hash_bits)."""
    with np.errstate(over="ignore"):
        s = lowbias32(np.uint32(seed & 0xFFFFFFFF))
        s = lowbias32(np.uint32(level) ^ s)
        v = lowbias32(np.asarray(gy, dtype=np.int64).astype(np.uint32) ^ s)
        return lowbias32(np.asarray(gx, dtype=np.int64).astype(np.uint32) ^ v)


def hash2(gx: np.ndarray, gy: np.ndarray, level: int, seed: int) -> tuple[np.ndarray, np.ndarray]:
    """H(p, l, seed) in [-1024, 1023] per axis (divide by 1024 for [-1, 1)): bits 0-21."""
    v = hash_bits(gx, gy, level, seed)
    hx = (v & np.uint32(2047)).astype(np.int64) - 1024
    hy = ((v >> np.uint32(11)) & np.uint32(2047)).astype(np.int64) - 1024
    return hx, hy


WALK_STEP = 0x9E3779B9  # the walk's step t hashes with walk_seed + t * WALK_STEP (mod 2^32)


def walk_seed(seed: int, subpass: int) -> int:
    """The seed of the random walk in correction subpass number ``subpass`` (counted over all passes)."""
    with np.errstate(over="ignore"):
        return int(lowbias32(np.uint32((seed ^ ((subpass + 1) * 0x85EBCA6B)) & 0xFFFFFFFF)))


FIDELITY_SALT = 0x6A09E667  # keeps the fidelity stage's random search apart from the correction's walk


def fidelity_seed(seed: int, subpass: int) -> int:
    """The seed of the fidelity stage's random search in its subpass number ``subpass``."""
    return walk_seed((seed ^ FIDELITY_SALT) & 0xFFFFFFFF, subpass)


def quantized_colors(stack: np.ndarray) -> np.ndarray:
    """A level's colors as the fidelity stage compares them: (m, m, C <= 4) integers
    in [0, 255] (the first 4 channels, clipped to [0, 1])."""
    return np.rint(np.clip(stack[:, :, :4], 0.0, 1.0) * 255.0).astype(np.int64)


def walk_offsets(gx: np.ndarray, gy: np.ndarray, level: int, wseed: int, t: int, radius: int):
    """Step t's offset of the random walk, in [-radius, radius) per axis, as the correction shader computes it."""
    hx, hy = hash2(gx, gy, level, (wseed + t * WALK_STEP) & 0xFFFFFFFF)
    return (hx * radius) >> 10, (hy * radius) >> 10


def jitter(gx: np.ndarray, gy: np.ndarray, level: int, seed: int, h: int, rq: int):
    """J_l(p) = floor(h * H(p) * r + 1/2), exactly as the upsample shader computes it."""
    hx, hy = hash2(gx, gy, level, seed)
    half = 1 << (JITTER_SHIFT - 1)
    return ((h * hx * rq + half) >> JITTER_SHIFT), ((h * hy * rq + half) >> JITTER_SHIFT)


def parent_step(gmx: np.ndarray, gmy: np.ndarray, level: int, seed: int,
                dithered: bool = True) -> tuple[np.ndarray, np.ndarray]:
    """Which parent texel each pixel g of a level is upsampled from (common.glsl
    parent_step): floor(g / 2) + the step (ex, ey) returned, 0, or per axis
    one time in four (x: bits 22 and 23 of the hash of (gmx, gmy) both set, y:
    bits 24 and 25; g wrapped to the period), the step to the nearest other one
    (+1 for an odd g, -1 for an even g). The child's place from that parent is D = (g mod 2) - 2 e. Inside a
    coherent patch both parents predict the same coordinate; at a seam the
    child takes a side at random, so a coarse level's texel borders do not come
    down the pyramid as straight lines. ``dithered`` False: the plain rule."""
    gmx, gmy = np.asarray(gmx, np.int64), np.asarray(gmy, np.int64)
    if not dithered:
        return np.zeros_like(gmx), np.zeros_like(gmy)
    v = hash_bits(gmx, gmy, level, seed)
    dx = ((v >> np.uint32(22)) & (v >> np.uint32(23)) & np.uint32(1)).astype(np.int64)
    dy = ((v >> np.uint32(24)) & (v >> np.uint32(25)) & np.uint32(1)).astype(np.int64)
    return dx * (2 * (gmx & 1) - 1), dy * (2 * (gmy & 1) - 1)


def child_offset(d: np.ndarray, h: int) -> np.ndarray:
    """floor(h * (D - 1/2)) for D, the child's place from its parent q:
    {0, 1} from its own parent (LH05 stack upsampling), {-1, 2} from the nearest
    other (:func:`parent_step`)."""
    return d * h - ((h + 1) >> 1)


# -- anisometric synthesis (engine/controls/direction.py) ---------------------
# With a direction field a coordinate is F = 256 x + r in 1/256 exemplar px: a
# state texel holds the nearest texel x (wrapped) and r in [-128, 128).
FRAC_BITS = 8
FRAC_ONE = 1 << FRAC_BITS


def split_q8(F: np.ndarray, m: int) -> tuple[np.ndarray, np.ndarray]:
    """(nearest texel wrapped to [0, m), remainder in [-128, 128)) of coordinates F in 1/256 px."""
    F = np.asarray(F, np.int64) & (FRAC_ONE * m - 1)
    r = (F + FRAC_ONE // 2) >> FRAC_BITS
    return r & (m - 1), F - (r << FRAC_BITS)


def nearest_q8(F: np.ndarray, m: int) -> np.ndarray:
    """The nearest exemplar texel (wrapped) of coordinates F in 1/256 px."""
    return ((np.asarray(F, np.int64) + FRAC_ONE // 2) >> FRAC_BITS) & (m - 1)


def jmul(J: np.ndarray, dx, dy, h: int) -> tuple[np.ndarray, np.ndarray]:
    """h (J d) in 1/256 px: floor(h (J d) / 16) for J in Q12 (..., 4) (shaders: jmul)."""
    J = np.asarray(J, np.int64)
    vx = h * (J[..., 0] * dx + J[..., 1] * dy)
    vy = h * (J[..., 2] * dx + J[..., 3] * dy)
    return vx >> 4, vy >> 4


def child_offset_q8(J: np.ndarray, dx: np.ndarray, dy: np.ndarray, h: int) -> tuple[np.ndarray, np.ndarray]:
    """LH06 anisometric upsampling: h J (D - 1/2) in 1/256 px for D = p - 2q
    (each in {0, 1} from its own parent, {-1, 2} from the nearest other),
    floor(J v / 32) with v = h (2D - 1), less half a pixel at h = 1 (so that
    J = I gives child_offset exactly, in 1/256 px)."""
    J = np.asarray(J, np.int64)
    vx, vy = h * (2 * np.asarray(dx, np.int64) - 1), h * (2 * np.asarray(dy, np.int64) - 1)
    ox = (J[..., 0] * vx + J[..., 1] * vy) >> 5
    oy = (J[..., 2] * vx + J[..., 3] * vy) >> 5
    half = FRAC_ONE // 2 if h == 1 else 0
    return ox - half, oy - half


def inverse_direction_signs(J: np.ndarray, dx: int, dy: int) -> tuple[np.ndarray, np.ndarray]:
    """The signs (+-1, 0 counting as +1) of J^-1 d = adj(J) d / det J (det > 0):
    which immediate neighbors the appearance correction reads for diagonal d."""
    J = np.asarray(J, np.int64)
    px = J[..., 3] * dx - J[..., 1] * dy
    py = -J[..., 2] * dx + J[..., 0] * dy
    return np.where(px >= 0, 1, -1), np.where(py >= 0, 1, -1)


def inverse_direction_rounded(J: np.ndarray, dx: int, dy: int, lim: int = 2) -> tuple[np.ndarray, np.ndarray]:
    """round(J^-1 d) clamped to [-lim, lim] (the color model's neighbor for tap d):
    floor((2 * 4096 adj(J) d + det) / (2 det))."""
    J = np.asarray(J, np.int64)
    det = J[..., 0] * J[..., 3] - J[..., 1] * J[..., 2]
    px = J[..., 3] * dx - J[..., 1] * dy
    py = -J[..., 2] * dx + J[..., 0] * dy
    rx = (2 * 4096 * px + det) // (2 * det)
    ry = (2 * 4096 * py + det) // (2 * det)
    return np.clip(rx, -lim, lim), np.clip(ry, -lim, lim)
