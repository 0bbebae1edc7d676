"""A generated lattice benchmark that cannot be overfit (issue 66): images made
from random bases of every kind, random cell contents and random degradations,
and stochastic images from other generators that must get no lattice.

Every image is a pure function of (kind, content, index): ``lattice_case`` and
``stochastic_case`` rebuild it from those alone, so a failure can be looked at
again, and the set grows by raising the count, not by choosing images.

Lattice kinds (the basis turned by any angle, 0-180 degrees):
    square        two equal perpendicular vectors (a square grid turned 45
                  degrees is a diamond plate or diagonally laid tiles)
    rectangular   perpendicular, sides 1.25:1 to 3:1
    hexagonal     two equal vectors 60 degrees apart
    oblique       any two vectors, 50-130 degrees apart, up to 2.5:1
    staggered     rows of cells, each row shifted by a random fraction
                  (0.1-0.9) of a cell against the one before: bricks, shingles

Cell contents:
    shapes        one to three discs, rings, rounded bars or crosses
    tiles         a tile per cell with grout (the lattice's Voronoi cell:
                  squares, diamonds, hexagons; a brick in staggered rows)
    photo         a crop of a CC0 photo stretched over each cell (the
                  package's grass, gravel and gravel bed)
    noise         a periodic noise motif (no edges between cells at all)

Degradations, each drawn per image: per-cell colour variation, per-cell
jitter of the contents, a lighting gradient and slow blotches, blur and pixel
noise.

``few`` images hold a lattice that repeats fewer than about 2.6 times along a
vector: an answer there cannot be checked, so "no lattice" is right.

Stochastic kinds (must get no lattice): filtered noise, fractal noise,
irregular cells (Voronoi of random points), scattered blobs, streaks (wood and
bark), planks of random widths and lengths, water (noise of one scale, a ring
of frequencies: the hardest, it has a period but no lattice) and crops of the package's stochastic photos.
"""
from __future__ import annotations

import math
import os

import numpy as np
from lattice_scenes import nearest_point  # (tests/ is on the path wherever these are made)
from scipy import ndimage


SIDE = 256
LATTICE_KINDS = ("square", "rectangular", "hexagonal", "oblique", "staggered")
CONTENTS = ("shapes", "tiles", "photo", "noise")
STOCHASTIC_KINDS = ("noise", "fractal", "cells", "scatter", "streaks", "planks", "water", "photo")
# A lattice to find repeats at least this many times along each reduced
# vector; a "few" case at most FEW_REPEATS times along its longest.
MIN_REPEATS = 3.4
FEW_REPEATS = 2.6
MIN_LENGTH = 8.0
ASSETS = os.path.join(os.path.dirname(os.path.dirname(os.path.abspath(__file__))), "infinitex", "assets")
PHOTOS = ("grass.png", "gravel.png", "gravel_bed.png")
_photo_cache: dict[str, np.ndarray] = {}


def _rng(*key: int) -> np.random.Generator:
    return np.random.default_rng([20260607, *key])


def _photo(name: str) -> np.ndarray:
    if name not in _photo_cache:
        from PIL import Image
        with Image.open(os.path.join(ASSETS, name)) as im:
            _photo_cache[name] = np.asarray(im.convert("L"), np.float64) / 255.0
    return _photo_cache[name]


def reduce(t1, t2) -> tuple[np.ndarray, np.ndarray]:
    """Lagrange-Gauss reduction (the two shortest vectors of the lattice);
    the generator's own, so the truth does not depend on the detector's code."""
    a, b = np.asarray(t1, float), np.asarray(t2, float)
    if a @ a > b @ b:
        a, b = b, a
    for _ in range(64):
        b = b - round(float(a @ b) / float(a @ a)) * a
        if b @ b >= a @ a:
            break
        a, b = b, a
    return a, b


def _turn(v, angle: float) -> np.ndarray:
    c, s = math.cos(angle), math.sin(angle)
    return np.array([c * v[0] - s * v[1], s * v[0] + c * v[1]])


def random_lattice(kind: str, rng: np.random.Generator, side: int = SIDE, few: bool = False):
    """(t1, t2, frame): a random basis of the kind, turned by any angle, whose
    reduced vectors repeat at least MIN_REPEATS times across the image (``few``:
    the longest one at most FEW_REPEATS times); ``frame`` is (geometry, angle):
    the geometry (w, h, offset) of staggered rows, else None, and the angle
    the basis was turned by."""
    for _ in range(1000):
        longest = side / (rng.uniform(1.5, FEW_REPEATS) if few else MIN_REPEATS)
        L = rng.uniform(MIN_LENGTH, longest)
        if rng.random() < 0.5:  # small cells are common in real textures
            L = math.exp(rng.uniform(math.log(MIN_LENGTH), math.log(longest)))
        frame = None
        if kind == "square":
            t1, t2 = np.array([L, 0.0]), np.array([0.0, L])
        elif kind == "rectangular":
            r = rng.uniform(1.25, 3.0)
            t1, t2 = np.array([L, 0.0]), np.array([0.0, L * r])
        elif kind == "hexagonal":
            t1, t2 = np.array([L, 0.0]), L * np.array([0.5, math.sqrt(3) / 2])
        elif kind == "oblique":
            r, ang = rng.uniform(1.0, 2.5), math.radians(rng.uniform(50, 130))
            t1, t2 = np.array([L, 0.0]), L * r * np.array([math.cos(ang), math.sin(ang)])
        elif kind == "staggered":
            w = L * rng.uniform(1.2, 3.0)
            h = L
            o = rng.uniform(0.1, 0.9)
            t1, t2 = np.array([w, 0.0]), np.array([o * w, h])
            frame = (w, h, o)
        else:
            raise ValueError(kind)
        if rng.random() < 0.5:
            t1, t2 = t2, t1
        rot = rng.uniform(0, math.pi)
        t1, t2 = _turn(t1, rot), _turn(t2, rot)
        a, b = reduce(t1, t2)
        la, lb = math.hypot(*a), math.hypot(*b)
        if la < MIN_LENGTH:
            continue
        if few and lb >= side / FEW_REPEATS:
            return t1, t2, (frame, rot)
        if not few and lb <= side / MIN_REPEATS:
            return t1, t2, (frame, rot)
    raise RuntimeError("no basis")


def _hash_ids(c1: np.ndarray, c2: np.ndarray, size: int = 100003) -> np.ndarray:
    return (c1.astype(np.int64) * 7919 + c2.astype(np.int64) * 104729) % size


def _cells(t1, t2, frame, origin, side: int):
    """Per pixel: the id of its cell (a parallelogram of the reduced basis; a
    brick in staggered rows) and of its tile (the lattice's Voronoi cell; the
    brick), the fractional coordinates (fa, fb) in [0, 1) inside the cell, the
    matrix F from those to pixels, and the distance in pixels to the tile's
    border."""
    ys, xs = np.mgrid[0:side, 0:side].astype(np.float64) + 0.5
    px, py = xs - origin[0], ys - origin[1]
    geometry, rot = frame
    if geometry is not None:  # staggered rows, in the rows' frame
        w, h, o = geometry
        d = np.array([math.cos(rot), math.sin(rot)])
        n = np.array([-d[1], d[0]])
        u, v = px * d[0] + py * d[1], px * n[0] + py * n[1]
        row = np.floor(v / h)
        uu = u - row * o * w
        col = np.floor(uu / w)
        fa, fb = uu / w - col, v / h - row
        F = np.stack([w * d, h * n], axis=1)
        border = np.minimum(np.minimum(fa * w, (1 - fa) * w), np.minimum(fb * h, (1 - fb) * h))
        return _hash_ids(col, row), _hash_ids(col, row), fa, fb, F, border
    a, b = reduce(t1, t2)
    R = np.stack([a, b], axis=1)
    ab = np.einsum("ij,jyx->iyx", np.linalg.inv(R), np.stack([px, py]))
    base = np.floor(ab)
    n1, n2, rx, ry = nearest_point(px, py, R)
    border = np.full(px.shape, np.inf)
    for v in (a, b, a + b, a - b):
        lv = math.hypot(*v)
        proj = (rx * v[0] + ry * v[1]) / lv
        border = np.minimum(border, lv / 2 - np.abs(proj))
    # Contents in the reduced cell (the generating basis may be a long, thin
    # parallelogram that would cut shapes into slivers).
    fa, fb = ab[0] - base[0], ab[1] - base[1]
    return _hash_ids(base[0], base[1]), _hash_ids(n1, n2), fa, fb, R, border


def _contrast(rng, channels: int, low: float, high: float) -> np.ndarray:
    """A colour step that shows in luminance too (at least ``low`` on average)."""
    c = rng.uniform(-high, high, channels)
    m = c.mean()
    if abs(m) < low:
        c = c + (math.copysign(low, m if m else 1.0) - m)
    return c


def _shapes(rng, fa, fb, F, short: float, channels: int) -> np.ndarray:
    out = np.zeros(fa.shape + (channels,))
    for _ in range(int(rng.integers(1, 4))):
        ca, cb = rng.uniform(0, 1, 2)
        da = ((fa - ca + 0.5) % 1.0) - 0.5
        db = ((fb - cb + 0.5) % 1.0) - 0.5
        dx, dy = F[0, 0] * da + F[0, 1] * db, F[1, 0] * da + F[1, 1] * db
        r = rng.uniform(0.12, 0.3) * short
        what = rng.choice(["disc", "ring", "bar", "cross"])
        if what == "disc":
            dist = np.hypot(dx, dy) - r
        elif what == "ring":
            dist = np.abs(np.hypot(dx, dy) - r) - max(1.0, 0.25 * r)
        else:
            ang = rng.uniform(0, math.pi)
            c, s = math.cos(ang), math.sin(ang)
            u, v = c * dx + s * dy, -s * dx + c * dy
            width = max(1.0, rng.uniform(0.08, 0.2) * short)
            dist = np.maximum(np.abs(u) - r, np.abs(v) - width / 2)
            if what == "cross":
                dist = np.minimum(dist, np.maximum(np.abs(v) - r, np.abs(u) - width / 2))
        inside = 1.0 / (1.0 + np.exp(dist / 0.7))
        out += inside[..., None] * _contrast(rng, channels, 0.15, 0.45)
    return out


def _tiles(rng, border, channels: int) -> np.ndarray:
    grout = rng.uniform(0.8, 3.0)
    tile = np.clip(border - grout / 2, 0, 1)
    bevel = np.clip(border / (grout + 3.0), 0, 1)
    body = rng.uniform(-0.25, 0.25, channels)
    joint = body + _contrast(rng, channels, 0.12, 0.35)
    return tile[..., None] * (body + 0.08 * bevel[..., None]) + (1 - tile)[..., None] * joint


def _photo_cells(rng, fa, fb, F, channels: int) -> np.ndarray:
    photo = _photo(str(rng.choice(PHOTOS)))
    ph, pw = photo.shape
    cw = min(pw - 2, max(4.0, math.hypot(*F[:, 0]) * rng.uniform(0.8, 1.5)))
    ch = min(ph - 2, max(4.0, math.hypot(*F[:, 1]) * rng.uniform(0.8, 1.5)))
    x0, y0 = rng.uniform(0, pw - 1 - cw), rng.uniform(0, ph - 1 - ch)
    g = ndimage.map_coordinates(photo, [y0 + fb * ch, x0 + fa * cw], order=1, mode="nearest")
    g = (g - g.mean()) / (g.std() + 1e-9) * rng.uniform(0.08, 0.2)
    tint = rng.uniform(0.6, 1.0, channels)
    return g[..., None] * tint


def _noise_cells(rng, fa, fb, channels: int) -> np.ndarray:
    M = 32
    motif = ndimage.gaussian_filter(rng.normal(0, 1, (M, M, channels)), (rng.uniform(1, 4),) * 2 + (0,), mode="wrap")
    motif = motif / (motif.std() + 1e-9) * rng.uniform(0.08, 0.2)
    out = np.empty(fa.shape + (channels,))
    for c in range(channels):
        out[..., c] = ndimage.map_coordinates(motif[..., c], [fb * M, fa * M], order=1, mode="grid-wrap")
    return out


def _degrade(rng, img: np.ndarray) -> np.ndarray:
    side = img.shape[0]
    ys, xs = np.mgrid[0:side, 0:side].astype(np.float64) / side - 0.5
    g = rng.uniform(-0.4, 0.4, 2) * (rng.random() < 0.7)
    light = 1.0 + g[0] * xs + g[1] * ys
    if rng.random() < 0.5:
        blot = ndimage.gaussian_filter(rng.normal(0, 1, (side, side)), side / 6)
        light = light + blot / (blot.std() + 1e-9) * rng.uniform(0.03, 0.15)
    img = img * light[..., None]
    sigma = rng.uniform(0, 1.5) if rng.random() < 0.6 else 0.0
    if sigma > 0.2:
        img = ndimage.gaussian_filter(img, (sigma, sigma, 0))
    img = img + rng.normal(0, rng.uniform(0, 0.05), img.shape)
    return np.clip(img, 0, 1).astype(np.float32)


def lattice_case(kind: str, content: str, index: int, side: int = SIDE, few: bool = False):
    """(image (side, side, 3) float32 in [0, 1], t1, t2): the index-th image of
    that kind and content."""
    rng = _rng(LATTICE_KINDS.index(kind), CONTENTS.index(content), index, int(few))
    t1, t2, frame = random_lattice(kind, rng, side, few)
    return render(t1, t2, frame, content, rng, _rng(index, 7), side), np.asarray(t1, float), np.asarray(t2, float)


def staggered(w: float, h: float, offset: float, angle_deg: float):
    """(t1, t2, frame) of rows of w x h cells, each row shifted by ``offset``
    of a cell, turned by ``angle_deg`` (for :func:`render`)."""
    rot = math.radians(angle_deg)
    return _turn((w, 0.0), rot), _turn((offset * w, h), rot), ((w, h, offset), rot)


def render(t1, t2, frame, content: str, rng: np.random.Generator, cell_rng: np.random.Generator,
           side: int = SIDE, variation: float | None = None) -> np.ndarray:
    """The image of a lattice (t1, t2; ``frame`` from :func:`random_lattice`
    or :func:`staggered`, or None) with that content, degraded, every random
    choice drawn from ``rng`` (the cells' own from ``cell_rng``)."""
    frame = frame if frame is not None else (None, 0.0)
    origin = rng.uniform(0, side, 2)
    ids, tile_ids, fa, fb, F, border = _cells(np.asarray(t1, float), np.asarray(t2, float), frame, origin, side)
    a, b = reduce(t1, t2)
    short = min(math.hypot(*a), math.hypot(*F[:, 0]), math.hypot(*F[:, 1]))
    jitter = rng.uniform(0, 0.6)
    shift = cell_rng.normal(0, jitter, (100003, 2)) / np.array([math.hypot(*F[:, 0]), math.hypot(*F[:, 1])])
    drawn = rng.uniform(0.0, 0.2)  # drawn either way: the same stream of choices
    variation = drawn if variation is None else variation
    gain = 1.0 + cell_rng.uniform(-variation, variation, (100003, 3))
    ja, jb = (fa + shift[ids, 0]) % 1.0, (fb + shift[ids, 1]) % 1.0
    base = rng.uniform(0.3, 0.6, 3)
    if content == "shapes":
        pattern = _shapes(rng, ja, jb, F, short, 3)
    elif content == "tiles":
        pattern = _tiles(rng, border, 3)
    elif content == "photo":
        pattern = _photo_cells(rng, ja, jb, F, 3)
    elif content == "noise":
        pattern = _noise_cells(rng, ja, jb, 3)
    else:
        raise ValueError(content)
    img = (base + pattern) * gain[tile_ids if content == "tiles" else ids]
    return _degrade(rng, img)


def stochastic_case(kind: str, index: int, side: int = SIDE) -> np.ndarray:
    """The index-th stochastic image of that kind: (side, side, 3) float32."""
    rng = _rng(100 + STOCHASTIC_KINDS.index(kind), index)
    ys, xs = np.mgrid[0:side, 0:side].astype(np.float64) + 0.5
    if kind == "noise":
        g = np.zeros((side, side))
        for _ in range(int(rng.integers(1, 4))):
            n = ndimage.gaussian_filter(rng.normal(0, 1, (side, side)), rng.uniform(0.7, 14))
            g += n / (n.std() + 1e-9) * rng.uniform(0.05, 0.2)
    elif kind == "fractal":
        fy = np.fft.fftfreq(side)[:, None]
        fx = np.fft.rfftfreq(side)[None, :]
        f = np.hypot(fx, fy)
        f[0, 0] = 1.0
        spec = (rng.normal(size=f.shape) + 1j * rng.normal(size=f.shape)) * f ** -rng.uniform(0.8, 1.6)
        spec[0, 0] = 0
        g = np.fft.irfft2(spec, s=(side, side))
        g = g / (g.std() + 1e-9) * rng.uniform(0.08, 0.2)
    elif kind == "cells":  # cobbles, cracked earth: Voronoi of random points
        n = int(rng.integers(15, 300))
        pts = rng.uniform(0, side, (n, 2))
        from scipy.spatial import cKDTree
        d, i = cKDTree(pts).query(np.stack([xs.ravel(), ys.ravel()], axis=1), k=2)
        edge = (d[:, 1] - d[:, 0]).reshape(side, side)
        tone = rng.uniform(-0.15, 0.15, n)[i[:, 0]].reshape(side, side)
        g = tone + np.where(edge < rng.uniform(1, 4), -0.25, 0.0)
    elif kind == "scatter":  # pebbles, spots, leaves: random blobs
        g = np.zeros((side, side))
        r0 = rng.uniform(2, 20)
        for _ in range(int(rng.integers(20, 400 if r0 < 8 else 120))):
            cx, cy = rng.uniform(0, side, 2)
            r = r0 * rng.uniform(0.6, 1.4)
            g += rng.uniform(-0.3, 0.3) / (1 + np.exp((np.hypot(xs - cx, ys - cy) - r) / 0.8))
    elif kind == "streaks":  # wood, bark: noise stretched along a direction
        ang = rng.uniform(0, math.pi)
        n = rng.normal(0, 1, (side, side))
        s_along, s_across = rng.uniform(8, 40), rng.uniform(0.7, 3)
        n = ndimage.gaussian_filter(n, (s_across, s_along))
        n = ndimage.rotate(n, math.degrees(ang), reshape=False, mode="reflect")
        g = n / (n.std() + 1e-9) * rng.uniform(0.08, 0.2)
    elif kind == "planks":  # boards of random widths, joints at random places
        ang = rng.uniform(0, math.pi)
        c, s = math.cos(ang), math.sin(ang)
        u, v = c * xs + s * ys, -s * xs + c * ys
        mean = rng.uniform(10, 60)
        edges = np.cumsum(rng.uniform(0.5, 1.6, 400) * mean) - 200 * mean
        row = np.searchsorted(edges, v)
        length = rng.uniform(2, 8) * mean
        offs = rng.uniform(0, length, row.max() + 2)
        col = np.floor((u + offs[row]) / length)
        shade = rng.uniform(-0.15, 0.15, 100003)[_hash_ids(col, row)]
        grain = ndimage.gaussian_filter(rng.normal(0, 1, (side, side)), (1, 1)) * 0.04
        in_row = v - np.concatenate([[-1e9], edges])[row]
        joint = (in_row < 1.5) | (((u + offs[row]) % length) < 1.5)
        g = shade + grain + np.where(joint, -0.3, 0.0)
    elif kind == "water":  # caustics, ripples: noise of one scale (a ring of frequencies), maybe drawn along a direction
        fy = np.fft.fftfreq(side)[:, None]
        fx = np.fft.rfftfreq(side)[None, :]
        f0, width = 1.0 / rng.uniform(6, 40), rng.uniform(0.1, 0.35)
        ring = np.exp(-0.5 * ((np.hypot(fx, fy) - f0) / (width * f0)) ** 2)
        if rng.random() < 0.5:
            ang = rng.uniform(0, math.pi)
            ring = ring * (0.3 + np.abs(math.cos(ang) * fx + math.sin(ang) * fy) / (np.hypot(fx, fy) + 1e-9)) ** 2
        spec = (rng.normal(size=ring.shape) + 1j * rng.normal(size=ring.shape)) * ring
        g = np.fft.irfft2(spec, s=(side, side))
        if rng.random() < 0.5:
            g = np.abs(g)  # bright caustic lines
        g = (g - g.mean()) / (g.std() + 1e-9) * rng.uniform(0.08, 0.18)
    elif kind == "photo":
        photo = _photo(str(rng.choice(PHOTOS)))
        ph, pw = photo.shape
        crop = rng.uniform(0.35, 1.0) * min(ph, pw)
        x0, y0 = rng.uniform(0, pw - crop), rng.uniform(0, ph - crop)
        sc = crop / side
        g = ndimage.map_coordinates(photo, [y0 + ys * sc, x0 + xs * sc], order=1, mode="nearest") - 0.5
    else:
        raise ValueError(kind)
    img = (rng.uniform(0.35, 0.6, 3) + g[..., None] * rng.uniform(0.6, 1.0, 3))
    return _degrade(rng, img)
