"""Painted randomness (LH05 4.2): fields over the exemplar and over the canvas.

The GL passes equal the numpy oracle with both fields, overlapping windows
agree bit for bit near 0 and near +-2^30, a neutral field changes nothing,
a calm canvas gives the exact tiling, a calm exemplar region is copied in
larger verbatim patches, and toroidal tiles stay periodic."""
import numpy as np
import oracle
import pytest

from bench.measures import verbatim_regions
from infinitex.engine.controls import NEUTRAL, TILE, CanvasField, Controls, ExemplarField, modulated_rq
from infinitex.engine.params import SynthParams
from infinitex.engine.pyramid import Rect
from infinitex.engine.synth import Synthesizer

FAR = 2 ** 30


def exemplar_field(m: int, seed: int = 3) -> ExemplarField:
    rng = np.random.default_rng(seed)
    v = np.full((m, m), NEUTRAL, np.uint16)
    v[m // 4:m // 2, m // 8:m // 2] = 0                      # a protected block
    v[3 * m // 4:, :] = rng.integers(0, 65536, (m - 3 * m // 4, m), dtype=np.uint16)  # rough noise
    return ExemplarField(v)


def canvas_field(x: int, y: int, seed: int = 5) -> CanvasField:
    rng = np.random.default_rng(seed)
    region = rng.integers(0, 65536, (150, 170), dtype=np.uint16)
    region[40:90, 30:120] = 0
    return CanvasField.from_image(region, x, y)


def test_modulation_arithmetic(gpu):
    assert modulated_rq(614, NEUTRAL, NEUTRAL) == 614       # neutral: unchanged, exactly
    assert modulated_rq(614, 0, 65535) == 0
    assert modulated_rq(614, 65535, 65535) == 1024          # clamped to r = 1
    assert modulated_rq(600, NEUTRAL, 16384) == 300
    # The shader's function (common.glsl) equals the numpy one on 65,536 inputs.
    import moderngl

    from infinitex.engine.gpu import GLSL_VERSION, read_shader
    rng = np.random.default_rng(0)
    n = 256
    rq = rng.integers(0, 1025, (n, n))
    e = rng.integers(0, 65536, (n, n))
    c = rng.integers(0, 65536, (n, n))
    e[::7] = NEUTRAL
    c[:, ::5] = NEUTRAL
    src = GLSL_VERSION + "\n#define SUB_S 2\n" + read_shader("common.glsl") + """
        uniform usampler2D inp;
        out ivec4 result;
        void main() {
            uvec4 v = texelFetch(inp, ivec2(gl_FragCoord.xy), 0);
            result = ivec4(modulated_rq(int(v.x), v.y, v.z), 0, 0, 0);
        }"""
    vert = GLSL_VERSION + "\n" + read_shader("fullscreen.vert")
    gpu.activate()  # another test may have made its own context current
    prog = gpu.ctx.program(vertex_shader=vert, fragment_shader=src)
    vao = gpu.ctx.vertex_array(prog, [(gpu.quad, "2f", "in_pos")])
    inp = gpu.uint_texture((n, n), np.stack([rq, e, c, np.zeros_like(rq)], axis=-1))
    out = gpu.ctx.texture((n, n), 1, dtype="i4")
    fbo = gpu.ctx.framebuffer([out])
    inp.use(0)
    prog["inp"].value = 0
    fbo.use()
    fbo.viewport = (0, 0, n, n)
    vao.render(moderngl.TRIANGLES)
    got = np.frombuffer(out.read(), dtype=np.int32).reshape(n, n)
    for o in (fbo, out, inp, vao, prog):
        o.release()
    assert np.array_equal(got, modulated_rq(rq, e, c))


@pytest.mark.parametrize("k", [0, 1, 2, 3, 5])
def test_field_levels_equal_the_oracle_reading(analyses, k):
    """The engine's tiled mipmaps equal the oracle's dense reductions."""
    an = analyses["gravel-appearance"]
    rng = np.random.default_rng(k)
    f = CanvasField.from_image(rng.integers(0, 65536, (300, 260), dtype=np.uint16), -1000, 777)
    e = ExemplarField(rng.integers(0, 65536, (an.size, an.size), dtype=np.uint16))
    level = an.L - k
    x0, y0 = (-1000 >> k) - 3, (777 >> k) - 2
    gy, gx = np.mgrid[y0:y0 + (320 >> k) + 6, x0:x0 + (300 >> k) + 6]
    ux = rng.integers(-an.size, 2 * an.size, gx.shape)
    uy = rng.integers(-an.size, 2 * an.size, gx.shape)
    E, C = oracle.field_values(Controls(e, f), an, SynthParams.default(an.L), level, ux, uy, gx, gy)
    assert np.array_equal(f.region(k, x0, y0, gx.shape[1], gx.shape[0]), C)
    m = an.size
    assert np.array_equal(e.level(an.L, level)[(uy & (m - 1)) >> k, (ux & (m - 1)) >> k], E)


@pytest.mark.parametrize("which", ["exemplar", "canvas", "both"])
@pytest.mark.parametrize("x, y", [(-20, 30), (FAR - 150, -FAR + 60)])
def test_gl_matches_oracle_with_fields(analyses, gpu, which, x, y):
    an = analyses["gravel-appearance"]
    e = exemplar_field(an.size) if which != "canvas" else None
    c = canvas_field(x - 40, y - 30) if which != "exemplar" else None
    controls = Controls(e, c)
    params = SynthParams.default(an.L, seed=4)
    gl = Synthesizer(an, params, gpu=gpu, controls=controls).window(Rect.of(x, y, 40, 36))
    ref = oracle.synthesize(an, params, x, y, 40, 36, controls=controls)
    assert np.array_equal(gl, ref)
    plain = Synthesizer(an, params, gpu=gpu).window(Rect.of(x, y, 40, 36))
    assert not np.array_equal(gl, plain)  # the fields do something here


@pytest.mark.parametrize("ox, oy", [(0, 0), (FAR - 300, -FAR + 100), (-FAR + 10, FAR - 400)])
def test_overlapping_windows_agree_with_fields(analyses, gpu, ox, oy):
    an = analyses["gravel-appearance"]
    controls = Controls(exemplar_field(an.size), canvas_field(ox + 20, oy + 10))
    synth = Synthesizer(an, SynthParams.default(an.L), gpu=gpu, controls=controls)
    big = synth.window(Rect.of(ox, oy, 200, 160))
    small = synth.window(Rect.of(ox + 37, oy + 21, 90, 101))
    assert np.array_equal(small, big[21:122, 37:127])
    viewport = synth.viewport()
    try:  # a panning viewport, in another order, gives the same pixels
        viewport.show(Rect.of(ox + 100, oy + 80, 100, 80))
        viewport.show(Rect.of(ox, oy, 120, 100))
        assert np.array_equal(viewport.read(Rect.of(ox, oy, 120, 100)), big[:100, :120])
    finally:
        viewport.release()


def test_neutral_fields_change_nothing(analyses, gpu):
    an = analyses["gravel-appearance"]
    params = SynthParams.default(an.L, seed=2)
    neutral = Controls(ExemplarField(np.full((an.size, an.size), NEUTRAL, np.uint16)),
                       CanvasField.from_image(np.full((100, 100), NEUTRAL, np.uint16), -50, -50))
    a = Synthesizer(an, params, gpu=gpu, controls=neutral).window(Rect.of(-60, -60, 90, 90))
    b = Synthesizer(an, params, gpu=gpu).window(Rect.of(-60, -60, 90, 90))
    assert np.array_equal(a, b)
    assert neutral.normalized() == Controls()


def test_calm_canvas_on_a_toroidal_exemplar_is_the_exact_tiling(analyses, gpu):
    an = analyses["torus-appearance"]
    m = an.size
    x, y = -77, 1234
    calm = CanvasField.from_image(np.zeros((400, 400), np.uint16), x - 150, y - 150)
    synth = Synthesizer(an, SynthParams.default(an.L, seed=8), gpu=gpu, controls=Controls(None, calm))
    S = synth.window(Rect.of(x, y, 64, 48))
    gy, gx = np.mgrid[y:y + 48, x:x + 64]
    # All jitter off: S = p + c mod m for one constant offset c (the exact tiling).
    dx, dy = (S[..., 0] - gx) % m, (S[..., 1] - gy) % m
    assert (dx == dx[0, 0]).all() and (dy == dy[0, 0]).all()


def test_calm_exemplar_region_is_copied_in_larger_patches(analyses, gpu):
    an = analyses["gravel-appearance"]
    m = an.size
    v = np.full((m, m), NEUTRAL, np.uint16)
    v[:, : m // 2] = 0  # protect the left half of the exemplar
    params = SynthParams.default(an.L, seed=1)
    rect = Rect.of(0, 0, 256, 256)
    calm = Synthesizer(an, params, gpu=gpu, controls=Controls(ExemplarField(v))).window(rect)
    plain = Synthesizer(an, params, gpu=gpu).window(rect)

    def left_patch_mean(S):
        mean_px, _ = verbatim_regions(S, m, toroidal=an.toroidal, mask=S[..., 0] < m // 2)
        return mean_px
    assert left_patch_mean(calm) > 1.5 * left_patch_mean(plain)


def test_toroidal_tile_with_a_canvas_field_is_periodic(analyses, gpu):
    an = analyses["gravel-appearance"]
    field = canvas_field(0, 0)
    synth = Synthesizer(an, SynthParams.default(an.L), gpu=gpu, controls=Controls(None, field))
    tile = synth.toroidal(64)
    plain = Synthesizer(an, SynthParams.default(an.L), gpu=gpu).toroidal(64)
    assert tile.shape == (64, 64, 2) and not np.array_equal(tile, plain)
    # One period of a periodic texture: the same tile at another period offset.
    params = synth.params
    from dataclasses import replace
    synth.params = replace(params, period=64)
    shifted = synth.window(Rect.of(64 * 3, -64 * 2, 64, 64))
    synth.params = params
    assert np.array_equal(shifted, tile)


def test_canvas_field_tiles_and_mips():
    region = np.arange(100 * 130, dtype=np.uint32).reshape(100, 130).astype(np.uint16)
    f = CanvasField.from_image(region, -70, 45)
    assert all(t.shape == (TILE, TILE) for t in f.tiles.values())
    assert np.array_equal(f.region(0, -70, 45, 130, 100), region)
    assert f.region(0, 1000, 1000, 10, 10) is None
    half = f.region(1, -36, 22, 66, 51)
    assert half is not None and half.shape == (51, 66)


def test_local_updates_after_20_strokes_equal_a_fresh_synthesis(analyses, gpu):
    an = analyses["gravel-appearance"]
    rng = np.random.default_rng(11)
    params = SynthParams.default(an.L, seed=6)
    x0, y0 = FAR - 5000, -FAR + 3000
    view = Rect.of(x0, y0, 180, 140)
    synth = Synthesizer(an, params, gpu=gpu)
    vp = synth.viewport()
    field = CanvasField()
    efield = None
    try:
        for i in range(20):
            zoom = int(rng.integers(0, 3))
            level = an.L - zoom
            lv = Rect(view.x0 >> zoom, view.y0 >> zoom, (view.x1 >> zoom) + 1, (view.y1 >> zoom) + 1)
            vp.show(lv, zoom)
            before = vp.read(lv, zoom)
            # A stroke of 4 dabs: inside, across the border of, or outside the view.
            where = rng.choice(["inside", "across", "outside"])
            cx = x0 + {"inside": 90, "across": -10, "outside": 900}[where] + rng.integers(-30, 30)
            cy = y0 + {"inside": 70, "across": 140, "outside": -700}[where] + rng.integers(-30, 30)
            value = int(rng.choice([0, 65535, NEUTRAL, 20000]))
            if i % 5 == 4:  # a stroke on the exemplar field: the whole canvas changes
                efield = (efield or ExemplarField.blank(an.size)).painted(
                    float(rng.integers(0, an.size)), float(rng.integers(0, an.size)), 12.0, value)
                vp.pyramid.update_controls(Controls(efield, field), [])
                vp.show(lv, zoom)
                after = vp.read(lv, zoom)
                fresh = Synthesizer(an, params, gpu=gpu, controls=Controls(efield, field)).window(lv, level)
                assert np.array_equal(after, fresh), f"exemplar stroke {i}"
                continue
            old = field
            for d in range(4):
                field, r = field.painted(cx + 7 * d, cy + 3 * d, float(rng.integers(5, 40)), value,
                                         strength=float(rng.uniform(0.3, 1)), hardness=float(rng.uniform(0, 1)))
            changed = [Rect(*r) for r in old.changed_rects(field)]
            vp.pyramid.update_controls(Controls(efield, field), changed)
            after = vp.read(lv, zoom)
            fresh = Synthesizer(an, params, gpu=gpu, controls=Controls(efield, field)).window(lv, level)
            assert np.array_equal(after, fresh), f"stroke {i} ({where}, zoom 1/{1 << zoom})"
            # Pixels beyond every dab's reach did not change.
            if changed:
                pyr = vp.pyramid
                reach = [oracle.reach_bound(pyr, c) for c in changed]
                ys, xs = np.mgrid[lv.y0:lv.y1, lv.x0:lv.x1]
                near = np.zeros(xs.shape, bool)
                for rr in reach:
                    k = zoom
                    near |= ((xs >= rr.x0 >> k) & (xs < -((-rr.x1) >> k)) & (ys >= rr.y0 >> k)
                             & (ys < -((-rr.y1) >> k)))
                assert np.array_equal(after[~near], before[~near])
            if where == "outside":
                assert np.array_equal(after, before)
    finally:
        vp.release()
