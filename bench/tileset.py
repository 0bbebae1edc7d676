"""Tile sets for game engines (corner Wang sets, variants of one tile):
seams, repetition and speed.

    python -m bench.tileset [--json OUT.json] [--figure OUT.png] [--quick]

For each exemplar, a corner Wang set of 2 and of 3 colours (tiles of 128 px)
and 8 variants of one toroidal tile:

- seams: in a random 8 x 8 arrangement, the neighbourhood distance to the
  exemplar of 5 x 5 neighbourhoods straddling tile edges over those inside
  tiles (1.0 = edges look like the inside; target <= 1.2), and the mean colour
  difference of neighbouring pixels across edges over inside (the surface
  seams' measure; a lattice's lines falling on the edges raise it);
- repetition: the highest autocorrelation of a random 16 x 16 arrangement's
  luminance at shifts of a tile (128 px) or more (bench/streaks.py's measure,
  raw and blurred 6 px), against the exemplar's own at shifts of 32 px or more
  (streaks; target: at most the exemplar's own), our infinite texture's over
  the same area and one toroidal tile repeated 16 x 16;
- cuts: the neighbourhood distance of neighbourhoods that hold a cut (where
  two windows of the texture meet) over those that hold only a seam of the
  synthesis itself (1.0: the cuts hide as well as the synthesis's seams);
- the largest share of identical coordinates between two tiles' interiors
  (0 = no exact repeat of a tile's inside in another).

And the time of a 16-tile set of 512 px tiles written to disk at Balanced
(target: under 30 s on the 2-core machine). Prints a table, writes JSON and a
figure (the atlas | 8 x 8 tiles at random | one toroidal tile repeated 8 x 8).
"""
from __future__ import annotations

import argparse
import json
import os
import sys
import tempfile
import time

import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, ROOT)
SHARED = os.path.join(os.path.dirname(ROOT), "shared", "exemplars")

from bench.measures import PATCH, PCA_DIMS, _chan, _patches, autocorrelation  # noqa: E402
from bench.streaks import luminance, peak  # noqa: E402
from infinitex.engine.gpu import Gpu  # noqa: E402
from infinitex.engine.imagefile import to_u8, write_png  # noqa: E402
from infinitex.engine.pyramid import Rect  # noqa: E402
from infinitex.engine.safeio import atomic_write  # noqa: E402
from infinitex.export.loaded import LoadedDocument  # noqa: E402
from infinitex.export.tileset import Mender, TileSetJob, plan_for  # noqa: E402
from infinitex.export.wang import TileSetBuilder, assemble  # noqa: E402
from infinitex.project import Document, ExemplarSource  # noqa: E402

EXEMPLARS = [os.path.join(ROOT, "infinitex", "assets", "gravel.png")] + [
    os.path.join(SHARED, n) for n in ("pebbles.png", "granite.png", "caustics.png", "grass.png", "brick.png")]
N = 128


def seam_ratio(img: np.ndarray, n: int) -> float:
    img = img.astype(np.float64)
    dx = np.abs(np.diff(img, axis=1)).sum(-1)
    dy = np.abs(np.diff(img, axis=0)).sum(-1)
    ex = np.zeros(dx.shape[1], bool)
    ex[n - 1::n] = True
    ey = np.zeros(dy.shape[0], bool)
    ey[n - 1::n] = True
    across = np.concatenate([dx[:, ex].ravel(), dy[ey].ravel()])
    inside = np.concatenate([dx[:, ~ex].ravel(), dy[~ey].ravel()])
    return float(across.mean() / inside.mean())


def _energy_ratio(exemplar, img, first: np.ndarray, second: np.ndarray, periodic: bool, samples: int) -> float:
    """Mean squared distance of 5 x 5 neighbourhoods (given by their top-left
    corners: masks over the valid positions) to their nearest exemplar
    neighbourhood (matched in the leading PCA dimensions, as
    bench.measures.neighborhood_energy): the first set's over the second's."""
    from scipy.spatial import cKDTree
    ex, out = _chan(exemplar), _chan(img)
    if periodic:
        ex = np.pad(ex, ((0, PATCH - 1), (0, PATCH - 1), (0, 0)), mode="wrap")
    pe = _patches(ex)
    rng = np.random.default_rng(0)
    mean = pe.mean(axis=0)
    basis = np.linalg.svd(pe - mean, full_matrices=False)[2][:PCA_DIMS].T
    tree = cKDTree((pe - mean) @ basis)
    win = np.lib.stride_tricks.sliding_window_view(out, (PATCH, PATCH), axis=(0, 1))
    energies = []
    for mask in (first, second):
        ys, xs = np.nonzero(mask)
        pick = rng.choice(len(ys), min(samples, len(ys)), replace=False)
        po = win[ys[pick], xs[pick]].reshape(len(pick), -1)
        _, j = tree.query((po - mean) @ basis, workers=-1)
        energies.append(np.mean(np.sum((po - pe[j]) ** 2, axis=1)))
    return float(energies[0] / energies[1])


def seam_energy(exemplar: np.ndarray, img: np.ndarray, n: int, periodic: bool, samples: int = 4000) -> float:
    """Neighbourhood distance across tile edges over inside tiles: 5 x 5
    neighbourhoods that straddle a tile edge over those that do not (1.0:
    edges look like the inside, whatever the texture's own structure at the
    edges' phase)."""
    h, w = img.shape[0] - PATCH + 1, img.shape[1] - PATCH + 1
    cy, cx = np.mgrid[:h, :w] + PATCH // 2  # the patches' centres
    near = lambda c: np.minimum(c % n, n - 1 - c % n) < PATCH // 2  # noqa: E731 - straddles an edge line
    edge = near(cy) | near(cx)
    return _energy_ratio(exemplar, img, edge, ~edge, periodic, samples)


def tile_peak(y: np.ndarray, n: int, blur: float = 0.0) -> float:
    """Highest autocorrelation at shifts of ``n`` px or more (up to a quarter of the image)."""
    if blur:
        from scipy import ndimage
        y = ndimage.gaussian_filter(y, blur, mode="reflect")
    ac, dy, dx = autocorrelation(y)
    lim = min(y.shape) // 4
    ok = (np.maximum(np.abs(dx), np.abs(dy)) >= n) & (np.abs(dx) <= lim) & (np.abs(dy) <= lim)
    return float(ac[ok].max())


def interior_repeat(job: TileSetJob) -> float:
    p = job.plan
    n, k = p.tile, p.margin + p.band
    cores = [job.atlas[t["y"] + k:t["y"] + n - k, t["x"] + k:t["x"] + n - k] for t in p.tiles()]
    worst = 0.0
    for i in range(len(cores)):
        for j in range(i):
            worst = max(worst, float(np.all(cores[i] == cores[j], axis=-1).mean()))
    return worst


def build(session: LoadedDocument, colors: int, n: int, variants: int = 0) -> tuple[TileSetJob, float]:
    t = time.perf_counter()
    job = TileSetJob(session, plan_for(session, colors, n, variants))
    job.run()
    return job, time.perf_counter() - t


def traced(session: LoadedDocument, colors: int, n: int, variants: int = 0) -> np.ndarray:
    """The set's atlas of exemplar coordinates and canvas positions (where
    each pixel was taken from), (H, W, 4), made as the job makes it (the same
    cuts: they read the same colours)."""
    synth = session.synth
    plan = plan_for(session, colors, n, variants)

    def render(rect):
        yield
        y, x = np.mgrid[rect.y0:rect.y1, rect.x0:rect.x1]
        return np.concatenate([synth.window(rect, remainder=False), np.stack([x, y], -1)], axis=-1).astype(np.int32)

    def toroidal():
        yield
        y, x = np.mgrid[:n, :n]
        return np.concatenate([synth.toroidal(n)[..., :2], np.stack([x - 10 ** 6, y], -1)], axis=-1).astype(np.int32)
    mender = Mender(synth, session.analysis.L, n if variants else 0)
    work = TileSetBuilder(plan, render, lambda c: synth.colors(c[..., :2]), toroidal, mender).build()
    try:
        while True:
            try:
                next(work)
            except StopIteration as stop:
                return stop.value
    finally:
        mender.release()


def _breaks(field: np.ndarray) -> np.ndarray:
    """Pixels next to a neighbour whose value is not one step on (x + 1 to the
    right, y + 1 below)."""
    brk = np.zeros(field.shape[:2], bool)
    dx = np.any(np.diff(field, axis=1) != np.array([1, 0]), axis=-1)
    dy = np.any(np.diff(field, axis=0) != np.array([0, 1]), axis=-1)
    brk[:, :-1] |= dx
    brk[:, 1:] |= dx
    brk[:-1] |= dy
    brk[1:] |= dy
    return brk


def cut_energy(exemplar: np.ndarray, img: np.ndarray, traced_coords: np.ndarray, periodic: bool,
               samples: int = 4000) -> float:
    """How well the cuts hide, against the synthesis's own seams: the
    neighbourhood distance (as seam_energy) of 5 x 5 neighbourhoods that hold
    a cut (neighbours taken from places of the canvas that are not neighbours)
    over those that hold none but a seam of the synthesis itself (neighbours
    from places of the exemplar that are not neighbours)."""
    from scipy import ndimage

    def holding(brk):
        return ndimage.maximum_filter(brk, size=PATCH)[PATCH // 2:-(PATCH // 2), PATCH // 2:-(PATCH // 2)]
    cut = holding(_breaks(traced_coords[..., 2:]))
    own = holding(_breaks(traced_coords[..., :2])) & ~cut
    return _energy_ratio(exemplar, img, cut, own, periodic, samples)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--json", metavar="OUT.json")
    ap.add_argument("--figure", metavar="OUT.png")
    ap.add_argument("--quick", action="store_true", help="gravel and pebbles only, no timing case")
    a = ap.parse_args(argv)
    exemplars = [e for e in EXEMPLARS if os.path.exists(e)][:2 if a.quick else None]
    gpu = Gpu()
    rows, shots = [], []
    print(f"tiles of {N} px; seams (neighbourhoods / colour steps, edge over inside): 8 x 8 tiles at random; "
          f"repetition: 16 x 16, shifts >= {N} px (raw / blurred 6 px); cuts: neighbourhoods holding a cut "
          "over those holding a seam of the synthesis")
    print(f"{'exemplar':10s} {'set':10s} {'time':>6s} {'seams':>10s} {'cuts':>5s} {'repeat':>13s} {'exemplar':>13s} "
          f"{'infinite':>13s} {'one tile':>13s} {'inside same':>11s}")
    for path in exemplars:
        name = os.path.splitext(os.path.basename(path))[0]
        session = LoadedDocument(gpu)
        session.load_now(Document(ExemplarSource.from_file(path)))
        ex = session.exemplar
        own = (peak(luminance(ex.pixels), ex.toroidal)[0], peak(luminance(ex.pixels), ex.toroidal, 6.0)[0])
        side = 16 * N
        inf = luminance(session.synth.colors(session.synth.window(Rect(10007, -20011, 10007 + side, -20011 + side))))
        infinite = (tile_peak(inf, N), tile_peak(inf, N, 6.0))
        torus = session.synth.colors(session.synth.toroidal(N))
        rep = luminance(np.tile(torus, (16, 16, 1)))
        one = (tile_peak(rep, N), tile_peak(rep, N, 6.0))
        for label, colors, variants in (("wang C=2", 2, 0), ("wang C=3", 3, 0), ("variants 8", 1, 8)):
            job, el = build(session, colors, N, variants)
            px = job.map_pixels(session.material.primary)
            plan = job.plan
            shown = assemble(px, plan, plan.arrangement(8, 8, seed=1))
            seams = seam_ratio(shown, N)
            nbhd = seam_energy(ex.pixels, shown, N, ex.toroidal)
            pos = assemble(traced(session, colors, N, variants), plan, plan.arrangement(8, 8, seed=1))
            cuts = cut_energy(ex.pixels, shown, pos, ex.toroidal)
            y = luminance(assemble(px, plan, plan.arrangement(16, 16, seed=2)))
            repeat = (tile_peak(y, N), tile_peak(y, N, 6.0))
            same = interior_repeat(job)
            row = {"exemplar": name, "set": label, "tile": N, "time_s": round(el, 2), "seams": round(seams, 3),
                   "seam_neighbourhoods": round(nbhd, 3), "cut_neighbourhoods": round(cuts, 3),
                   "repeat": [round(v, 3) for v in repeat], "exemplar_own": [round(v, 3) for v in own],
                   "infinite": [round(v, 3) for v in infinite], "one_tile": [round(v, 3) for v in one],
                   "interior_same": same}
            rows.append(row)
            print(f"{name:10s} {label:10s} {el:5.1f}s {nbhd:5.2f}/{seams:4.2f} {cuts:5.2f} {repeat[0]:6.3f}/{repeat[1]:.3f} "
                  f"{own[0]:6.3f}/{own[1]:.3f} {infinite[0]:6.3f}/{infinite[1]:.3f} {one[0]:6.3f}/{one[1]:.3f} "
                  f"{same:11.3f}")
            if colors == 2 and len(shots) < 3:
                shots.append((px, assemble(px, plan, plan.arrangement(8, 8, seed=1)), np.tile(torus, (8, 8, 1))))
        session.release()
    timing = None
    if not a.quick:
        session = LoadedDocument(gpu)
        session.load_now(Document(ExemplarSource.from_file(EXEMPLARS[0])))
        with tempfile.TemporaryDirectory() as tmp:
            t = time.perf_counter()
            job = TileSetJob(session, plan_for(session, 2, 512), os.path.join(tmp, "set.png"))
            job.run()
            timing = time.perf_counter() - t
        session.release()
        print(f"\n16 tiles of 512 px (gravel, Balanced), made and written: {timing:.1f} s (target < 30 s)")
    print(f"\nseams (neighbourhoods), median over sets: {np.median([r['seam_neighbourhoods'] for r in rows]):.2f} "
          f"(max {max(r['seam_neighbourhoods'] for r in rows):.2f}); colour steps: median "
          f"{np.median([r['seams'] for r in rows]):.2f} (max {max(r['seams'] for r in rows):.2f}); corner sets repeating more than the exemplar's own (raw): "
          f"{sum(r['repeat'][0] > r['exemplar_own'][0] for r in rows if 'wang' in r['set'])} of "
          f"{sum('wang' in r['set'] for r in rows)}")
    if a.json:
        atomic_write(a.json, json.dumps({"renderer": gpu.renderer, "rows": rows, "set_16x512_s": timing},
                                        indent=1).encode())
    if a.figure and shots:
        h = 8 * N // 2
        parts = []
        for atlas, arranged, tiled in shots:
            def half(img):
                hh, ww = img.shape[0] // 2 * 2, img.shape[1] // 2 * 2
                return img[:hh, :ww].reshape(hh // 2, 2, ww // 2, 2, -1).mean(axis=(1, 3))
            a_img = half(atlas)
            pad = np.ones((h, 8, atlas.shape[2]), np.float32)
            col = np.zeros((h, a_img.shape[1], atlas.shape[2]), np.float32) + 1
            col[:a_img.shape[0]] = a_img
            parts.append(np.concatenate([col, pad, half(arranged), pad, half(tiled)], axis=1))
        grey = [np.repeat(p, 3, axis=2) if p.shape[2] == 1 else p[..., :3] for p in parts]
        fig = np.concatenate([np.concatenate([g, np.ones((8, g.shape[1], 3), np.float32)]) for g in grey])
        write_png(a.figure, to_u8(fig))
    gpu.release()
    return 0


if __name__ == "__main__":
    sys.exit(main())
