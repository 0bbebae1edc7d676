"""Painted randomness in documents, project files, the session and the CLI."""
import base64
import io
import json
import os
from dataclasses import replace

import numpy as np
import pytest
from clirun import infinitex
from PIL import Image

from infinitex.project import (
    Document,
    ExemplarSource,
    History,
    Project,
    ProjectError,
    load_project,
    project_to_json,
    save_project,
)
from infinitex.app.session import Frame, Session
from infinitex.export.window import ExportJob
from infinitex.engine.controls import CanvasField, ExemplarField
from infinitex.engine.params import DEFAULT_STRUCTURE
from infinitex.engine.pyramid import Rect
from infinitex.engine.synth import Synthesizer

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
GRAVEL = os.path.join(ROOT, "infinitex", "assets", "gravel.png")


@pytest.fixture(scope="module")
def doc():
    return Document(ExemplarSource.from_file(GRAVEL))


def painted_doc(doc, m=128):
    rng = np.random.default_rng(2)
    c = CanvasField()
    for i in range(12):
        c, _ = c.painted(float(rng.uniform(-300, 300)), float(rng.uniform(-200, 200)), float(rng.uniform(5, 60)),
                         int(rng.integers(0, 65536)), float(rng.uniform(0.2, 1)), float(rng.uniform(0, 1)))
    e = ExemplarField.blank(m).painted(40, 50, 20, 0).painted(100, 90, 12, 65535, 0.5)
    return replace(doc, randomness_canvas=c, randomness_exemplar=e)


def test_project_round_trip_keeps_the_fields_exactly(doc, tmp_path):
    doc = replace(doc, structure=0)  # Variety: the version then says only what the fields need
    d = painted_doc(doc)
    path = tmp_path / "p.itex"
    save_project(str(path), Project(d))
    raw = json.loads(path.read_text())
    assert raw["version"] == 2 and len(raw["randomness"]["canvas"]["tiles"]) == len(d.randomness_canvas.tiles)
    back = load_project(str(path)).document
    assert back == d
    assert np.array_equal(back.randomness_exemplar.values, d.randomness_exemplar.values)
    for k, t in d.randomness_canvas.tiles.items():
        assert np.array_equal(back.randomness_canvas.tiles[k], t)
    # Without fields, the file stays version 1 (older readers open it).
    save_project(str(path), Project(doc))
    assert json.loads(path.read_text())["version"] == 1 and "randomness" not in json.loads(path.read_text())


def _png(a) -> str:
    buf = io.BytesIO()
    Image.fromarray(a).save(buf, "PNG")
    return base64.b64encode(buf.getvalue()).decode()


@pytest.mark.parametrize("damage", [
    lambda r: r["canvas"]["tiles"][0].update(png16="!!!"),
    lambda r: r["canvas"]["tiles"][0].update(png16=_png(np.zeros((64, 64), np.uint8))),      # 8-bit
    lambda r: r["canvas"]["tiles"][0].update(png16=_png(np.zeros((32, 64), np.uint16))),     # wrong size
    lambda r: r["canvas"]["tiles"].append(dict(r["canvas"]["tiles"][0])),                    # duplicate tile
    lambda r: r["canvas"]["tiles"][0].update(x=2 ** 40),
    lambda r: r["canvas"].update(tile=32),
    lambda r: r["exemplar"].update(png16=_png(np.zeros((100, 100), np.uint16))),             # not a power of two
    lambda r: r.update(canvas=[1, 2]),
])
def test_damaged_fields_are_project_errors(doc, tmp_path, damage):
    d = project_to_json(Project(painted_doc(doc)))
    damage(d["randomness"])
    p = tmp_path / "p.itex"
    p.write_text(json.dumps(d))
    with pytest.raises(ProjectError, match="randomness field"):
        load_project(str(p))


def test_undo_memory_grows_with_what_was_painted(doc):
    """Each stroke stores only the tiles it touched; untouched tiles are shared."""
    h = History(doc)
    field = CanvasField()
    touched = set()
    for stroke in range(10):
        g = object()
        for dab in range(20):
            field, r = field.painted(1000.0 * stroke + 3 * dab, 50.0, 20.0, 0)
            touched.add(stroke)
            h.apply(replace(h.current, randomness_canvas=field), "paint", group=g)
        h.end_group()
    arrays = {id(t) for d, *_ in h.undo_stack + [(h.current, "")] if d.randomness_canvas
              for t in d.randomness_canvas.tiles.values()}
    per_stroke = len(h.current.randomness_canvas.tiles) / 10
    # One copy of each tile a stroke touched, per stroke that touched it: no whole-field copies.
    assert len(arrays) <= len(h.current.randomness_canvas.tiles) * 1.0 + 1
    assert per_stroke <= 6  # a 100 x 40 px stroke touches at most 3 x 2 tiles


def settled_session(gpu, doc, want: Rect) -> tuple[Session, Frame]:
    """A session on ``doc`` whose view of ``want`` (finest level) is refined."""
    s = Session(gpu)
    s.load_now(doc)
    frame = Frame(level=s.L, want=want)
    while not s.refine(frame, 1.0):
        pass
    return s, frame


@pytest.mark.parametrize("structure", [0, DEFAULT_STRUCTURE])
def test_session_paints_locally_and_matches_a_fresh_synthesis(doc, gpu, tmp_path, structure):
    doc = replace(doc, structure=structure)
    s, frame = settled_session(gpu, doc, Rect.of(-200, -150, 400, 300))
    full = sum(s.pyramid.buffers[l].valid.w * s.pyramid.buffers[l].valid.h for l in range(s.L + 1))
    d = doc
    field = CanvasField()
    pixels = []
    for i in range(8 if structure == 0 else 4):  # at Balanced each dab re-synthesizes most of this view
        field, _ = field.painted(-100 + 25 * i, 10.0 + 3 * i, 24.0, 0)
        d = replace(d, randomness_canvas=field)
        s.sync(d)
        assert not s.pyramid.settled and s.pyramid.pixels_synthesized == 0  # a dab never holds the editor up
        n = 0
        while not s.refine(frame, 0.05):  # the refinement settles it a budget at a time
            n += s.refiner.last_pixels
        pixels.append(n + s.refiner.last_pixels)
        assert s.pyramid.settled
    got = s.pyramid.read(s.L, frame.want)
    fresh = Synthesizer(s.analysis, s.params, gpu=gpu, controls=d.controls(s.analysis.size)).window(frame.want)
    assert np.array_equal(got, fresh)
    if structure == 0:  # a dab re-synthesizes a part of the view (bench/paint.py measures it); the fidelity
        assert max(pixels) * 2 < full  # stage carries a change further (its margins), over most of this small view
    far, _ = field.painted(5000.0, 5000.0, 24.0, 0)
    s.sync(replace(d, randomness_canvas=far))
    assert s.refine(frame, 1.0) and s.refiner.last_pixels == 0  # paint outside what is held costs nothing now
    s.sync(d)
    # Exports use the fields too.
    job = ExportJob(s, Rect.of(-50, -20, 96, 64), os.path.join(str(tmp_path), "unused.png"))
    while not job.step(1.0):
        pass
    assert np.array_equal(job.coords, fresh[130:194, 150:246])
    s.release()


def test_a_pan_during_a_local_update_fills_the_view_and_ends_exact(doc, gpu):
    """At Balanced a dab's update spans many frames; panning meanwhile gets its
    share of each frame (the new area shows before the update ends) and the
    end is the fresh synthesis."""
    doc = replace(doc, structure=DEFAULT_STRUCTURE)
    s, frame = settled_session(gpu, doc, Rect.of(-200, -150, 300, 200))
    field, _ = CanvasField().painted(-60.0, -40.0, 30.0, 0)
    d = replace(doc, randomness_canvas=field)
    s.sync(d)
    assert not s.refine(frame, 0.01) and not s.pyramid.settled
    panned = Frame(level=s.L, want=Rect.of(-200 + 160, -150, 300, 200))
    steps = 0
    while not s.refiner.holds(s.L, panned.want):
        assert not s.refine(panned, 0.02)
        steps += 1
    assert not s.pyramid.settled  # the new area came first, the update is still going on
    while not s.refine(panned, 0.05):
        pass
    fresh = Synthesizer(s.analysis, s.params, gpu=gpu, controls=d.controls(s.analysis.size)).window(panned.want)
    assert np.array_equal(s.pyramid.read(s.L, panned.want), fresh)
    s.release()


def test_cli_maps(tmp_path):
    emap = np.full((128, 128), 128, np.uint8)
    emap[10:60, 10:90] = 0
    Image.fromarray(emap).save(tmp_path / "e.png")
    cmap = np.zeros((120, 200), np.uint8)
    Image.fromarray(cmap).save(tmp_path / "c.png")

    def run(*a):
        return infinitex(*a, "-q")  # in this process (tests/clirun.py)
    base = ["--size", "96", "80", "--origin", "-20", "-10"]
    assert run("synth", GRAVEL, "-o", str(tmp_path / "a.png"), *base).returncode == 0
    r = run("synth", GRAVEL, "-o", str(tmp_path / "b.png"), *base, "--randomness-canvas", str(tmp_path / "c.png"),
            "--randomness-origin", "-50", "-40", "--randomness-exemplar", str(tmp_path / "e.png"))
    assert r.returncode == 0, r.stderr
    a, b = np.asarray(Image.open(tmp_path / "a.png")), np.asarray(Image.open(tmp_path / "b.png"))
    assert not np.array_equal(a, b)
    r = run("export", GRAVEL, "-o", str(tmp_path / "c_out.png"), "--rect", "-20", "-10", "96", "80",
            "--randomness-canvas", str(tmp_path / "c.png"), "--randomness-origin", "-50", "-40",
            "--randomness-exemplar", str(tmp_path / "e.png"))
    assert r.returncode == 0, r.stderr
    assert np.array_equal(np.asarray(Image.open(tmp_path / "c_out.png")), b)  # synth = export
    (tmp_path / "bad.png").write_bytes(b"not an image")
    r = run("synth", GRAVEL, "-o", str(tmp_path / "x.png"), "--randomness-canvas", str(tmp_path / "bad.png"))
    assert r.returncode == 3 and len(r.stderr.strip().splitlines()) == 1 and "randomness map" in r.stderr
    assert not (tmp_path / "x.png").exists()


def test_the_canvas_label_overlay_rewrites_what_a_stroke_changed_exactly(gpu):
    """The overlay of the canvas labels after a dab (only the texels it changed
    rewritten) equals one made from scratch, at 1:1 and zoomed out."""
    from infinitex.app.render.overlays import LabelOverlay
    from infinitex.engine.controls import CanvasLabels
    colors = ((10, 20, 30), (200, 100, 50), (0, 255, 0))
    base = CanvasLabels.from_image(np.full((300, 500), 2, np.uint8), -120, -80)
    for zoom_out, radius in ((1, 20.0), (3000, 700.0)):  # 3000: the overlay holds every 2nd canvas pixel
        inc, fresh = LabelOverlay(gpu.ctx), LabelOverlay(gpu.ctx)
        labels = base
        w, h = 900 * zoom_out / 1000 + 400, 700 * zoom_out / 1000 + 300
        inc.canvas_labels(labels, colors, -200, -150, w, h)
        for i, (value, x) in enumerate(((3, 10.0), (0, 40.0), (1, 90.0))):
            labels, _ = labels.painted(x, 20.0 + 7 * i, radius, value, hardness=0.5, seed=i)
            tex = inc.canvas_labels(labels, colors, -200, -150, w, h)
            ref = fresh.canvas_labels(labels, colors, -200, -150, w, h)
            assert inc.placement == fresh.placement
            assert tex.read() == ref.read(), (zoom_out, i)
            fresh.release()
        inc.release()


def test_every_local_edit_is_refined_locally(doc):
    """A paint dab, a label dab, a feature move and a comb dab are re-synthesized
    in place (and shown at once as quick looks), not by the coarse preview a
    dragged slider gets; a change of a global setting is not local."""
    from infinitex.app.ui.canvas_refine import local_edit
    from infinitex.engine.controls import DirectionField
    from infinitex.engine.controls.direction import jacobian
    field, _ = CanvasField().painted(10.0, 10.0, 8.0, 0)
    combed, _ = DirectionField().painted(10.0, 10.0, 8.0, jacobian(30.0, 1.0), 1.0)
    assert local_edit(doc, replace(doc, randomness_canvas=field))
    assert local_edit(doc, replace(doc, direction=combed))
    assert not local_edit(doc, replace(doc, seed=doc.seed + 1))
    assert not local_edit(None, doc)


def test_a_dragged_control_previews_one_change_at_a_time(doc):
    """While a control is held, a change waits for the one in progress to be
    presentable (EditHold); released, the newest is taken at once and the
    picture kept until it is presentable; local edits never wait."""
    from infinitex.app.ui.canvas_refine import EditHold
    h = EditHold()
    a, b, c = doc, replace(doc, seed=doc.seed + 1), replace(doc, seed=doc.seed + 2)
    assert h.doc(a) is a and not h.waiting
    assert h.doc(b) is b and h.waiting  # a change: shown once presentable
    assert h.doc(c) is b  # the next waits while b's preview is coarse
    h.reached(3, 4)
    assert h.doc(c) is b and h.waiting
    h.reached(4, 4)
    assert not h.waiting and h.doc(c) is c and h.waiting
    d = replace(doc, seed=doc.seed + 3)
    assert h.doc(d, dragging=False) is d and h.waiting  # released: at once, the picture kept
    field, _ = CanvasField().painted(10.0, 10.0, 8.0, 0)
    e = replace(d, randomness_canvas=field)
    assert h.doc(e) is e and not h.waiting  # a dab: its own exact local update
    f = replace(e, seed=e.seed + 1)
    assert h.doc(f, holding=False) is f and not h.waiting  # a model shown: no hold


def test_the_hold_never_gives_way_to_an_empty_canvas(doc, monkeypatch):
    """However long a change takes to become presentable (a loaded machine),
    the picture is kept until it is: the canvas draws no level coarser than
    the presentable one, so giving way earlier shows it empty (a 10 s safety
    net did, on a loaded machine's slider drag: the flat grey of an empty
    canvas); and a drag's progress is never thrown away for a newer value."""
    from infinitex.app.ui import canvas_refine
    clock = [100.0]
    monkeypatch.setattr(canvas_refine.time, "monotonic", lambda: clock[0])
    h = canvas_refine.EditHold()
    a, b, c = doc, replace(doc, seed=doc.seed + 1), replace(doc, seed=doc.seed + 2)
    h.doc(a)
    assert h.doc(b) is b and h.waiting
    for level in (-1, 0, 3):
        clock[0] += 60.0
        h.reached(level, 4)
        assert h.waiting and h.doc(c) is b  # not presentable yet: the picture stays, b goes on
    h.reached(4, 4)
    assert not h.waiting and h.doc(c) is c and h.waiting  # presentable: shown, then the newest is taken


def test_every_control_round_trips_through_autosave_recovery_and_a_model(doc, tmp_path, monkeypatch):
    """Painted randomness (soft edges included), features, a combed direction
    field and labels survive an autosave and its recovery exactly; opening a
    model sets the plane's controls aside (the model's are painted in its
    atlas), they survive a save and a recovery while it is open, and closing
    the model brings them back exactly (the comb arch was gone after Open
    model, recovery and Close model)."""
    from infinitex.engine.controls import DirectionField, Feature
    from infinitex.engine.controls.direction import comb
    from infinitex.engine.surface.shapes import cube
    from infinitex.project import Autosave
    from infinitex.project.surface import SurfaceSettings
    monkeypatch.setenv("INFINITEX_STATE", str(tmp_path / "state"))
    d = painted_doc(doc)
    field = d.randomness_canvas
    for i in range(6):  # a soft band: its edges are not tile-shaped
        field, _ = field.painted(400.0 + 20 * i, -60.0 + 3 * i, 30.0, 0, 0.6, 0.1)
    direction = DirectionField()
    for i in range(8):  # a comb along an arch
        a = np.radians(20 * i)
        direction, _ = direction.edited(*_comb_box(600 + 80 * np.cos(a), 80 * np.sin(a)), comb(90 + 20 * i))
    d = replace(d, randomness_canvas=field, direction=direction,
                features=(Feature(exemplar=(40, 50), canvas=(120, -30), inner=12, outer=18),))

    def same(a, b):
        assert a == b
        for k, t in a.randomness_canvas.tiles.items():
            assert np.array_equal(b.randomness_canvas.tiles[k], t)
        assert a.direction.key == b.direction.key and a.features == b.features

    def recovered(x):  # what recovery reads (Autosave.pending_all loads the file a crashed editor left)
        auto = Autosave(str(tmp_path / "state" / "autosave.itex"))
        assert auto.tick(Project(x), dirty=True, force=True)
        back = load_project(auto.path).document
        auto.clear()
        return back

    same(d, recovered(d))
    with_model = d.with_model(SurfaceSettings(cube(n=2), 256, repeats=2.0))
    assert with_model.randomness_canvas is None and with_model.direction is None and not with_model.features
    painted_on_model, _ = CanvasField().painted(100.0, 100.0, 20.0, 65535)  # the model's own, in its atlas
    with_model = replace(with_model, randomness_canvas=painted_on_model)
    back = recovered(with_model)
    assert back.plane == with_model.plane and back.randomness_canvas == painted_on_model
    path = tmp_path / "m.itex"
    save_project(str(path), Project(back))
    closed = load_project(str(path)).document.without_model()
    same(d, closed)
    assert closed.surface is None and closed.plane is None
    with pytest.raises(ProjectError, match="model"):
        replace(d, plane=with_model.plane).validate()


def _comb_box(cx, cy, r=40):
    """A round comb dab's (x0, y0, weights) at (cx, cy)."""
    from infinitex.engine.controls.fields import dab_weights
    x0, y0 = int(cx - r), int(cy - r)
    return x0, y0, dab_weights(cx, cy, r, 0.5, x0, y0, 2 * r, 2 * r)


@pytest.mark.parametrize("tool_kind", ["paint", "comb", "smooth", "grow"])
def test_every_stroke_says_where_it_changed(doc, tool_kind):
    """A tool's edits carry their regions (Editor.edit(..., region=...)), and the
    synthesis redoes only those: every pixel a stroke changes is inside what
    it says, for the randomness brush and each direction mode, soft and hard."""
    from types import SimpleNamespace

    from imgui_bundle import imgui

    from infinitex.app.session import _reads_alike
    from infinitex.app.ui.tools.direction import DirectionTool
    from infinitex.app.ui.tools.paint import PaintCanvasTool
    from infinitex.engine.rect import uncovered
    from infinitex.project import View
    ctx = imgui.create_context()
    try:
        edits = []
        ed = SimpleNamespace(doc=doc, view=View(), history=None, tell=lambda text: None)

        def edit(d, label, group=None, region=None):
            edits.append((ed.doc, d, region))
            ed.doc = d
        ed.edit = edit
        tool = PaintCanvasTool(ed) if tool_kind == "paint" else DirectionTool(ed)
        if tool_kind != "paint":
            tool.mode = tool_kind
        rng = np.random.default_rng(5)
        for stroke in range(3):
            tool.brush.radius = float(rng.uniform(4, 30))
            tool.brush.hardness = float(rng.uniform(0, 1))
            if tool_kind == "paint":
                tool.brush.value = float(rng.uniform(0, 2))
            pts = np.cumsum(rng.normal(0, 9, (12, 2)), axis=0) + rng.uniform(-200, 200, 2)
            tool.press(tuple(pts[0]), (0, 0))
            for p in pts[1:]:
                tool.drag(tuple(p), (0, 0))
            tool.release()
        assert len(edits) > 10
        for before, after, region in edits:
            assert region is not None
            a, b = before.controls(128), after.controls(128)
            found = [Rect(*r) for r in a.changed_rects(b)]
            missed = [r for r in uncovered(found, [Rect(*r) for r in region]) if not _reads_alike(a, b, r)]
            assert not missed, (region, missed)
    finally:
        imgui.destroy_context(ctx)
