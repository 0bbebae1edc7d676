"""Generated near-regular and stochastic images for the lattice tests and benchmark."""
from __future__ import annotations

import math

import numpy as np
from scipy import ndimage


def random_basis(rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """t1 of 8 to 64 px, t2 at 60-120 degrees from it with aspect up to 3:1
    either way, the whole basis rotated by up to 45 degrees."""
    c = rng.uniform(8, 64)
    aspect = rng.uniform(1, 3)
    if rng.random() < 0.5:
        l1, l2 = c, c * aspect
    else:
        l1, l2 = c * aspect, c
    if max(l1, l2) > 64 * 1.5:
        s = 64 * 1.5 / max(l1, l2)
        l1, l2 = max(8.0, l1 * s), max(8.0, l2 * s)
    ang = math.radians(rng.uniform(60, 120))
    rot = math.radians(rng.uniform(-45, 45))
    t1 = l1 * np.array([math.cos(rot), math.sin(rot)])
    t2 = l2 * np.array([math.cos(rot + ang), math.sin(rot + ang)])
    return t1, t2


def near_regular(rng: np.random.Generator, t1, t2, side: int | None = None, noise: float = 0.03,
                 variation: float = 0.08, channels: int = 3) -> np.ndarray:
    """An image of a random motif repeated on the lattice (t1, t2): a few
    periodic blobs per cell, each cell's colors varied by ``variation``, each
    cell's motif shifted by up to 0.3 px, plus Gaussian pixel noise."""
    t1, t2 = np.asarray(t1, float), np.asarray(t2, float)
    if side is None:
        side = int(np.clip(6 * max(np.hypot(*t1), np.hypot(*t2)), 128, 512))
    B = np.stack([t1, t2], axis=1)
    Binv = np.linalg.inv(B)
    ys, xs = np.mgrid[0:side, 0:side].astype(np.float64) + 0.5
    origin = rng.uniform(0, side, 2)
    ab = np.einsum("ij,jyx->iyx", Binv, np.stack([xs - origin[0], ys - origin[1]]))
    cells = np.floor(ab).astype(np.int64)
    cid = (cells[0] * 7919 + cells[1] * 104729) % 100003
    cell_rng = np.random.default_rng(int(rng.integers(1 << 30)))
    table_shift = cell_rng.normal(0, 0.3, (100003, 2)) / np.array([np.hypot(*t1), np.hypot(*t2)])
    table_gain = 1.0 + cell_rng.uniform(-variation, variation, (100003, channels))
    fa = ab[0] - cells[0] + table_shift[cid, 0]
    fb = ab[1] - cells[1] + table_shift[cid, 1]
    base = rng.uniform(0.2, 0.5, channels)
    img = np.broadcast_to(base, (side, side, channels)).copy()
    # Blobs in cell coordinates, measured in pixels through B (so they are round-ish).
    for _ in range(int(rng.integers(2, 5))):
        ca, cb = rng.uniform(0, 1, 2)
        rad = rng.uniform(0.12, 0.3) * min(np.hypot(*t1), np.hypot(*t2))
        col = rng.uniform(-0.4, 0.5, channels)
        da = ((fa - ca + 0.5) % 1.0) - 0.5
        db = ((fb - cb + 0.5) % 1.0) - 0.5
        dx = B[0, 0] * da + B[0, 1] * db
        dy = B[1, 0] * da + B[1, 1] * db
        w = 1.0 / (1.0 + np.exp((np.hypot(dx, dy) - rad) / 1.2))
        img += w[:, :, None] * col
    img *= table_gain[cid]
    img += rng.normal(0, noise, img.shape)
    return np.clip(img, 0, 1).astype(np.float32)


def stochastic(rng: np.random.Generator, side: int = 256, channels: int = 3) -> np.ndarray:
    """Filtered noise at one or two random scales: no lattice."""
    img = np.zeros((side, side, channels))
    for _ in range(int(rng.integers(1, 3))):
        sigma = rng.uniform(1, 12)
        n = ndimage.gaussian_filter(rng.normal(0, 1, (side, side, channels)), (sigma, sigma, 0))
        img += n / (n.std() + 1e-9) * rng.uniform(0.05, 0.2)
    return np.clip(img + 0.5, 0, 1).astype(np.float32)


def lattice_error(found_t1, found_t2, t1, t2) -> float:
    """How far a found basis is from generating the true lattice: the largest
    relative error of each found vector to the nearest true lattice vector
    (relative to its length, or in px over 25 for short vectors: 0.5 px counts
    as 2%), and of the cell area. 0.02 or less is a match."""
    B = np.stack([np.asarray(t1, float), np.asarray(t2, float)], axis=1)
    errs = []
    for v in (found_t1, found_t2):
        v = np.asarray(v, float)
        n = np.rint(np.linalg.solve(B, v))
        if not n.any():
            return math.inf
        d = float(np.hypot(*(v - B @ n)))
        errs.append(min(d / max(1e-9, float(np.hypot(*v))), d / 25.0))
    area = abs(np.linalg.det(np.stack([found_t1, found_t2], axis=1)))
    errs.append(abs(area / abs(np.linalg.det(B)) - 1.0) / 2.0)
    return max(errs)


def bricks(rng: np.random.Generator, side: int = 256, bw: float = 32.0, bh: float = 16.0, mortar: float = 2.0,
           angle: float = 0.0, variation: float = 0.15, noise: float = 0.03) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Running-bond bricks (each row offset by half a brick), rotated by
    ``angle`` degrees; returns the image and the lattice vectors t1, t2."""
    c, s = math.cos(math.radians(angle)), math.sin(math.radians(angle))
    ys, xs = np.mgrid[0:side, 0:side].astype(np.float64) + 0.5
    u = c * xs + s * ys
    v = -s * xs + c * ys
    row = np.floor(v / bh)
    uu = u + 0.5 * bw * (row % 2)
    col = np.floor(uu / bw)
    fu, fv = uu - col * bw, v - row * bh
    inside = np.minimum(np.minimum(fu, bw - fu), np.minimum(fv, bh - fv))
    brick = np.clip((inside - mortar / 2) / 1.0, 0, 1)
    ids = ((col.astype(np.int64) * 7919 + row.astype(np.int64) * 104729) % 10007)
    tone = np.random.default_rng(int(rng.integers(1 << 30))).uniform(-variation, variation, (10007, 3))
    base = np.array([0.62, 0.32, 0.22])
    img = (0.78 * (1 - brick))[..., None] * np.ones(3) + brick[..., None] * (base + tone[ids])
    grain = ndimage.gaussian_filter(rng.normal(0, 1, (side, side)), 1.2)
    img += (noise * grain / grain.std())[..., None]
    t1 = np.array([c * bw, s * bw])
    t2 = np.array([-s * bh + c * bw / 2, c * bh + s * bw / 2])
    return np.clip(img, 0, 1).astype(np.float32), t1, t2


def tiles(rng: np.random.Generator, side: int = 256, cell: float = 32.0, grout: float = 3.0,
          variation: float = 0.2, noise: float = 0.02) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Square tiles with a cross motif, per-tile colour variation."""
    ys, xs = np.mgrid[0:side, 0:side].astype(np.float64) + 0.5
    cx, cy = np.floor(xs / cell), np.floor(ys / cell)
    fx, fy = xs - cx * cell, ys - cy * cell
    edge = np.minimum(np.minimum(fx, cell - fx), np.minimum(fy, cell - fy))
    tile = np.clip(edge - grout / 2, 0, 1)
    cross = ((np.abs(fx - cell / 2) < cell / 10) | (np.abs(fy - cell / 2) < cell / 10)).astype(float)
    ids = (cx.astype(np.int64) * 7919 + cy.astype(np.int64) * 104729) % 10007
    tone = np.random.default_rng(int(rng.integers(1 << 30))).uniform(-variation, variation, (10007, 3))
    body = np.array([0.25, 0.45, 0.6]) + tone[ids] - 0.25 * cross[..., None]
    img = (0.85 * (1 - tile))[..., None] * np.ones(3) + tile[..., None] * body
    img += rng.normal(0, noise, img.shape)
    return np.clip(img, 0, 1).astype(np.float32), np.array([cell, 0.0]), np.array([0.0, cell])


def rows(rng: np.random.Generator, side: int = 256, period: float = 24.0, angle: float = 0.0,
         kind: str = "planks", noise: float = 0.04, bend: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
    """A one-dimensional lattice rotated by ``angle`` degrees: ``planks`` (rows
    of boards, each its own shade, a wavy grain, 2 px dark joints) or
    ``stripes`` (a sine across the rows); ``bend``: the rows curve by that many
    pixels across, once over the image. Returns the image and the unit vector
    along the rows."""
    c, s = math.cos(math.radians(angle)), math.sin(math.radians(angle))
    ys, xs = np.mgrid[0:side, 0:side].astype(np.float64) + 0.5
    u, v = c * xs + s * ys, -s * xs + c * ys  # along, across
    v = v + bend * np.sin(2 * np.pi * u / side)
    if kind == "stripes":
        img = 0.5 + 0.35 * np.sin(2 * np.pi * v / period)
    else:
        idx = np.floor(v / period).astype(np.int64)
        shade = rng.uniform(0.45, 0.7, 4096)[idx % 4096]
        lam, phase = rng.uniform(30, 70, 4096)[idx % 4096], rng.uniform(0, 2 * np.pi, 4096)[idx % 4096]
        grain = 0.06 * np.sin(2 * np.pi * u / lam + phase + 3 * np.sin(v / 5.0))  # each board its own
        img = np.where(v - idx * period < 2.0, 0.12, shade + grain)
    img = img + noise * rng.standard_normal((side, side))
    tone = np.array([1.0, 0.8, 0.6])
    return np.clip(img[..., None] * tone, 0, 1).astype(np.float32), np.array([c, s])
