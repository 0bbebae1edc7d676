"""Photo-like near-regular scenes with known lattices: a second development set
for lattice detection, from a source other than the game textures of
:mod:`near_regular`.

Each scene is drawn from a seed: running-bond bricks, staggered shingles and
roof tiles, hexagonal tiles, perforated sheets (round holes on a hexagonal
lattice), diamond plate (a centred rectangular lattice), square and diagonal
tiles with a motif, a basket weave (blocks of strands alternating direction: the
primitive cell is the diagonal one), ashlar (rows of random-length blocks: only
the rows repeat), and stochastic scenes with no lattice (random stones, random
spots, fibres, clouds). Each is rendered as a photograph would show it: per-cell
colour and surface variation, cells a fraction of a pixel off their place,
bevel shading, a lighting gradient, sensor noise and a slight blur, sometimes
turned by a few degrees.

The set is split before any tuning: :func:`scenes` with ``half="tune"`` gives
the even-numbered scenes, ``half="held"`` the odd ones; the detector is tuned on
the first and the second is only reported (bench.lattice).
"""
from __future__ import annotations

import math

import numpy as np
from scipy import ndimage

KINDS = ("running_bond", "shingles", "hex_tiles", "perforated", "diamond_plate",
         "square_tiles", "diagonal_tiles", "basket_weave", "ashlar", "stochastic")
PER_KIND = 8  # scenes per kind (stochastic: twice as many)


def _frame(side: int, angle: float):
    """Pixel centres turned by ``angle`` degrees: (u, v) in the pattern's frame,
    and the rotation taking pattern vectors to image vectors."""
    c, s = math.cos(math.radians(angle)), math.sin(math.radians(angle))
    ys, xs = np.mgrid[0:side, 0:side].astype(np.float64) + 0.5
    xs, ys = xs - side / 2, ys - side / 2
    u, v = c * xs + s * ys, -s * xs + c * ys
    rot = np.array([[c, -s], [s, c]])
    return u, v, rot


def _cell_noise(ids: np.ndarray, rng: np.random.Generator, n: int = 4) -> np.ndarray:
    """A random value per cell id (n values each), deterministic from rng."""
    table = rng.uniform(-1, 1, (65536, n))
    return table[(ids.astype(np.int64) * 2654435761 % 65536)]


def _photo(rng: np.random.Generator, img: np.ndarray, height: np.ndarray | None = None) -> np.ndarray:
    """Bevel shading from a height map, a lighting gradient, grain, blur, noise."""
    side = img.shape[0]
    if height is not None:
        gy, gx = np.gradient(ndimage.gaussian_filter(height, 1.0))
        light = np.array([-0.6, -0.8])
        shade = 1.0 + 1.5 * (gx * light[0] + gy * light[1])
        img = img * np.clip(shade, 0.4, 1.6)[..., None]
    ys, xs = np.mgrid[0:side, 0:side] / side
    a, b = rng.uniform(-0.25, 0.25, 2)
    img = img * (1.0 + a * (xs - 0.5) + b * (ys - 0.5))[..., None]
    grain = ndimage.gaussian_filter(rng.standard_normal((side, side)), rng.uniform(0.7, 2.0))
    img = img * (1.0 + rng.uniform(0.03, 0.1) * grain / grain.std())[..., None]
    img = ndimage.gaussian_filter(img, (rng.uniform(0.3, 0.9),) * 2 + (0,))
    img = img + rng.normal(0, rng.uniform(0.005, 0.02), img.shape)
    return np.clip(img, 0, 1).astype(np.float32)


def _palette(rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """A cell colour and a joint colour."""
    cell = rng.uniform(0.25, 0.8, 3)
    joint = rng.uniform(0.1, 0.9, 3)
    if np.abs(joint - cell).mean() < 0.2:
        joint = np.clip(cell + np.where(cell.mean() > 0.5, -0.35, 0.35), 0, 1)
    return cell, joint


def _staggered(rng, side, angle, w, h, mortar, rounded=False):
    """Running bond (rounded=False) or shingles (rounded bottoms, overlap shadow)."""
    u, v, rot = _frame(side, angle)
    u = u + rng.uniform(0, w)
    v = v + rng.uniform(0, h)
    row = np.floor(v / h)
    jit = _cell_noise(row, rng, 1)[..., 0] * 0.4  # each row a fraction of a pixel off
    uu = u + 0.5 * w * (row % 2) + jit
    col = np.floor(uu / w)
    fu, fv = uu - col * w, v - row * h
    cid = col * 7919 + row * 104729
    var = _cell_noise(cid, rng, 4)
    cell, joint = _palette(rng)
    if rounded:  # the tile's bottom is an arc; the tile above casts a shadow
        arc = h * 0.25 * (1 - ((fu - w / 2) / (w / 2)) ** 2)
        edge = np.minimum(np.minimum(fu, w - fu), np.minimum(fv, h - fv + arc))
        body = np.clip((edge - mortar / 2), 0, 1)
        tone = cell * (1 + 0.25 * var[..., :3]) * (0.6 + 0.4 * fv[..., None] / h)
        height = body * (fv / h)
    else:
        edge = np.minimum(np.minimum(fu, w - fu), np.minimum(fv, h - fv))
        body = np.clip((edge - mortar / 2), 0, 1)
        tone = cell * (1 + 0.25 * var[..., :3])
        height = np.clip(edge / 2.0, 0, 1)
    img = body[..., None] * tone + (1 - body[..., None]) * joint
    t1 = rot @ np.array([w, 0.0])
    t2 = rot @ np.array([w / 2, h])
    return img, height, [t1, t2]


def nearest_point(x: np.ndarray, y: np.ndarray, B: np.ndarray) -> tuple[np.ndarray, ...]:
    """The lattice point B (k1, k2) (B's columns: the basis) nearest each (x, y)
    among the four corners of its cell: (k1, k2, dx, dy), (dx, dy) = (x, y)
    less that point."""
    inv = np.linalg.inv(B)
    n1 = inv[0, 0] * x + inv[0, 1] * y
    n2 = inv[1, 0] * x + inv[1, 1] * y
    best = None
    for d1 in (0, 1):
        for d2 in (0, 1):
            k1, k2 = np.floor(n1) + d1, np.floor(n2) + d2
            dx, dy = x - (B[0, 0] * k1 + B[0, 1] * k2), y - (B[1, 0] * k1 + B[1, 1] * k2)
            dist = dx * dx + dy * dy
            if best is None:
                best = [dist, k1, k2, dx, dy]
            else:
                closer = dist < best[0]
                for i, val in enumerate((dist, k1, k2, dx, dy)):
                    best[i] = np.where(closer, val, best[i])
    return tuple(best[1:])


def _centred(rng, side, angle, a, b, draw):
    """A lattice (a, 0), (a/2, b) (hexagonal when b = a sqrt(3)/2): draw(du, dv,
    cid) gives (colour mix in [0, 1], height) from the offset to the nearest
    lattice point."""
    u, v, rot = _frame(side, angle)
    u = u + rng.uniform(0, a)
    v = v + rng.uniform(0, b)
    k1, k2, du, dv = nearest_point(u, v, np.array([[a, a / 2], [0.0, b]]))
    mix, height = draw(du, dv, k1 * 7919 + k2 * 104729)
    t1, t2 = rot @ np.array([a, 0.0]), rot @ np.array([a / 2, b])
    return mix, height, [t1, t2]


def _square(rng, side, angle, cell, grout, motif):
    u, v, rot = _frame(side, angle)
    u, v = u + rng.uniform(0, cell), v + rng.uniform(0, cell)
    cx, cy = np.floor(u / cell), np.floor(v / cell)
    fx, fy = u - cx * cell - cell / 2, v - cy * cell - cell / 2
    edge = cell / 2 - np.maximum(np.abs(fx), np.abs(fy))
    body = np.clip(edge - grout / 2, 0, 1)
    var = _cell_noise(cx * 7919 + cy * 104729, rng, 3)
    cell_c, joint = _palette(rng)
    if motif == "cross":
        m = ((np.abs(fx) < cell / 10) | (np.abs(fy) < cell / 10)).astype(float)
    elif motif == "dot":
        m = (np.hypot(fx, fy) < cell / 5).astype(float)
    else:
        m = np.zeros_like(fx)
    tone = cell_c * (1 + 0.2 * var) - 0.2 * m[..., None]
    img = body[..., None] * tone + (1 - body[..., None]) * joint
    return img, np.clip(edge / 3, 0, 1), [rot @ np.array([cell, 0.0]), rot @ np.array([0.0, cell])]


def _basket(rng, side, angle, block, strands):
    u, v, rot = _frame(side, angle)
    u, v = u + rng.uniform(0, block), v + rng.uniform(0, block)
    bx, by = np.floor(u / block), np.floor(v / block)
    fx, fy = u - bx * block, v - by * block
    horiz = (bx + by) % 2 == 0
    across = np.where(horiz, fy, fx)
    along = np.where(horiz, fx, fy)
    p = block / strands
    k = np.floor(across / p)
    fa = across - k * p
    strand = np.sin(np.pi * fa / p) * np.clip(np.minimum(along, block - along) / 1.5, 0, 1)
    cell, joint = _palette(rng)
    var = _cell_noise(bx * 7919 + by * 104729 + k * 31, rng, 3)
    img = strand[..., None] * cell * (1 + 0.15 * var) + (1 - strand[..., None]) * joint * 0.5
    t1, t2 = rot @ np.array([block, block]), rot @ np.array([block, -block])
    return img, strand, [t1, t2]


def _ashlar(rng, side, angle, h, mortar):
    u, v, rot = _frame(side, angle)
    v = v + rng.uniform(0, h)
    row = np.floor(v / h)
    cell, joint = _palette(rng)
    # Random block lengths per row: cumulative cuts from a per-row random table.
    lengths = rng.uniform(1.2 * h, 4 * h, (4096, 64))
    cuts = np.cumsum(lengths, axis=1) - side * 2
    r = (row.astype(np.int64) % 4096)
    uu = u
    idx = np.zeros(u.shape, np.int64)
    for j in range(64):
        idx += (uu >= cuts[r, j])
    start = np.where(idx > 0, cuts[r, np.maximum(idx - 1, 0)], -side * 3)
    end = cuts[r, np.minimum(idx, 63)]
    fv = v - row * h
    edge = np.minimum(np.minimum(uu - start, end - uu), np.minimum(fv, h - fv))
    body = np.clip(edge - mortar / 2, 0, 1)
    var = _cell_noise(r * 131 + idx, rng, 3)
    img = body[..., None] * cell * (1 + 0.3 * var) + (1 - body[..., None]) * joint
    return img, np.clip(edge / 2, 0, 1), [rot @ np.array([0.0, h])]


def _stochastic(rng, side):
    kind = int(rng.integers(4))
    cell, joint = _palette(rng)
    ys, xs = np.mgrid[0:side, 0:side].astype(np.float64)
    if kind == 0:  # random stones: a Voronoi diagram of random points
        n = int(rng.integers(40, 200))
        pts = rng.uniform(0, side, (n, 2))
        d = np.full((side, side), np.inf)
        d2 = np.full((side, side), np.inf)
        ids = np.zeros((side, side), np.int64)
        for i, (px, py) in enumerate(pts):
            di = np.hypot(xs - px, ys - py)
            closer = di < d
            d2 = np.where(closer, d, np.minimum(d2, di))
            ids = np.where(closer, i, ids)
            d = np.minimum(d, di)
        body = np.clip((d2 - d) / 2 - 1, 0, 1)
        var = _cell_noise(ids, rng, 3)
        img = body[..., None] * cell * (1 + 0.4 * var) + (1 - body[..., None]) * joint
        return img, body
    if kind == 1:  # random spots
        field = np.zeros((side, side))
        for _ in range(int(rng.integers(60, 300))):
            px, py, r = rng.uniform(0, side), rng.uniform(0, side), rng.uniform(2, 10)
            field = np.maximum(field, np.clip(r - np.hypot(xs - px, ys - py), 0, 1))
        img = field[..., None] * cell + (1 - field[..., None]) * joint
        return img, field
    if kind == 2:  # fibres along one direction, randomly placed
        a = rng.uniform(0, np.pi)
        noise = rng.standard_normal((side, side))
        sig = (rng.uniform(6, 20), rng.uniform(0.7, 2))
        f = ndimage.gaussian_filter(noise, sig, mode="wrap")
        f = ndimage.rotate(f, math.degrees(a), reshape=False, mode="wrap")
        f = (f - f.min()) / (np.ptp(f) + 1e-9)
        return f[..., None] * cell + (1 - f[..., None]) * joint, f
    noise = sum(ndimage.gaussian_filter(rng.standard_normal((side, side)), s, mode="wrap") * s
                for s in (1, 2, 4, 8, 16))  # clouds
    f = (noise - noise.min()) / (np.ptp(noise) + 1e-9)
    return f[..., None] * cell + (1 - f[..., None]) * joint, f


def scene(index: int) -> tuple[np.ndarray, dict]:
    """Scene ``index``: the image (side, side, 3) in [0, 1] and its truth entry
    ({"what", "kind": grid | rows | none, "vectors"}) as in near_regular.json."""
    kinds = [k for k in KINDS for _ in range(PER_KIND)] + ["stochastic"] * PER_KIND
    kind = kinds[index % len(kinds)]
    rng = np.random.default_rng(1_000_003 * index + 17)
    side = int(rng.choice([256, 384, 512]))
    angle = float(rng.choice([0.0, 0.0, 0.0, rng.uniform(-8, 8)]))
    height = None
    vectors: list = []
    if kind == "running_bond":
        h = rng.uniform(8, 28)
        img, height, vectors = _staggered(rng, side, angle, h * rng.uniform(2, 4), h, rng.uniform(1.5, 4))
    elif kind == "shingles":
        h = rng.uniform(10, 30)
        img, height, vectors = _staggered(rng, side, angle, h * rng.uniform(0.8, 2.0), h, rng.uniform(1, 3), True)
    elif kind in ("hex_tiles", "perforated", "diamond_plate"):
        a = rng.uniform(12, 40)
        b = a * math.sqrt(3) / 2 if kind != "diamond_plate" else a * rng.uniform(0.35, 0.8)
        cell, joint = _palette(rng)
        grout = rng.uniform(1.5, 3.5)
        hole = rng.uniform(0.2, 0.4) * a

        def draw(du, dv, cid):
            if kind == "hex_tiles":  # distance to the hexagon's border
                r = a / 2
                hexd = np.maximum(np.abs(du), np.abs(du) * 0.5 + np.abs(dv) * math.sqrt(3) / 2)
                m = np.clip(r - hexd - grout / 2, 0, 1)
                return m, np.clip((r - hexd) / 3, 0, 1)
            if kind == "perforated":
                m = np.clip(np.hypot(du, dv) - hole, 0, 1)  # 1 on the sheet, 0 in the hole
                return m, m
            m = np.clip(1 - np.hypot(du / (0.35 * a), dv / (0.12 * a)), 0, 1)  # a raised lozenge
            return 1 - 0.6 * m, m
        mix, height, vectors = _centred(rng, side, angle, a, b, draw)
        img = mix[..., None] * cell + (1 - mix[..., None]) * joint
    elif kind in ("square_tiles", "diagonal_tiles"):
        cell = rng.uniform(12, 48)
        ang = angle + (45.0 if kind == "diagonal_tiles" else 0.0)
        img, height, vectors = _square(rng, side, ang, cell, rng.uniform(1.5, 4),
                                       str(rng.choice(["cross", "dot", "plain"])))
    elif kind == "basket_weave":
        strands = int(rng.integers(2, 5))
        img, height, vectors = _basket(rng, side, angle, strands * rng.uniform(4, 9), strands)
    elif kind == "ashlar":
        img, height, vectors = _ashlar(rng, side, angle, rng.uniform(12, 40), rng.uniform(1.5, 4))
    else:
        img, height = _stochastic(rng, side)
    entry = {"what": kind, "kind": "none" if kind == "stochastic" else "rows" if kind == "ashlar" else "grid",
             "vectors": [[float(x) for x in t] for t in vectors], "index": index}
    return _photo(rng, img, height), entry


def count() -> int:
    return len(KINDS) * PER_KIND + PER_KIND


def scenes(half: str):
    """(image, entry) for the ``tune`` half (even indices) or the ``held`` half (odd)."""
    start = {"tune": 0, "held": 1}[half]
    for i in range(start, count(), 2):
        yield scene(i)
