"""The quality measures of bench/ on cases with known answers."""
import os

import numpy as np
from PIL import Image

from bench.measures import (
    copied_windows,
    coverage,
    histogram_distance,
    neighborhood_energy,
    repetition,
    sheared_seams,
    straight_seam_runs,
    usage_peak,
    verbatim_regions,
)

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))


def _gravel():
    return np.asarray(Image.open(os.path.join(ROOT, "infinitex", "assets", "gravel.png")), dtype=np.float64) / 255.0


def test_tiled_exemplar_has_near_zero_energy_and_maximal_repetition():
    from conftest import periodic_noise
    ex = periodic_noise(64, channels=1, seed=3)[..., 0]  # tiles seamlessly: no seam neighborhoods
    tiled = np.tile(ex, (4, 4))
    energy, complete = neighborhood_energy(ex, tiled, periodic=True)
    shuffled = np.random.default_rng(0).permutation(tiled.ravel()).reshape(tiled.shape)
    e_shuf, _ = neighborhood_energy(ex, shuffled, periodic=True)
    assert energy < 1e-6 and complete < 1e-6 and e_shuf > 1e-3
    assert repetition(tiled) > 0.95
    assert repetition(shuffled) < 0.1


def test_a_copy_shifted_by_an_odd_offset_also_has_near_zero_energy():
    # Coarse scales read every subsampling phase: a copy of the exemplar one
    # pixel off (a lattice cell placed at an odd offset) is still a copy.
    from conftest import periodic_noise
    ex = periodic_noise(64, channels=1, seed=3)[..., 0]
    shifted = np.roll(np.tile(ex, (4, 4)), (1, 3), axis=(0, 1))
    for s in (2, 4):
        energy, complete = neighborhood_energy(ex, shifted, scales=(s,), periodic=True)
        assert energy < 1e-6 and complete < 1e-6


def test_pixel_shuffle_has_high_energy_but_the_same_histogram():
    ex = _gravel()
    shuffled = np.random.default_rng(1).permutation(ex.ravel()).reshape(ex.shape)
    energy, _ = neighborhood_energy(ex, shuffled)
    tiled_energy, _ = neighborhood_energy(ex, np.tile(ex, (2, 2)))
    assert energy > 0.003 and energy > 20 * tiled_energy
    assert histogram_distance(ex, shuffled) < 1e-12
    assert histogram_distance(ex, np.clip(ex + 0.2, 0, 1)) > 0.1


def test_a_coordinate_map_copying_one_block_has_a_large_verbatim_region():
    m = 128
    rng = np.random.default_rng(2)
    coords = rng.integers(0, m, size=(100, 100, 2))
    mean_noise, max_noise = verbatim_regions(coords, m)
    assert max_noise < 5
    yy, xx = np.mgrid[20:70, 10:70]
    coords[20:70, 10:70, 0] = xx + 5
    coords[20:70, 10:70, 1] = yy + 3
    mean_block, max_block = verbatim_regions(coords, m)
    assert max_block == 50 * 60
    assert mean_block > 0.25 * 50 * 60 * (50 * 60) / 10000


def test_toroidal_continuation_counts_across_the_wrap():
    m = 32
    yy, xx = np.mgrid[0:64, 0:64]
    coords = np.stack([xx % m, yy % m], axis=-1)
    assert verbatim_regions(coords, m, toroidal=True)[1] == 64 * 64
    assert verbatim_regions(coords, m, toroidal=False)[1] == m * m


def test_coverage_even_and_single_pixel():
    m = 16
    yy, xx = np.mgrid[0:64, 0:64]
    even, used = coverage(np.stack([xx % m, yy % m], axis=-1), m)
    assert abs(even - 1.0) < 1e-9 and used == 1.0
    one, used1 = coverage(np.zeros((64, 64, 2), dtype=int), m)
    assert one == 0.0 and used1 == 1 / (m * m)


def test_portilla_simoncelli_distance_has_known_answers(gpu):
    """The field's texture statistics (benchmark-only: plenoptic on CPU torch;
    skipped where the bench extras are not installed): the same texture scores
    about 0, another texture, a shuffle and noise score high."""
    import pytest
    pytest.importorskip("plenoptic")
    from bench.measures import ps_distance
    g = _gravel()
    brick = np.asarray(Image.open(os.path.join(ROOT, "infinitex", "assets", "brick.png")).convert("L"),
                       dtype=np.float64) / 255.0
    rng = np.random.default_rng(0)
    tiled = np.tile(g, (2, 2))
    assert ps_distance(g, g) == 0.0
    assert ps_distance(g, tiled) < 1e-3
    shuffled = rng.permutation(tiled.ravel()).reshape(tiled.shape)
    noise = rng.random((256, 256))
    assert ps_distance(g, shuffled) > 0.8
    assert ps_distance(g, noise) > 2.0
    assert ps_distance(g, brick) > 0.8
    # a synthesized gravel is far closer to the gravel than any of those
    from infinitex.engine.analysis import analyze
    from infinitex.engine.exemplar import load_exemplar
    from infinitex.engine.pyramid import Rect
    from infinitex.engine.synth import Synthesizer
    synth = Synthesizer(analyze(load_exemplar(os.path.join(ROOT, "infinitex", "assets", "gravel.png"))), gpu=gpu)
    ours = synth.colors(synth.window(Rect.of(0, 0, 256, 256)))
    synth.release()
    d = ps_distance(g, ours.astype(np.float64))
    assert d < 0.5 * ps_distance(g, shuffled), d


def test_sheared_seams_and_usage_peak_have_known_answers():
    """The defect figures: a plain tiling has no sheared seams and even usage;
    a tiling whose rows slip by one pixel every 4 rows shears a quarter of the
    vertical pairs; coordinates that keep returning to one block peak there."""
    m = 64
    yy, xx = np.mgrid[0:128, 0:128]
    tiled = np.stack([xx % m, yy % m], axis=-1)
    assert sheared_seams(tiled, m) == 0.0 and usage_peak(tiled, m) == 1.0
    slipped = tiled.copy()
    slipped[..., 0] = (xx + yy // 4) % m  # every 4th row starts one pixel further
    assert abs(sheared_seams(slipped, m) - 0.5 * (31 / 127)) < 1e-9
    rng = np.random.default_rng(1)
    stuck = rng.integers(0, m, (128, 128, 2))
    stuck[:64] = rng.integers(0, 16, (64, 128, 2))  # half the pixels from the first 16 px block
    assert usage_peak(stuck, m) > 8.0 and usage_peak(tiled, m) == 1.0


def test_straight_seam_runs_have_known_answers():
    """A plain tiling has no seams; two patches meeting along one straight
    column boundary make one run as long as the map is tall, on a coarse
    border or not as the canvas position says; a seam that steps every 8 rows
    has no run of 12 px."""
    m, n = 64, 40
    yy, xx = np.mgrid[0:n, 0:n]
    tiled = np.stack([xx % m, yy % m], axis=-1)
    assert straight_seam_runs(tiled, m) == (0.0, 0.0)
    cut = tiled.copy()
    cut[:, 20:, 0] = (xx[:, 20:] + 7) % m  # a seam between columns 19 and 20, all the way down
    pairs = n * (n - 1) * 2
    assert straight_seam_runs(cut, m, origin=(0, 0)) == (1000.0 * n / pairs, 1.0)  # canvas x 20: a multiple of 4
    assert straight_seam_runs(cut, m, origin=(1, 0)) == (1000.0 * n / pairs, 0.0)
    stairs = tiled.copy()
    for y in range(n):
        x0 = 10 + y // 8  # the seam steps one column to the right every 8 rows
        stairs[y, x0:, 0] = (xx[y, x0:] + 7) % m
    runs, _ = straight_seam_runs(stairs, m)
    assert runs == 0.0 and straight_seam_runs(stairs, m, length=8)[0] == 1000.0 * n / pairs
    two = tiled.copy()
    for y in list(range(0, 15)) + list(range(25, 38)):  # two runs down one boundary (15 and 13 px), apart,
        two[y, 20:, 0] = (xx[y, 20:] + 7) % m             # and three 20 px runs along rows 15, 25 and 38
    assert straight_seam_runs(two, m, origin=(0, 0)) == (1000.0 * (15 + 13 + 60) / pairs, 2 / 5)
    assert straight_seam_runs(two, m, length=14)[0] == 1000.0 * (15 + 60) / pairs


def test_copied_windows_have_known_answers():
    """A tiling copies every window (but across a non-tiling exemplar's seams, and
    across the wrap only when periodic); noise and a shuffle copy none; a pasted
    block copies its interior windows exactly."""
    from conftest import periodic_noise
    ex = periodic_noise(64, channels=3, seed=5)
    ex = np.rint(ex * 255) / 255
    tiled = np.tile(ex, (3, 3, 1))
    assert copied_windows(ex, tiled, periodic=True) == 1.0
    seams = copied_windows(ex, tiled, periodic=False)   # windows across the tile seams are not in ex
    n = 3 * 64 - 4
    assert abs(seams - (n - 2 * 4) ** 2 / n ** 2) < 0.02
    rng = np.random.default_rng(7)
    assert copied_windows(ex, rng.random((100, 100, 3))) == 0.0
    assert copied_windows(ex, rng.permutation(tiled.reshape(-1, 3)).reshape(tiled.shape), periodic=True) < 0.01
    canvas = rng.random((100, 100, 3))
    canvas[10:50, 20:60] = ex[5:45, 7:47]
    assert copied_windows(ex, canvas) == (36 * 36) / (96 * 96)
    gray = _gravel()
    assert copied_windows(gray, gray) == 1.0 and copied_windows(gray, gray[::-1]) < 0.01  # flips are not copies
    # Copies off by a level or two (a peer's rounding) still count; changed by 5 levels they do not.
    off = rng.integers(-2, 3, gray.shape) / 255
    assert copied_windows(gray, np.clip(gray + off, 0, 1)) > 0.95
    assert copied_windows(gray, np.clip(gray + 5 / 255 * np.sign(gray - 0.5), 0, 1)) < 0.01


def test_streak_peak_finds_a_period_and_ignores_noise():
    from bench.streaks import MIN_SHIFT, peak
    rng = np.random.default_rng(5)
    cell = rng.random((40, 40))
    tiled = np.tile(cell, (8, 8))  # 320 px, period 40: a repetition at (40, 0) and (0, 40)
    value, (dx, dy) = peak(tiled, periodic=False)
    assert value > 0.95 and dx % 40 == 0 and dy % 40 == 0  # the period or a multiple (tied)
    noise = rng.random((320, 320))
    assert peak(noise, periodic=False)[0] < 0.05
    assert peak(noise, periodic=False, blur=6.0)[0] < 0.5  # blurring keeps a noise field unrepeated
    # shifts under MIN_SHIFT never count: a period of 16 shows only at its multiples >= 32
    fine = np.tile(rng.random((16, 16)), (20, 20))
    value, (dx, dy) = peak(fine, periodic=True)
    assert value > 0.95 and max(abs(dx), abs(dy)) >= MIN_SHIFT and dx % 16 == 0 and dy % 16 == 0
