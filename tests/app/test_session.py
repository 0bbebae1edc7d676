"""The editor's engine side on a headless context: what the canvas shows is
exactly what the engine and the export produce, whatever the refinement path."""
import os
import subprocess
import sys
from dataclasses import replace

import numpy as np
import pytest
from PIL import Image

from infinitex.project import Display, Document, ExemplarSource, Project, View, save_project
from infinitex.app.render.canvas import Canvas
from infinitex.app.session import Session, frame_for
from infinitex.export import decode_coords, encode_coords
from infinitex.export.window import ExportJob, colors_u8
from infinitex.engine.controls import CanvasField, Controls
from infinitex.engine.pyramid import Rect, SynthesisError

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))


@pytest.fixture(scope="module")
def session(gpu):
    s = Session(gpu)
    s.load_now(Document(ExemplarSource.from_file(os.path.join(ROOT, "infinitex", "assets", "gravel.png"))))
    yield s
    s.release()


def _refine(session, frame, budget=0.01):
    for _ in range(10000):
        if session.refine(frame, budget):
            return
    raise AssertionError("refinement did not finish")


def _rgb(a):
    return np.repeat(a, 3, axis=2) if a.shape[2] == 1 else a[..., :3]


@pytest.mark.parametrize("zoom", [1.0, 0.25])
def test_canvas_equals_the_engine_window(session, gpu, zoom):
    canvas = Canvas(gpu)
    canvas.set_exemplar(session.stack, session.analysis.toroidal, None, session.generation)
    W, H = 200, 120
    canvas.ensure_size(W, H)
    view = View(-123456.4, 98765.2, zoom)
    frame = frame_for(view, W, H, session.L)
    _refine(session, frame)
    canvas.render(session.pyramid, frame, view, Display())
    shown = canvas.read()
    s = round(1 / zoom)
    tlx, tly = view.top_left(W, H)
    rect = Rect.of(int(tlx) // s, int(tly) // s, W, H)
    coords = session.synth.window(rect, level=frame.level)
    assert np.array_equal(shown, _rgb(colors_u8(session.stack, coords, frame.level)))
    canvas.release()


def test_progressive_refinement_equals_one_shot(session, gpu):
    """A tiny budget (many bands, a pan in the middle) ends bit-identical."""
    W, H = 150, 100
    v1, v2 = View(5000.0, -7000.0, 1.0), View(5037.0, -6990.0, 1.0)
    for v in (v1, v2):
        for _ in range(3):
            session.refine(frame_for(v, W, H, session.L), 0.002)
    frame = frame_for(v2, W, H, session.L)
    _refine(session, frame, 0.002)
    got = session.pyramid.read(frame.level, frame.want)
    assert np.array_equal(got, session.synth.window(frame.want))


def test_a_jump_synthesizes_each_level_once(session, gpu, monkeypatch):
    """Refined a level at a time in small budgets, a view far from what is held
    costs what one request of it costs: each coarse level is asked at once for
    all that the finer levels' targets (prefetch, chunks) will read, never sent
    back for more strips (it was 1.5-2.5x as many pixels per coarse level)."""
    from infinitex.engine.pyramid import Pyramid
    frame = frame_for(View(-3.0e6, 2.0e6, 1.0), 300, 200, session.L)
    total = 0
    for _ in range(10000):
        done = session.refine(frame, 0.002)
        total += session.refiner.last_pixels
        if done:
            break
    fresh = Pyramid(gpu, session.synth.gan, session.params, scrolling=True, prefetch=16, controls=session.controls)
    once = fresh.request(frame.level, frame.want)
    assert np.array_equal(session.pyramid.read(frame.level, frame.want), fresh.read(frame.level, frame.want))
    fresh.release()
    assert total <= 1.02 * once, (total, once)


def test_a_request_in_progress_survives_pans_edits_and_paint(session):
    """The view refines a piece of a draw at a time; a pan away, a parameter
    change and a paint dab in the middle of a request leave the pyramid
    consistent, and the end is the fresh synthesis of the final document."""
    W, H = 160, 120
    params0, controls0 = session.params, session.controls
    pyr = session.pyramid
    try:
        frame = frame_for(View(20000.0, 300.0, 1.0), W, H, session.L)
        for _ in range(100):
            session.refine(frame, 0.0005)
            if pyr.requests.current is not None and not pyr.requests.advance(0.0):  # a piece, not the whole request
                break
        level, rect = pyr.requests.current
        frame2 = frame_for(View(-90000.0, 300.0, 1.0), W, H, session.L)
        session.refine(frame2, 0.0005)  # the request no longer wanted is dropped
        assert pyr.requests.current is None or pyr.requests.current[1] != rect
        for _ in range(100):
            session.refine(frame2, 0.0005)
            if pyr.requests.current is not None:
                break
        assert pyr.requests.current is not None
        p2 = replace(params0, seed=params0.seed + 1)
        session.synth.set_params(p2, controls0)
        pyr.set_params(p2, controls0)
        assert pyr.requests.current is None  # dropped with the levels it depended on
        for _ in range(5):
            session.refine(frame2, 0.001)
        cx, cy = ((frame2.want.x0 + frame2.want.x1) / 2, (frame2.want.y0 + frame2.want.y1) / 2)
        field, _ = CanvasField().painted(cx, cy, 24.0, 0)
        c2 = Controls(randomness_canvas=field)
        session.synth.set_params(p2, c2)
        pyr.update_controls(c2, defer=True)
        _refine(session, frame2, 0.001)
        assert np.array_equal(pyr.read(frame2.level, frame2.want), session.synth.window(frame2.want))
    finally:
        session.synth.set_params(params0, controls0)
        pyr.set_params(params0, controls0)


@pytest.mark.parametrize("zoom", [1.0, 0.5, 3.0])
def test_redrawing_only_what_changed_equals_a_full_redraw(session, gpu, zoom, monkeypatch):
    """The editor redraws only the canvas pixels whose texels the synthesis
    changed (SpreadRequests.take_touched), a few rows a frame where that is much
    (Canvas.redraw); whenever nothing waits, the canvas equals a full redraw."""
    from infinitex.app.render import canvas as canvas_module
    monkeypatch.setattr(canvas_module, "REDRAW_PX", 3000)  # spread at this small size too
    W, H = 180, 140
    a, b = Canvas(gpu), Canvas(gpu)
    for c in (a, b):
        c.set_exemplar(session.stack, session.analysis.toroidal, None, session.generation)
        c.ensure_size(W, H)
    view = View(777.3, -4242.6, zoom)
    frame = frame_for(view, W, H, session.L)
    session.pyramid.invalidate(0)
    source = ("test",)
    a.redraw(session.pyramid, frame, view, Display(), None, source)  # a first, full render
    boxes = []
    render = a.render
    monkeypatch.setattr(a, "render", lambda *args, **kw: boxes.append(kw.get("box")) or render(*args, **kw))
    field, _ = CanvasField().painted(777.0, -4242.0, 12.0, 65535)  # twice the randomness: seen on any level
    controls0 = session.controls
    spread = 0
    try:
        for controls in (controls0, Controls(randomness_canvas=field)):  # a fresh view, then a dab on it
            if controls is not controls0:
                session.synth.set_params(session.params, controls)
                session.pyramid.update_controls(controls, defer=True)
                shown = a.read()
            for i in range(10000):
                done = session.refine(frame, 0.001)  # short steps: the write-backs end between frames
                a.redraw(session.pyramid, frame, view, Display(), None, source)
                b.render(session.pyramid, frame, view, Display())
                if a.pending is None:
                    assert np.array_equal(a.read(), b.read())
                else:
                    spread += 1
                if controls is not controls0 and i == 0:
                    # The dab shows in the frame it was made (a quick look), long before it is exact.
                    assert session.pyramid.looks.patches and not done
                    assert not np.array_equal(a.read(), shown)
                if done and a.pending is None:
                    break
            assert done
    finally:
        session.synth.set_params(session.params, controls0)
        session.pyramid.set_params(session.params, controls0)
    assert spread > 0 and all(box is not None for box in boxes)  # (no full render after the first)
    assert any(box[2] * box[3] < W * H for box in boxes)
    a.release()
    b.release()


def test_preview_completes_whole_levels(session):
    session.pyramid.invalidate(0)
    frame = frame_for(View(0.0, 0.0, 1.0), 300, 200, session.L)
    done = session.refiner.coarse(frame, 0.0, min_level=2)
    assert done == 2
    assert session.refiner.holds(2, session.pyramid.plan(frame.level, frame.want)[2])


def test_the_canvas_never_draws_levels_magnified_past_8x(session, gpu):
    """Levels coarser than the view's less PREVIEW_MAX_K stay undrawn (the
    canvas's background) where nothing finer is held: a strip a pan uncovers
    shows no melted coarse texture; from that level on the texture shows."""
    from infinitex.app.render.canvas import PREVIEW_MAX_K
    canvas = Canvas(gpu)
    canvas.set_exemplar(session.stack, session.analysis.toroidal, None, session.generation)
    W, H = 96, 64
    canvas.ensure_size(W, H)
    view = View(5000.0, -7000.0, 1.0)
    frame = frame_for(view, W, H, session.L)
    session.pyramid.invalidate(0)
    plan = session.pyramid.plan(frame.level, frame.want)
    coarse = frame.level - PREVIEW_MAX_K - 1
    for l in range(coarse + 1):
        session.pyramid.request(l, plan[l])
    canvas.render(session.pyramid, frame, view, Display())
    empty = canvas.read()
    assert (empty == empty[0, 0]).all()  # nothing but the background
    session.pyramid.request(coarse + 1, plan[coarse + 1])
    canvas.render(session.pyramid, frame, view, Display())
    assert canvas.read().std() > 5  # the level magnified 8x: texture
    canvas.release()


def test_export_is_independent_of_tiles_and_matches_the_window(session, tmp_path):
    rect = Rect.of(-70, 33, 150, 97)
    a = ExportJob(session, rect, str(tmp_path / "a.png"), tile=64, coords_path=str(tmp_path / "a_coords.png"))
    a.run()
    b = ExportJob(session, rect, str(tmp_path / "b.png"), tile=512)
    b.run()
    ia, ib = np.asarray(Image.open(tmp_path / "a.png")), np.asarray(Image.open(tmp_path / "b.png"))
    assert np.array_equal(ia, ib)
    coords = session.synth.window(rect)
    assert np.array_equal(decode_coords(np.asarray(Image.open(tmp_path / "a_coords.png"))), coords)
    assert np.array_equal(ia, colors_u8(session.stack, coords, session.L)[..., 0])


def test_toroidal_export_wraps_seamlessly(session, tmp_path):
    job = ExportJob(session, Rect(0, 0, 64, 64), str(tmp_path / "t.png"), toroidal=64, tile=48)
    job.run()
    tile = job.coords
    assert np.array_equal(tile, session.synth.toroidal(64))


def test_export_cancel_and_limits(session, tmp_path):
    job = ExportJob(session, Rect(0, 0, 400, 400), str(tmp_path / "c.png"), tile=64)
    job.step(0.0)
    job.cancel()
    assert job.step() and job.cancelled and not (tmp_path / "c.png").exists()
    with pytest.raises(SynthesisError, match="limited"):
        ExportJob(session, Rect(0, 0, 20000, 10), str(tmp_path / "x.png"))
    with pytest.raises(SynthesisError, match="empty"):
        ExportJob(session, Rect(0, 0, 0, 10), str(tmp_path / "x.png"))


def test_coordinate_map_encoding_is_exact():
    rng = np.random.default_rng(0)
    c = rng.integers(0, 4096, size=(20, 30, 2)).astype(np.int32)
    assert np.array_equal(decode_coords(encode_coords(c)), c)


def test_export_cli_matches_the_editor_export(session, tmp_path):
    doc = Document(ExemplarSource.from_file(os.path.join(ROOT, "infinitex", "assets", "gravel.png")))
    doc = replace(doc, seed=0)
    proj = tmp_path / "p.itex"
    save_project(str(proj), Project(doc, View(10.0, 20.0, 1.0)))
    out = tmp_path / "cli.png"
    r = subprocess.run([sys.executable, "main.py", "export", str(proj), "-o", str(out), "--rect", "-5", "7", "90", "60",
                        "--coords", "-q"], cwd=ROOT, capture_output=True, text=True)
    assert r.returncode == 0, r.stderr
    job = ExportJob(session, Rect.of(-5, 7, 90, 60), str(tmp_path / "ed.png"))
    job.run()
    assert np.array_equal(np.asarray(Image.open(out)), np.asarray(Image.open(tmp_path / "ed.png")))
    assert (tmp_path / "cli_coords.png").exists()
    bad = subprocess.run([sys.executable, "main.py", "export", str(tmp_path / "nope.itex"), "-o", str(out)],
                         cwd=ROOT, capture_output=True, text=True)
    assert bad.returncode != 0 and "error:" in bad.stderr and "Traceback" not in bad.stderr


def test_canvas_magnification_equals_the_exports(session, gpu):
    """At 800% the canvas draws what an export magnified 8x writes (LH05
    section 5 with the shear pull, canvas.frag = Material.magnified), within
    the 8-bit display stack's rounding; gravel's 1 px sheared seams included."""
    canvas = Canvas(gpu)
    canvas.set_exemplar(session.stack, session.analysis.toroidal, None, session.generation)
    W, H, z = 160, 96, 8
    canvas.ensure_size(W, H)
    view = View(-4000.0 + W / (2 * z), 7000.0 + H / (2 * z), float(z))
    assert view.top_left(W, H) == (-4000.0, 7000.0)
    frame = frame_for(view, W, H, session.L)
    _refine(session, frame)
    canvas.render(session.pyramid, frame, view, Display())
    shown = canvas.read().astype(np.int64)
    coords = session.synth.window(Rect.of(-4001, 6999, W // z + 2, H // z + 2))
    want = _rgb(np.rint(session.material.magnified(session.material.primary, coords, z) * 255)).astype(np.int64)
    assert np.abs(shown - want).max() <= 3
    canvas.release()


def test_a_quick_preview_shows_first_then_the_full_analysis(gpu, tmp_path):
    """Opening an image not yet in the cache: the session installs a quick
    analysis without similarity sets first (a texture at once), then the full
    one; the second time (cached) there is no preview. Exports and the command
    line (LoadedDocument) never get a preview."""
    import time
    from infinitex.engine.analysis import search_k
    from infinitex.export.loaded import LoadedDocument
    doc = Document(ExemplarSource.from_file(os.path.join(ROOT, "infinitex", "assets", "gravel.png")))
    s = Session(gpu, cache_dir=str(tmp_path))
    s.load(doc)
    seen = []
    quick = None
    t = time.monotonic() + 300
    while time.monotonic() < t:
        job = s.poll()
        if job is not None:
            seen.append((s.quick_analysis, search_k(s.analysis.settings, s.analysis.size), s.generation))
            quick = quick or s.analysis
            if job.done:
                break
        time.sleep(0.01)
    assert seen == [(True, 0, 1), (False, 2, 2)], seen
    assert s.analysis.levels[3].nbhd is quick.levels[3].nbhd  # the full analysis took the preview's work
    assert s.key == doc.analysis_key()
    # The preview is a real texture of the same exemplar (the random-walk search).
    s.release()
    s2 = Session(gpu, cache_dir=str(tmp_path))
    s2.load(doc)
    s2.job.wait()
    assert s2.job.preview is None  # the full analysis is cached: no preview needed
    s2.poll()
    assert not s2.quick_analysis and s2.generation == 1
    s2.release()
    plain = LoadedDocument(gpu, cache_dir=str(tmp_path / "other"))
    job = plain.load(doc)
    job.wait()
    assert job.preview is None and plain.poll() is job and not plain.quick_analysis
    plain.release()


def test_direction_jacobians_after_a_dab_equal_a_fresh_computation(gpu):
    """The canvas keeps each level's J texture and rewrites only the tiles a
    comb dab changed; it holds what a fresh computation gives, at every level."""
    from types import SimpleNamespace

    from infinitex.engine.controls import DirectionField
    from infinitex.engine.controls.direction import jacobian
    canvas = Canvas(gpu)
    field = DirectionField().painted(40.0, 30.0, 20.0, jacobian(30.0, 1.2), 1.0)[0]
    for k, r in [(0, Rect(-50, -40, 150, 120)), (2, Rect(-20, -15, 40, 30))]:
        pyr = SimpleNamespace(controls=SimpleNamespace(direction=field), params=SimpleNamespace(period=0))
        canvas._jacobians(pyr, (k, False), k, r)
        dabbed = field
        for cx in (10.0, 70.0, 130.0):
            dabbed = dabbed.painted(cx, 60.0, 16.0, jacobian(-50.0, 0.8), 0.7)[0]
        pyr.controls.direction = dabbed
        tex = canvas._jacobians(pyr, (k, False), k, r)
        fbo = gpu.ctx.framebuffer([tex])
        got = np.frombuffer(fbo.read(viewport=(0, 0, r.w, r.h), components=4, dtype="i2", alignment=1), np.int16)
        fbo.release()
        assert np.array_equal(got.reshape(r.h, r.w, 4), dabbed.region(k, r.x0, r.y0, r.w, r.h)), k
        assert not np.array_equal(dabbed.region(k, r.x0, r.y0, r.w, r.h), field.region(k, r.x0, r.y0, r.w, r.h))
    canvas.release()
