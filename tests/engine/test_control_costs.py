"""Issue 29, item 15: controls that cost what they touch. Placed features are
found and packed with arrays (no Python work per feature and strip), and a
pixel tests only the features listed for its cell instead of every feature of
its strip (65,536 features inside a 512^2 export took 36 s instead of 4.8 s);
the result stays bit-identical. The deepest lattice (16 x 16 cells) finds its
restricted similarity sets with one matrix product per batch of cells instead
of 255 passes over the exemplar (149 s for a 256^2 synth)."""
import numpy as np
import pytest

import infinitex.engine.controls.features as features_mod
from infinitex.engine.controls import Controls, Feature
from infinitex.engine.controls.features import MAX_FEATURES, feature_bins
from infinitex.engine.params import SynthParams
from infinitex.engine.pyramid import Rect
from infinitex.engine.similarity import lattice_similarity_sets
from infinitex.engine.synth import Synthesizer

FAR = 2 ** 30


def random_features(rng, n, cx, cy, spread, L, max_r=300):
    m = 1 << L
    out = []
    for i in range(n):
        inner = int(rng.integers(0, max_r))
        a = int(rng.integers(0, L + 1))
        levels = [None, (a, int(rng.integers(a, L + 1)))][i % 2]
        out.append(Feature((int(rng.integers(0, m)), int(rng.integers(0, m))),
                           (cx + int(rng.integers(-spread, spread)), cy + int(rng.integers(-spread, spread))),
                           inner, inner + int(rng.integers(0, max_r)), levels))
    return tuple(out)


def reference_table(c: Controls, level, L, m, toroidal, x0, y0, x1, y1, period=0):
    """The feature table from the definition, one Feature at a time (the code before issue 29)."""
    k = L - level
    rows = []
    for f in c.features:
        bx0, by0, bx1, by1 = f.bbox()
        if not period and not (bx0 < x1 << k and x0 << k < bx1 and by0 < y1 << k and y0 << k < by1):
            continue
        a, b = f.level_range(L)
        if not a <= level <= b:
            continue
        f = f.clamped(m, toroidal)
        px, py = f.canvas
        rows.append([[px >> k, py >> k, (((px << 4) >> k) & 15) + 16 * (((py << 4) >> k) & 15),
                      (f.radius_at(level, L) << 4) >> k], [f.exemplar[0], f.exemplar[1], 0, 0]])
    return np.asarray(rows, dtype=np.int32) if rows else None


def test_feature_table_on_arrays_equals_the_definition():
    rng = np.random.default_rng(0)
    for trial in range(120):
        L = int(rng.integers(5, 10))
        base = int(rng.choice([0, FAR - 5000, -FAR + 5000]))
        c = Controls(features=random_features(rng, int(rng.integers(1, 50)), base, base, 3000, L))
        c.validate(1 << L)
        for _ in range(4):
            level = int(rng.integers(0, L + 1))
            k = L - level
            x0 = (base >> k) + int(rng.integers(-(3000 >> k), (3000 >> k) + 1))
            y0 = (base >> k) + int(rng.integers(-(3000 >> k), (3000 >> k) + 1))
            args = (level, L, 1 << L, bool(rng.integers(0, 2)), x0, y0, x0 + int(rng.integers(1, 400)),
                    y0 + int(rng.integers(1, 400)), int(rng.choice([0, 0, 64, 1 << level])))
            want, got = reference_table(c, *args), c.feature_table(*args)
            assert (want is None) == (got is None)
            assert want is None or np.array_equal(want, got), trial


def simulate(table, g, s, h, m, period, rows_of):
    """apply_features (shaders/common.glsl) over pixels g (N, 2) with start
    coordinates s, testing for each pixel the table rows rows_of(pixel) allows."""
    s = s.copy()
    for i, (a, u) in enumerate(table.astype(np.int64)):
        d = g - a[:2]
        if period:
            d = ((d + period // 2) & (period - 1)) - period // 2
        lim = (a[3] >> 4) + 2
        d16 = d * 16 + 8 - np.array([a[2] & 15, a[2] >> 4])
        hit = (np.abs(d) <= lim).all(axis=1) & ((d16 * d16).sum(axis=1) <= a[3] * a[3]) & rows_of(i)
        s[hit] = (u[:2] + h * d[hit]) & (m - 1)
    return s


@pytest.mark.parametrize("period, entries", [(0, None), (0, 64), (32, None), (256, None), (256, 64), (1, None)])
def test_the_cells_lists_give_what_testing_every_feature_gives(monkeypatch, period, entries):
    if entries is not None:  # long lists: the cells grow until they fit
        monkeypatch.setattr(features_mod, "MAX_BIN_ENTRIES", entries)
    rng = np.random.default_rng(period + 7)
    for trial in range(6):
        L, level = 8, int(rng.integers(2, 9))
        m, h = 256, 1 << (8 - level)
        x0, y0 = int(rng.integers(-3000, 3000)), int(rng.integers(-3000, 3000))
        w, hh = int(rng.integers(1, 140)), int(rng.integers(1, 140))
        k = L - level
        feats = random_features(rng, 300, (x0 + w // 2) << k, (y0 + hh // 2) << k, (w + 60) << k, L, max_r=40 << k)
        c = Controls(features=feats)
        table = c.feature_table(level, L, m, False, x0, y0, x0 + w, y0 + hh, period)
        if table is None:
            continue
        cells, lists, (ox, oy), shift = feature_bins(table, x0, y0, w, hh, period)
        assert entries is None or shift > features_mod.BIN_SHIFT or cells.size <= 2
        for a, n in cells.reshape(-1, 2):  # each list in table order, without repeats
            assert np.all(np.diff(lists[a:a + n]) > 0)
        ys, xs = np.mgrid[y0:y0 + hh, x0:x0 + w]
        g = np.stack([xs.ravel(), ys.ravel()], axis=1).astype(np.int64)
        q = (g & (period - 1)) if period else g - (ox, oy)
        cell = np.clip(q >> shift, 0, np.array(cells.shape[1::-1]) - 1)
        member = np.zeros((cells.shape[0] * cells.shape[1], len(table)), bool)
        for ci, (a, n) in enumerate(cells.reshape(-1, 2)):
            member[ci, lists[a:a + n]] = True
        flat_cell = cell[:, 1] * cells.shape[1] + cell[:, 0]
        s0 = rng.integers(0, m, g.shape)
        every = simulate(table, g, s0, h, m, period, lambda i: True)
        binned = simulate(table, g, s0, h, m, period, lambda i: member[flat_cell, i])
        assert np.array_equal(every, binned), (trial, period)
        assert (every != s0).any() or trial  # the features do reach the strip


def test_a_pixel_tests_about_the_features_that_reach_it():
    # 65,536 features (the documented maximum) inside 512 x 512: each pixel
    # tested all the features of its strip before (up to 65,536 at every pixel).
    rng = np.random.default_rng(2)
    feats = tuple(Feature((int(rng.integers(0, 64)), int(rng.integers(0, 64))),
                          (int(rng.integers(-256, 256)), int(rng.integers(-256, 256))), 4, 16)
                  for _ in range(MAX_FEATURES))
    c = Controls(features=feats)
    L, m = 6, 64
    tests = reach = 0
    for level in range(L + 1):
        k = L - level
        x0, y0, x1, y1 = -300 >> k, -300 >> k, (300 >> k) + 1, (300 >> k) + 1
        found = c.feature_lookup(level, L, m, False, x0, y0, x1, y1)
        if found is None:
            continue
        table, cells, entries, _origin, shift = found
        size = 1 << shift
        wx = np.minimum(size, (x1 - x0) - np.arange(cells.shape[1]) * size)
        wy = np.minimum(size, (y1 - y0) - np.arange(cells.shape[0]) * size)
        tests += int((cells[..., 1] * wy[:, None] * wx[None, :]).sum())
        reach += int((((table[:, 0, 3] >> 4) * 2 + 5) ** 2).sum())
    everything = sum(((300 >> (L - lv)) * 2 + 1) ** 2 * MAX_FEATURES for lv in range(L - 1))
    assert tests <= 3 * reach, (tests, reach)
    assert tests * 50 < everything


def test_far_features_cost_a_strip_nothing_and_no_python_per_feature(monkeypatch):
    rng = np.random.default_rng(3)
    feats = random_features(rng, MAX_FEATURES - 3, FAR - 100_000, -FAR + 100_000, 50_000, 7)
    near = random_features(rng, 3, 100, 100, 20, 7, max_r=30)
    c = Controls(features=feats + near)
    calls = []
    for name in ("bbox", "level_range", "radius_at", "clamped", "validate"):
        real = getattr(Feature, name)
        monkeypatch.setattr(Feature, name, lambda self, *a, _r=real, **k: calls.append(1) or _r(self, *a, **k))
    c.validate(128)
    found = [c.feature_lookup(lv, 7, 128, False, 0, 0, 256 >> (7 - lv), 256 >> (7 - lv)) for lv in range(8)]
    packed = [0 if f is None else len(f[0]) for f in found]
    assert max(packed) <= 3 and sum(packed) > 0  # only the near ones reach the strip
    assert calls == []  # found and packed on arrays
    assert c.normalized() is c and c.features_key == Controls(features=feats + near).features_key


def test_validation_on_arrays_keeps_each_sentence():
    good = tuple(Feature((1, 2), (i, i), 3, 5) for i in range(1000))
    for bad, words in [(Feature((200, 1), (0, 0), 3, 5), "outside the 128x128 exemplar"),
                       (Feature((1, 1), (0, 0), 6, 5), "Feature radii"),
                       (Feature((1, 1), (0, 0), 3, 5, (3, 9)), "levels must lie within 0..7"),
                       (Feature((1, 1), (0, 0), 3, 5, (-1, 2)), "levels must lie within 0..7")]:
        with pytest.raises(ValueError, match=words):
            Controls(features=good + (bad,) + good).validate(128)
    Controls(features=good).validate(128)


@pytest.mark.parametrize("period", [0, 64])
def test_gl_with_the_cells_equals_gl_testing_every_feature(analyses, gpu, monkeypatch, period):
    an = analyses["gravel-appearance"]
    rng = np.random.default_rng(11)
    x, y = (FAR - 700, -FAR + 900) if not period else (-64, 128)
    feats = random_features(rng, 2500, x + 80, y + 70, 150, an.L, max_r=24)
    from dataclasses import replace
    params = replace(SynthParams.default(an.L, seed=5), period=period)
    rect = Rect.of(x, y, 160, 140)
    binned = Synthesizer(an, params, gpu=gpu, controls=Controls(features=feats)).window(rect)
    monkeypatch.setattr(features_mod, "BIN_SHIFT", 30)  # one cell: every feature at every pixel, as before
    flat = Synthesizer(an, params, gpu=gpu, controls=Controls(features=feats)).window(rect)
    plain = Synthesizer(an, params, gpu=gpu).window(rect)
    assert np.array_equal(binned, flat)
    assert (binned != plain).any(axis=-1).mean() > 0.5  # the features are there


# -- lattices ---------------------------------------------------------------------


def reference_lattice_sets(desc, k, nx, ny):
    """The restricted similarity sets from the definition: every offset, one pass each."""
    m = desc.shape[0]
    cx, cy = m // nx, m // ny
    ys, xs = np.mgrid[0:m, 0:m]
    ident = np.stack([xs, ys], axis=-1).astype(np.int64)
    out = np.repeat(ident[:, :, None, :], k, axis=2)
    offsets = [(i * cx, j * cy) for j in range(ny) for i in range(nx) if i or j]
    if k == 1 or not offsets:
        return out.astype(np.int16)
    d64 = desc.astype(np.int64)
    dist = np.stack([((np.roll(d64, shift=(-oy, -ox), axis=(0, 1)) - d64) ** 2).sum(axis=-1)
                     for ox, oy in offsets], axis=-1)
    best = np.argsort(dist, axis=-1, kind="stable")[..., :k - 1]  # ties: the first offset
    out[:, :, 1:1 + best.shape[-1]] = (ident[:, :, None, :] + np.array(offsets)[best]) % m
    return out.astype(np.int16)


@pytest.mark.parametrize("m, nx, ny, k, spread", [(32, 2, 2, 2, 3), (64, 4, 2, 3, 1), (64, 16, 16, 4, 2),
                                                  (64, 1, 4, 4, 3), (32, 1, 1, 2, 5), (64, 16, 1, 5, 1),
                                                  (128, 16, 16, 3, 30000), (128, 8, 16, 2, 1000)])
def test_lattice_sets_equal_the_definition_ties_included(m, nx, ny, k, spread):
    desc = np.random.default_rng(m + nx + k).integers(-spread, spread + 1, (m, m, 8)).astype(np.int16)
    got = lattice_similarity_sets(desc, k, nx, ny)
    assert got.dtype == np.int16 and np.array_equal(got, reference_lattice_sets(desc, k, nx, ny))


def test_deepest_lattice_sets_take_no_pass_per_offset(monkeypatch):
    calls = []
    real = np.roll
    monkeypatch.setattr(np, "roll", lambda *a, **kw: calls.append(1) or real(*a, **kw))
    desc = np.random.default_rng(1).integers(-300, 300, (256, 256, 8)).astype(np.int16)
    out = lattice_similarity_sets(desc, 3, 16, 16)
    assert calls == []  # 255 passes over the exemplar per level before
    assert out.shape == (256, 256, 3, 2)


def test_lattice_levels_report_their_progress():
    from infinitex.engine.analysis import AnalysisSettings, analyze
    from infinitex.engine.exemplar import from_array
    rng = np.random.default_rng(4)
    cell = rng.random((4, 4, 3)).astype(np.float32)
    ex = from_array(np.tile(cell, (16, 16, 1)) + 0.01 * rng.random((64, 64, 3)).astype(np.float32), toroidal=True)
    seen = []
    analyze(ex, AnalysisSettings(lattice=(16, 16)), use_cache=False, progress=lambda f, msg: seen.append(msg))
    assert sum("lattice similarity sets" in s for s in seen) >= 4
