"""Analysis: stack, similarity-set rules, cache behaviour, progress and cancel."""
import os

import numpy as np
import pytest
from conftest import periodic_noise

from infinitex.engine.analysis import (
    AnalysisCancelled,
    AnalysisSettings,
    analysis_key,
    analyze,
)
from infinitex.engine.exemplar import from_array
from infinitex.engine.neighborhoods import gaussian_stack
from infinitex.engine.similarity import border_margin


@pytest.fixture(scope="module")
def small_ex():
    return from_array(periodic_noise(64, channels=1, seed=5), toroidal=False)


def test_gaussian_stack_levels(small_ex):
    stack = gaussian_stack(small_ex.pixels, small_ex.toroidal)
    assert len(stack) == small_ex.levels + 1
    assert all(s.shape == small_ex.pixels.shape for s in stack)
    np.testing.assert_allclose(stack[0], small_ex.pixels.mean(), rtol=1e-5)
    assert np.array_equal(stack[-1], small_ex.pixels)
    # Coarser levels are smoother.
    rough = [np.abs(np.diff(s, axis=1)).mean() for s in stack[1:]]
    assert all(a < b for a, b in zip(rough, rough[1:]))


@pytest.mark.parametrize("toroidal", [True, False])
def test_similarity_set_rules(tmp_path, small_ex, toroidal):
    ex = from_array(small_ex.pixels, toroidal=toroidal)
    an = analyze(ex, AnalysisSettings(k=3), cache_dir=str(tmp_path))
    m = ex.size
    spacing = 0.05 * m
    for level in range(1, an.L + 1):
        sims = an.levels[level].simset.astype(np.int64)
        assert sims.shape == (m, m, 3, 2)
        ys, xs = np.mgrid[0:m, 0:m]
        u = np.stack([xs, ys], axis=-1)
        first = sims[:, :, 0]
        for i in (1, 2):
            other = sims[:, :, i]
            moved = (other != first).any(-1)
            d = np.abs(other - u)
            if toroidal:
                d = np.minimum(d, m - d)
            dist = np.sqrt((d ** 2).sum(-1))
            assert (dist[moved] >= spacing - 1e-9).all(), f"level {level}: entry {i} too close"
        if toroidal:
            assert np.array_equal(first, u)
        else:
            b = border_margin(m, an.h(level))
            inside = (sims >= b) & (sims < m - b)
            assert inside.all(), f"level {level}: candidate in the border band"
            interior = ((u >= b) & (u < m - b)).all(-1)
            assert np.array_equal(first[interior], u[interior])


def test_cache_hit_and_corrupt_entry(tmp_path, small_ex):
    calls = []
    first = analyze(small_ex, cache_dir=str(tmp_path), progress=lambda f, m: calls.append(f))
    assert calls[0] == 0.0 and calls[-1] == 1.0 and calls == sorted(calls)
    path = os.path.join(tmp_path, analysis_key(small_ex, AnalysisSettings()) + ".npz")
    assert os.path.exists(path)
    msgs = []
    again = analyze(small_ex, cache_dir=str(tmp_path), progress=lambda f, m: msgs.append(m))
    assert msgs == ["loaded from cache"]
    for a, b in zip(first.levels, again.levels):
        assert np.array_equal(a.nbhd, b.nbhd) and np.array_equal(a.simset, b.simset)
    with open(path, "wb") as f:
        f.write(b"garbage" * 100)
    msgs.clear()
    fixed = analyze(small_ex, cache_dir=str(tmp_path), progress=lambda f, m: msgs.append(m))
    assert "loaded from cache" not in msgs
    assert np.array_equal(fixed.levels[-1].simset, first.levels[-1].simset)
    assert analyze(small_ex, cache_dir=str(tmp_path)).levels[-1].nbhd.shape == (64, 64, 8)


def test_cache_key_depends_on_content_and_settings(small_ex):
    other = from_array(small_ex.pixels[::-1], toroidal=small_ex.toroidal)
    k = analysis_key(small_ex, AnalysisSettings())
    assert k != analysis_key(other, AnalysisSettings())
    assert k != analysis_key(small_ex, AnalysisSettings(model="color"))
    assert k != analysis_key(small_ex, AnalysisSettings(k=3))


@pytest.mark.parametrize("settings", [AnalysisSettings(), AnalysisSettings(feature_weight=1.0)])
def test_the_full_analysis_reuses_the_quick_previews(small_ex, settings):
    """The editor's quick preview (k = 0) hands its stack and neighborhoods
    to the full analysis, which then equals one computed from scratch."""
    from dataclasses import replace
    quick = analyze(small_ex, replace(settings, k=0), use_cache=False)
    reused = analyze(small_ex, settings, use_cache=False, reuse=quick)
    fresh = analyze(small_ex, settings, use_cache=False)
    assert reused.key == fresh.key
    for a, b, q in zip(reused.levels, fresh.levels, quick.levels):
        assert a.nbhd is q.nbhd and a.stack is q.stack  # taken, not computed again
        for name in ("stack", "feat", "proj", "nbhd", "simset"):
            x, y = getattr(a, name), getattr(b, name)
            assert (x is None and y is None) or np.array_equal(x, y), name
        assert a.shift == b.shift
    other = from_array(small_ex.pixels[::-1], toroidal=small_ex.toroidal)
    with pytest.raises(ValueError, match="same exemplar"):
        analyze(other, settings, use_cache=False, reuse=quick)
    with pytest.raises(ValueError, match="same exemplar"):
        analyze(small_ex, replace(settings, model="color"), use_cache=False, reuse=quick)


def test_cancel(tmp_path, small_ex):
    def stop(fraction, message):
        if fraction > 0.3:
            raise AnalysisCancelled()
    with pytest.raises(AnalysisCancelled):
        analyze(small_ex, cache_dir=str(tmp_path), progress=stop)
    assert not [f for f in os.listdir(tmp_path) if f.endswith(".npz")]


def test_bad_settings_rejected(small_ex):
    for bad in (AnalysisSettings(k=5), AnalysisSettings(k=-1), AnalysisSettings(model="fft"),
                AnalysisSettings(k=0, lattice=(4, 4))):
        with pytest.raises(ValueError):
            analyze(small_ex, bad, use_cache=False)


def test_feature_distance_marks_the_elements_and_changes_the_appearance(small_ex):
    """LH06's feature-distance channel from the exemplar's own elements: bright
    disks on a dark ground give 1 deep inside a disk, 0 far outside, 1/2 on its
    edge, the same through the wrap; the channel changes the appearance vectors."""
    from infinitex.engine.neighborhoods import feature_distance, otsu_threshold
    m = 64
    ys, xs = np.mgrid[0:m, 0:m]
    img = np.full((m, m, 3), 0.2, np.float32)
    for cx, cy in ((20, 20), (50, 40), (62, 8)):   # the last one wraps around the border
        d = np.hypot(((xs - cx + m / 2) % m) - m / 2, ((ys - cy + m / 2) % m) - m / 2)
        img[d < 8] = 0.9
    assert 0.2 < otsu_threshold(img.mean(axis=2)) < 0.9
    f = feature_distance(img, True)[..., 0]
    assert f.shape == (m, m) and f.min() == 0.0 and f.max() == 1.0
    assert f[20, 20] == 1.0 and f[40, 50] == 1.0 and f[8, 1] > 0.7   # inside, also across the wrap
    assert f[36, 5] == 0.0                                           # far outside
    assert abs(f[20, 28] - 0.5) <= 0.15                              # on an edge
    plain = analyze(small_ex, AnalysisSettings())
    fd = analyze(small_ex, AnalysisSettings(feature_weight=1.0))
    assert plain.key != fd.key
    assert not np.array_equal(plain.levels[-1].feat, fd.levels[-1].feat)
    assert np.array_equal(plain.levels[-1].stack, fd.levels[-1].stack)  # colors unchanged


def test_the_analysis_does_not_depend_on_the_machines_blas():
    """The same exemplar gives the same features with any BLAS thread count
    (OpenBLAS splits and orders its sums by thread count and CPU kernel):
    another machine must synthesize the same texture. The appearance vectors
    are rounded to integers, so this fails if they are computed in float32.
    A flat level (E_0) has no appearance at all."""
    from threadpoolctl import threadpool_limits

    from infinitex.engine.neighborhoods import appearance_features
    # 128 px: large enough for OpenBLAS to split the products by thread (float32
    # features differ between 1, 2 and 3 threads on all three levels at 128 px, not at 64).
    ex = from_array(periodic_noise(128, channels=3, seed=11), toroidal=True)
    stack = gaussian_stack(ex.pixels, ex.toroidal)
    for level in (1, 2, 5):
        h = 1 << (ex.levels - level)
        got = []
        for threads in (1, 2, 3):
            with threadpool_limits(limits=threads, user_api="blas"):
                got.append(appearance_features(stack[level], h, 1.5, ex.toroidal))
        assert all(np.array_equal(got[0], g) for g in got[1:]), level
    assert not appearance_features(stack[0], 1 << ex.levels, 1.5, ex.toroidal).any()
    an = analyze(ex, AnalysisSettings(k=0), use_cache=False)
    with threadpool_limits(limits=3, user_api="blas"):
        again = analyze(ex, AnalysisSettings(k=0), use_cache=False)
    for a, b in zip(an.levels, again.levels):
        assert np.array_equal(a.feat, b.feat) and np.array_equal(a.nbhd, b.nbhd) and np.array_equal(a.proj, b.proj)
