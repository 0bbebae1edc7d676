"""Tile sets for game engines: corner Wang tiles (Lagae and Dutre 2006) and
edge-compatible variants of one toroidal tile, composed from windows of the
document's infinite texture.

How the tiles agree exactly. Every pixel of a tile within ``margin`` of an
edge is a function of that edge's two corner colours only, so any two tiles
that share the edge's corners show the same pixels on both sides of it:

- each corner colour c has a *corner window* K_c, a square of the texture
  centred on the corner point; the four tiles round a corner of colour c take
  its four quarters, so the texture runs on across the corner;
- each edge (its two corner colours and its direction) has an *edge strip*, a
  band of the texture centred on the edge line and as long as the edge: the
  corner windows of its two ends at its ends, an *edge window* E in between,
  joined by least-cost cuts (``seamcut``) in bands just outside the corner
  squares. The strip is made once per edge key, and the tile above an edge
  takes its upper half, the tile below its lower half: across the edge the
  pixels are one continuous piece of texture;
- the tile's interior is a window of its own, joined to its four strips by a
  least-cost cut inside the tile, in a ring between ``margin`` and
  ``margin + band`` from the edges: of CANDIDATES windows, the one whose cut
  costs least (image quilting's choice of the block that agrees with its
  overlap). The cut never reaches the margin, so the edges stay exact, and
  every tile's interior differs;
- the composed tile is then *mended*: the finest level's correction of the
  synthesis runs on it (with what its neighbours show around it), so the
  texture on both sides of a cut is re-matched to the exemplar as the
  synthesis matches its own seams; the pixels within the margin are kept.

Variants (``colors == 1``): K tiles that share the borders of one toroidal
tile (the synthesis's own, LH05 6) and differ inside; tile 0 is the toroidal
tile itself, the others take its ring and a window of their own inside.

The composition works on exemplar coordinates, so every map of a material gets
the same set, and the cuts are chosen on the first map's colours. With a
lattice, every window starts on a lattice point and the tile is a whole
number of cells, so grid lines run on across cuts and edges."""
from __future__ import annotations

from collections.abc import Callable, Iterator
from dataclasses import dataclass
from functools import cached_property

import numpy as np

from infinitex.engine.rect import Rect

from .seamcut import before_seam, before_seam_and_cost, seam_cost

WANG_SIZES = (64, 128, 256, 512, 1024, 2048)
WANG_COLORS = (2, 3)
MAX_VARIANTS = 64
MAX_SET_PIXELS = 64 * 1024 * 1024   # the atlas is made in memory, like a window export
CANDIDATES = 2                       # interior windows tried per tile: the one whose cuts cost least is kept
BATCH_WIDTH = 2048                   # windows are made side by side in rows of at most this many px
ROW_GAP = 8                          # px of canvas between two rows of windows
MEND_PAD = 16                        # px of neighbours' texture around a tile when its cuts are mended
MEND_ROUNDS = 2                      # the mend run again on its result (cuts 2-6% closer to the synthesis's seams)

# Corner colours on the points of a C^2 x C^2 torus in which every 2 x 2
# combination appears once (a de Bruijn torus): the atlas laid out by it is
# itself a valid arrangement, so it tiles, and a sampler filtering across an
# atlas tile's border reads a valid neighbour.
_PACKING_2 = ((1, 1, 1, 0), (1, 1, 0, 1), (0, 1, 0, 0), (1, 0, 0, 0))
_DE_BRUIJN_3 = (0, 0, 1, 0, 2, 1, 1, 2, 2)  # every pair of 0..2 once, cyclically


class TileSetError(ValueError):
    """A tile set that cannot be made as asked (one sentence)."""


def corner_packing(colors: int) -> np.ndarray:
    """(C^2, C^2) int array: the corner colour of each point of the packing torus."""
    if colors == 2:
        return np.array(_PACKING_2, np.int64)
    if colors == 3:  # rows of one de Bruijn sequence shifted by y(y-1)/2: all 9 shifts differ
        return np.array([[_DE_BRUIJN_3[(x + y * (y - 1) // 2) % 9] for x in range(9)] for y in range(9)], np.int64)
    raise TileSetError(f"A corner Wang set has 2 or 3 corner colours, not {colors}.")


@dataclass(frozen=True)
class TileSetPlan:
    """What a set is: ``colors`` corner colours (1: ``variants`` variants of
    one toroidal tile), tiles of ``tile`` px; ``cell``: the lattice cell the
    windows align to ((1, 1) without a lattice); ``origin``: where the windows
    are taken from in the canvas."""

    colors: int
    tile: int
    variants: int = 0
    cell: tuple[int, int] = (1, 1)
    origin: tuple[int, int] = (0, 0)

    def validate(self) -> None:
        n = self.tile
        if n not in WANG_SIZES:
            raise TileSetError(f"A tile set's tile size is one of {', '.join(map(str, WANG_SIZES))} px, not {n}.")
        if self.colors == 1:
            if not 2 <= self.variants <= MAX_VARIANTS:
                raise TileSetError(f"Variants of one tile: 2 to {MAX_VARIANTS}, not {self.variants}.")
        elif self.colors not in WANG_COLORS:
            raise TileSetError(f"A corner Wang set has 2 or 3 corner colours, not {self.colors}.")
        cx, cy = self.cell
        if n % cx or n % cy:
            raise TileSetError(f"With a lattice the tile is a whole number of cells ({cx}x{cy} px): "
                               f"{n} px is not; use a tile size the cell divides.")
        if self.count * n * n > MAX_SET_PIXELS:
            raise TileSetError(f"{self.count} tiles of {n} px make a {self.count * n * n // 2**20} Mpixel atlas, "
                               f"more than the {MAX_SET_PIXELS // 2**20} allowed; use smaller tiles.")

    @property
    def count(self) -> int:
        return self.variants if self.colors == 1 else self.colors ** 4

    @property
    def margin(self) -> int:
        """Pixels from an edge that depend on the edge's key alone."""
        return max(2, self.tile // 32)

    @property
    def band(self) -> int:
        """Width of the bands the cuts run in: 3N/16 in a corner set (room to go
        round large elements: N/8 cut pebbles and caustics' lines more, N/4
        showed the shared frames more often, bench.tileset); N/8 for variants,
        whose whole ring is the one toroidal tile's."""
        return self.tile // 8 if self.colors == 1 else self.tile * 3 // 16

    @property
    def grid(self) -> tuple[int, int]:
        """The atlas's (columns, rows)."""
        if self.colors > 1:
            return self.colors ** 2, self.colors ** 2
        cols = int(np.ceil(np.sqrt(self.variants)))
        return cols, -(-self.variants // cols)

    def tiles(self) -> list[dict]:
        """Each tile in atlas order: its corner colours (``nw``, ``ne``, ``sw``,
        ``se``; all 0 for variants, with ``variant``) and atlas position."""
        n = self.tile
        cols, _ = self.grid
        if self.colors == 1:
            return [{"variant": k, "nw": 0, "ne": 0, "sw": 0, "se": 0, "x": (k % cols) * n, "y": (k // cols) * n}
                    for k in range(self.variants)]
        g = corner_packing(self.colors)
        m = g.shape[0]
        return [{"nw": int(g[j, i]), "ne": int(g[j, (i + 1) % m]), "sw": int(g[(j + 1) % m, i]),
                 "se": int(g[(j + 1) % m, (i + 1) % m]), "x": i * n, "y": j * n}
                for j in range(m) for i in range(m)]

    def arrangement(self, cols: int, rows: int, seed: int = 0) -> np.ndarray:
        """(rows, cols) atlas indices of a random valid arrangement (corner
        colours drawn at random on the grid points; variants drawn at random)."""
        rng = np.random.default_rng(seed)
        if self.colors == 1:
            return rng.integers(0, self.variants, size=(rows, cols))
        corners = rng.integers(0, self.colors, size=(rows + 1, cols + 1))
        index = {(t["nw"], t["ne"], t["sw"], t["se"]): i for i, t in enumerate(self.tiles())}
        return np.array([[index[(corners[j, i], corners[j, i + 1], corners[j + 1, i], corners[j + 1, i + 1])]
                          for i in range(cols)] for j in range(rows)])


def assemble(atlas: np.ndarray, plan: TileSetPlan, layout: np.ndarray) -> np.ndarray:
    """The image of an arrangement (``layout``: atlas indices) cut from an atlas."""
    n = plan.tile
    tiles = plan.tiles()
    rows, cols = layout.shape
    out = np.empty((rows * n, cols * n) + atlas.shape[2:], atlas.dtype)
    for j in range(rows):
        for i in range(cols):
            t = tiles[int(layout[j, i])]
            out[j * n:(j + 1) * n, i * n:(i + 1) * n] = atlas[t["y"]:t["y"] + n, t["x"]:t["x"] + n]
    return out


def _up(v: int, k: int) -> int:
    return -(-v // k) * k


Render = Callable[[Rect], Iterator]          # a generator: yields while working, returns coordinates
Appearance = Callable[[np.ndarray], np.ndarray]  # coordinates -> float colours (the cuts' cost)


class TileSetBuilder:
    """Makes a set's tile coordinates. ``build()`` is a generator (it yields
    between pieces of work, so the editor can spread it over frames) that
    returns the atlas's coordinates (rows*N, cols*N, 2) int32. ``render(rect)``
    is a generator returning the canvas coordinates of a rectangle;
    ``toroidal()`` one returning the N x N toroidal tile (variants only)."""

    def __init__(self, plan: TileSetPlan, render: Render, appearance: Appearance,
                 toroidal: Callable[[], Iterator] | None = None, correct=None):
        plan.validate()
        self.plan, self.render, self.appearance, self.toroidal = plan, render, appearance, toroidal
        self.correct = correct  # correct(padded coords, pad, origin) -> the tile's corrected coords, or None
        self.reach = plan.margin + plan.band           # a corner window's half side, a strip's half width
        self._below = plan.origin[1]                   # the canvas rows below this one are free
        self._inner: list[tuple[np.ndarray, tuple[int, int]]] = []  # interior windows made, not yet tried
        self._inner_left = 0        # interior windows still to be made (set by build)
        self.work_total = 1
        self.work_done = 0          # windows made
        self.making = 0             # windows in the request being made (its progress counts for them)

    @cached_property
    def _grid(self) -> tuple[np.ndarray, ...]:
        """A tile's pixel rows y, columns x, distances to the nearer side
        edge, to the nearer top or bottom edge, and to the nearest edge."""
        n = self.plan.tile
        y, x = np.mgrid[:n, :n]
        lr, tb = np.minimum(x, n - 1 - x), np.minimum(y, n - 1 - y)
        return y, x, lr, tb, np.minimum(lr, tb)

    # -- windows of the canvas ---------------------------------------------------

    def _row(self, rel: Rect, k: int) -> Iterator:
        """k new windows of the canvas, side by side in a row of their own, made
        by one request (its coarse levels shared, not padded again per window:
        a 512 px window alone costs 1.7x what it does as a quarter of a
        2048 x 512 one); ``rel``: a window relative to its reference point,
        which sits on a lattice point. Returns [(coordinates, the window's
        canvas place)]."""
        (cx, cy), (x0, _) = self.plan.cell, self.plan.origin
        step = _up(rel.w, cx)
        ox = x0 - rel.x0
        oy = self._below - rel.y0
        ox, oy = ox + (-ox) % cx, oy + (-oy) % cy
        self._below = oy + rel.y1 + ROW_GAP
        self.making = k
        row = yield from self.render(Rect(ox + rel.x0, oy + rel.y0, ox + rel.x0 + (k - 1) * step + rel.w, oy + rel.y1))
        self.work_done += k
        self.making = 0
        return [(row[:, i * step:i * step + rel.w], (ox + rel.x0 + i * step, oy + rel.y0)) for i in range(k)]

    def _per_row(self, w: int) -> int:
        """How many windows w px wide a row holds (at least one)."""
        return max(1, BATCH_WIDTH // _up(w, self.plan.cell[0]))

    def _rows(self, rel: Rect, k: int) -> Iterator:
        """k windows as ``_row``'s, in rows of at most BATCH_WIDTH px."""
        per = self._per_row(rel.w)
        out = []
        for i in range(0, k, per):
            out += yield from self._row(rel, min(per, k - i))
        return out

    def _interior_window(self) -> Iterator:
        """The next interior window and its canvas place, made in rows (a row
        at a time, as the tiles need them)."""
        if not self._inner:
            n = self.plan.tile
            k = min(self._inner_left, self._per_row(n))
            self._inner = yield from self._row(Rect(0, 0, n, n), k)
            self._inner_left -= k
        return self._inner.pop(0)

    def _before(self, a: np.ndarray, b: np.ndarray) -> np.ndarray:
        """Pixels before the least-cost seam across a band (L, W) between
        coordinate images a and b (they take a)."""
        return before_seam(seam_cost(self.appearance(a), self.appearance(b)))

    # -- the set -------------------------------------------------------------------

    def build(self) -> Iterator:
        p = self.plan
        n = p.tile
        if p.colors == 1 and self.toroidal is not None:
            self.work_total = 1 + (p.variants - 1) * CANDIDATES
            self._inner_left = (p.variants - 1) * CANDIDATES
            frame = yield from self.toroidal()
            self.work_done += 1
            tiles = [frame]
            for _ in range(1, p.variants):
                tile, place = yield from self._interior(frame)
                tiles.append(self._mend(tile, place, lambda t, q: np.pad(t, ((q, q), (q, q), (0, 0)), mode="wrap")))
        else:
            c = p.colors
            self.work_total = c + 2 * c * c + p.count * CANDIDATES
            self._inner_left = p.count * CANDIDATES
            r = self.reach
            corners = [k for k, _ in (yield from self._rows(Rect(-r, -r, r, r), c))]
            pairs = [(a, b) for a in range(c) for b in range(c)]
            strips = {}
            for vertical, rel in ((False, Rect(0, -r, n, r)), (True, Rect(-r, 0, r, n))):
                edges = yield from self._rows(rel, len(pairs))
                for (a, b), (e, _) in zip(pairs, edges):
                    strips["hv"[vertical], a, b] = self._strip(corners[a], corners[b], e, vertical)
                    yield
                del edges, e  # (the strips are copies)
            tiles = []
            for t in p.tiles():
                frame = self._frame(strips, t["nw"], t["ne"], t["sw"], t["se"])
                tile, place = yield from self._interior(frame)
                tiles.append(self._mend(tile, place, lambda tl, q, t=t: self._surround(tl, q, strips, corners, t)))
        cols, rows = p.grid
        atlas = np.zeros((rows * n, cols * n, tiles[0].shape[2]), np.int32)
        for t, coords in zip(p.tiles(), tiles):
            atlas[t["y"]:t["y"] + n, t["x"]:t["x"] + n] = coords
        return atlas

    def _surround(self, tile: np.ndarray, q: int, strips: dict, corners: list, t: dict) -> np.ndarray:
        """The tile with q px around it as any neighbour shows them near the
        shared edge: the other halves of its strips, the corner windows."""
        n, r = self.plan.tile, self.reach
        out = np.zeros((n + 2 * q, n + 2 * q, tile.shape[2]), tile.dtype)
        out[q:q + n, q:q + n] = tile
        out[:q, q:q + n] = strips["h", t["nw"], t["ne"]][r - q:r]
        out[q + n:, q:q + n] = strips["h", t["sw"], t["se"]][r:r + q]
        out[q:q + n, :q] = strips["v", t["nw"], t["sw"]][:, r - q:r]
        out[q:q + n, q + n:] = strips["v", t["ne"], t["se"]][:, r:r + q]
        out[:q, :q] = corners[t["nw"]][r - q:r, r - q:r]
        out[:q, q + n:] = corners[t["ne"]][r - q:r, r:r + q]
        out[q + n:, :q] = corners[t["sw"]][r:r + q, r - q:r]
        out[q + n:, q + n:] = corners[t["se"]][r:r + q, r:r + q]
        return out

    def _mend(self, tile: np.ndarray, place: tuple[int, int], surround) -> np.ndarray:
        """The tile's cuts mended by the synthesis's own correction (MEND_ROUNDS
        times, each on the last one's result), run on the tile as composed (with what neighbours show around it) at its
        interior window's canvas place (where that window was synthesized, so
        the controls painted there apply alike); pixels within the margin of
        an edge stay as they are, so edges stay exact."""
        if self.correct is None:
            return tile
        q = min(MEND_PAD, self.reach)
        fixed = self._grid[4] < self.plan.margin
        out = tile.copy()
        for _ in range(MEND_ROUNDS):
            mended = self.correct(surround(out, q)[..., :2], q, place)
            out[..., :2] = np.where(fixed[..., None], tile[..., :2], mended)
        return out

    def _strip(self, ka: np.ndarray, kb: np.ndarray, e: np.ndarray, vertical: bool) -> np.ndarray:
        """The strip of an edge whose first corner (left, or top) has window
        ``ka``, second ``kb`` and edge window ``e``: (2 * reach, N) coordinates
        (transposed when ``vertical``), the edge line between rows reach - 1
        and reach."""
        n, m, r = self.plan.tile, self.plan.margin, self.reach
        if vertical:
            ka, kb, e = ka.swapaxes(0, 1), kb.swapaxes(0, 1), e.swapaxes(0, 1)
        strip = e.copy()
        # left end: the corner's columns < margin, a seam in [margin, reach - 1), then E
        band = slice(m, r - 1)
        take = self._before(ka[:, r:][:, band], e[:, band])
        strip[:, :m] = ka[:, r:r + m]
        strip[:, band] = np.where(take[..., None], ka[:, r:][:, band], e[:, band])
        # right end, mirrored: E up to column n - r, a seam, the corner's from n - margin
        band = slice(n - r + 1, n - m)
        take = self._before(e[:, band], kb[:, :r][:, 1:r - m])
        strip[:, band] = np.where(take[..., None], e[:, band], kb[:, 1:r - m])
        strip[:, n - m:] = kb[:, r - m:r]
        return strip.swapaxes(0, 1) if vertical else strip

    def _frame(self, strips: dict, nw: int, ne: int, sw: int, se: int) -> np.ndarray:
        """A tile's coordinates within reach of its edges, from its four strips
        (the interior is ``_interior``'s). A pixel within the margin of an
        edge comes from that edge's strip (in a corner square both strips hold
        the corner window there); ring pixels from the nearer edge's."""
        n, m, r = self.plan.tile, self.plan.margin, self.reach
        top, bottom = strips["h", nw, ne][r:], strips["h", sw, se][:r]
        left, right = strips["v", nw, sw][:, r:], strips["v", ne, se][:, :r]
        y, x, lr, tb, _ = self._grid
        use_v = (lr < m) | ((lr < r) & (lr < tb) & (tb >= m))
        use_h = ~use_v & (tb < r)
        out = np.zeros((n, n, top.shape[2]), np.int32)
        for mask, rows, cols, src in ((use_h & (y < r), slice(0, r), slice(None), top),
                                      (use_h & (y >= n - r), slice(n - r, n), slice(None), bottom),
                                      (use_v & (x < r), slice(None), slice(0, r), left),
                                      (use_v & (x >= n - r), slice(None), slice(n - r, n), right)):
            region = out[rows, cols]
            sel = mask[rows, cols]
            region[sel] = src[sel]
        return out

    def _interior(self, frame: np.ndarray) -> Iterator:
        """A tile from its frame and an interior window of its own, joined by a
        least-cost cut in the ring between margin and margin + band: of
        CANDIDATES windows, the one whose four cuts cost least (image
        quilting's choice of the block that agrees with its overlap).
        Returns (the tile, its interior window's canvas place)."""
        n, m, bw = self.plan.tile, self.plan.margin, self.plan.band
        y, x, _, _, d = self._grid
        ring = d < m + bw
        fl = self.appearance(frame[ring][None])[0]
        fa = np.zeros((n, n, fl.shape[-1]), np.float32)
        fa[ring] = fl
        # one seam along each side, from the frame (before it) to the interior:
        # the frame is what any side's seam leaves outside, so the four close
        across = np.arange(m, m + bw)
        bands = [np.broadcast_arrays(rows, cols) for rows, cols in (
            (across[None, :], x[0][:, None]),              # top: along x, down
            (n - 1 - across[None, :], x[0][:, None]),      # bottom: up
            (y[:, 0][:, None], across[None, :]),           # left: along y, right
            (y[:, 0][:, None], n - 1 - across[None, :]))]  # right: leftwards
        best = None
        for _ in range(CANDIDATES):
            inner, place = yield from self._interior_window()
            ia = np.zeros_like(fa)
            ia[ring] = self.appearance(inner[ring][None])[0]
            side = d < m
            total = 0.0
            for rr, cc in bands:
                take, cost = before_seam_and_cost(seam_cost(fa[rr, cc], ia[rr, cc]))
                side[rr[take], cc[take]] = True
                total += cost
            if best is None or total < best[0]:
                best = (total, np.where(side[..., None], frame, inner), place)
            yield
        return best[1], best[2]  # the tile, and where it is mended: its interior's own place
