"""Synthesis in a mesh's texture atlas (LH06 6; Controls.surface) against the numpy oracle.

A fake atlas domain (random indirection maps and random Jacobians per level,
nothing from a mesh) drives the GL passes and tests/oracle.py's ATLAS rule,
written from shaders/common.glsl (atlas_texel) and upsample.frag
(parent_texel): the whole finest state (nearest texels and 1/256 px
remainders) over the atlas window agrees bit for bit, for both neighborhood
models, with and without similarity sets and the fidelity stage. The links do
something there, and with every link off (all -1) a surface is exactly the
direction field with the same J.

Features placed on a model (engine/surface/features.py) on real models (the
cube and the cylinder of engine/surface/shapes.py): GL against the oracle's
atlas feature rule (copies across seams, a copy on its own chart only, later
rows winning), and the synthesized coordinates inside a disc against the
definition F = u_F + J (x - p) in the centre's chart and in the chart across."""
from dataclasses import replace

import numpy as np
import oracle
import pytest
from conftest import periodic_noise

from infinitex.engine.analysis import AnalysisSettings, analyze
from infinitex.engine.controls import Controls, Feature
from infinitex.engine.controls.direction import IDENTITY, DirectionField, jacobian
from infinitex.engine.exemplar import from_array
from infinitex.engine.params import SynthParams, structure_params
from infinitex.engine.pyramid import Rect
from infinitex.engine.surface import AtlasDomain
from infinitex.engine.surface.shapes import cube, cylinder
from infinitex.engine.synth import Synthesizer

N = 64  # the atlas at the finest level (n x n texels); level l holds n >> (L - l)
CHARTS = 4
NONE = np.array([-1, -1, 0, 0], np.int16)


class FakeSurface:
    """A stand-in for engine/surface/atlas.py's AtlasDomain: per level k a
    square atlas of n >> k texels with a deterministic random indirection map
    (charts 0..3 in 4 x 4 blocks, some texels of no chart, a fifth of the texels of
    another chart than their block's; about 70% link to a random texel of the
    level's atlas for a random chart, the rest link nowhere) and random J
    (moderate rotations, scales and aspects, per 4 x 4 block with some texels
    of their own). Outside the atlas: no links, and the nearest edge's J.
    ``links=False``: every link -1; ``jac``: J from this function instead."""

    def __init__(self, n: int, levels: int, seed: int, links: bool = True, jac=None):
        self.key = f"fake-atlas-{n}-{levels}-{seed}-{int(links)}-{jac is not None}"
        self.n, self._jac_fn = n, jac
        self._links, self._jac = [], []
        for k in range(levels + 1):
            nl = max(n >> k, 1)
            rng = np.random.default_rng((seed, k))
            lk = np.empty((nl, nl, 4), np.int16)
            lk[:] = NONE
            if links:
                nb = -(-nl // 4)
                blocks = rng.choice(np.arange(-1, CHARTS), size=(nb, nb), p=[0.15] + [0.85 / CHARTS] * CHARTS)
                own = np.repeat(np.repeat(blocks, 4, 0), 4, 1)[:nl, :nl]
                stray = rng.random((nl, nl)) < 0.2
                own = np.where(stray, rng.integers(-1, CHARTS, (nl, nl)), own)
                serves = np.where(rng.random((nl, nl)) < 0.7, rng.integers(0, CHARTS, (nl, nl)), -1)
                target = rng.integers(0, nl, (nl, nl, 2))
                lk[..., 0], lk[..., 1] = own, serves
                lk[..., 2:] = np.where((serves >= 0)[..., None], target, 0)
            self._links.append(lk)
            nb = -(-nl // 4)
            theta = np.repeat(np.repeat(rng.uniform(-180, 180, (nb, nb)), 4, 0), 4, 1)[:nl, :nl]
            scale = np.repeat(np.repeat(rng.uniform(0.75, 1.35, (nb, nb)), 4, 0), 4, 1)[:nl, :nl]
            aspect = np.repeat(np.repeat(rng.uniform(0.8, 1.25, (nb, nb)), 4, 0), 4, 1)[:nl, :nl]
            own_j = rng.random((nl, nl)) < 0.15
            theta = np.where(own_j, rng.uniform(-180, 180, (nl, nl)), theta)
            self._jac.append(jacobian(theta, scale, aspect))

    def jacobians(self, k: int, x0: int, y0: int, w: int, h: int) -> np.ndarray:
        if self._jac_fn is not None:
            return self._jac_fn(k, x0, y0, w, h)
        t = self._jac[k]
        ys = np.clip(np.arange(y0, y0 + h), 0, t.shape[0] - 1)
        xs = np.clip(np.arange(x0, x0 + w), 0, t.shape[1] - 1)
        return np.ascontiguousarray(t[ys[:, None], xs[None, :]])

    def links(self, k: int, x0: int, y0: int, w: int, h: int) -> np.ndarray:
        t = self._links[k]
        nl = t.shape[0]
        out = np.empty((h, w, 4), np.int16)
        out[:] = NONE
        ax0, ay0, ax1, ay1 = max(x0, 0), max(y0, 0), min(x0 + w, nl), min(y0 + h, nl)
        if ax0 < ax1 and ay0 < ay1:
            out[ay0 - y0:ay1 - y0, ax0 - x0:ax1 - x0] = t[ay0:ay1, ax0:ax1]
        return out


@pytest.fixture(scope="module")
def atlas_analyses(toroidal_ex):
    """32 px exemplars, as test_direction.py's: bordered and toroidal, each model, with and without similarity sets."""
    bordered = from_array(periodic_noise(32, seed=3), toroidal=False)
    return {
        "bordered-appearance": analyze(bordered, AnalysisSettings(model="appearance", k=2)),
        "bordered-color-k0": analyze(bordered, AnalysisSettings(model="color", k=0)),
        "torus-color": analyze(toroidal_ex, AnalysisSettings(model="color", k=3)),
        "torus-appearance-k0": analyze(toroidal_ex, AnalysisSettings(model="appearance", k=0)),
    }


def atlas_window(an, params, controls, gpu, n=N) -> np.ndarray:
    with Synthesizer(an, params, gpu=gpu, controls=controls) as s:
        return s.window(Rect(0, 0, n, n), remainder=True)


def redirected_reads(surface: FakeSurface, k: int) -> float:
    """The share of (pixel, 3 x 3 neighbor) reads inside level k's atlas that a link redirects."""
    nl = max(surface.n >> k, 1)
    lk = surface.links(k, -1, -1, nl + 2, nl + 2).astype(np.int64)
    reader = lk[1:-1, 1:-1, 0]
    n = reader.shape[0]
    hits = 0
    for dy in (-1, 0, 1):
        for dx in (-1, 0, 1):
            q = lk[1 + dy:1 + dy + n, 1 + dx:1 + dx + n]
            hits += int(oracle._follow(reader, q).sum())
    return hits / (9 * n * n)


# name, Structure preset (0: no fidelity stage), its vote (False: the search alone), seed, atlas size
CASES = [("bordered-appearance", 0, True, 1, N), ("bordered-color-k0", 1, False, 2, N), ("torus-color", 2, True, 3, N),
         ("torus-appearance-k0", 1, True, 4, N), ("bordered-appearance", 0, True, 6, 128)]


@pytest.mark.parametrize("name, structure, vote, seed, n", CASES)
def test_gl_matches_oracle_in_an_atlas(atlas_analyses, gpu, name, structure, vote, seed, n):
    an = atlas_analyses[name]
    surface = FakeSurface(n, an.L, seed)
    assert min(redirected_reads(surface, k) for k in range(3)) > 0.02  # the rule is exercised
    controls = Controls(surface=surface)
    assert controls.directed
    params = structure_params(SynthParams.default(an.L, seed=seed), structure)
    assert bool(params.fidelity and any(params.fidelity)) == bool(structure)
    if structure:
        params = replace(params, fidelity_vote=vote)
    gl = atlas_window(an, params, controls, gpu, n)
    assert gl.shape == (n, n, 4)
    ref = oracle.synthesize(an, params, 0, 0, n, n, controls=controls)
    assert np.array_equal(gl, ref), (name, int((gl != ref).any(-1).sum()))
    assert (gl[..., 2:] != 0).any(-1).mean() > 0.5  # sub-pixel parts are used
    # The links do something (and the oracle sees it too).
    unlinked = Controls(surface=FakeSurface(n, an.L, seed, links=False))
    gl_off = atlas_window(an, params, unlinked, gpu, n)
    assert (gl_off != gl).any(-1).mean() > 0.3


@pytest.mark.parametrize("name, structure", [("bordered-appearance", 1), ("torus-color", 0)])
def test_links_off_equal_the_direction_field(atlas_analyses, gpu, name, structure):
    """A surface whose links are all -1 reads like a painted direction field
    with the same J at every level: the same state, in GL and in the oracle."""
    an = atlas_analyses[name]
    rng = np.random.default_rng(7)
    pad = 48
    jmap = jacobian(rng.uniform(-180, 180, (N + 2 * pad, N + 2 * pad)),
                    rng.uniform(0.8, 1.25, (N + 2 * pad, N + 2 * pad)), 1.1)
    field = DirectionField.from_jacobians(jmap, -pad, -pad)

    def jac(k, x0, y0, w, h):
        v = field.region(k, x0, y0, w, h)
        return np.broadcast_to(IDENTITY, (h, w, 4)).astype(np.int16) if v is None else v

    surface = FakeSurface(N, an.L, 5, links=False, jac=jac)
    params = structure_params(SynthParams.default(an.L, seed=8), structure)
    by_field = atlas_window(an, params, Controls(direction=field), gpu)
    by_surface = atlas_window(an, params, Controls(surface=surface), gpu)
    assert np.array_equal(by_surface, by_field)
    assert np.array_equal(by_surface, oracle.synthesize(an, params, 0, 0, N, N, controls=Controls(surface=surface)))
    assert (by_field[..., 2:] != 0).any(-1).mean() > 0.5


# -- features placed on a model (engine/surface/features.py) ----------------------------------------
# Real models in a 128 px atlas at 16 exemplar px per world unit (J near the identity on the cube,
# about diag(0.82, 0.40) on the cylinder's side). Per model: a feature with the default levels whose
# disc crosses a seam into a chart whose UVs keep their orientation (the cube's +z face into its
# turned +x face, and around its corner into +y and -y; the cylinder's side across its u seam, into
# the same chart's other end), and a second one with explicit levels reaching the finest level,
# overlapping the first (and winning there). Some copies' discs lie over other charts' texels (the
# cube's +y copy over the -y face; the cylinder's second feature over the top cap below the side in
# the atlas): the chart rule keeps them off those.

ATLAS = 128
SIGMA = 16.0
MODELS = {
    "cube": (cube, (Feature((10, 12), (35, 106), 12, 16), Feature((20, 9), (30, 103), 4, 7, (1, 5)))),
    "cylinder": (cylinder, (Feature((10, 12), (5, 64), 8, 12), Feature((20, 9), (16, 78), 8, 11, (1, 5)))),
}
_ATLASES: dict = {}


def model_atlas(name: str) -> AtlasDomain:
    if name not in _ATLASES:
        _ATLASES[name] = AtlasDomain(MODELS[name][0](), ATLAS, sigma=SIGMA)
    return _ATLASES[name]


def copies_of(controls: Controls, i: int) -> np.ndarray:
    """Feature i's copies (surface/features.py COLUMNS), the engine's CPU-side rows."""
    c = controls.surface.feature_copies(controls.features_key, controls._features)
    return c[c[:, 0] == i]


def row_hits(controls: Controls, an, level: int) -> list[tuple[np.ndarray, np.ndarray]]:
    """Per oracle row active at ``level`` (table order), the texels of the level's atlas inside its
    disc: (those of its chart, those of other charts)."""
    k = an.L - level
    n = ATLAS >> k
    gy, gx = np.mgrid[0:n, 0:n].astype(np.int64)
    own = controls.surface.owner(k)
    out = []
    for row in oracle.atlas_feature_rows(controls, an, level):
        inside, _ = oracle.atlas_feature_hit(row, gx, gy, an.h(level), an.size)
        out.append((inside & (own == row[2]), inside & (own >= 0) & (own != row[2])))
    return out


# model, analysis (similarity sets k > 0 or k = 0), structure (1: with the fidelity stage), seed
FEATURE_CASES = [("cube", "bordered-appearance", 0, 11), ("cube", "torus-appearance-k0", 1, 12),
                 ("cylinder", "bordered-color-k0", 0, 13), ("cylinder", "torus-color", 1, 14)]


@pytest.mark.parametrize("model, name, structure, seed", FEATURE_CASES)
def test_features_on_a_model_match_the_oracle(atlas_analyses, gpu, monkeypatch, model, name, structure, seed):
    an = atlas_analyses[name]
    atlas = model_atlas(model)
    feats = MODELS[model][1]
    controls = Controls(features=feats, surface=atlas)
    controls.validate(an.size)
    params = structure_params(SynthParams.default(an.L, seed=seed), structure)
    assert bool(params.fidelity and any(params.fidelity)) == bool(structure)
    assert feats[0].levels is None and feats[1].levels is not None
    # The case exercises what it claims: the first feature has copies across its seams, and at its
    # last level (default range: L - 2) its centre copy and a copy across set texels of their charts;
    # the second feature's disc overlaps the first's there; some copy's disc lies over texels of
    # other charts (at some level).
    across = copies_of(controls, 0)
    assert len(across) >= 2 and len({(int(r[1]), int(r[2])) for r in across}) == len(across)
    level = feats[0].level_range(an.L)[1]
    assert level == an.L - 2
    hits = row_hits(controls, an, level)
    assert len(hits) == len(across) + len(copies_of(controls, 1))
    counts = [int(own.sum()) for own, _ in hits]
    assert counts[0] >= 3 and max(counts[1:len(across)]) >= 3, counts
    assert (hits[0][0] & hits[len(across)][0]).sum() >= 3  # the second feature's centre copy overlaps
    assert sum(int(other.sum()) for lv in range(an.L + 1) for _, other in row_hits(controls, an, lv)) >= 3

    gl = atlas_window(an, params, controls, gpu, ATLAS)
    ref = oracle.synthesize(an, params, 0, 0, ATLAS, ATLAS, controls=controls)
    assert np.array_equal(gl, ref), (model, name, int((gl != ref).any(-1).sum()))
    plain = atlas_window(an, params, Controls(surface=atlas), gpu, ATLAS)
    assert (plain != gl).any(-1).sum() >= 50  # the features do something

    # Order matters (later rows win), and GL follows it.
    swapped = Controls(features=feats[::-1], surface=atlas)
    gl_swapped = atlas_window(an, params, swapped, gpu, ATLAS)
    assert (gl_swapped != gl).any(-1).sum() >= 3
    assert np.array_equal(gl_swapped, oracle.synthesize(an, params, 0, 0, ATLAS, ATLAS, controls=swapped))

    # Teeth: an engine that applied each copy to every chart's texels would fail this test.
    monkeypatch.setattr(oracle, "FEATURE_CHARTS", False)
    assert not np.array_equal(gl, oracle.synthesize(an, params, 0, 0, ATLAS, ATLAS, controls=controls))


def _q8_diff(F: np.ndarray, expected: np.ndarray, m: int) -> np.ndarray:
    """F - expected (1/256 px) wrapped to [-128 m, 128 m)."""
    P = 256 * m
    return np.mod(F - expected + P // 2, P) - P // 2


@pytest.mark.parametrize("model", ["cube", "cylinder"])
def test_a_feature_on_a_model_is_the_exemplar_disc_laid_on_the_surface(atlas_analyses, gpu, model):
    """At the finest level (the feature's range reaches it; write-back imposes it after correction),
    inside the disc the state is the definition: in the centre's chart F = u_F + J_F (x - p_F), J_F
    the atlas' J under the centre; in the chart across, F = u_F + J' (x' - p') with the copy's p', J'
    (both to the 1/256 px floor of the shader), and J' (x' - p') = J_F A^-1 (x' - M p_F) for the
    seam's affine map M = (A, t) from the atlas (to the copy's rounding of p' to 1/8 texel)."""
    an = atlas_analyses["bordered-appearance"]
    atlas = model_atlas(model)
    L, m = an.L, an.size
    r = 8
    f = Feature(MODELS[model][1][0].exemplar, MODELS[model][1][0].canvas, r, r, (2, L))
    controls = Controls(features=(f,), surface=atlas)
    u = np.array(f.clamped(m, an.toroidal).exemplar, np.float64)
    gl = atlas_window(an, structure_params(SynthParams.default(L, seed=21), 1), controls, gpu, ATLAS)
    F = gl[..., :2].astype(np.int64) * 256 + gl[..., 2:]
    own = atlas.owner(0)
    ys, xs = np.mgrid[0:ATLAS, 0:ATLAS]
    X = np.stack([xs + 0.5, ys + 0.5], axis=-1)  # texel centres, finest texels

    px, py = f.canvas
    c = int(own[py, px])
    J = atlas.jacobians(0, px, py, 1, 1)[0, 0].astype(np.float64) / 4096
    p = np.array([px + 0.5, py + 0.5])
    rows = copies_of(controls, 0)
    assert len(rows) >= 2
    assert rows[0][1:4].tolist() == [8 * px + 4, 8 * py + 4, c] and np.array_equal(rows[0][4:8], J * 4096)

    def check(chart, Jm, centre, expected_of, tol_lo, tol_hi):
        d = X - centre
        e = np.stack([Jm[0] * d[..., 0] + Jm[1] * d[..., 1], Jm[2] * d[..., 0] + Jm[3] * d[..., 1]], -1)
        sel = (own == chart) & (np.hypot(e[..., 0], e[..., 1]) <= r - 0.1)
        if not sel.any():
            return 0  # (a copy whose disc only grazes its chart)
        diff = _q8_diff(F[sel], expected_of(X[sel]), m)
        assert diff.min() > tol_lo and diff.max() <= tol_hi, (chart, diff.min(), diff.max())
        return int(sel.sum())

    def linear(Jm, centre):
        def at(x):
            d = x - centre
            return 256 * (u + np.stack([Jm[0] * d[:, 0] + Jm[1] * d[:, 1], Jm[2] * d[:, 0] + Jm[3] * d[:, 1]], -1))
        return at

    assert check(c, J, p, linear(J, p), -1, 1e-6) >= 100  # the centre's chart
    e_chart = atlas.chart[atlas.b_tri]
    counts = []
    for row in rows[1:]:
        c2, J2, p2 = int(row[3]), row[4:8] / 4096, row[1:3] / 8
        counts.append(check(c2, J2, p2, linear(J2, p2), -1, 1e-6))  # the copy across, as stored
        # The same surface point gives the same exemplar point: the seam map of the nearest edge of
        # the centre's chart into chart c2 sends p to p' and J to J A^-1 (p' rounds to 1/8 texel:
        # at most 1/16 texel per axis, times |J'| <= 1.5 here: < 1/8 px).
        sel = np.flatnonzero((e_chart == c) & (atlas.b_other >= 0) & (atlas.chart[np.maximum(atlas.b_other, 0)] == c2))
        a, b = atlas.uvpx[atlas.b_a[sel]], atlas.uvpx[atlas.b_b[sel]]
        t = np.clip(((p - a) * (b - a)).sum(-1) / ((b - a) ** 2).sum(-1), 0, 1)
        M = atlas.b_map[sel[np.argmin(np.hypot(*(p - a - t[:, None] * (b - a)).T))]]
        Mp = M[:, :2] @ p + M[:, 2]
        JA = (J.reshape(2, 2) @ np.linalg.inv(M[:, :2])).ravel()
        assert np.abs(Mp - p2).max() <= 1 / 16 + 1e-9
        check(c2, J2, p2, linear(JA, Mp), -32, 32)
    assert max(counts) >= 5, counts  # (a copy may just reach into a chart: a few texels)
