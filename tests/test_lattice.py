"""Near-regular textures: lattice detection, rectification and lattice-aware synthesis."""
from dataclasses import replace

import numpy as np
import oracle
import pytest
from lattice_gen import bricks, lattice_error, near_regular, random_basis, stochastic, tiles

from engine.analysis import AnalysisSettings, analyze
from engine.controls import Controls
from engine.lattice import Lattice, LatticeError, autocorrelation_at, detect, rectified_exemplar
from engine.params import SynthParams
from engine.pyramid import Rect
from engine.synth import Synthesizer

FAR = 2 ** 30


# -- detection ----------------------------------------------------------------


def test_detection_finds_generated_lattices():
    """80 near-regular images: rotations to 45 degrees, 60-120 degree angles
    (shear), aspect up to 3:1, cells 8 to 96 px, pixel noise, per-cell colour
    and position variation. Both vectors within 2% (0.5 px for short ones),
    and the cell area too, in at least 95% of the cases."""
    rng = np.random.default_rng(3)
    good = 0
    n = 80
    for _ in range(n):
        t1, t2 = random_basis(rng)
        d = detect(near_regular(rng, t1, t2))
        good += d.lattice is not None and lattice_error(d.t1, d.t2, t1, t2) <= 0.02
    assert good >= 0.95 * n, f"{good}/{n} lattices found"


def test_stochastic_images_have_no_lattice():
    rng = np.random.default_rng(11)
    for _ in range(30):
        d = detect(stochastic(rng))
        assert d.lattice is None and d.confidence < 0.3


def test_detected_brick_lattice_keeps_rows_horizontal():
    img, t1, t2 = bricks(np.random.default_rng(1), side=256, bw=40, bh=18)
    d = detect(img)
    assert d.lattice is not None and d.confidence > 0.6
    lat = d.lattice
    assert abs(lat.t1[1]) < 0.2 and abs(lat.t1[0] - 40) < 0.4   # the row vector
    assert abs(abs(lat.t2[0]) - 20) < 0.4 and abs(lat.t2[1] - 18) < 0.4
    lat.validate(256, 256)  # the chosen block fits


@pytest.mark.parametrize("text, message", [
    ("0,0,10,0,20,0.5,2,2", "collinear"),
    ("0,0,2,0,0,10,2,2", "at least"),
    ("0,0,10,0,0,10,3,2", "power of two"),
    ("0,0,10,0,0,10,2", "8 numbers"),
    ("0,0,ten,0,0,10,2,2", "8 numbers"),
    ("0,0,nan,0,0,10,2,2", "finite"),
])
def test_degenerate_lattices_are_refused(text, message):
    with pytest.raises(LatticeError, match=message):
        Lattice.parse(text)


def test_block_outside_the_image_is_refused():
    lat = Lattice.parse("10,10,40,0,0,40,4,2")
    lat.validate(200, 100)
    with pytest.raises(LatticeError, match="does not fit"):
        lat.validate(160, 100)
    assert Lattice.parse(lat.to_text()) == lat


def test_rectification_maps_the_block_onto_the_square():
    """A lattice drawn at a slant comes out axis-aligned: the rectified
    exemplar's cells are m/nx x m/ny and it tiles (it is a block of whole cells)."""
    rng = np.random.default_rng(5)
    t1, t2 = np.array([30.0, 8.0]), np.array([-6.0, 26.0])
    img = near_regular(rng, t1, t2, side=256, noise=0.0, variation=0.0)
    lat = Lattice((40.0, 30.0), tuple(t1), tuple(t2), 4, 4)
    ex = rectified_exemplar(img, lat)
    m = ex.size
    cx, cy = lat.cell(m)
    assert ex.toroidal and m == lat.exemplar_size()
    px = ex.pixels
    assert autocorrelation_at(px, (cx, 0)) > 0.9 and autocorrelation_at(px, (0, cy)) > 0.9
    assert autocorrelation_at(px, (cx // 2, cy // 3)) < 0.7
    wrapped = np.concatenate([px, px], axis=1)
    seam = np.abs(wrapped[:, m - 1] - wrapped[:, m]).mean()
    assert seam < 1.5 * np.abs(np.diff(px, axis=1)).mean()


# -- synthesis ----------------------------------------------------------------


def _lattice_case(kind: str):
    rng = np.random.default_rng(1)
    if kind == "bricks":
        img, _, _ = bricks(rng, side=256, bw=40, bh=18)
    else:
        img, _, _ = tiles(rng, side=256, cell=32)
    lat = detect(img).lattice
    ex = rectified_exemplar(img, lat)
    an = analyze(ex, AnalysisSettings(lattice=(lat.nx, lat.ny)))
    return lat, ex, an


@pytest.fixture(scope="module")
def cases():
    return {kind: _lattice_case(kind) for kind in ("bricks", "tiles")}


def _regularity(synth, lat, an, ex) -> np.ndarray:
    cx, cy = lat.cell(an.size)
    out = synth.colors(synth.window(Rect.of(-200, 300, 384, 384))).astype(np.float64) / 255.0
    ref = np.array([autocorrelation_at(ex.pixels, (cx, 0)), autocorrelation_at(ex.pixels, (0, cy))])
    got = np.array([autocorrelation_at(out, (cx, 0)), autocorrelation_at(out, (0, cy))])
    return got / ref


@pytest.mark.parametrize("kind", ["bricks", "tiles"])
def test_lattice_mode_keeps_the_lattice_and_plain_mode_breaks_it(cases, gpu, kind):
    lat, ex, an = cases[kind]
    params = SynthParams.default(an.L)
    with_lattice = Synthesizer(an, params, gpu=gpu, controls=Controls(lattice=lat))
    plain = Synthesizer(an, params, gpu=gpu)
    kept = _regularity(with_lattice, lat, an, ex)
    broken = _regularity(plain, lat, an, ex)
    assert (np.abs(kept - 1.0) <= 0.2).all(), f"lattice mode: {kept}"
    assert (broken < 0.6).any(), f"plain mode kept the rows too: {broken}"


def test_coarse_offsets_are_whole_cells(cases, gpu):
    """On every lattice level, S_l(p) - h_l p is the same modulo the cell
    everywhere (the unjittered tiling's phase): coarse structure moved by
    whole cells only. Finer levels move freely."""
    lat, ex, an = cases["bricks"]
    ctl = Controls(lattice=lat)
    synth = Synthesizer(an, SynthParams.default(an.L), gpu=gpu, controls=ctl)
    m = an.size
    cx, cy = lat.cell(m)
    K = lat.level_count(m)
    assert 1 <= K <= an.L
    for level in range(an.L + 1):
        h = an.h(level)
        S = synth.window(Rect.of(-40, 17, 48, 40), level=level).astype(np.int64)
        gy, gx = np.mgrid[17:57, -40:8]
        off_x = (S[..., 0] - h * gx) % cx
        off_y = (S[..., 1] - h * gy) % cy
        same = (off_x == off_x[0, 0]).all() and (off_y == off_y[0, 0]).all()
        if level < K:
            assert same, f"level {level} moved by a fraction of a cell"
        elif level >= K + 1:
            assert not same, f"level {level} should jitter freely"


@pytest.mark.parametrize("ox, oy", [(0, 0), (FAR - 200, -FAR + 50), (-FAR + 3, FAR - 300)])
def test_windows_agree_in_lattice_mode(cases, gpu, ox, oy):
    lat, ex, an = cases["tiles"]
    synth = Synthesizer(an, replace(SynthParams.default(an.L), seed=4), gpu=gpu, controls=Controls(lattice=lat))
    big = synth.window(Rect.of(ox, oy, 120, 100))
    small = synth.window(Rect.of(ox + 37, oy + 21, 50, 61))
    assert np.array_equal(small, big[21:82, 37:87])


@pytest.mark.parametrize("levels", [None, 2])
def test_gl_matches_oracle_in_lattice_mode(cases, gpu, levels):
    lat, ex, an = cases["bricks"]
    ctl = Controls(lattice=replace(lat, levels=levels))
    params = replace(SynthParams.default(an.L), seed=7)
    synth = Synthesizer(an, params, gpu=gpu, controls=ctl)
    for x, y in [(5, -9), (-FAR + 17, FAR - 64)]:
        gl = synth.window(Rect.of(x, y, 24, 20))
        assert np.array_equal(gl, oracle.synthesize(an, params, x, y, 24, 20, controls=ctl))


def test_toroidal_tile_of_whole_cells_wraps(cases, gpu):
    lat, ex, an = cases["tiles"]
    synth = Synthesizer(an, SynthParams.default(an.L), gpu=gpu, controls=Controls(lattice=lat))
    n = 256
    cx, cy = lat.cell(an.size)
    assert n % cx == 0 and n % cy == 0
    tile = synth.toroidal(n)
    periodic = replace(synth.params, period=n)
    saved, synth.params = synth.params, periodic
    try:
        wide = synth.window(Rect.of(-n // 2, -n // 4, 2 * n, n))
    finally:
        synth.params = saved
    assert np.array_equal(wide, np.tile(tile, (3, 3, 1))[3 * n // 4:7 * n // 4, n // 2:5 * n // 2])
    img = synth.colors(tile).astype(np.float64)
    seam = np.abs(img[:, 0] - img[:, -1]).mean()
    assert seam <= 1.3 * np.abs(np.diff(img, axis=1)).mean()


def test_lattice_controls_must_match_the_analysis(cases, gpu):
    lat, ex, an = cases["tiles"]
    with pytest.raises(ValueError, match="analyzed for"):
        Synthesizer(an, SynthParams.default(an.L), gpu=gpu, controls=Controls(lattice=replace(lat, nx=lat.nx * 2)))
