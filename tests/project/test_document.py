"""The document model, project files, undo/redo and autosave: no GL, no window."""
import json
import os
import sys
from dataclasses import replace

import pytest

from infinitex.project import (
    EMBED_LIMIT,
    Autosave,
    Display,
    Document,
    ExemplarSource,
    History,
    Project,
    ProjectError,
    View,
    load_project,
    project_to_json,
    save_project,
)

ASSETS = os.path.join(os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__)))), "infinitex", "assets")


@pytest.fixture
def doc():
    return Document(ExemplarSource.from_file(os.path.join(ASSETS, "gravel.png")))


def test_document_model_imports_neither_gl_nor_imgui():
    import subprocess
    code = ("import sys, infinitex.project, infinitex.project.realize; "
            "bad = [m for m in sys.modules if m.split('.')[0] in ('moderngl', 'imgui_bundle', 'glfw')]; "
            "print(bad); sys.exit(1 if bad else 0)")
    root = os.path.dirname(os.path.dirname(ASSETS))
    assert subprocess.run([sys.executable, "-c", code], cwd=root).returncode == 0


def test_undo_redo_and_slider_drag_is_one_step(doc):
    h = History(doc)
    assert not h.dirty and not h.can_undo()
    for v in (0.1, 0.2, 0.3):  # one drag: three values, one group
        h.apply(doc.with_jitter(7, 3, v), "Randomness", group=("jitter", 3))
    h.end_group()
    h.apply(replace(h.current, seed=5), "Seed")
    assert len(h.undo_stack) == 2 and h.dirty
    assert h.undo() and h.current.seed == 0 and h.current.jitter_for(7)[3] == pytest.approx(0.3)
    assert h.undo() and h.current == doc and not h.dirty
    assert not h.undo()
    assert h.redo() and h.redo() and h.current.seed == 5
    assert not h.redo()
    h.undo()
    h.apply(replace(h.current, seed=9), "Seed")  # a new edit clears redo
    assert not h.can_redo()


def test_each_step_carries_where_it_changed_the_canvas(doc):
    """An edit's region reaches the synthesis through the history: a stroke's
    dabs are one step with their union, an undo and a redo say it again, and
    what changed between two documents is known only while the older one was
    current lately (else None: the synthesis compares the controls)."""
    from infinitex.project.history import JOURNAL
    h = History(doc)
    d0 = h.current
    stroke = object()
    for i in range(3):  # one stroke, three frames of dabs
        h.apply(replace(h.current, seed=10 + i), "Paint", group=stroke, region=[(i, 0, i + 4, 4)])
    h.end_group()
    d1 = h.current
    assert h.undo_stack[-1].region == ((0, 0, 4, 4), (1, 0, 5, 4), (2, 0, 6, 4))
    assert sorted(h.changes_between(d0, d1)) == sorted(h.undo_stack[-1].region)
    assert h.changes_between(d1, d1) == ()
    h.apply(replace(h.current, seed=2), "New seed")  # a panel's edit says nothing
    d2 = h.current
    assert h.changes_between(d1, d2) is None and h.changes_between(d0, d2) is None
    h.undo()
    assert h.current is d1 and h.changes_between(d2, d1) is None  # undoing the seed: not said either
    h.undo()
    assert h.current is d0 and h.changes_between(d1, d0) == ((0, 0, 4, 4), (1, 0, 5, 4), (2, 0, 6, 4))
    h.redo()
    assert h.changes_between(d0, h.current) == ((0, 0, 4, 4), (1, 0, 5, 4), (2, 0, 6, 4))
    assert h.changes_between(d2, h.current) is None          # d2 is not what came before
    assert h.changes_between(h.current, d0) is None          # only towards the current document
    base = h.current
    for i in range(JOURNAL):
        h.apply(replace(h.current, seed=100 + i), "Paint", region=[(0, 0, 1, 1)])
    assert h.changes_between(base, h.current) is None        # too long ago: not known


def test_identical_edit_is_not_a_step_and_invalid_edit_is_refused(doc):
    h = History(doc)
    assert not h.apply(doc, "nothing")
    with pytest.raises(ProjectError):
        h.apply(replace(doc, passes=99), "bad")
    assert h.current == doc and not h.can_undo()


def test_jitter_is_matched_by_feature_size_across_exemplar_sizes(doc):
    d = doc.with_jitter(7, 7, 0.1).with_jitter(7, 0, 0.9)   # finest and coarsest of 8 levels
    assert d.jitter_for(7)[7] == 0.1 and d.jitter_for(7)[0] == 0.9
    j = d.jitter_for(8)                                        # a 256^2 exemplar: one more coarse level
    assert j[8] == 0.1 and j[1] == 0.9 and j[0] == 0.6


def test_passes_per_level_follow_the_exemplar_and_reach_the_synthesis(doc):
    assert doc.passes_for(7) == (0, 0, 0, 2, 2, 2, 2, 2) and doc.params(7).level_passes is None
    assert replace(doc, passes=3, corrected=(1, 7)).passes_for(7) == (0, 3, 0, 0, 0, 0, 0, 3)
    d = doc.with_level_passes(7, 7, 4).with_level_passes(7, 1, 1)
    assert d.level_passes == (0, 1, 0, 2, 2, 2, 2, 4)
    p = d.params(7)
    assert [p.passes_at(l) for l in range(8)] == [0, 1, 0, 2, 2, 2, 2, 4]
    # Matched from the finest level down: a 256^2 exemplar's extra coarse level gets none.
    assert d.passes_for(8) == (0, 0, 1, 0, 2, 2, 2, 2, 4)
    assert doc.with_level_passes(7, 7, 99).passes_for(7)[7] == 8
    with pytest.raises(ProjectError, match="per level"):
        replace(doc, level_passes=(2, 9)).validate()


def test_project_round_trip_per_level_passes(doc, tmp_path):
    proj = Project(doc.with_level_passes(7, 6, 4))
    path = tmp_path / "p.itex"
    save_project(str(path), proj)
    back = load_project(str(path))
    assert back == proj and back.document.params(7).passes_at(6) == 4
    saved = json.loads(path.read_text())
    assert saved["synthesis"]["level_passes"] == [0, 0, 0, 2, 2, 2, 4, 2]
    del saved["synthesis"]["level_passes"]  # projects from before per-level passes: one count
    path.write_text(json.dumps(saved))
    assert load_project(str(path)).document.level_passes == ()
    for bad in ([2, "x"], [2, 9], [True], "2"):
        saved["synthesis"]["level_passes"] = bad
        path.write_text(json.dumps(saved))
        with pytest.raises(ProjectError, match="level_passes"):
            load_project(str(path))


def test_structure_reaches_the_synthesis_and_round_trips(doc, tmp_path):
    from infinitex.engine.params import DEFAULT_STRUCTURE, STRUCTURE_LEVELS
    assert doc.structure == DEFAULT_STRUCTURE and doc.params(7).fidelity is not None
    assert replace(doc, structure=0).params(7).fidelity is None  # Variety: the per-pixel synthesis alone
    strong = replace(doc, structure=STRUCTURE_LEVELS - 1)
    assert sum(strong.params(7).fidelity) > sum(doc.params(7).fidelity)
    assert strong.params(7).fidelity_radius > doc.params(7).fidelity_radius
    assert strong.params(7).jitter == doc.params(7).jitter == doc.jitter_for(7)  # the randomness as set
    with pytest.raises(ProjectError, match="Structure"):
        replace(doc, structure=STRUCTURE_LEVELS).validate()
    path = tmp_path / "s.itex"
    save_project(str(path), Project(replace(doc, structure=3)))
    saved = json.loads(path.read_text())
    assert saved["version"] == 6 and saved["synthesis"]["structure"] == 3
    assert load_project(str(path)).document.structure == 3
    del saved["synthesis"]["structure"]  # a project from before the fidelity stage keeps its texture
    path.write_text(json.dumps(saved))
    assert load_project(str(path)).document.structure == 0
    for bad in (9, -1, "3", True, 2.5):
        saved["synthesis"]["structure"] = bad
        path.write_text(json.dumps(saved))
        with pytest.raises(ProjectError, match="structure"):
            load_project(str(path))


def test_project_round_trip_embedded(doc, tmp_path):
    d = replace(doc.with_all_jitter(7, 0.25), seed=42, passes=3, kappa=0.75, corrected=(4, 5, 6, 7), toroidal=True,
                fit="crop-2048", k=0, feature_weight=0.75)
    proj = Project(d, View(123.5, -4.25, 0.5), Display("patches", 3, "nearest"))
    path = tmp_path / "p.itex"
    save_project(str(path), proj)
    back = load_project(str(path))
    assert back == proj
    saved = json.loads(path.read_text())
    assert saved["exemplar"]["embedded"] and saved["analysis"]["feature_weight"] == 0.75
    del saved["analysis"]["feature_weight"]  # projects from before the channel existed: off
    path.write_text(json.dumps(saved))
    assert load_project(str(path)).document.feature_weight == 0.0
    saved["analysis"]["feature_weight"] = 9
    path.write_text(json.dumps(saved))
    with pytest.raises(ProjectError, match="feature_weight"):
        load_project(str(path))


def test_project_referencing_a_large_exemplar_checks_its_hash(doc, tmp_path):
    img = tmp_path / "ex.png"
    img.write_bytes(doc.exemplar.data)
    d = replace(doc, exemplar=ExemplarSource.from_file(str(img)))
    path = tmp_path / "p.itex"
    save_project(str(path), Project(d), embed=False)
    data = json.loads(path.read_text())
    assert data["exemplar"]["embedded"] is None and data["exemplar"]["path"] == "ex.png"
    assert load_project(str(path)).document.exemplar.sha256 == d.exemplar.sha256
    img.write_bytes(doc.exemplar.data + b"changed")
    with pytest.raises(ProjectError, match="does not match"):
        load_project(str(path))
    img.unlink()
    with pytest.raises(ProjectError, match="cannot be found"):
        load_project(str(path))
    assert EMBED_LIMIT >= 1 << 20


@pytest.mark.parametrize("content, words", [
    (b"", "not an Infinitex project"),
    (b"\x00\xff garbage", "not an Infinitex project"),
    (b"[1, 2]", "not an Infinitex project"),
    (b'{"format": "something-else"}', "not an Infinitex project"),
    (b'{"format": "infinitex-project", "version": 99}', "newer version"),
    (b'{"format": "infinitex-project", "version": 1}', "lacks project.exemplar"),
])
def test_broken_or_foreign_files_are_refused(tmp_path, content, words):
    p = tmp_path / "x.itex"
    p.write_bytes(content)
    with pytest.raises(ProjectError, match=words):
        load_project(str(p))


def test_damaged_fields_are_refused(doc, tmp_path):
    good = project_to_json(Project(doc))
    cases = [("synthesis", "passes", 99, "passes"), ("synthesis", "jitter", ["a"], "jitter"),
             ("analysis", "model", "neural", "model"), ("exemplar", "sha256", "0" * 64, "does not match"),
             ("exemplar", "embedded", "!!!", "damaged"), ("synthesis", "seed", True, "wrong type")]
    for section, key, value, words in cases:
        d = json.loads(json.dumps(good))
        d[section][key] = value
        p = tmp_path / "x.itex"
        p.write_text(json.dumps(d))
        with pytest.raises(ProjectError, match=words):
            load_project(str(p))
    with pytest.raises(ProjectError, match="No such file"):
        load_project(str(tmp_path / "missing.itex"))


def test_failed_save_keeps_the_previous_file(doc, tmp_path, monkeypatch):
    path = tmp_path / "p.itex"
    save_project(str(path), Project(doc))
    before = path.read_bytes()

    def boom(*a, **k):
        raise OSError(28, "No space left on device")
    monkeypatch.setattr(os, "replace", boom)
    with pytest.raises(ProjectError, match="No space left"):
        save_project(str(path), Project(replace(doc, seed=7)))
    assert path.read_bytes() == before
    assert [f.name for f in tmp_path.iterdir()] == ["p.itex"]  # no temporary file left behind
    with pytest.raises(ProjectError):
        save_project(str(tmp_path / "no" / "such" / "dir.itex"), Project(doc))


def test_autosave_recovers_after_a_crash(doc, tmp_path):
    a = Autosave(str(tmp_path / "auto.itex"), interval=0.0)
    assert a.pending() is None
    assert not a.tick(Project(doc), dirty=False)
    edited = Project(replace(doc, seed=3), View(10, 20, 2.0))
    assert a.tick(edited, dirty=True)
    assert not a.tick(edited, dirty=True)  # unchanged: not rewritten
    # A new session (after a crash: the writer's lock went with it) finds it:
    a.release()
    assert Autosave(a.path).pending() == edited
    a.clear()
    assert Autosave(a.path).pending() is None


def test_view_zoom_keeps_the_point_under_the_cursor():
    v = View(100.0, 50.0, 1.0)
    w, h, sx, sy = 800, 600, 123.0, 456.0
    x0, y0 = v.x - w / 2, v.y - h / 2
    before = (x0 + sx / v.zoom, y0 + sy / v.zoom)
    z = v.zoom_at(2.0 ** 0.25, sx, sy, w, h)
    after = (z.x - w / (2 * z.zoom) + sx / z.zoom, z.y - h / (2 * z.zoom) + sy / z.zoom)
    assert after == pytest.approx(before)
    assert View(0, 0, 1.0).zoom_at(1e-6, 0, 0, w, h).zoom == 1 / 64
    assert View(0, 0, 1.0).zoom_at(1e6, 0, 0, w, h).zoom == 16
    assert View(0.3, 0.7, 1.0).top_left(101, 51) == (-50, -25)  # 1:1 snaps to whole pixels


def test_settings_keep_recent_files_and_survive_damage(tmp_path):
    from infinitex.app.settings import RECENT_MAX, Settings, load_settings, save_settings
    path = str(tmp_path / "settings.json")
    assert load_settings(path) == Settings()
    s = Settings()
    for i in range(RECENT_MAX + 3):
        s = s.with_recent(str(tmp_path / f"f{i}.png"))
    s = s.with_recent(str(tmp_path / "f5.png"))  # reopened: moves to the top, no duplicate
    assert len(s.recent) == RECENT_MAX and s.recent[0].endswith("f5.png") and len(set(s.recent)) == RECENT_MAX
    s = Settings(s.recent, (1600, 900), ("Advanced", "Randomness"))
    assert save_settings(s, path) and load_settings(path) == s
    for bad in (b"\xff\xfe", b"[" * 100000, b'{"recent": "x", "window": [1, 2]}', b'{"recent": [1, "rel.png"]}'):
        with open(path, "wb") as f:
            f.write(bad)
        got = load_settings(path)
        assert got.window is None and all(os.path.isabs(r) for r in got.recent)


def test_autosave_remembers_which_project_it_belongs_to(tmp_path):
    from infinitex.project import Autosave, View
    doc = Document(ExemplarSource.from_file(os.path.join(ASSETS, "gravel.png")), seed=5)
    a = Autosave(str(tmp_path / "autosave.itex"))
    proj = Project(doc, View(120.0, -40.0, 2.0), origin=str(tmp_path / "mine.itex"))
    assert a.tick(proj, True, force=True)
    a.release()  # as when its process ends
    back = Autosave(str(tmp_path / "autosave.itex")).pending()
    assert back.origin == str(tmp_path / "mine.itex") and back.view == proj.view and back.document.seed == 5
    assert "autosave_of" not in project_to_json(Project(doc))  # ordinary saves do not carry it
