"""The fidelity stage (discrete patch optimization, shaders/fidelity.frag): exact
(GL equals the numpy oracle for both neighborhood models, with and without
similarity sets, near 0 and +-2^30, with and without the vote; windows and pans
agree; toroidal tiles stay periodic; local updates equal a fresh synthesis), a fixed point on a tiled
exemplar, and closer to the exemplar than the per-pixel correction alone."""
from dataclasses import replace

import numpy as np
import oracle
import pytest

from infinitex.engine.analysis import AnalysisSettings, analyze
from infinitex.engine.controls import CanvasField, Controls, ExemplarMask
from infinitex.engine.params import STRUCTURE_LEVELS, SynthParams, structure_params
from infinitex.engine.pyramid import Rect
from infinitex.engine.synth import Synthesizer

FAR = 2 ** 30


def with_fidelity(an, seed: int = 3, **kw) -> SynthParams:
    """Default parameters with the fidelity stage on the 3 finest levels (2, 2, 1 iterations)."""
    L = an.L
    fid = tuple({L: 1, L - 1: 2, L - 2: 2}.get(l, 0) for l in range(L + 1))
    return replace(SynthParams.default(L, seed=seed), fidelity=fid, **kw)


@pytest.fixture(scope="module")
def gravel_k0(gravel):
    return analyze(gravel, AnalysisSettings(model="appearance", k=0))


@pytest.mark.parametrize("name", ["gravel-appearance", "gravel-color", "torus-color-k3", "k0"])
@pytest.mark.parametrize("x, y", [(5, -9), (FAR - 40, -FAR + 7), (-FAR + 11, FAR - 30)])
def test_gl_matches_the_oracle(analyses, gravel_k0, gpu, name, x, y):
    an = gravel_k0 if name == "k0" else analyses[name]
    params = with_fidelity(an)
    gl = Synthesizer(an, params, gpu=gpu).window(Rect.of(x, y, 20, 16))
    assert np.array_equal(gl, oracle.synthesize(an, params, x, y, 20, 16)), (name, x, y)


def test_gl_matches_the_oracle_with_avoided_regions_and_on_every_corrected_level(analyses, gpu):
    an = analyses["gravel-appearance"]
    mask = np.zeros((an.size, an.size), np.uint8)
    mask[6:38, 50:82] = 1
    controls = Controls(avoid=ExemplarMask(mask))
    params = replace(SynthParams.default(an.L, seed=8),
                     fidelity=tuple(1 if l >= 3 else 0 for l in range(an.L + 1)))
    gl = Synthesizer(an, params, gpu=gpu, controls=controls).window(Rect.of(-13, 21, 18, 14))
    assert np.array_equal(gl, oracle.synthesize(an, params, -13, 21, 18, 14, controls=controls))


@pytest.mark.parametrize("vote", [False, True])
@pytest.mark.parametrize("ox, oy", [(0, 0), (FAR - 300, -FAR + 100)])
def test_overlapping_windows_and_a_pan_agree(analyses, gpu, ox, oy, vote):
    an = analyses["gravel-appearance"]
    synth = Synthesizer(an, with_fidelity(an, fidelity_vote=vote), gpu=gpu)
    big = synth.window(Rect.of(ox, oy, 150, 110))
    assert np.array_equal(synth.window(Rect.of(ox + 41, oy + 17, 60, 70)), big[17:87, 41:101])
    vp = synth.viewport()
    try:
        for dx, dy in [(90, 60), (60, 30), (20, 10), (0, 0)]:
            vp.show(Rect.of(ox + dx, oy + dy, 96, 72))
        assert np.array_equal(vp.read(Rect.of(ox, oy, 96, 72)), big[:72, :96])
    finally:
        vp.release()


@pytest.mark.parametrize("vote", [False, True])
def test_toroidal_tiles_stay_periodic(analyses, gpu, vote):
    an = analyses["gravel-appearance"]
    synth = Synthesizer(an, with_fidelity(an, fidelity_vote=vote), gpu=gpu)
    n = 64
    tile = synth.toroidal(n)
    synth.params = replace(synth.params, period=n)
    wide = synth.window(Rect.of(-n // 2, -n, 2 * n, 2 * n))
    assert np.array_equal(wide, np.tile(tile, (3, 3, 1))[n:3 * n, n // 2:n // 2 + 2 * n])


@pytest.mark.parametrize("vote", [False, True])
def test_a_local_update_equals_a_fresh_synthesis(analyses, gpu, vote):
    an = analyses["gravel-appearance"]
    params = with_fidelity(an, seed=5, fidelity_vote=vote)
    view = Rect.of(FAR - 2000, 300, 160, 120)
    synth = Synthesizer(an, params, gpu=gpu)
    vp = synth.viewport()
    field = CanvasField()
    try:
        vp.show(view)
        for i, (cx, cy, value) in enumerate([(60, 50, 0), (150, 20, 65535), (-20, 110, 0), (700, 700, 0)]):
            old = field
            field, _ = field.painted(view.x0 + cx, view.y0 + cy, 18.0, value)
            vp.pyramid.update_controls(Controls(randomness_canvas=field),
                                       [Rect(*r) for r in old.changed_rects(field)])
            fresh = Synthesizer(an, params, gpu=gpu, controls=Controls(randomness_canvas=field)).window(view)
            assert np.array_equal(vp.read(view), fresh), f"stroke {i}"
    finally:
        vp.release()


def test_a_deferred_update_spread_over_calls_with_pans_and_new_dabs_equals_a_fresh_synthesis(analyses, gpu):
    """What the editor does: a dab only records work; settle() does it a piece
    at a time while the view pans and more dabs come; the end is exact."""
    an = analyses["gravel-appearance"]
    params = with_fidelity(an, seed=9)
    view = Rect.of(-FAR + 500, FAR - 900, 160, 120)
    vp = Synthesizer(an, params, gpu=gpu).viewport()
    pyr = vp.pyramid
    field = CanvasField()
    try:
        vp.show(view)
        calls = 0
        for i, (cx, cy, value) in enumerate([(60, 50, 0), (150, 20, 65535), (30, 100, 0)]):
            field, _ = field.painted(view.x0 + cx, view.y0 + cy, 18.0, value)
            assert pyr.update_controls(Controls(randomness_canvas=field), defer=True) == 0
            assert not pyr.settled
            for _ in range(3 + i):  # a few pieces, not the whole update
                assert not pyr.settle(0.0)
                calls += 1
            view = Rect.of(view.x0 + 37, view.y0 - 21, 160, 120)  # a pan between pieces
            vp.show(view)
        while not pyr.settle(0.0):
            calls += 1
        assert pyr.settled and calls > 20
        fresh = Synthesizer(an, params, gpu=gpu, controls=Controls(randomness_canvas=field)).window(view)
        assert np.array_equal(vp.read(view), fresh)

        # New parameters in the middle of an update: it is dropped with what it changed.
        field, _ = field.painted(view.x0 + 80, view.y0 + 60, 18.0, 65535)
        pyr.update_controls(Controls(randomness_canvas=field), defer=True)
        assert not pyr.settle(0.0)
        params2 = replace(params, seed=10)
        pyr.set_params(params2)
        vp.show(view)
        assert pyr.settle(0.0)
        fresh = Synthesizer(an, params2, gpu=gpu, controls=Controls(randomness_canvas=field)).window(view)
        assert np.array_equal(vp.read(view), fresh)
    finally:
        vp.release()


def test_a_tiled_toroidal_exemplar_is_a_fixed_point(analyses, gpu):
    """With no jitter the synthesis tiles a toroidal exemplar; every patch then
    matches the exemplar exactly and every prediction agrees, so the stage
    (search and vote) changes nothing."""
    an = analyses["torus-appearance"]
    params = replace(SynthParams(jitter=(0.0,) * (an.L + 1)), fidelity_vote=True,
                     fidelity=tuple(2 if l >= 2 else 0 for l in range(an.L + 1)))
    synth = Synthesizer(an, params, gpu=gpu)
    for x, y in [(0, 0), (-77, 1234), (FAR - 100, -FAR)]:
        s = synth.window(Rect.of(x, y, 70, 50))
        gy, gx = np.mgrid[y:y + 50, x:x + 70]
        assert np.array_equal(s[..., 0], gx % an.size) and np.array_equal(s[..., 1], gy % an.size)


def _patch_error(an, coords) -> float:
    """Mean squared difference of each 7x7 color patch of the output from the
    exemplar patch at its centre's coordinate (fine level; 0 = all copied whole)."""
    E = an.levels[an.L].stack.astype(np.float64)
    m = an.size
    out = E[coords[..., 1], coords[..., 0]]
    H, W = coords.shape[:2]
    err = []
    for dy in range(-3, 4):
        for dx in range(-3, 4):
            inner = out[3 + dy:H - 3 + dy, 3 + dx:W - 3 + dx]
            c = coords[3:H - 3, 3:W - 3]
            ex = E[np.clip(c[..., 1] + dy, 0, m - 1), np.clip(c[..., 0] + dx, 0, m - 1)]
            err.append(((inner - ex) ** 2).mean())
    return float(np.mean(err))


def test_the_stage_brings_patches_closer_to_the_exemplar(analyses, gpu):
    an = analyses["gravel-appearance"]
    rect = Rect.of(1000, -3000, 128, 128)
    plain = Synthesizer(an, SynthParams.default(an.L, seed=3), gpu=gpu).window(rect)
    fid = Synthesizer(an, with_fidelity(an), gpu=gpu).window(rect)
    assert _patch_error(an, fid) < 0.7 * _patch_error(an, plain)


def test_structure_presets():
    L = 7
    base = SynthParams.default(L)
    assert structure_params(base, 0) == base  # Variety: the stage off, the randomness as set
    presets = [structure_params(base, s) for s in range(1, STRUCTURE_LEVELS)]
    work = [sum(p.fidelity_passes(l) for l in range(L + 1)) * (2 * p.fidelity_radius + 1) ** 2 for p in presets]
    assert all(a < b for a, b in zip(work, work[1:])) and work[0] > 0  # more structure, more work
    with pytest.raises(ValueError):
        structure_params(base, STRUCTURE_LEVELS)
    # Fewer levels than the presets name: matched from the finest level.
    small = structure_params(SynthParams.default(2), STRUCTURE_LEVELS - 1)
    assert len(small.fidelity) == 3 and small.fidelity[-1] > 0
    with pytest.raises(ValueError):
        replace(base, fidelity=(9,) * (L + 1)).validate(L)
    with pytest.raises(ValueError, match="radius"):
        replace(base, fidelity=(1,) * (L + 1), fidelity_radius=7).validate(L)


@pytest.mark.parametrize("name", ["gravel-appearance", "torus-color-k3", "k0"])
@pytest.mark.parametrize("x, y", [(3, -7), (-FAR + 9, FAR - 28)])
def test_gl_matches_the_oracle_with_the_vote(analyses, gravel_k0, gpu, name, x, y):
    an = gravel_k0 if name == "k0" else analyses[name]
    params = with_fidelity(an, seed=6, fidelity_vote=True)
    gl = Synthesizer(an, params, gpu=gpu).window(Rect.of(x, y, 20, 16))
    assert np.array_equal(gl, oracle.synthesize(an, params, x, y, 20, 16)), (name, x, y)
    # The vote does something: without it the window differs.
    assert not np.array_equal(gl, Synthesizer(an, replace(params, fidelity_vote=False), gpu=gpu)
                              .window(Rect.of(x, y, 20, 16)))


@pytest.mark.slow  # the oracle on a 3 x 3 grid: 10 s (its margins grow with the grid)
def test_the_vote_matches_the_oracle_on_a_3x3_subpass_grid(analyses, gpu):
    an = analyses["gravel-color"]
    params = with_fidelity(an, seed=7, fidelity_vote=True, subgrid=3)
    gl = Synthesizer(an, params, gpu=gpu).window(Rect.of(FAR - 30, 17, 18, 14))
    assert np.array_equal(gl, oracle.synthesize(an, params, FAR - 30, 17, 18, 14))


def test_the_vote_keeps_out_of_avoided_regions_and_matches_the_oracle(analyses, gpu):
    an = analyses["gravel-appearance"]
    mask = np.zeros((an.size, an.size), np.uint8)
    mask[6:38, 50:82] = 1
    controls = Controls(avoid=ExemplarMask(mask))
    params = replace(SynthParams.default(an.L, seed=8), fidelity_vote=True,
                     fidelity=tuple(1 if l >= 3 else 0 for l in range(an.L + 1)))
    gl = Synthesizer(an, params, gpu=gpu, controls=controls).window(Rect.of(-13, 21, 18, 14))
    assert np.array_equal(gl, oracle.synthesize(an, params, -13, 21, 18, 14, controls=controls))
    big = Synthesizer(an, params, gpu=gpu, controls=controls).window(Rect.of(500, -700, 96, 96))
    assert not mask[big[..., 1], big[..., 0]].any()


def test_the_vote_does_not_stretch_a_bordered_exemplars_edge(analyses, gpu):
    """On a non-toroidal exemplar, predictions past the usable border would all
    clamp to its edge and outvote the rest; they do not vote, so the output
    neither piles up on the edge nor repeats a coordinate across neighbors
    (with them voting: 1.6% on the edge, 3.9% repeated; without: 0.4%, 1.2%)."""
    an = analyses["gravel-appearance"]
    assert not an.toroidal
    from infinitex.engine.stages import border_margin
    b = border_margin(an.size, 1)
    params = structure_params(SynthParams.default(an.L), 2)
    assert params.fidelity_vote
    c = Synthesizer(an, params, gpu=gpu).window(Rect.of(500, -700, 256, 256))
    on_edge = ((c == b) | (c == an.size - 1 - b)).mean()
    repeated = np.all(c[:, 1:] == c[:, :-1], axis=-1).mean() + np.all(c[1:] == c[:-1], axis=-1).mean()
    assert on_edge < 0.008 and repeated < 0.02, (on_edge, repeated)


@pytest.mark.parametrize("radius", [2, 5])
def test_other_patch_radii_match_the_oracle(analyses, gpu, radius):
    an = analyses["gravel-color"]
    params = with_fidelity(an, seed=4, fidelity_radius=radius)
    gl = Synthesizer(an, params, gpu=gpu).window(Rect.of(-FAR + 5, 33, 18, 14))
    assert np.array_equal(gl, oracle.synthesize(an, params, -FAR + 5, 33, 18, 14))

