"""Exemplars with large areas of one colour (a logo, a clean graphic, a
painted-out half) are ordinary exemplars: the similarity search keeps a
spread of equal neighborhoods in its tree (engine/similarity.py), so its cost
does not grow with how many descriptors are equal (a 512^2 flat image used
to stall the analysis for minutes), and images without such runs are
searched exactly as before."""
from __future__ import annotations

import numpy as np

from infinitex.engine.similarity import MAX_EQUAL, similarity_sets, spread_equal


def test_a_run_of_equal_descriptors_is_thinned_evenly():
    rng = np.random.default_rng(1)
    desc = rng.random((1000, 3)).astype(np.float32)
    desc[100:900] = desc[100]                              # 800 equal descriptors
    pool = np.arange(0, 1000)
    kept = spread_equal(desc, pool, 64)
    equal = kept[(kept >= 100) & (kept < 900)]
    assert 32 < equal.size <= 64 and np.all(np.diff(equal) == 13)  # every 13th of 800: spread
    assert equal[0] == 100 and equal[-1] > 850                      # through the whole run, not its start
    assert np.array_equal(kept[(kept < 100) | (kept >= 900)], np.r_[0:100, 900:1000])  # the rest untouched
    assert np.array_equal(spread_equal(desc[:100], np.arange(100), 64), np.arange(100))  # no run: unchanged


def test_a_flat_exemplar_is_searched_in_a_small_tree(monkeypatch):
    sizes = []
    import scipy.spatial  # similarity.py imports it when a tree is built
    real = scipy.spatial.cKDTree

    def recording(points, *a, **kw):
        sizes.append(len(points))
        return real(points, *a, **kw)
    monkeypatch.setattr(scipy.spatial, "cKDTree", recording)
    m, k = 64, 4
    desc = np.zeros((m, m, 6), np.float32)
    desc[:, : m // 2] = np.random.default_rng(2).random((m, m // 2, 6))  # half textured, half flat
    sets = similarity_sets(desc, m, 1, k, True, 0.05)
    assert sizes and sizes[0] <= m * m // 2 + MAX_EQUAL
    assert sets.shape == (m, m, k, 2)
    # the flat half still gets k distinct, spaced candidates of the same (flat) look
    flat = sets[:, m // 2 + 8:].reshape(-1, k, 2).astype(np.int64)
    d = np.abs(flat[:, 1:, None] - flat[:, None, 1:])
    d = np.minimum(d, m - d)
    spread = np.sqrt((d ** 2).sum(-1)) + np.eye(k - 1)[None] * m
    assert (spread.min(axis=(1, 2)) >= 0.05 * m).mean() > 0.95
    assert (flat[:, 1:, 0] >= m // 2).mean() > 0.95        # matched within the flat half
