"""Large exemplars (up to 2048 px) and the random-walk search without
similarity sets (k = 0, TBN10): the fast analysis is exact where it must be,
and the synthesis keeps every determinism property."""

import numpy as np
import oracle
import pytest
from conftest import periodic_noise

from infinitex.engine import fixed
from infinitex.engine.analysis import SIMSET_MAX, AnalysisSettings, analyze
from infinitex.engine.neighborhoods import (
    appearance_features,
    augmented_period,
    color_features,
    exemplar_neighborhoods,
    gather_exemplar_neighborhood,
    gaussian_stack,
    projected,
    runs,
    runtime_projection,
    tap,
    tap_index,
)
from infinitex.engine.exemplar import ExemplarError, fit_rule, from_array
from infinitex.engine.params import DEFAULT_WALK, SynthParams
from infinitex.engine.pyramid import Rect
from infinitex.engine.synth import Synthesizer

FAR = 2 ** 30


@pytest.mark.parametrize("m", [32, 64, 256])
@pytest.mark.parametrize("mirror", [False, True])
def test_tap_runs_copy_exactly_what_a_gather_reads(m, mirror):
    """Taps copied by slices (runs) equal the gathered periodic augmentation,
    for every offset from 0 to beyond one period."""
    rng = np.random.default_rng(m)
    img = rng.random((m, m, 2)).astype(np.float32)
    period = 2 * m if mirror else m
    aug = augmented_period(img, not mirror)
    for off in (0, 1, -1, 3, m // 2, -m // 2, m - 1, m, -m, 2 * m + 5, -2 * m - 3):
        idx = tap_index(m, off, m, mirror)
        assert np.array_equal(idx, (np.arange(m) + off) % period if not mirror else
                              [i if i < m else 2 * m - 1 - i for i in (np.arange(m) + off) % period])
        rebuilt = np.empty(m, np.int64)
        for a, b, sl in runs(idx):
            rebuilt[a:b] = np.arange(2 * m)[sl]
        assert np.array_equal(rebuilt, idx)
    taps = [(3, -m), (-2 * m, 5), (m // 2, m // 2)]
    w = rng.random((len(taps) * 2, 3))
    got = projected(img, taps, w, mirror, np.empty((m * m, 3), np.float32))
    want = np.concatenate([aug[(np.arange(m)[:, None] + dy) % period, (np.arange(m)[None, :] + dx) % period]
                           for dx, dy in taps], axis=2).reshape(m * m, -1) @ w
    assert np.abs(got - want).max() < 1e-5


@pytest.mark.parametrize("toroidal", [False, True])
def test_gaussian_stack_filters_the_periodic_augmentation(toroidal):
    """The DCT (mirrored) or FFT (toroidal) stack equals filtering the explicit
    augmentation by FFT, as LH05 3.2 defines it."""
    m = 64
    img = np.random.default_rng(2).random((m, m, 3)).astype(np.float32)
    aug = augmented_period(img.astype(np.float64), toroidal)
    n = aug.shape[0]
    spec = np.fft.fft2(aug, axes=(0, 1))
    f2 = np.fft.fftfreq(n)[:, None] ** 2 + np.fft.fftfreq(n)[None, :] ** 2
    stack = gaussian_stack(img, toroidal)
    assert len(stack) == 7 and np.array_equal(stack[-1], img)
    assert np.allclose(stack[0], img.mean(axis=(0, 1)), atol=1e-6)
    for level in range(1, 6):
        sigma = (1 << (6 - level)) / 2.0
        want = np.real(np.fft.ifft2(spec * np.exp(-2 * np.pi ** 2 * sigma ** 2 * f2)[:, :, None], axes=(0, 1)))
        assert np.abs(stack[level] - want[:m, :m]).max() < 1e-5, level


@pytest.mark.parametrize("model", ["appearance", "color"])
def test_exemplar_neighborhoods_are_the_exact_integer_projection(model):
    """N_E computed a band at a time in float32 BLAS is exactly
    floor(gathered @ proj / 2^shift) in int64, the formula the shader uses."""
    ex = from_array(periodic_noise(64, seed=5), toroidal=False)
    stack = gaussian_stack(ex.pixels, False)
    for level in (2, 4, 6):
        h = 1 << (6 - level)
        feat = appearance_features(stack[level], h, 1.5, False) if model == "appearance" else color_features(stack[level])
        assert feat.dtype == np.int8 and np.abs(feat.astype(int)).max() <= fixed.FEAT_MAX
        raw = gather_exemplar_neighborhood(feat, h, model)
        proj, shift = runtime_projection(raw, int(np.abs(feat).max()), model)
        assert np.array_equal(exemplar_neighborhoods(feat, h, model, proj, shift).reshape(-1, 8),
                              fixed.project(raw, proj, shift))


def test_appearance_features_are_the_pca_of_the_weighted_taps():
    """Up to PCA_SAMPLES a side every texel's statistics give the axes: the vectors
    span what the 25 weighted taps hold (their first axis carries the most)."""
    m, h = 64, 2
    img = periodic_noise(m, seed=9)
    feat = appearance_features(img, h, 1.5, True).reshape(-1, 8).astype(float)
    assert np.abs(feat).max() == fixed.FEAT_MAX
    var = feat.var(axis=0)
    assert var[0] == var.max() and var[0] > 2 * var[-1]
    taps = np.concatenate([tap(img, dx * h, dy * h, False) * np.exp(-(dx * dx + dy * dy) / 4.5)
                           for dy in range(-2, 3) for dx in range(-2, 3)], axis=2).reshape(m * m, -1)
    # Each feature is (nearly) a linear function of the taps: least squares leaves ~ only rounding.
    coef, *_ = np.linalg.lstsq(np.c_[taps, np.ones(m * m)], feat, rcond=None)
    resid = feat - np.c_[taps, np.ones(m * m)] @ coef
    assert np.abs(resid).max() <= 1.0


@pytest.fixture(scope="module")
def walk_analyses(gravel, toroidal_ex):
    return {"gravel": analyze(gravel, AnalysisSettings(k=0)),
            "torus-color": analyze(toroidal_ex, AnalysisSettings(model="color", k=0))}


@pytest.mark.parametrize("name", ["gravel", "torus-color"])
def test_search_without_similarity_sets_matches_the_oracle(walk_analyses, gpu, name):
    """k = 0: no similarity sets; the random walk is on by default; GL equals the
    numpy oracle, and overlapping windows agree near 0 and near +-2^30."""
    an = walk_analyses[name]
    assert an.k == 0 and all(lv.simset is None for lv in an.levels)
    params = SynthParams.default(an.L, seed=3)
    assert params.walk_steps(an.k) == DEFAULT_WALK and params.walk_steps(2) == 0
    synth = Synthesizer(an, params, gpu=gpu)
    try:
        for x, y in [(5, -3), (-FAR + 9, FAR - 50), (FAR - 60, -FAR + 2)]:
            gl = synth.window(Rect.of(x, y, 24, 20))
            assert np.array_equal(gl, oracle.synthesize(an, params, x, y, 24, 20)), (x, y)
            big = synth.window(Rect.of(x - 36, y - 28, 96, 80))
            assert np.array_equal(big[28:48, 36:60], gl)
        if not an.toroidal:  # candidates stay off the border band
            from infinitex.engine.similarity import border_margin
            S = synth.window(Rect.of(0, 0, 128, 128))
            b = border_margin(an.size, 1)
            assert S.min() >= 0 and S.max() < an.size
            assert ((S >= b) & (S <= an.size - 1 - b)).all(axis=-1).mean() > 0.99
    finally:
        synth.release()


def test_fit_rules_keep_up_to_2048_px_on_request():
    assert fit_rule("resize") == ("resize", 512) and fit_rule("crop-2048") == ("crop", 2048)
    with pytest.raises(ExemplarError):
        fit_rule("resize-4096")
    img = np.random.default_rng(0).random((1100, 1500, 1)).astype(np.float32)
    assert from_array(img).size == 512
    assert from_array(img, fit="resize-2048").size == 1024
    assert from_array(img, fit="crop-2048").size == 1024
    sq = np.random.default_rng(1).random((1024, 1024, 1)).astype(np.float32)
    kept = from_array(sq, fit="resize-2048")
    assert kept.size == 1024 and np.array_equal(kept.pixels, sq) and kept.hires is None
    assert from_array(sq).size == 512


@pytest.fixture(scope="module")
def large():
    """A 2048^2 exemplar (mirrored borders) and its analysis, made once."""
    img = periodic_noise(2048, channels=3, seed=11)
    img = 0.5 * img + 0.5 * np.roll(img, 700, axis=1)[::-1]  # not periodic: exercise the mirrored path
    ex = from_array(img, fit="resize-2048", toroidal=False)
    assert ex.size == 2048 and ex.size > SIMSET_MAX
    return analyze(ex, AnalysisSettings())


@pytest.mark.slow
def test_a_2048_px_exemplar_synthesizes_deterministically(large, gpu):
    """A 2048^2 exemplar: 12 levels, no similarity sets (k = 0 above 512 px),
    coordinates wider than 10 bits; overlapping windows agree near 0 and
    near +-2^30; GL equals the oracle."""
    an = large
    assert an.L == 11 and an.k == 0 and an.settings.k == 2
    params = SynthParams.default(an.L, seed=1)
    synth = Synthesizer(an, params, gpu=gpu)
    try:
        for x, y in [(0, 0), (-FAR + 100, FAR - 300), (FAR - 200, -FAR + 7)]:
            a = synth.window(Rect.of(x, y, 160, 120))
            b = synth.window(Rect.of(x + 40, y + 30, 200, 150))
            assert np.array_equal(a[30:, 40:], b[:90, :120]), (x, y)
        gl = synth.window(Rect.of(-FAR + 131, 17, 20, 16))
        assert np.array_equal(gl, oracle.synthesize(an, params, -FAR + 131, 17, 20, 16))
        wide = synth.window(Rect.of(0, 0, 512, 512))
        assert wide.max() > 1024 and wide.min() >= 0 and wide.max() < 2048  # beyond 10 bits, inside the exemplar
    finally:
        synth.release()


def test_analyses_without_similarity_sets_are_not_cached(toroidal_ex, tmp_path):
    """k = 0 takes seconds, less than reading its cache entry back (1.7 GB at
    2048 px): nothing is written; with sets the entry is written and reused."""
    analyze(toroidal_ex, AnalysisSettings(k=0), cache_dir=str(tmp_path))
    assert list(tmp_path.iterdir()) == []
    a = analyze(toroidal_ex, AnalysisSettings(k=1), cache_dir=str(tmp_path))
    assert len(list(tmp_path.iterdir())) == 1 and a.seconds > 0
    assert analyze(toroidal_ex, AnalysisSettings(k=1), cache_dir=str(tmp_path)).seconds == 0
