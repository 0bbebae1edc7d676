"""Texture in motion (LH06 7; engine/advect.py, engine/controls/flow.py).

A frame is a function of (document, flow, frame number, pixel): overlapping
windows of a frame agree bit for bit near 0 and near +-2^30; a window of frame
t computed alone equals the same window reached by playing from frame 0; a
loop's frame N is its frame 0 (on the canvas and on a toroidal tile, which
stays periodic in every frame); a uniform integer velocity slides the static
texture rigidly; renewal replaces the old chain within a period without ever
blending two textures; the velocity map is sampled exactly as documented."""
import numpy as np
import pytest

from infinitex.engine.advect import SEAM, VOTE, FlowFrames, SynthSource
from infinitex.engine.controls.flow import MAX_FRAME, Q, Flow, FlowError, VelocityMap
from infinitex.engine.rect import Rect
from infinitex.engine.synth import Synthesizer

FAR = 2 ** 30


def vortex(w: int, h: int, speed: float = 1.5, x: int = 0, y: int = 0) -> VelocityMap:
    ys, xs = np.mgrid[0:h, 0:w].astype(np.float64)
    dx, dy = xs - w / 2, ys - h / 2
    r = np.hypot(dx, dy) + 1e-9
    s = speed * np.clip(r / (w / 4), 0, 1)
    return VelocityMap(np.rint(np.stack([-dy / r * s, dx / r * s], -1) * Q).astype(np.int32), x, y)


@pytest.fixture(scope="module")
def synth(analyses, gpu):
    s = Synthesizer(analyses["torus-appearance"], gpu=gpu)
    yield s
    s.release()


def frames(synth, flow, period=0, seed=3):
    return FlowFrames(SynthSource(synth, period), flow, seed)


@pytest.mark.parametrize("near", [0, FAR, -FAR])
def test_overlapping_windows_of_a_frame_agree(synth, near):
    flow = Flow(map=vortex(48, 40, x=near - 10, y=near - 4), period=4)
    a = frames(synth, flow).frame(6, Rect.of(near - 16, near - 16, 40, 32))
    b = frames(synth, flow).frame(6, Rect.of(near, near - 8, 32, 40))
    np.testing.assert_array_equal(a[8:, 16:], b[:24, :24])
    assert a.shape == (32, 40, 4)


def test_a_frame_alone_equals_the_frame_reached_by_playing(synth):
    flow = Flow(map=vortex(40, 40, x=-4, y=-4), period=4)
    rect = Rect.of(0, 0, 32, 32)
    player = frames(synth, flow)
    played = [player.frame(t, rect) for t in range(11)]
    for t in (3, 4, 9, 10):  # within a period, at a renewal, and later
        np.testing.assert_array_equal(frames(synth, flow).frame(t, rect), played[t])
    moved = sum(int(np.any(played[t] != played[t + 1])) for t in range(10))
    assert moved == 10  # the texture moves every frame


def test_a_loop_closes_exactly(synth):
    flow = Flow(map=vortex(40, 40, x=-4, y=-4), period=4, loop=8)
    f = frames(synth, flow)
    rect = Rect.of(0, 0, 32, 32)
    np.testing.assert_array_equal(f.frame(8, rect), f.frame(0, rect))
    np.testing.assert_array_equal(f.frame(13, rect), f.frame(5, rect))
    assert np.any(f.frame(7, rect) != f.frame(0, rect))


def test_a_flipbook_tile_stays_periodic_in_every_frame(synth):
    n = 32
    flow = Flow(map=vortex(n, n), period=4, loop=8)
    f = frames(synth, flow, period=n)
    for t in (1, 5, 7):
        a = f.frame(t, Rect.of(0, 0, n, n))
        b = f.frame(t, Rect.of(n - 8, 4, n, n))  # the same tile, one period on
        np.testing.assert_array_equal(np.roll(a, (-4, -(n - 8)), (0, 1)), b)
    np.testing.assert_array_equal(f.frame(8, Rect.of(0, 0, n, n)), f.frame(0, Rect.of(0, 0, n, n)))


def test_a_uniform_velocity_slides_the_static_texture(synth):
    flow = Flow.of(2.0, -1.0, period=4)
    f = frames(synth, flow)
    rect = Rect.of(100, 50, 24, 24)
    static = synth.window(Rect.of(100 - 2 * 9, 50 + 9, 24, 24), remainder=True)
    np.testing.assert_array_equal(f.frame(9, rect), static)  # frame t shows T(p - t V): no renewal seams
    half = frames(synth, Flow.of(0.5, 0.0, period=4))
    c = half.frame(1, rect)
    assert np.all(np.abs(c[..., 2]) + np.abs(c[..., 3]) > 0)  # half a pixel: the rest as a remainder


def test_renewal_swaps_chains_without_blending(synth):
    flow = Flow(map=vortex(160, 160, speed=0.5, x=-32, y=-32), period=8)
    f = FlowFrames(SynthSource(synth), flow, 3, gl=False)  # the numpy composition, whose parts are read here
    rect = Rect.of(0, 0, 96, 96)  # several blobs (engine/advect.py BLOB)
    (ko, bo, ao), (kn, bn, an) = f.chains(11)
    assert (ao, an) == (11 - 0, 11 - 8) and bn == 8
    composite, _, seam = f._frame(11, rect, False)
    m = VOTE + SEAM  # the window _frame worked on: rect and these margins
    old = f._chain(ko, bo, ao)[0][m:-m, m:-m]
    new = f._chain(kn, bn, an)[0][m:-m, m:-m]
    from_old = np.all(composite == old, -1)
    from_new = np.all(composite == new, -1)
    assert np.all(from_old | from_new)  # every pixel is one chain's, never a mix
    assert from_new.mean() > 0.2 and from_old.mean() > 0.2  # halfway through the period: both show
    # The correction mends the cuts between them, and touches nothing else (the seams
    # as frame() finds them: over the correction's region, so those near rect's edge too).
    region = f.source.correction_region(rect)
    seam = f._frame(11, region, False)[2][rect.y0 - region.y0:rect.y1 - region.y0,
                                           rect.x0 - region.x0:rect.x1 - region.x0]
    shown = f.frame(11, rect)
    changed = np.any(shown != composite, -1)
    assert changed.any() and not np.any(changed & ~seam) and seam.mean() < 0.9
    last, _, _ = f._frame(15, rect, False)  # the period's last frame: the new chain everywhere
    np.testing.assert_array_equal(last, f._chain(kn, bn, an + 4)[0][m:-m, m:-m])


def test_velocity_map_sampling_is_bilinear_in_integers():
    vals = np.zeros((2, 2, 2), np.int32)
    vals[0, 0] = (256, 0)
    vals[1, 1] = (0, -512)
    flow = Flow(velocity=(10, 20), map=VelocityMap(vals, 5, 7))
    vx, vy = flow.sample(np.array([5 * Q, 5 * Q + 128, 6 * Q, 4 * Q]), np.array([7 * Q, 7 * Q + 128, 8 * Q, 7 * Q]))
    assert vx.tolist() == [10 + 256, 10 + 64, 10, 10 + 0]
    assert vy.tolist() == [20, 20 - 128, 20 - 512, 20]
    # The map convention: red right, green up (OpenGL) unless y_up is False; 0.5 is still.
    up = VelocityMap.from_unit(np.array([[[1.0, 1.0], [0.5, 0.0]]]), speed=2.0)
    assert up.values.tolist() == [[[512, -512], [0, 512]]]
    down = VelocityMap.from_unit(np.array([[[127 / 255, 1.0]]]), speed=2.0, y_up=False)
    assert down.values.tolist() == [[[0, 512]]]


def test_bad_flows_get_one_sentence(synth):
    for bad, words in [(dict(period=1), "renewal period"), (dict(period=6, loop=16), "divides"),
                       (dict(distortion=0.0), "distortion")]:
        with pytest.raises(FlowError, match=words):
            Flow(**bad).validate()
    with pytest.raises(FlowError, match="px per frame"):
        Flow.of(40.0, 0.0)
    with pytest.raises(FlowError, match="px per frame"):
        Flow.of(float("nan"), 0.0)
    with pytest.raises(FlowError, match="at most"):
        VelocityMap(np.full((2, 2, 2), 33 * Q, np.int32))
    with pytest.raises(FlowError, match="0 to"):
        frames(synth, Flow()).chains(MAX_FRAME)


def test_the_suggested_period_follows_the_shear():
    assert Flow.of(3.0, 1.0).suggested_period() == 16  # uniform: nothing stretches
    gentle, strong = vortex(128, 128, speed=0.5), vortex(128, 128, speed=3.0)
    p_gentle, p_strong = Flow(map=gentle).suggested_period(), Flow(map=strong).suggested_period()
    assert 6 <= p_strong < p_gentle <= 32
    assert Flow(map=strong).suggested_period(loop=48) in (2, 3, 4, 6, 8, 12, 16, 24, 48)
    assert 48 % Flow(map=gentle).suggested_period(loop=48) == 0
    with pytest.raises(FlowError, match="divides it"):
        Flow(map=gentle).suggested_period(loop=131)


@pytest.mark.parametrize("near", [0, -FAR])
def test_the_cuts_are_corrected_as_the_numpy_oracle_corrects(synth, near):
    """The GL part of a frame (the finest level's correction of the composite)
    against tests/oracle.py's subpasses on the same state."""
    import oracle
    from infinitex.engine.params import subpass_order
    flow = Flow(map=vortex(128, 112, speed=1.0, x=near - 16, y=near - 16), period=8)
    f = frames(synth, flow)
    rect = Rect.of(near, near, 96, 80)
    region = f.source.correction_region(rect)
    raw, _, seam = f._frame(11, region, False)
    assert seam.any()
    gl = f.source.correct(rect, raw)
    an, p, L = synth.analysis, synth.params, synth.L
    S = raw[..., :2].astype(np.int64)
    n = 0
    for order in subpass_order(p.subgrid, p.passes_at(L)):
        for phase in order:
            S = oracle.correct_subpass(S, phase, (region.x0, region.y0), an, p, L, synth.controls, n)
            n += 1
    if p.fidelity_at(L):
        S = oracle.fidelity_stage(S, (region.x0, region.y0), an, p, L, synth.controls)
    y, x = slice(rect.y0 - region.y0, rect.y1 - region.y0), slice(rect.x0 - region.x0, rect.x1 - region.x0)
    np.testing.assert_array_equal(gl[..., :2], S[y, x])
    assert np.any(gl[..., :2] != raw[y, x, :2])  # it did correct something


@pytest.mark.parametrize("near", [0, FAR, -FAR])
def test_gl_composes_frames_as_the_numpy_oracle(synth, near):
    """engine/advect_gl.py (the passes the frames are made with) against
    engine/advect.py's numpy composition: coordinates and seams, bit for bit,
    within a period, at a renewal and played in order."""
    flow = Flow(map=vortex(96, 96, x=near - 16, y=near - 8), period=8)
    rect = Rect.of(near, near, 64, 48)
    gl, ref = frames(synth, flow), FlowFrames(SynthSource(synth), flow, 3, gl=False)
    assert gl._gl is not None and ref._gl is None
    for t in (0, 5, 11, 12):
        a, b = gl._frame(t, rect, False), ref._frame(t, rect, False)
        np.testing.assert_array_equal(a[0], b[0])
        np.testing.assert_array_equal(a[2], b[2])
    gl.release()


def test_gl_composes_tiles_and_uniform_flows_as_the_oracle(synth):
    n = 32
    for flow, period, rect in ((Flow(map=vortex(n, n), period=4, loop=8), n, Rect(0, 0, n, n)),
                               (Flow.of(1.5, -0.5, period=4), 0, Rect.of(100, 50, 40, 40))):
        gl = FlowFrames(SynthSource(synth, period), flow, 3)
        ref = FlowFrames(SynthSource(synth, period), flow, 3, gl=False)
        for t in (1, 6):
            a, b = gl._frame(t, rect, False), ref._frame(t, rect, False)
            np.testing.assert_array_equal(a[0], b[0])
            np.testing.assert_array_equal(a[2], b[2])
        gl.release()


def test_a_velocity_map_is_tiles_shared_between_edits():
    """A map is held as tiles on the canvas grid: dense in, dense out, the
    same key however it was made; a dab changes only the tiles it touches
    (the others are the same objects: an undo step costs what it changed)
    and moves each texel toward the target by its weight, growing the map."""
    from infinitex.engine.controls.fields import dab_weights
    from infinitex.engine.controls.flow import TILE
    rng = np.random.default_rng(3)
    vals = rng.integers(-900, 900, (150, 170, 2)).astype(np.int32)
    vals[40:110, 20:90] = 0  # a still hole: tiles there are not kept
    m = VelocityMap(vals, -77, 45)
    np.testing.assert_array_equal(m.values, vals)
    assert (m.x, m.y, m.w, m.h) == (-77, 45, 170, 150) and m.peak == int(np.abs(vals).max())
    assert m == VelocityMap(m.values.copy(), -77, 45) and m != VelocityMap(vals, -76, 45)
    w = dab_weights(300.5, 120.0, 30.0, 0.5, 270, 90, 62, 62)
    p = m.painted(270, 90, w, (512, -256))
    assert (p.x, p.y, p.w, p.h) == (-77, 45, 270 + 62 + 77, 150)  # grown to hold the dab
    expect = np.zeros((p.h, p.w, 2), np.float64)
    expect[:150, :170] = vals
    sub = expect[90 - 45:152 - 45, 270 + 77:332 + 77]
    sub += (np.array([512, -256]) - sub) * w[..., None]
    np.testing.assert_array_equal(p.values, np.rint(expect).astype(np.int32))
    touched = {(tx, ty) for tx in range(270 // TILE, -(-332 // TILE)) for ty in range(90 // TILE, -(-152 // TILE))}
    assert all(p.tiles[k] is m.tiles[k] for k in m.tiles if k not in touched)
    # Sampling the painted map is sampling its dense values.
    X = rng.integers(-100 * Q, 400 * Q, 500)
    Y = rng.integers(30 * Q, 210 * Q, 500)
    a = Flow(map=p).sample(X, Y)
    b = Flow(map=VelocityMap(np.array(p.values), p.x, p.y)).sample(X, Y)
    assert np.array_equal(a[0], b[0]) and np.array_equal(a[1], b[1])
    # Laid over: the other map's rectangle replaced; erased to still, no tile is left.
    top = VelocityMap(np.full((10, 20, 2), 7, np.int32), 0, 100)
    merged = m.merged(top)
    assert np.all(merged.values[55:65, 77:97] == 7)
    np.testing.assert_array_equal(merged.values[:55], vals[:55])
    full = np.ones((m.h, m.w))
    assert not m.painted(m.x, m.y, full, (0, 0)).tiles
    with pytest.raises(FlowError, match="at most 256 px"):
        m.painted(400, 90, w, (1, 1), limit=256)


def test_a_draft_is_the_uncorrected_frame_colored_within_a_level(synth):
    """What the editor plays: the uncorrected frame's coordinates, colored in GL
    from the map's 8 bits; within one level of the exports' float colors, the
    same in the numpy composition."""
    from infinitex.engine.imagefile import to_u8
    from infinitex.engine.subpixel import sample
    flow = Flow(map=vortex(48, 48, x=-8, y=-8), velocity=(100, -30), period=4)
    rect = Rect.of(-4, 2, 40, 36)
    pal = to_u8(synth.analysis.levels[synth.L].stack)
    ref_coords = FlowFrames(SynthSource(synth), flow, 3, correct=False).frame(6, rect)
    ref = to_u8(sample(synth.analysis.levels[synth.L].stack, ref_coords, synth.analysis.toroidal))
    ref = np.repeat(ref[..., :1], 3, axis=2) if ref.shape[2] < 3 else ref[..., :3]
    for gl in (True, False):
        draft = FlowFrames(SynthSource(synth), flow, 3, gl=gl).draft_rgb(6, rect, pal)
        assert draft.shape == (36, 40, 3) and draft.dtype == np.uint8
        diff = np.abs(draft.astype(int) - ref.astype(int))
        assert diff.max() <= 1, (gl, diff.max())
        assert np.any(ref_coords[..., 2:] != 0)  # (sub-pixel rests were sampled)


def test_an_erased_corner_gives_its_room_back_and_loops_never_rewind(synth):
    from infinitex.engine.controls.fields import dab_weights
    w = dab_weights(16.0, 16.0, 12.0, 0.5, 0, 0, 32, 32)
    m = VelocityMap(np.zeros((1, 1, 2), np.int32), 0, 0).painted(0, 0, w, (300, 0))
    m = m.painted(1000, 0, w, (300, 0))
    assert m.w > 1000
    m = m.painted(1000, 0, np.ones((32, 32)), (0, 0))  # erased: the map is the first dab's again
    assert m.w <= 64 and m.x == 0 and np.array_equal(m.values[:32, :32, 0] > 0, w > 0)
    # A loop of 9 chains (9 = 1 mod 8): its last chain, which runs into its first, starts elsewhere.
    loop = FlowFrames(SynthSource(synth), Flow(map=vortex(32, 32), period=4, loop=36), 3)
    offsets = [loop.key_offset(k) for k in range(9)]
    assert offsets[8] != offsets[0] and offsets[8] != offsets[7]
    assert all(offsets[k] != offsets[k + 1] for k in range(8))
