"""Direction and scale fields (anisometric synthesis, LH06 5; engine/controls/direction.py).

The GL passes equal the numpy oracle with a field whose Jacobian varies within
the window (rotations, scales, aspects, a shear, opposite directions that cancel
in the mipmap), for both neighborhood models, with and without similarity sets
and the fidelity stage, near 0 and near +-2^30, comparing the whole state
(nearest texels and sub-pixel remainders); overlapping windows and a pan agree
bit for bit; an identity field, or one painted far away, changes nothing; a 90
degree field turns the texture by 90 degrees; toroidal tiles stay periodic (the
field is read at p mod n_l); the oracle's per-footprint mipmap equals the
engine's tiled one."""
from dataclasses import replace

import numpy as np
import oracle
import pytest
from conftest import periodic_noise

from infinitex.engine.analysis import AnalysisSettings, analyze
from infinitex.engine.controls import (NEUTRAL, CanvasField, CanvasLabels, Controls, ExemplarField,
                                       ExemplarLabels, ExemplarMask, Feature)
from infinitex.engine.controls.direction import IDENTITY, MIN_DET, DirectionField, jacobian
from infinitex.engine.exemplar import from_array
from infinitex.engine.params import SynthParams, structure_params
from infinitex.engine.pyramid import COORD_LIMIT, Rect
from infinitex.engine.synth import Synthesizer

FAR = 2 ** 30
SHEAR = np.array([4096, 2048, 0, 4096], np.int16)  # x' = x + y / 2


def mixed_jacobians(w: int, h: int, seed: int = 0) -> np.ndarray:
    """A (h, w, 4) Q12 map whose J changes within a few pixels, in 4 x 2 blocks:
    a 30 degree rotation, a 2.5x scale (grown past the exemplar's pixels on the
    two finest levels: upsampling alone there), a -60 degree 1.5 aspect, 45 degrees
    (J^-1 d with zero components: the appearance model's sign rule), a 0.7x
    scale at 120 degrees, a smoothly turning band, a per-pixel checkerboard of
    opposite directions (20 and 200 degrees: their 2 x 2 means cancel, so the
    mipmap keeps the top-left child) and a 0.5x scale (J^-1 d halfway between
    integers: the color model's rounding); then some blocks of shear and identity."""
    ys, xs = np.mgrid[0:h, 0:w]
    out = np.empty((h, w, 4), np.int16)
    block = (4 * xs) // w + 4 * ((2 * ys) // h)  # 0..7
    out[block == 0] = jacobian(30.0)
    out[block == 1] = jacobian(0.0, 2.5)
    out[block == 2] = jacobian(-60.0, 1.0, 1.5)
    out[block == 3] = jacobian(45.0)
    out[block == 4] = jacobian(120.0, 0.7)
    turning = jacobian(4.0 * xs + 2.0 * ys, 1.0 + 0.3 * np.sin(ys / 5.0))
    out[block == 5] = turning[block == 5]
    checker = np.where(((xs + ys) & 1)[..., None] == 0, jacobian(20.0), jacobian(200.0))
    out[block == 6] = checker[block == 6]
    out[block == 7] = jacobian(0.0, 0.5)
    rng = np.random.default_rng(seed)
    # A few blocks of shear and of the identity scattered over the map.
    for _ in range(6):
        bx, by = int(rng.integers(0, w - 8)), int(rng.integers(0, h - 8))
        out[by:by + int(rng.integers(3, 9)), bx:bx + int(rng.integers(3, 9))] = SHEAR if rng.integers(2) else IDENTITY
    return out


def mixed_field(x: int, y: int, w: int, h: int, seed: int = 0) -> DirectionField:
    """The mixed map over a window's surroundings (the window +-48 px; beyond: identity)."""
    return DirectionField.from_jacobians(mixed_jacobians(w + 96, h + 96, seed), x - 48, y - 48)


@pytest.fixture(scope="module")
def direction_analyses(toroidal_ex):
    """Small exemplars (32 px): a bordered one (its candidates clamped off the
    border band) and a toroidal one (wrapped), each model, with and without
    similarity sets."""
    bordered = from_array(periodic_noise(32, seed=3), toroidal=False)
    return {
        "bordered-appearance": analyze(bordered, AnalysisSettings(model="appearance", k=2)),
        "bordered-color-k0": analyze(bordered, AnalysisSettings(model="color", k=0)),
        "torus-color": analyze(toroidal_ex, AnalysisSettings(model="color", k=3)),
        "torus-appearance-k0": analyze(toroidal_ex, AnalysisSettings(model="appearance", k=0)),
    }


def window(an, params, controls, gpu, x, y, w, h) -> np.ndarray:
    return Synthesizer(an, params, gpu=gpu, controls=controls).window(Rect.of(x, y, w, h), remainder=True)


# -- the mipmap ---------------------------------------------------------------

@pytest.mark.parametrize("k", [0, 1, 2, 3, 5])
@pytest.mark.parametrize("period", [0, 64])
def test_oracle_levels_equal_the_engine_mipmap(direction_analyses, k, period):
    """The oracle's per-footprint reduction equals DirectionField.region (tiled,
    cached mipmaps), with and without a period; the cancelling checkerboard
    takes the top-left child."""
    an = direction_analyses["bordered-appearance"]
    L = an.L
    f = DirectionField.from_jacobians(mixed_jacobians(200, 150, seed=k), -70, 33)
    params = SynthParams.default(L, period=period)
    level = max(L - k, 0)
    kk = L - level
    x0, y0 = (-70 >> kk) - 3, (33 >> kk) - 2
    w, h = (200 >> kk) + 7, (150 >> kk) + 6
    gy, gx = np.mgrid[y0:y0 + h, x0:x0 + w]
    got = oracle.direction_values(Controls(direction=f), an, params, level, gx, gy)
    want = f.region(kk, x0, y0, w, h, params.period)
    want = np.broadcast_to(IDENTITY, (h, w, 4)) if want is None else want
    assert np.array_equal(got, want)
    dets = got[..., 0] * got[..., 3] - got[..., 1] * got[..., 2]
    assert dets.min() >= MIN_DET
    if kk == 1 and not period:  # opposite directions that cancel: the top-left child
        fine = f.dense(2 * x0, 2 * y0, 2 * w, 2 * h).astype(np.int64)
        tl = fine[0::2, 0::2]
        cancel = (tl + fine[0::2, 1::2] + fine[1::2, 0::2] + fine[1::2, 1::2] == 0).all(axis=-1)
        assert cancel.sum() > 100
        assert np.array_equal(got[cancel], tl[cancel])


# -- GL equals the oracle -----------------------------------------------------

POSITIONS = [(-21, 13), (FAR - 150, -FAR + 60), (-FAR + 10, FAR - 100)]


@pytest.mark.parametrize("name", ["bordered-appearance", "bordered-color-k0", "torus-color", "torus-appearance-k0"])
@pytest.mark.parametrize("x, y", POSITIONS)
def test_gl_matches_oracle_with_a_field(direction_analyses, gpu, name, x, y):
    an = direction_analyses[name]
    w, h = 40, 32
    controls = Controls(direction=mixed_field(x, y, w, h, seed=len(name)))
    params = SynthParams.default(an.L, seed=4)
    gl = window(an, params, controls, gpu, x, y, w, h)
    assert gl.shape == (h, w, 4)
    ref = oracle.synthesize(an, params, x, y, w, h, controls=controls)
    assert np.array_equal(gl, ref), (name, x, y, int((gl != ref).any(-1).sum()))
    assert np.all((gl[..., 2:] >= -128) & (gl[..., 2:] < 128)) and np.all((gl[..., :2] >= 0) & (gl[..., :2] < an.size))
    assert (gl[..., 2:] != 0).any(-1).mean() > 0.5  # sub-pixel parts are used
    plain = window(an, params, Controls(), gpu, x, y, w, h)
    assert (gl[..., :2] != plain[..., :2]).any(-1).mean() > 0.5  # the field does something here


@pytest.mark.parametrize("name, vote", [("bordered-appearance", True), ("bordered-color-k0", False),
                                        ("torus-color", True), ("torus-appearance-k0", False)])
@pytest.mark.parametrize("x, y", [(-9, 5), (FAR - 90, -FAR + 30)])
def test_gl_matches_oracle_with_a_field_and_the_fidelity_stage(direction_analyses, gpu, name, vote, x, y):
    """With the vote, and the search alone."""
    an = direction_analyses[name]
    w, h = 24, 20
    controls = Controls(direction=mixed_field(x - 8, y - 6, w + 16, h + 12, seed=3))
    params = replace(structure_params(SynthParams.default(an.L, seed=6), 1), fidelity_vote=vote)
    assert params.fidelity is not None and any(params.fidelity)
    gl = window(an, params, controls, gpu, x, y, w, h)
    ref = oracle.synthesize(an, params, x, y, w, h, controls=controls)
    assert np.array_equal(gl, ref), (name, x, y, int((gl != ref).any(-1).sum()))


@pytest.mark.parametrize("name", ["bordered-appearance", "torus-color"])
def test_gl_matches_oracle_where_a_field_is_the_identity(direction_analyses, gpu, name):
    """A field painted over the left part of the window only: its identity
    pixels take the fidelity stage's row taps (fidelity.frag UPRIGHT), the
    others their own taps (TILTED, over their box), in the same subpasses."""
    an = direction_analyses[name]
    x, y, w, h = -9, 5, 28, 20
    painted = mixed_jacobians(18, h + 40, seed=5)
    controls = Controls(direction=DirectionField.from_jacobians(painted, x - 6, y - 20))
    params = replace(structure_params(SynthParams.default(an.L, seed=6), 1), fidelity_vote=False)
    gl = window(an, params, controls, gpu, x, y, w, h)
    ref = oracle.synthesize(an, params, x, y, w, h, controls=controls)
    assert np.array_equal(gl, ref), (name, int((gl != ref).any(-1).sum()))
    J = controls.direction.dense(x, y, w, h)
    upright = (J == IDENTITY).all(-1)
    assert upright[:, 12:].all() and not upright[:, :12].all()  # both kinds of pixel in the window


@pytest.mark.parametrize("scale, levels", [(4.0, 2), (2.0, 1)])
def test_grown_past_the_exemplar_is_magnified(direction_analyses, gpu, scale, levels):
    """Grown s times, the levels whose texels step under one exemplar pixel are
    upsampled alone (no jitter, correction or fidelity stage: synthesis
    magnification): within each block of 2^levels pixels that one coarser texel
    covers, the coordinate steps by exactly 256 / s per pixel (in 1/256 px)."""
    an = direction_analyses["torus-appearance-k0"]
    m = an.size
    x, y, w, h = -37, 21, 48, 40
    field = DirectionField.uniform(0.0, scale, 1.0, x - 64, y - 64, x + w + 64, y + h + 64)
    params = structure_params(SynthParams.default(an.L, seed=2), 2)
    st = window(an, params, Controls(direction=field), gpu, x, y, w, h).astype(np.int64)
    F = st[..., :2] * 256 + st[..., 2:]
    b = 1 << levels
    step = int(256 / scale)
    dx = np.mod(F[:, 1:, 0] - F[:, :-1, 0], 256 * m)
    dy = np.mod(F[1:, :, 1] - F[:-1, :, 1], 256 * m)
    inside_x = ((np.arange(x, x + w - 1) + 1) % b) != 0  # x and x + 1 under one coarser texel
    inside_y = ((np.arange(y, y + h - 1) + 1) % b) != 0
    assert np.all(dx[:, inside_x] == step) and np.all(dy[inside_y, :] == step)
    assert np.all(np.mod(F[:, 1:, 1] - F[:, :-1, 1], 256 * m)[:, inside_x] == 0)
    # The level above them is synthesized: its blocks do not continue each other everywhere.
    assert np.any(dx[:, ~inside_x] != step)


def test_gl_matches_oracle_near_the_coordinate_limit(direction_analyses, gpu):
    """At the far corners of the canvas (|x|, |y| close to COORD_LIMIT)."""
    an = direction_analyses["torus-color"]
    x, y = COORD_LIMIT - 200, -COORD_LIMIT + 150
    controls = Controls(direction=mixed_field(x, y, 32, 24, seed=9))
    params = structure_params(SynthParams.default(an.L, seed=2), 1)
    gl = window(an, params, controls, gpu, x, y, 32, 24)
    assert np.array_equal(gl, oracle.synthesize(an, params, x, y, 32, 24, controls=controls))


@pytest.mark.parametrize("name, structure", [("bordered-appearance", 0), ("torus-color", 1)])
def test_gl_matches_oracle_with_a_field_and_placed_features(direction_analyses, gpu, name, structure):
    """A placed feature sets whole texels (remainder 0) at its levels, through correction."""
    an = direction_analyses[name]
    x, y, w, h = (-15, 8, 40, 32) if structure == 0 else (-15, 8, 26, 22)
    feats = (Feature((5, 7), (x + 12, y + 10), 6, 14, (0, an.L)), Feature((20, 3), (x + 30, y + 22), 5, 9, None),
             Feature((11, 25), (x + 25, y + 5), 4, 4, (2, an.L)))
    if structure:  # (the oracle tests features pixel by pixel: fewer levels where its windows are larger)
        feats = (Feature((5, 7), (x + 12, y + 10), 6, 8, (3, an.L)),)
    controls = Controls(features=feats, direction=mixed_field(x, y, w, h, seed=7))
    params = structure_params(SynthParams.default(an.L, seed=4), structure)
    gl = window(an, params, controls, gpu, x, y, w, h)
    assert np.array_equal(gl, oracle.synthesize(an, params, x, y, w, h, controls=controls))
    ys, xs = np.mgrid[y:y + h, x:x + w]
    inside = (xs + 0.5 - (x + 12)) ** 2 + (ys + 0.5 - (y + 10)) ** 2 <= 36  # the exact copy at the finest level
    assert inside.sum() > 50 and not gl[inside][:, 2:].any()
    pairs = inside[:, 1:] & inside[:, :-1]  # a verbatim copy: whole steps of one texel
    assert np.all((gl[:, 1:, :2] - gl[:, :-1, :2])[pairs] % an.size == (1, 0))


@pytest.mark.parametrize("name, structure", [("bordered-appearance", 1), ("torus-color", 0)])
def test_gl_matches_oracle_with_a_field_and_the_other_controls(direction_analyses, gpu, name, structure):
    """Randomness fields (over the exemplar: read at the upsampled coordinate's
    nearest texel), an avoided region and texture by numbers, with a field."""
    an = direction_analyses[name]
    m = an.size
    x, y, w, h = (7, -26, 36, 30) if structure == 0 else (7, -26, 24, 20)
    rng = np.random.default_rng(1)
    ev = np.full((m, m), NEUTRAL, np.uint16)
    ev[m // 4:m // 2, :] = 0
    ev[3 * m // 4:, :] = rng.integers(0, 65536, (m - 3 * m // 4, m), dtype=np.uint16)
    cv = rng.integers(0, 65536, (h + 40, w + 40), dtype=np.uint16)
    mask = np.zeros((m, m), np.uint8)
    mask[3:10, 18:27] = 1
    lab = np.zeros((m, m), np.uint8)
    lab[:, m // 2:] = 2
    bands = np.where((np.arange(w + 60)[None, :] // 16) % 2 == 0, 1, 3).astype(np.uint8).repeat(h + 50, axis=0)
    field = mixed_field(x, y, w, h, seed=11)
    controls = Controls(ExemplarField(ev), CanvasField.from_image(cv, x - 20, y - 20), avoid=ExemplarMask(mask),
                        labels_exemplar=ExemplarLabels(lab),
                        labels_canvas=CanvasLabels.from_image(bands, x - 30, y - 25), direction=field)
    assert controls.labels_active
    params = structure_params(SynthParams.default(an.L, seed=9), structure)
    gl = window(an, params, controls, gpu, x, y, w, h)
    assert np.array_equal(gl, oracle.synthesize(an, params, x, y, w, h, controls=controls))
    field_only = window(an, params, Controls(direction=field), gpu, x, y, w, h)
    assert (gl != field_only).any(-1).mean() > 0.5  # the other controls do something here


# -- windows agree ------------------------------------------------------------

@pytest.mark.parametrize("ox, oy", [(0, 0), (FAR - 300, -FAR + 100), (-FAR + 10, FAR - 400)])
def test_overlapping_windows_agree_with_a_field(direction_analyses, gpu, ox, oy):
    an = direction_analyses["bordered-appearance"]
    controls = Controls(direction=mixed_field(ox, oy, 96, 80, seed=5))
    synth = Synthesizer(an, structure_params(SynthParams.default(an.L, seed=1), 1), gpu=gpu, controls=controls)
    big = synth.window(Rect.of(ox, oy, 96, 80), remainder=True)
    assert big.shape == (80, 96, 4) and (big[..., 2:] != 0).any()
    small = synth.window(Rect.of(ox + 37, oy + 21, 50, 45), remainder=True)
    assert np.array_equal(small, big[21:66, 37:87])
    vp = synth.viewport()
    try:  # a panning viewport (scrolling buffers), in another order, gives the same state
        vp.show(Rect.of(ox + 50, oy + 40, 46, 40))
        vp.show(Rect.of(ox, oy, 60, 50))
        assert np.array_equal(vp.pyramid.read(an.L, Rect.of(ox, oy, 60, 50), remainder=True), big[:50, :60])
    finally:
        vp.release()


# -- the identity changes nothing ----------------------------------------------

@pytest.mark.parametrize("name, structure", [("bordered-appearance", 0), ("bordered-color-k0", 1),
                                             ("torus-color", 0), ("torus-appearance-k0", 1)])
def test_identity_fields_change_nothing(direction_analyses, gpu, name, structure):
    an = direction_analyses[name]
    params = structure_params(SynthParams.default(an.L, seed=3), structure)
    x, y, w, h = -30, -20, 64, 48
    plain = Synthesizer(an, params, gpu=gpu).window(Rect.of(x, y, w, h))
    # Tiles that hold the identity only: no field at all.
    ident = DirectionField.from_jacobians(np.broadcast_to(IDENTITY, (160, 200, 4)).copy(), x - 60, y - 50)
    assert ident.identity and not Controls(direction=ident).directed
    assert np.array_equal(Synthesizer(an, params, gpu=gpu, controls=Controls(direction=ident)).window(
        Rect.of(x, y, w, h)), plain)
    # A field painted a million pixels away: the directed passes run, with J = I here.
    far = DirectionField.uniform(30.0, 1.5, 1.2, 10 ** 6, -10 ** 6, 10 ** 6 + 100, -10 ** 6 + 100)
    controls = Controls(direction=far)
    assert controls.directed
    got = window(an, params, controls, gpu, x, y, w, h)
    assert got.shape == (h, w, 4)
    assert np.array_equal(got[..., :2], plain) and not got[..., 2:].any()


# -- a rotation turns the texture ---------------------------------------------

@pytest.fixture(scope="module")
def stripes():
    """Horizontal stripes (8 px period along y) with some noise, 32 px, toroidal."""
    m = 32
    y = np.arange(m)[:, None]
    img = 0.5 + 0.35 * np.cos(2 * np.pi * y / 8) + 0.15 * (periodic_noise(m, 1, seed=7)[..., 0] - 0.5)
    return analyze(from_array(np.broadcast_to(img, (m, m)), toroidal=True), AnalysisSettings(model="appearance"))


def orientation(an, S):
    """(mean squared gradient along x, along y, centred autocorrelation of the
    luminance over lags [-12, 12]^2 normalized at 0)."""
    img = an.levels[an.L].stack[..., 0][S[..., 1], S[..., 0]].astype(np.float64)
    gx = ((img[:, 1:] - img[:, :-1]) ** 2).mean()
    gy = ((img[1:] - img[:-1]) ** 2).mean()
    a = img - img.mean()
    f = np.fft.fft2(a)
    ac = np.fft.fftshift(np.real(np.fft.ifft2(f * np.conj(f))))
    c0y, c0x = ac.shape[0] // 2, ac.shape[1] // 2
    ac = ac[c0y - 12:c0y + 13, c0x - 12:c0x + 13]
    return gx, gy, ac / ac[12, 12]


@pytest.mark.parametrize("theta", [90.0, -90.0])
def test_a_right_angle_field_turns_the_texture(stripes, gpu, theta):
    an, m = stripes, stripes.size
    x, y, w = -40, 17, 96
    params = SynthParams.default(an.L, seed=2)
    plain = window(an, params, Controls(), gpu, x, y, w, w)
    field = DirectionField.uniform(theta, 1.0, 1.0, x - 64, y - 64, x + w + 64, y + w + 64)
    turned = window(an, params, Controls(direction=field), gpu, x, y, w, w)
    assert not turned[..., 2:].any()  # a right angle maps whole pixels to whole pixels
    # Coherent steps: canvas +x is exemplar +x without the field; with it, J (1, 0) = (0, -+1).
    sign = 1 if theta > 0 else -1
    for S, step_x, step_y in ((plain, (1, 0), (0, 1)), (turned, (0, -sign % m), (sign % m, 0))):
        dx = (S[:, 1:, :2] - S[:, :-1, :2]) % m
        dy = (S[1:, :, :2] - S[:-1, :, :2]) % m
        assert np.all(dx == step_x, axis=-1).mean() > 0.4, step_x
        assert np.all(dy == step_y, axis=-1).mean() > 0.4, step_y
    # The stripes (across y in the exemplar) run along y on the canvas instead of x.
    gx0, gy0, ac0 = orientation(an, plain[..., :2])
    gx1, gy1, ac1 = orientation(an, turned[..., :2])
    assert gy0 > 3 * gx0 and gx1 > 3 * gy1
    # The autocorrelation turns with it: its peaks (along the stripes, and every
    # 8 px across them) move from the x axis to the y axis.
    assert np.corrcoef(ac1.ravel(), np.rot90(ac0).ravel())[0, 1] > 0.9
    assert np.corrcoef(ac1.ravel(), ac0.ravel())[0, 1] < 0.2
    for ac, along, across in ((ac0, ac0[12, 16], ac0[16, 12]), (ac1, ac1[16, 12], ac1[12, 16])):
        assert along > 0.5 and across < -0.3  # 4 px: along a stripe, half a period across
    peaks = []
    for ac in (ac0, ac1):
        ring = ac.copy()
        ring[10:15, 10:15] = -np.inf  # the highest correlation away from lag 0
        py, px = np.unravel_index(np.argmax(ring), ring.shape)
        peaks.append((px - 12, py - 12))
    assert peaks[0][1] == 0 and peaks[0][0] != 0  # on the x axis without the field
    assert peaks[1][0] == 0 and peaks[1][1] != 0  # on the y axis with it


# -- toroidal tiles -------------------------------------------------------------

def test_toroidal_tile_with_a_field_is_periodic(direction_analyses, gpu):
    an = direction_analyses["torus-color"]
    n = 32
    params = SynthParams.default(an.L, seed=5)
    inside = mixed_jacobians(n, n, seed=2)
    # Over [0, n)^2 the mixed map; around it another one (read mod n, it must not matter).
    outside = np.broadcast_to(jacobian(75.0, 2.0), (3 * n, 3 * n, 4)).copy()
    outside[n:2 * n, n:2 * n] = inside
    fa = DirectionField.from_jacobians(inside, 0, 0)
    fb = DirectionField.from_jacobians(outside, -n, -n)
    periodic = replace(params, period=n)
    tile = Synthesizer(an, periodic, gpu=gpu, controls=Controls(direction=fa)).window(Rect(0, 0, n, n),
                                                                                      remainder=True)
    assert tile.shape == (n, n, 4) and tile[..., 2:].any()
    t = Synthesizer(an, params, gpu=gpu, controls=Controls(direction=fa)).toroidal(n)
    assert np.array_equal(t, tile[..., :t.shape[-1]])
    # The same tile with the other surroundings, and equal to the oracle.
    other = Synthesizer(an, periodic, gpu=gpu, controls=Controls(direction=fb))
    assert np.array_equal(other.window(Rect(0, 0, n, n), remainder=True), tile)
    assert np.array_equal(tile, oracle.synthesize(an, periodic, 0, 0, n, n, controls=Controls(direction=fa)))
    # A larger window at an odd offset repeats the tile exactly.
    big = other.window(Rect.of(-n + 5, -n - 3, 3 * n, 2 * n + 7), remainder=True)
    ys, xs = np.mgrid[-n - 3:n + 4, -n + 5:2 * n + 5]
    assert np.array_equal(big, tile[ys % n, xs % n])
    # And the field does something.
    assert (tile[..., :2] != Synthesizer(an, periodic, gpu=gpu).window(Rect(0, 0, n, n))).any(-1).mean() > 0.5


def test_a_tile_smaller_than_the_exemplar_ignores_the_field_outside_it(analyses, gpu):
    """A 32 px tile of a 128 px exemplar: its coarse levels' pixels are larger
    than the tile; they take the tile's own field repeated, not what is painted
    beside the tile (a field painted only outside leaves the tile as it is)."""
    an = analyses["gravel-appearance"]
    n = 32
    params = replace(SynthParams.default(an.L, seed=2), period=n)
    inside = DirectionField.from_jacobians(mixed_jacobians(n, n, seed=4), 0, 0)
    around = np.broadcast_to(jacobian(90.0, 1.5), (4 * n, 4 * n, 4)).copy()
    around[:n, :n] = mixed_jacobians(n, n, seed=4)
    beside = DirectionField.from_jacobians(around, 0, 0)
    only_outside = DirectionField.from_jacobians(np.broadcast_to(jacobian(90.0), (n, 3 * n, 4)).copy(), n, 0)
    with Synthesizer(an, params, gpu=gpu, controls=Controls(direction=inside)) as s:
        tile = s.window(Rect(0, 0, n, n), remainder=True)
    with Synthesizer(an, params, gpu=gpu, controls=Controls(direction=beside)) as s:
        assert np.array_equal(s.window(Rect(0, 0, n, n), remainder=True), tile)
    with Synthesizer(an, params, gpu=gpu, controls=Controls(direction=only_outside)) as s:
        plain = s.window(Rect(0, 0, n, n), remainder=True)
    with Synthesizer(an, params, gpu=gpu) as s:
        assert np.array_equal(plain, s.window(Rect(0, 0, n, n), remainder=True))
    assert np.array_equal(tile, oracle.synthesize(an, params, 0, 0, n, n, controls=Controls(direction=inside)))


def test_direction_maps_are_read_in_bands_exactly_and_up_to_8192_px(tmp_path):
    """A map is converted BAND_PIXELS at a time (the float arrays stay small):
    the result equals converting it whole, and an 8192 x 8192 map fits the
    import budget (it was refused above about 2,360 px)."""
    from PIL import Image

    from infinitex.engine.controls.direction import angle_to_jacobians, flow_to_jacobians
    from infinitex.engine.controls import maps
    from infinitex.engine.controls.maps import direction_map_cost, load_direction_map
    from infinitex.engine.exemplar import IMPORT_BUDGET
    rng = np.random.default_rng(2)
    h, w = 2 * (maps.BAND_PIXELS // 90) + 37, 90  # three bands
    rgb = rng.integers(0, 256, size=(h, w, 3), dtype=np.uint8)
    Image.fromarray(rgb).save(tmp_path / "flow.png")
    want = flow_to_jacobians(rgb.astype(np.float64) / 255.0, True, 1.5, 1.0)
    assert np.array_equal(load_direction_map(str(tmp_path / "flow.png"), "flow", True, 1.5), want)
    gray = rng.integers(0, 65536, size=(h, w), dtype=np.uint16)
    Image.fromarray(gray).save(tmp_path / "angle.png")
    want = angle_to_jacobians(gray.astype(np.float64) / 65535.0)
    assert np.array_equal(load_direction_map(str(tmp_path / "angle.png"), "angle"), want)
    assert direction_map_cost(8192, 8192, "RGB", 64 << 20) <= IMPORT_BUDGET
