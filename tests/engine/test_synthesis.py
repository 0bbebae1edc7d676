"""Synthesis properties: spatial determinism, oracle agreement, tiling, correction."""
from dataclasses import replace

import numpy as np
import oracle
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from infinitex.engine.params import SynthParams, correction_margins
from infinitex.engine.pyramid import Rect, SynthesisError
from infinitex.engine.synth import Synthesizer

FAR = 2 ** 30


@pytest.fixture(scope="module")
def synths(analyses, gpu):
    return {name: Synthesizer(an, gpu=gpu) for name, an in analyses.items()}


@pytest.mark.parametrize("name", ["gravel-appearance", "gravel-color"])
@pytest.mark.parametrize("ox, oy", [(0, 0), (-37, 11), (FAR - 200, -FAR + 50), (-FAR + 3, FAR - 300)])
def test_overlapping_windows_agree(synths, name, ox, oy):
    synth = synths[name]
    big = synth.window(Rect.of(ox, oy, 120, 100))
    small = synth.window(Rect.of(ox + 37, oy + 21, 50, 61))
    assert np.array_equal(small, big[21:82, 37:87])
    # A window that overlaps only partly, computed in another order.
    shifted = synth.window(Rect.of(ox + 90, oy - 40, 64, 64))
    assert np.array_equal(shifted[40:64, 0:30], big[0:24, 90:120])


def test_different_places_differ(synths):
    synth = synths["gravel-appearance"]
    a = synth.window(Rect.of(0, 0, 64, 64))
    b = synth.window(Rect.of(5000, -7000, 64, 64))
    assert (a != b).any(axis=-1).mean() > 0.9


@pytest.mark.parametrize("name", ["gravel-appearance", "gravel-color", "torus-color-k3"])
def test_gl_matches_numpy_oracle(synths, analyses, name):
    synth = synths[name]
    for x, y in [(3, -5), (-FAR + 17, FAR - 64)]:
        gl = synth.window(Rect.of(x, y, 24, 20))
        ref = oracle.synthesize(analyses[name], synth.params, x, y, 24, 20)
        assert np.array_equal(gl, ref), f"GL and oracle differ at origin {(x, y)}"


@pytest.mark.parametrize("subgrid, passes", [(1, 2), (3, 1)])
def test_oracle_agreement_other_subpass_grids(analyses, gpu, subgrid, passes):
    an = analyses["gravel-appearance"]
    params = replace(SynthParams.default(an.L), subgrid=subgrid, passes=passes, seed=9)
    synth = Synthesizer(an, params, gpu=gpu)
    gl = synth.window(Rect.of(-11, 7, 20, 18))
    assert np.array_equal(gl, oracle.synthesize(an, params, -11, 7, 20, 18))


def test_zero_jitter_on_toroidal_exemplar_is_exact_tiling(analyses, gpu):
    an = analyses["torus-appearance"]
    synth = Synthesizer(an, SynthParams(jitter=(0.0,) * (an.L + 1)), gpu=gpu)
    for x, y in [(0, 0), (-77, 1234), (FAR - 100, -FAR)]:
        s = synth.window(Rect.of(x, y, 70, 50))
        gy, gx = np.mgrid[y:y + 50, x:x + 70]
        assert np.array_equal(s[..., 0], gx % an.size)
        assert np.array_equal(s[..., 1], gy % an.size)


@pytest.mark.parametrize("x, y", [(0, 0), (FAR - 96, -FAR)])
def test_a_coarse_levels_seams_do_not_come_down_its_texel_borders(analyses, gpu, x, y):
    """Jitter on one coarse level alone, no correction: every seam starts on
    that level's texel borders (every 8th finest pixel). Each finer pixel takes
    its parent or, at random per axis, the nearest other one (common.glsl
    parent_step), so at the finest level most seams have left those lines
    (upsampled from the parent floor(p/2) alone, all of them stay on them)."""
    an = analyses["gravel-appearance"]
    m, coarse = an.size, an.L - 3
    jitter = tuple(1.0 if l == coarse else 0.0 for l in range(an.L + 1))
    params = SynthParams(jitter=jitter, level_passes=(0,) * (an.L + 1))
    with Synthesizer(an, params, gpu=gpu) as synth:
        c = synth.window(Rect.of(x, y, 96, 96)).astype(np.int64)
    cols = ((c[:, 1:] - c[:, :-1] - [1, 0]) % m != 0).any(-1)  # a seam between x and x + 1
    rows = ((c[1:] - c[:-1] - [0, 1]) % m != 0).any(-1)
    on_x = (np.arange(x, x + 95) + 1) % 8 == 0  # the coarse texels' borders
    on_y = (np.arange(y, y + 95) + 1) % 8 == 0
    seams = cols.sum() + rows.sum()
    on_borders = cols[:, on_x].sum() + rows[on_y, :].sum()
    assert seams > 200
    assert on_borders < 0.5 * seams, (int(on_borders), int(seams))


def test_toroidal_output_is_one_period_of_a_periodic_texture(synths):
    synth = synths["gravel-appearance"]
    n = 64
    tile = synth.toroidal(n)
    assert tile.shape == (n, n, 2)
    periodic = replace(synth.params, period=n)
    saved, synth.params = synth.params, periodic
    try:
        wide = synth.window(Rect.of(-n // 2, -n, 2 * n, 2 * n))
    finally:
        synth.params = saved
    expected = np.tile(tile, (3, 3, 1))[n:3 * n, n // 2:n // 2 + 2 * n]
    assert np.array_equal(wide, expected)


def test_toroidal_seam_is_no_worse_than_interior(synths):
    """The wrap-around line (its mean difference across) is no worse than the
    worst line inside (0.083 against 0.071 on average and 0.091 at worst,
    2026-12-07); an ordinary window's is worse than any (0.134 against 0.094)."""
    synth = synths["gravel-appearance"]
    img = synth.colors(synth.toroidal(128))[..., 0].astype(np.float64)
    inner_x = np.abs(np.diff(img, axis=1)).mean(axis=0)  # one value per line between two columns
    inner_y = np.abs(np.diff(img, axis=0)).mean(axis=1)
    seam_x = np.abs(img[:, 0] - img[:, -1]).mean()
    seam_y = np.abs(img[0, :] - img[-1, :]).mean()
    assert seam_x <= inner_x.max() and seam_y <= inner_y.max()
    # Contrast: an ordinary window is not periodic.
    win = synth.colors(synth.window(Rect.of(0, 0, 128, 128)))[..., 0].astype(np.float64)
    assert np.abs(win[:, 0] - win[:, -1]).mean() > np.abs(np.diff(win, axis=1)).mean(axis=0).max()


def _pan_path(rng, steps):
    x, y = 0, 0
    for i in range(steps):
        if i == steps // 2:
            x, y = x + 100_000, y - 3_000  # a jump: nothing reusable
        else:
            x += int(rng.integers(-40, 41))
            y += int(rng.integers(-40, 41))
        yield x, y


def test_viewport_pan_path_matches_full_recompute(synths):
    synth = synths["gravel-appearance"]
    vp = synth.viewport()
    rng = np.random.default_rng(3)
    w, h = 96, 80
    counts = []
    try:
        for x, y in _pan_path(rng, 14):
            counts.append(vp.show(Rect.of(x, y, w, h)))
        final = vp.read(Rect.of(x, y, w, h))
        assert np.array_equal(final, synth.window(Rect.of(x, y, w, h)))
        # Incremental: a small move costs much less than the first frame.
        small_moves = [c for i, c in enumerate(counts[1:], 1) if i != 7]
        assert np.median(small_moves) < 0.5 * counts[0]
        # Moving back inside the held region costs nothing.
        assert vp.show(Rect.of(x + 2, y - 2, w, h)) == 0
    finally:
        vp.release()


def test_viewport_follows_parameter_changes(synths, analyses, gpu):
    an = analyses["gravel-appearance"]
    synth = Synthesizer(an, gpu=gpu)
    vp = synth.viewport()
    rect = Rect.of(10, 20, 64, 48)
    try:
        vp.show(rect)
        before = vp.read(rect)
        jit = list(synth.params.jitter)
        jit[an.L - 1] = 0.0  # only a fine level changes: coarse levels are kept
        vp.set_params(replace(synth.params, jitter=tuple(jit)))
        assert vp.pyramid.buffers[an.L - 2].valid is not None
        vp.show(rect)
        after = vp.read(rect)
        assert not np.array_equal(before, after)
        assert np.array_equal(after, synth.window(rect))
    finally:
        vp.release()


def test_zoomed_out_view_is_the_coarser_level(synths):
    synth = synths["gravel-appearance"]
    vp = synth.viewport()
    try:
        rect = Rect.of(-20, 30, 40, 32)
        vp.show(rect, zoom_out=2)
        assert vp.pyramid.buffers[synth.L] is None  # finest level never computed
        assert np.array_equal(vp.read(rect, zoom_out=2), synth.window(rect, level=synth.L - 2))
    finally:
        vp.release()


def test_correction_lowers_neighborhood_error_at_every_corrected_level(analyses, gpu):
    for name in ("gravel-appearance", "gravel-color"):
        an = analyses[name]
        base = SynthParams.default(an.L)
        for level in sorted(base.corrected_levels()):
            rect = Rect.of(0, 0, 48, 48)
            synth = Synthesizer(an, base, gpu=gpu)
            corrected = synth.window(rect, level=level)
            synth.set_params(replace(base, corrected=tuple(sorted(base.corrected_levels() - {level}))))
            uncorrected = synth.window(rect, level=level)
            e_corr = oracle.neighborhood_error(an, level, corrected)
            e_unc = oracle.neighborhood_error(an, level, uncorrected)
            assert e_corr < 0.8 * e_unc, f"{name} level {level}: {e_corr} vs {e_unc}"


def test_passes_per_level(analyses, gpu):
    """Per-level pass counts: GL equals the oracle (a coarse level corrected that
    is not by default, 3 passes at the finest, none at level 4); overlapping
    windows agree near 0 and near +-2^30; the same counts as ``passes`` give the
    same texture; a change invalidates only from the level it touches."""
    an = analyses["gravel-appearance"]
    L = an.L
    counts = (0, 0, 1, 2, 0, 4, 2, 3)[-(L + 1):]
    params = replace(SynthParams.default(an.L, seed=5), level_passes=counts)
    assert params.correcting_levels() == frozenset(l for l in range(L + 1) if counts[l])
    synth = Synthesizer(an, params, gpu=gpu)
    for x, y in [(3, -5), (-FAR + 17, FAR - 64)]:
        gl = synth.window(Rect.of(x, y, 24, 20))
        assert np.array_equal(gl, oracle.synthesize(an, params, x, y, 24, 20)), (x, y)
    for ox, oy in [(0, 0), (FAR - 200, -FAR + 50)]:
        big = synth.window(Rect.of(ox, oy, 120, 100))
        fresh = Synthesizer(an, params, gpu=gpu)
        small = fresh.window(Rect.of(ox + 37, oy + 21, 50, 61))
        assert np.array_equal(small, big[21:82, 37:87])
        fresh.release()
    plain = SynthParams.default(an.L, seed=5)
    same = replace(plain, level_passes=tuple(2 if l >= 3 else 0 for l in range(L + 1)))
    rect = Rect.of(-40, 17, 64, 48)
    a = Synthesizer(an, plain, gpu=gpu)
    b = Synthesizer(an, same, gpu=gpu)
    assert np.array_equal(a.window(rect), b.window(rect))
    assert not np.array_equal(a.window(rect), synth.window(rect))
    # Only the finest level's count changes: the coarser levels are kept.
    changed = replace(same, level_passes=same.level_passes[:-1] + (3,))
    kept = [plain.level_signature(l) == changed.level_signature(l) for l in range(L + 1)]
    assert kept == [True] * L + [False]
    for s in (a, b, synth):
        s.release()


def test_level_passes_are_validated():
    p = SynthParams.default(7)
    with pytest.raises(ValueError, match="one per level"):
        replace(p, level_passes=(2,) * 7).validate(7)
    with pytest.raises(ValueError, match="between 0 and 8"):
        replace(p, level_passes=(0, 0, 0, 2, 2, 2, 2, 9)).validate(7)
    assert replace(p, level_passes=(0,) * 8).correcting_levels() == frozenset()
    assert replace(p, passes=0).correcting_levels() == frozenset()


def test_exact_margins_are_what_lh05_reports():
    # LH05 3.4: their subpass order needs 10 and 11 pixels instead of 2cs^2 = 16.
    assert sorted(correction_margins(2, 2, 2)) == [10, 10, 11, 11]


def test_bad_requests_are_rejected(synths, analyses):
    synth = synths["gravel-appearance"]
    with pytest.raises(SynthesisError):
        synth.window(Rect.of(2 ** 31 - 10, 0, 64, 64))
    with pytest.raises(SynthesisError):
        synth.toroidal(100)
    an = analyses["gravel-appearance"]
    for bad in (dict(jitter=(0.5,) * 3), dict(jitter=(1.5,) * (an.L + 1)),
                dict(jitter=(0.5,) * (an.L + 1), kappa=-1), dict(jitter=(0.5,) * (an.L + 1), corrected=(99,))):
        with pytest.raises(ValueError):
            SynthParams(**bad).validate(an.L)


def test_several_headless_contexts_in_one_process(analyses, gpu):
    """A second engine (its own context, created and released in between, as an
    in-process CLI run does) leaves the first one working."""
    from infinitex.engine.gpu import Gpu
    an = analyses["gravel-appearance"]
    synth = Synthesizer(an, gpu=gpu)
    before = synth.window(Rect.of(5, 7, 40, 30))
    other = Gpu()
    Synthesizer(an, gpu=other).window(Rect.of(0, 0, 16, 16))
    other.release()
    assert np.array_equal(synth.window(Rect.of(5, 7, 40, 30)), before)


@pytest.mark.parametrize("name", ["gravel-appearance", "gravel-color", "torus-appearance"])
def test_random_walk_matches_the_oracle_and_stays_deterministic(analyses, gpu, name):
    """TBN10's coherent random walk (every choice from the hash): GL equals the
    numpy oracle, overlapping windows agree near 0 and far away, toroidal
    outputs stay periodic, and the walk changes the result."""
    an = analyses[name]
    params = replace(SynthParams.default(an.L), walk=6, seed=4)
    synth = Synthesizer(an, params, gpu=gpu)
    for x, y in [(3, -5), (-FAR + 17, FAR - 64)]:
        gl = synth.window(Rect.of(x, y, 24, 20))
        assert np.array_equal(gl, oracle.synthesize(an, params, x, y, 24, 20)), (x, y)
        big = synth.window(Rect.of(x - 40, y - 30, 100, 90))
        assert np.array_equal(big[30:50, 40:64], gl)
    plain = Synthesizer(an, replace(params, walk=0), gpu=gpu)
    a, b = synth.window(Rect.of(0, 0, 96, 96)), plain.window(Rect.of(0, 0, 96, 96))
    assert (a != b).any(axis=-1).mean() > 0.05
    if name == "gravel-appearance":
        n = 64
        tile = synth.toroidal(n)
        saved, synth.params = synth.params, replace(params, period=n)
        try:
            wide = synth.window(Rect.of(-n // 2, -n, 2 * n, 2 * n))
        finally:
            synth.params = saved
        assert np.array_equal(wide, np.tile(tile, (3, 3, 1))[n:3 * n, n // 2:n // 2 + 2 * n])
    plain.release()
    synth.release()


def _simulate(s, stages, dims, rects, init):
    """Subpasses on a CPU grid: each rewritten pixel becomes a hash of its
    neighbors within the stage's radius (reads outside the region clamped, as
    the shaders' are); only the ``rects`` (block texels) when given."""
    from infinitex.engine.params import subpass_order
    state = init.copy()
    n = -1
    for passes, r in stages:
        for order in subpass_order(s, passes):
            for ph in order:
                n += 1
                new = state.copy()
                bx0, by0, bx1, by1 = (0, 0, dims[0] // s, dims[1] // s) if rects is None else rects[n]
                for by in range(by0, by1):
                    for bx in range(bx0, bx1):
                        x, y = s * bx + ph[0], s * by + ph[1]
                        acc = n + 1
                        for dy in range(-r, r + 1):
                            for dx in range(-r, r + 1):
                                v = state[min(max(y + dy, 0), dims[1] - 1), min(max(x + dx, 0), dims[0] - 1)]
                                acc = (acc * 1000003 + int(v)) & 0xFFFFFFFF
                        new[y, x] = acc
                state = new
    return state


@settings(max_examples=25, deadline=None)
@given(s=st.integers(1, 3), c=st.integers(0, 2), rc=st.integers(1, 2), f=st.integers(0, 2), rf=st.integers(1, 3),
       w=st.integers(1, 9), h=st.integers(1, 9))
def test_subpass_rects_give_the_interior_exactly(s, c, rc, f, rf, w, h):
    """Rendering only params.subpass_rects leaves the strip exactly as rendering
    every block whole (and renders less whenever there is a margin)."""
    from infinitex.engine.params import subpass_rects
    stages = ((c, rc), (f, rf))
    m = correction_margins(s, c, rc, ((f, rf),))
    x0, y0 = m[0] + (-m[0]) % s, m[2] + (-m[2]) % s  # the region s-aligned, as Pyramid.padded
    dims = (x0 + w + m[1] + (-(x0 + w + m[1])) % s, y0 + h + m[3] + (-(y0 + h + m[3])) % s)
    rects = subpass_rects(s, stages, dims, (x0, y0, x0 + w, y0 + h))
    assert rects is not None
    init = np.random.default_rng(w * 10 + h).integers(0, 2 ** 31, (dims[1], dims[0]))
    full = _simulate(s, stages, dims, None, init)
    part = _simulate(s, stages, dims, rects, init)
    assert np.array_equal(full[y0:y0 + h, x0:x0 + w], part[y0:y0 + h, x0:x0 + w])
    if c + f:
        area = sum(max(0, b[2] - b[0]) * max(0, b[3] - b[1]) for b in rects)
        assert area < len(rects) * (dims[0] // s) * (dims[1] // s)


def test_the_projection_tables_and_the_float_projection_agree(analyses, gpu, monkeypatch):
    """Large exemplars project neighborhoods in floats instead of reading the
    per-texel tables (gpu.TABLE_MAX_BYTES): the same integers either way."""
    import infinitex.engine.gpu as gpu_module
    an = analyses["gravel-appearance"]
    rect = Rect.of(-FAR + 40, 333, 72, 56)
    with Synthesizer(an, gpu=gpu) as synth:
        assert synth.gan.projection_tables
        tables = synth.window(rect)
    monkeypatch.setattr(gpu_module, "TABLE_MAX_BYTES", 0)
    with Synthesizer(an, gpu=gpu) as synth:
        assert not synth.gan.projection_tables and synth.gan.level(an.L).proj_float
        floats = synth.window(rect)
    assert np.array_equal(tables, floats)


def test_textures_are_never_a_power_of_two_and_hold_their_data(gpu):
    """llvmpipe compiles a shader variant per combination of its textures'
    power-of-two sides: strips of changing sizes would compile new ones mid-stroke
    (about a second each, cold). Storage is never a power of two; data sits at 0,0."""
    rng = np.random.default_rng(3)
    for w, h in [(64, 32), (60, 30), (1, 1), (2, 5)]:
        data = rng.integers(-3000, 3000, size=(h, w, 2)).astype(np.int16)
        tex = gpu.int_texture((w, h), 2, data)
        sw, sh = tex.size
        assert sw in (w, w + 1) and sh in (h, h + 1)
        assert all(n == 1 or n & (n - 1) for n in (sw, sh))
        fbo = gpu.ctx.framebuffer([tex])
        back = np.frombuffer(fbo.read(viewport=(0, 0, w, h), components=2, dtype="i2", alignment=1), np.int16)
        assert np.array_equal(back.reshape(h, w, 2), data)
        fbo.release()
        tex.release()
    u = gpu.u16_texture(np.arange(16 * 8, dtype=np.uint16).reshape(8, 16))
    assert u.size == (17, 9)
    u.release()
