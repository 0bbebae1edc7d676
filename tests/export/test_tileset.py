"""Tile sets (infinitex/export/wang.py, tileset.py): corner Wang sets and
variants of one toroidal tile. The composition is checked without GL by
rendering canvas positions as the "coordinates": every pixel then says where
in the canvas it came from, so a seam that continues the texture is one where
neighbours across it come from neighbouring canvas positions."""
from __future__ import annotations

import json
import os
import sys

import numpy as np
import pytest
from PIL import Image

from infinitex.engine.rect import Rect
from infinitex.export.seamcut import before_seam, seam
from infinitex.export.wang import MEND_ROUNDS, TileSetBuilder, TileSetError, TileSetPlan, assemble, corner_packing

sys.path.insert(0, os.path.dirname(os.path.dirname(__file__)))
from clirun import infinitex  # noqa: E402

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
GRAVEL = os.path.join(ROOT, "infinitex", "assets", "gravel.png")


def _noise(m: int = 64, seed: int = 3) -> np.ndarray:
    rng = np.random.default_rng(seed)
    f = np.fft.fft2(rng.standard_normal((m, m, 3)), axes=(0, 1))
    fy, fx = np.fft.fftfreq(m)[:, None], np.fft.fftfreq(m)[None, :]
    f *= np.exp(-(fx ** 2 + fy ** 2) * (m / 8.0) ** 2)[:, :, None]
    img = np.real(np.fft.ifft2(f, axes=(0, 1)))
    return ((img - img.min()) / (img.max() - img.min())).astype(np.float32)


NOISE = _noise()


def _positions(rect):
    """A 'synthesizer' whose coordinates are the canvas positions themselves."""
    y, x = np.mgrid[rect.y0:rect.y1, rect.x0:rect.x1]
    yield
    return np.stack([x, y], axis=-1).astype(np.int32)


def _looks(coords):
    return NOISE[coords[..., 1] % 64, coords[..., 0] % 64]


def _build(plan: TileSetPlan, toroidal=None) -> np.ndarray:
    gen = TileSetBuilder(plan, _positions, _looks, toroidal).build()
    while True:
        try:
            next(gen)
        except StopIteration as stop:
            return stop.value


@pytest.fixture(scope="module")
def corner_set():
    plan = TileSetPlan(2, 64, origin=(-1000, 1 << 30))
    return plan, _build(plan)


def test_packing_holds_every_corner_combination_once():
    for c in (2, 3):
        g = corner_packing(c)
        n = g.shape[0]
        combos = {(g[y, x], g[y, (x + 1) % n], g[(y + 1) % n, x], g[(y + 1) % n, (x + 1) % n])
                  for y in range(n) for x in range(n)}
        assert n == c * c and len(combos) == c ** 4
        tiles = TileSetPlan(c, 64).tiles()
        assert len({(t["nw"], t["ne"], t["sw"], t["se"]) for t in tiles}) == c ** 4
        # the atlas is itself a valid arrangement on a torus: neighbours share corners
        at = {(t["x"] // 64, t["y"] // 64): t for t in tiles}
        for (i, j), t in at.items():
            right, below = at[((i + 1) % n, j)], at[(i, (j + 1) % n)]
            assert (t["ne"], t["se"]) == (right["nw"], right["sw"])
            assert (t["sw"], t["se"]) == (below["nw"], below["ne"])


def test_random_arrangements_are_valid():
    plan = TileSetPlan(3, 64)
    tiles = plan.tiles()
    lay = plan.arrangement(7, 5, seed=4)
    for j in range(5):
        for i in range(6):
            a, b = tiles[lay[j, i]], tiles[lay[j, i + 1]]
            assert (a["ne"], a["se"]) == (b["nw"], b["sw"])
    for j in range(4):
        for i in range(7):
            a, b = tiles[lay[j, i]], tiles[lay[j + 1, i]]
            assert (a["sw"], a["se"]) == (b["nw"], b["ne"])


def test_seam_follows_the_cheapest_path():
    cost = np.ones((30, 12))
    cost[np.arange(30), 3 + np.arange(30) // 6] = 0.0  # a staircase of free pixels
    c = seam(cost)
    assert np.array_equal(c, 3 + np.arange(30) // 6)
    assert before_seam(cost)[0].tolist() == [True] * 3 + [False] * 9


def test_corner_set_edges_continue_the_texture(corner_set):
    """Across every shared edge of a random arrangement, neighbours come from
    neighbouring canvas positions (one piece of texture), but at most where
    the edge strip's two cuts cross the edge line; and the pixels within the
    margin of an edge are the same in every tile with that edge's corners."""
    plan, atlas = corner_set
    n, m = plan.tile, plan.margin
    img = assemble(atlas, plan, plan.arrangement(6, 6, seed=1)).astype(np.int64)
    for axis, step in ((1, (1, 0)), (0, (0, 1))):
        d = np.diff(img, axis=axis)
        edge = np.take(d, np.arange(n - 1, img.shape[axis] - 1, n), axis=axis)
        broken = ~np.all(edge == np.array(step), axis=-1)
        per_edge = broken.reshape(-1) if axis == 0 else broken.T.reshape(-1)
        assert per_edge.reshape(-1, n).sum(axis=1).max() <= 2
    tiles = plan.tiles()

    def tile(t):
        return atlas[t["y"]:t["y"] + n, t["x"]:t["x"] + n]
    for a in tiles:
        for b in tiles:
            if (a["nw"], a["ne"]) == (b["nw"], b["ne"]):
                assert np.array_equal(tile(a)[:m], tile(b)[:m])
            if (a["sw"], a["se"]) == (b["sw"], b["se"]):
                assert np.array_equal(tile(a)[-m:], tile(b)[-m:])
            if (a["nw"], a["sw"]) == (b["nw"], b["sw"]):
                assert np.array_equal(tile(a)[:, :m], tile(b)[:, :m])
            if (a["ne"], a["se"]) == (b["ne"], b["se"]):
                assert np.array_equal(tile(a)[:, -m:], tile(b)[:, -m:])


def test_mending_sees_the_neighbours_and_keeps_the_edges():
    """The mend (the synthesis's correction of a composed tile) is given the
    tile with what its neighbours show around it: across every edge the
    surround continues the canvas positions of the tile's margin (the other
    half of the same strip). Whatever it returns, the margins stay as they
    were, so edges stay exact; inside, its answer is taken."""
    plan = TileSetPlan(2, 64, origin=(300, -5000))
    seen = []

    def scramble(padded, q, origin):
        seen.append((padded.copy(), q))
        return np.full((64, 64, 2), -7, np.int32)
    gen = TileSetBuilder(plan, _positions, _looks, None, scramble).build()
    while True:
        try:
            next(gen)
        except StopIteration as stop:
            atlas = stop.value
            break
    plain = _build(plan)
    n, m = plan.tile, plan.margin
    assert len(seen) == plan.count * MEND_ROUNDS
    seen = seen[MEND_ROUNDS - 1::MEND_ROUNDS]  # each tile's last round (it sees the round before's answer inside)
    ring = np.zeros((n, n), bool)
    ring[:m], ring[-m:], ring[:, :m], ring[:, -m:] = True, True, True, True
    for t, (padded, q) in zip(plan.tiles(), seen):
        mine = atlas[t["y"]:t["y"] + n, t["x"]:t["x"] + n]
        assert np.array_equal(mine[ring], plain[t["y"]:t["y"] + n, t["x"]:t["x"] + n][ring])
        assert np.all(mine[~ring] == -7)
        assert np.array_equal(padded[q:q + n, q:q + n][ring], mine[ring])
        assert MEND_ROUNDS == 1 or np.all(padded[q:q + n, q:q + n][~ring] == -7)  # the round before's answer
        r = m + plan.band  # away from the corners, where strips meet corner windows by a cut
        inner = slice(q + r, q + n - r)
        assert np.all(padded[q - 1, inner] == padded[q, inner] - np.array([0, 1]))      # above the top edge
        assert np.all(padded[q + n, inner] == padded[q + n - 1, inner] + np.array([0, 1]))  # below the bottom
        assert np.all(padded[inner, q - 1] == padded[inner, q] - np.array([1, 0]))      # left of the left edge
        assert np.all(padded[inner, q + n] == padded[inner, q + n - 1] + np.array([1, 0]))  # right


def test_corner_set_interiors_differ(corner_set):
    plan, atlas = corner_set
    n, inner = plan.tile, plan.margin + plan.band
    cores = [atlas[t["y"] + inner:t["y"] + n - inner, t["x"] + inner:t["x"] + n - inner] for t in plan.tiles()]
    for i in range(len(cores)):
        for j in range(i):
            same = np.all(cores[i] == cores[j], axis=-1).mean()
            assert same == 0.0


@pytest.mark.parametrize("colors, tile, variants, torus", [(2, 64, 0, False), (3, 128, 0, False), (1, 64, 5, True),
                                                          (1, 64, 3, False)])
def test_windows_are_made_in_rows_that_never_overlap(colors, tile, variants, torus):
    """The set's windows are made side by side, a row of them per request of
    the synthesis (each request pads its coarse levels once), and no two
    requests reach the same canvas pixel: every window is texture of its own."""
    plan = TileSetPlan(colors, tile, variants, origin=(-77, 1 << 30))
    asked, counted = [], []

    def render(rect):
        asked.append(rect)
        counted.append(b.making)  # the windows this request makes (the progress bar's share of it)
        return (yield from _positions(rect))

    def toroidal():
        yield
        return np.zeros((tile, tile, 2), np.int32)
    b = TileSetBuilder(plan, render, _looks, toroidal if torus else None)
    gen = b.build()
    while True:
        try:
            next(gen)
        except StopIteration:
            break
    windows = (plan.count - 1) * 2 if torus else colors + 2 * colors ** 2 + plan.count * 2
    assert b.work_done == b.work_total == windows + torus and b.making == 0
    assert sum(counted) == windows and min(counted) >= 1
    assert len(asked) <= -(-windows * tile // 2048) + 3 * (not torus)  # rows of up to 2048 px
    for i, a in enumerate(asked):
        assert a.w <= max(2048, 2 * tile) and a.h <= max(2048, 2 * tile)
        for b2 in asked[:i]:
            assert a.intersect(b2).empty


@pytest.mark.parametrize("rel, k", [(Rect(-40, -40, 40, 40), 30), (Rect(0, -3, 1500, 3), 3), (Rect(-5, 0, 5, 64), 7)])
def test_a_row_of_windows_is_windows_side_by_side(rel, k):
    """``_rows``: each window holds the canvas texture at its own place, on a
    lattice point (cell 8 x 4), and no two windows share a pixel."""
    b = TileSetBuilder(TileSetPlan(2, 64, cell=(8, 4), origin=(-3, 11)), _positions, _looks)
    gen = b._rows(rel, k)
    while True:
        try:
            next(gen)
        except StopIteration as stop:
            windows = stop.value
            break
    assert len(windows) == k
    boxes = []
    for coords, (x, y) in windows:
        assert coords.shape == (rel.h, rel.w, 2)
        assert tuple(coords[0, 0]) == (x, y) and tuple(coords[-1, -1]) == (x + rel.w - 1, y + rel.h - 1)
        assert (x - rel.x0) % 8 == 0 and (y - rel.y0) % 4 == 0
        box = Rect(x, y, x + rel.w, y + rel.h)
        assert all(box.intersect(o).empty for o in boxes)
        boxes.append(box)


def test_lattice_windows_keep_the_cell_phase():
    plan = TileSetPlan(2, 64, cell=(16, 8), origin=(37, -5))
    atlas = _build(plan)
    n = plan.tile
    ty, tx = np.mgrid[:atlas.shape[0], :atlas.shape[1]]
    assert np.all((atlas[..., 0] - tx % n) % 16 == 0)
    assert np.all((atlas[..., 1] - ty % n) % 8 == 0)
    with pytest.raises(TileSetError, match="whole number of cells"):
        TileSetPlan(2, 64, cell=(12, 12)).validate()


def test_variants_share_the_toroidal_borders():
    plan = TileSetPlan(1, 64, variants=4, origin=(500, 500))
    y, x = np.mgrid[:64, :64]
    torus = np.stack([x + 9000, y], axis=-1).astype(np.int32)

    def toroidal():
        yield
        return torus
    atlas = _build(plan, toroidal)
    tiles = plan.tiles()
    m = plan.margin
    ring = np.minimum(np.minimum(y, x), np.minimum(63 - y, 63 - x)) < m
    first = atlas[:64, :64]
    assert np.array_equal(first, torus)
    for t in tiles[1:]:
        tile = atlas[t["y"]:t["y"] + 64, t["x"]:t["x"] + 64]
        assert np.array_equal(tile[ring], torus[ring])
        assert (tile[..., 0] < 9000).mean() > 0.3  # a window of its own inside


@pytest.mark.parametrize("args, message", [
    (["--wang", "4"], "2 or 3 corner colours"),
    (["--wang", "2", "--tile", "100"], "tile size"),
    (["--variants", "1"], "2 to 64"),
    (["--wang", "3", "--tile", "1024"], "Mpixel atlas"),
    (["--wang", "2", "--format", "tiff"], "goes with none of"),
    (["--per-tile"], "--per-tile goes with"),
    (["--wang", "1"], "2 or 3 corner colours (--wang 2 or --wang 3), not 1"),
    (["--wang", "0"], "not 0; --variants K"),
    (["--wang", "2", "--direction-map", GRAVEL], "follows no direction field"),
])
def test_cli_refuses_bad_sets(tmp_path, args, message):
    r = infinitex("export", GRAVEL, "-o", tmp_path / "set.png", *args)
    assert r.returncode == 2 and message in r.stderr and not os.listdir(tmp_path), r.stderr


def test_cli_writes_a_corner_set(tmp_path):
    out = tmp_path / "set.png"
    r = infinitex("export", GRAVEL, "-o", out, "--wang", "2", "--tile", "64", "--per-tile", "-q")
    assert r.returncode == 0, r.stderr
    desc = json.loads((tmp_path / "set.json").read_text())
    assert desc["kind"] == "corner-wang" and desc["tile"] == 64 and len(desc["tiles"]) == 16
    atlas = np.asarray(Image.open(out).convert("RGB")).astype(np.float64)
    assert atlas.shape == (256, 256, 3)
    for t in desc["tiles"]:
        own = np.asarray(Image.open(tmp_path / t["files"]["image"]).convert("RGB"))
        assert np.array_equal(own, atlas[t["y"]:t["y"] + 64, t["x"]:t["x"] + 64])
    assert Image.open(tmp_path / desc["preview"]).size == (512, 512)
    # The atlas is a valid arrangement that wraps: its seams (tile edges, and
    # where it repeats) differ no more than neighbours inside tiles.
    wrapped = np.concatenate([atlas, atlas[:, :1]], axis=1)
    d = np.abs(np.diff(wrapped, axis=1)).sum(-1)
    edges = np.zeros(d.shape[1], bool)
    edges[63::64] = True
    assert d[:, edges].mean() <= 1.2 * d[:, ~edges].mean()
    # the same document gives the same bytes
    again = tmp_path / "again"
    again.mkdir()
    r = infinitex("export", GRAVEL, "-o", again / "set.png", "--wang", "2", "--tile", "64", "-q")
    assert r.returncode == 0 and (again / "set.png").read_bytes() == out.read_bytes()


def test_api_set_is_the_command_lines(tmp_path, monkeypatch):
    """The same set from the API (whole requests) and the command line, whose
    requests are cut into steps of STEP_S (here as small as they go: one cut
    draw a step), so its progress bar and Ctrl+C never wait for a whole piece
    (a piece at fidelity 4 took 2-12 s here, past 60 s under load)."""
    import infinitex as itx
    import infinitex.export.tileset as tileset
    monkeypatch.setattr(tileset, "STEP_S", 0.0)
    monkeypatch.setattr(tileset, "PACE_S", 0.0)
    steps, pieces = [], []
    from infinitex.engine.requests import SpreadRequests
    advance, start = tileset.TileSetJob._advance, SpreadRequests.start
    monkeypatch.setattr(tileset.TileSetJob, "_advance", lambda self: steps.append(1) or advance(self))
    monkeypatch.setattr(SpreadRequests, "start", lambda self, *a: pieces.append(1) or start(self, *a))
    r = infinitex("export", GRAVEL, "-o", tmp_path / "set.png", "--variants", "3", "--tile", "64", "-q")
    assert r.returncode == 0, r.stderr
    assert pieces and len(steps) > 8 * len(pieces), (len(steps), len(pieces))  # several steps a piece
    atlas, desc = itx.tile_set(GRAVEL, colors=1, n=64, variants=3)
    assert np.array_equal(atlas[..., 0], np.asarray(Image.open(tmp_path / "set.png")))  # gravel is grey
    assert desc["tiles"] == json.loads((tmp_path / "set.json").read_text())["tiles"]
    shown = itx.arrange(atlas, desc, 3, 2, seed=2)
    assert shown.shape == (128, 192, 1)


def test_cli_never_writes_over_its_exemplar(tmp_path):
    import shutil
    src = tmp_path / "set_preview.png"
    shutil.copy(GRAVEL, src)
    r = infinitex("export", src, "-o", tmp_path / "set.png", "--wang", "2", "--tile", "64")
    assert r.returncode != 0 and "input of this export" in r.stderr
    assert sorted(os.listdir(tmp_path)) == ["set_preview.png"]
