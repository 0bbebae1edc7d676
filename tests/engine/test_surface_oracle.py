"""Synthesis in a mesh's texture atlas (LH06 6; Controls.surface) against the numpy oracle.

A fake atlas domain (random indirection maps and random Jacobians per level,
nothing from a mesh) drives the GL passes and tests/oracle.py's ATLAS rule,
written from shaders/common.glsl (atlas_texel) and upsample.frag
(parent_texel): the whole finest state (nearest texels and 1/256 px
remainders) over the atlas window agrees bit for bit, for both neighborhood
models, with and without similarity sets and the fidelity stage. The links do
something there, and with every link off (all -1) a surface is exactly the
direction field with the same J."""
import numpy as np
import oracle
import pytest
from conftest import periodic_noise

from infinitex.engine.analysis import AnalysisSettings, analyze
from infinitex.engine.controls import Controls
from infinitex.engine.controls.direction import IDENTITY, DirectionField, jacobian
from infinitex.engine.exemplar import from_array
from infinitex.engine.params import SynthParams, structure_params
from infinitex.engine.pyramid import Rect
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


# name, structure (0: no fidelity stage; 1: its default iterations), seed, atlas size
CASES = [("bordered-appearance", 0, 1, N), ("bordered-color-k0", 1, 2, N), ("torus-color", 0, 3, N),
         ("torus-appearance-k0", 1, 4, N), ("bordered-appearance", 0, 6, 128)]


@pytest.mark.parametrize("name, structure, seed, n", CASES)
def test_gl_matches_oracle_in_an_atlas(atlas_analyses, gpu, name, structure, seed, n):
    an = atlas_analyses[name]
    surface = FakeSurface(n, an.L, seed)
    assert min(redirected_reads(surface, k) for k in range(3)) > 0.02  # the rule is exercised
    controls = Controls(surface=surface)
    assert controls.directed
    params = structure_params(SynthParams.default(an.L, seed=seed), structure)
    assert bool(params.fidelity and any(params.fidelity)) == bool(structure)
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
