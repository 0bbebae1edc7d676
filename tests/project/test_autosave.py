"""Autosaves per editor process, large exemplars in autosaves, and where project
saves go (issue 29, items 3 to 5): two editors never remove each other's
unsaved work, every autosave can be recovered, a project save never lands on
an image or on the document's own inputs. No GL, no window."""
import hashlib
import json
import os
import signal
import subprocess
import sys
import time
from dataclasses import replace
from types import SimpleNamespace

import numpy as np
import pytest
from PIL import Image

import infinitex.project.format as fmt
from infinitex.project import (
    Autosave,
    Document,
    ExemplarSource,
    History,
    Project,
    ProjectError,
    View,
    load_project,
    project_save_path,
    save_project,
)

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
GRAVEL = os.path.join(ROOT, "infinitex", "assets", "gravel.png")


@pytest.fixture
def state(tmp_path, monkeypatch):
    d = tmp_path / "state"
    monkeypatch.setenv("INFINITEX_STATE", str(d))
    return d


@pytest.fixture
def doc():
    return Document(ExemplarSource.from_file(GRAVEL))


def noise_png(path, side: int, seed: int) -> bytes:
    """A PNG that does not compress (random noise): its file is about 3 * side^2 bytes."""
    a = np.random.default_rng(seed).integers(0, 256, (side, side, 3), dtype=np.uint8)
    Image.fromarray(a).save(path, compress_level=1)
    return open(path, "rb").read()


# An editor process that autosaves unsaved work, says where, then waits (until killed).
WRITER = """
import os, sys, time
from infinitex.project import Autosave, Document, ExemplarSource, Project
a = Autosave()
assert a.tick(Project(Document(ExemplarSource.from_file(sys.argv[1]), seed=int(sys.argv[2]))), True, force=True)
print(a.path, flush=True)
if sys.argv[3] == "wait":
    time.sleep(600)
"""


def start_writer(state, seed: int, wait: bool = True) -> tuple[subprocess.Popen, str]:
    env = dict(os.environ, INFINITEX_STATE=str(state))
    proc = subprocess.Popen([sys.executable, "-c", WRITER, GRAVEL, str(seed), "wait" if wait else "exit"],
                            cwd=ROOT, env=env, stdout=subprocess.PIPE, text=True)
    path = proc.stdout.readline().strip()
    assert path and os.path.isfile(path), f"the writer did not autosave ({proc.poll()})"
    return proc, path


# -- item 3: one autosave per editor process, with a lock --------------------------


def test_a_second_editor_closed_without_edits_leaves_the_first_one_s_autosave(state, doc):
    a, a_path = start_writer(state, seed=7)
    try:
        before = open(a_path, "rb").read()
        # Editor B starts (A is running: its work is not offered) and is closed without edits.
        b = Autosave()
        assert b.path != a_path and os.path.dirname(b.path) == os.path.dirname(a_path)
        assert b.pending_all() == []
        assert b.tick(Project(replace(doc, seed=1)), True, force=True)  # B had edits for a while...
        b.clear()                                                        # ...saved them...
        b.close()                                                        # ...and quit.
        assert not os.path.exists(b.path)
        assert open(a_path, "rb").read() == before  # A's unsaved work is still there, untouched
        # A third editor starting while A runs is not offered A's work either.
        c = Autosave()
        assert c.pending_all() == [] and c.set_aside is None
        c.close()
        assert os.path.isfile(a_path)
    finally:
        a.kill()
        a.wait()
    # A killed (-9 above: SIGKILL): its autosave is offered at the next start, once.
    assert a.returncode == -signal.SIGKILL
    d = Autosave()
    found = d.pending_all()
    assert [r.path for r in found] == [a_path] and found[0].project.document.seed == 7
    assert found[0].project.document == replace(doc, seed=7)
    e = Autosave()  # a second editor starting now: d has claimed it
    assert e.pending_all() == []
    d.discard(found[0])
    assert not os.path.exists(a_path)
    assert not [n for n in os.listdir(state) if n.startswith(os.path.basename(a_path)[:-5])]  # its lock went too


def test_editor_exit_without_edits_removes_only_its_own_autosave(state, doc):
    """The editor's exit path (Documents.keep_unsaved_work) with a second editor's
    autosave in the same folder: the other file stays."""
    from infinitex.app.ui.files import Documents
    a, a_path = start_writer(state, seed=9)
    try:
        b = FakeEditor(doc)
        b.files.autosave.tick(b.files.autosave_project(), True, force=True)
        b.history.mark_saved()
        b.files.keep_unsaved_work()
        assert isinstance(b.files, Documents) and not os.path.exists(b.files.autosave.path)
        assert load_project(a_path).document.seed == 9
        # With unsaved edits the exiting editor keeps its own autosave for the next start.
        c = FakeEditor(doc)
        c.history.current = replace(doc, seed=3)
        c.files.keep_unsaved_work()
        assert load_project(c.files.autosave.path).document.seed == 3 and os.path.isfile(a_path)
    finally:
        a.kill()
        a.wait()


def test_several_dead_autosaves_are_offered_oldest_first_and_removed_one_by_one(state, doc):
    paths = []
    for seed in (11, 12, 13):
        w, p = start_writer(state, seed, wait=False)
        w.wait()
        paths.append(p)
    for i, p in enumerate(paths):  # the oldest is the one written first
        os.utime(p, (1e9 + i, 1e9 + i))
    # An older version's single autosave is offered too (it is the oldest here).
    legacy = state / "autosave.itex"
    save_project(str(legacy), Project(replace(doc, seed=10)), embed=True)
    os.utime(legacy, (1e9 - 1, 1e9 - 1))
    a = Autosave()
    found = a.pending_all()
    assert [r.project.document.seed for r in found] == [10, 11, 12, 13]
    assert found[0].path == str(legacy)
    a.discard(found[2])  # recovered or discarded: that one only
    assert not os.path.exists(paths[1]) and all(os.path.isfile(p) for p in (paths[0], paths[2], legacy))
    assert [r.project.document.seed for r in a.pending_all()] == [10, 11, 13]
    a.release()  # the editor quit without answering: the rest is offered at the next start
    b = Autosave()
    assert [r.project.document.seed for r in b.pending_all()] == [10, 11, 13]
    b.discard(b.pending_all()[0])
    assert not legacy.exists() and not (state / "autosave.lock").exists()



def test_pending_autosaves_are_read_one_at_a_time_and_not_held(state, doc, monkeypatch):
    """A dozen crashed editors' autosaves are each read once at start-up (a
    broken one is set aside) and not kept: what the questions name is held, the
    project is read again only for the one recovered."""
    for i in range(3):
        w, p = start_writer(state, seed=40 + i, wait=False)
        w.wait()
    loads = []
    real = fmt.load_project
    import infinitex.project.autosave as autosave_module
    monkeypatch.setattr(autosave_module, "load_project", lambda path, *a, **k: loads.append(path) or real(path, *a, **k))
    found = Autosave().pending_all()
    assert len(found) == 3 and len(loads) == 3
    assert all(set(vars(r) if hasattr(r, "__dict__") else r.__dataclass_fields__) == {"path", "time", "origin", "name"}
               for r in found)
    assert all(r.name == doc.exemplar.name for r in found)
    from infinitex.app.ui.files import recovery_question
    recovery_question(found[0], 0, 3)
    assert len(loads) == 3  # the question needs no project
    assert found[1].project.document.seed == 41 and loads[-1] == found[1].path


def test_a_broken_autosave_is_set_aside_and_the_others_are_still_offered(state, doc):
    w, good = start_writer(state, seed=21, wait=False)
    w.wait()
    bad = state / "autosave-4242-0badc0de.itex"
    bad.write_text('{"format": "infinitex-project", "version": 1}')
    a = Autosave()
    found = a.pending_all()
    assert [r.path for r in found] == [good]
    assert len(a.set_aside_all) == 1 and "\n" not in a.set_aside_all[0][1]
    assert os.path.basename(a.set_aside[0]).startswith("autosave-broken-") and not bad.exists()


def test_a_crafted_autosave_reads_nothing_outside_the_state_folder(state, doc, tmp_path, monkeypatch):
    """Referencing /etc/passwd (with its true hash) or a file outside the state
    folder: refused in one line and set aside; the file is never opened."""
    state.mkdir()
    outside = tmp_path / "outside.png"
    data = noise_png(outside, 16, 1)
    d = fmt.project_to_json(Project(doc), embed=True)
    opened = []
    real_open = os.open

    def spy(path, *a, **k):
        opened.append(os.path.realpath(os.fsdecode(path)))
        return real_open(path, *a, **k)
    for ref, content in [("/etc/passwd", open("/etc/passwd", "rb").read()), (str(outside), data),
                         ("../outside.png", data)]:
        d["exemplar"].update(embedded=None, path=ref, sha256=hashlib.sha256(content).hexdigest())
        (state / "autosave-1-00000001.itex").write_text(json.dumps(d))
        monkeypatch.setattr(os, "open", spy)
        a = Autosave()
        assert a.pending_all() == []
        monkeypatch.setattr(os, "open", real_open)
        assert a.set_aside is not None and "outside the project's folder" in a.set_aside[1]
        assert "\n" not in a.set_aside[1]
        assert os.path.realpath(ref if os.path.isabs(ref) else outside) not in opened
    # A "source" (where a file came from) is only a name: never read, never trusted as content.
    d["exemplar"].update(embedded=fmt.project_to_json(Project(doc), embed=True)["exemplar"]["embedded"],
                         path=None, sha256=doc.exemplar.sha256, source="/etc/shadow")
    (state / "autosave-1-00000002.itex").write_text(json.dumps(d))
    opened.clear()
    monkeypatch.setattr(os, "open", spy)
    found = Autosave().pending_all()
    monkeypatch.setattr(os, "open", real_open)
    assert found[0].project.document.exemplar.data == doc.exemplar.data and "/etc/shadow" not in opened


# -- item 4: large exemplars are kept beside the autosave, not embedded -------------


def test_an_autosave_of_a_large_material_stays_under_the_limit_and_recovers(state, tmp_path, monkeypatch):
    # The limits lowered 256-fold: a 96 MB project limit becomes 384 KB, so a
    # 480 KB noise exemplar stands for one of 120 MB (allowed up to 512 MB).
    monkeypatch.setattr(fmt, "MAX_PROJECT_BYTES", 384 * 1024)
    src = tmp_path / "pictures"
    src.mkdir()
    big = noise_png(src / "rock_basecolor.png", 400, 1)
    also_big = noise_png(src / "rock_normal.png", 340, 2)
    small = noise_png(src / "rock_height.png", 40, 3)
    assert len(big) > fmt.MAX_PROJECT_BYTES
    maps = [(r, ExemplarSource.from_file(str(src / f"rock_{r}.png"))) for r in ("basecolor", "normal", "height")]
    doc = Document(maps[0][1]).with_maps(maps)
    proj = Project(replace(doc, seed=5), View(3.0, 4.0, 2.0))
    # What the old autosave wrote (everything embedded) is refused when read back:
    save_project(str(tmp_path / "old.itex"), proj, embed=True)
    with pytest.raises(ProjectError, match="larger than"):
        load_project(str(tmp_path / "old.itex"))
    a = Autosave(interval=0.0)
    assert a.tick(proj, True)
    assert os.path.getsize(a.path) <= fmt.MAX_PROJECT_BYTES
    written = json.load(open(a.path))
    assert written["material"]["maps"][1]["embedded"] is not None  # the small map still embedded
    stored = sorted(n for n in os.listdir(state) if n.endswith(".data"))
    assert len(stored) == 2 and all(n.startswith(os.path.basename(a.path)[:-5]) for n in stored)
    # The originals change or go: the autosave does not depend on them.
    (src / "rock_basecolor.png").write_bytes(small)
    os.unlink(src / "rock_normal.png")
    a.release()  # the editor crashed
    b = Autosave()
    found = b.pending_all()
    assert b.set_aside is None and len(found) == 1
    back = found[0].project
    assert back == proj  # an equal document (by content hashes), view and display
    assert [s.data for _, s in back.document.maps] == [big, also_big, small]
    assert back.document.exemplar.path == str(src / "rock_basecolor.png")  # where it came from, kept
    # Recovered by b: b's own autosave holds it (its own stored copies), then a's goes with its files.
    assert b.tick(back, True, force=True)
    b.discard(found[0])
    names = os.listdir(state)
    assert not any(n.startswith(os.path.basename(a.path)[:-5]) for n in names)
    assert sum(n.endswith(".data") for n in names) == 2
    # A small document next: the large files it no longer needs go; clear() removes the rest.
    assert b.tick(Project(Document(ExemplarSource.from_bytes(small, "small.png"))), True, force=True)
    assert not [n for n in os.listdir(state) if n.endswith(".data")]
    b.tick(proj, True, force=True)
    b.clear()
    assert not [n for n in os.listdir(state) if n.endswith(".data") or n.endswith(".itex")]


def test_leftovers_of_a_crashed_editor_are_removed_only_once_it_is_gone(state, doc, tmp_path, monkeypatch):
    monkeypatch.setattr(fmt, "MAX_PROJECT_BYTES", 64 * 1024)
    big = noise_png(tmp_path / "big.png", 200, 4)
    a = Autosave()
    a.tick(Project(Document(ExemplarSource.from_file(str(tmp_path / "big.png")))), True, force=True)
    os.unlink(a.path)  # (the autosave itself lost: its stored file and lock are leftovers)
    stored = [n for n in os.listdir(state) if n.endswith(".data")]
    assert len(stored) == 1 and (state / stored[0]).read_bytes() == big
    Autosave().pending_all()  # a is alive: nothing of it is touched
    assert (state / stored[0]).exists()
    a.release()
    Autosave().pending_all()
    assert os.listdir(state) == []


# -- item 5: project saves get the project extension, never replace an input --------


def test_project_saves_get_the_project_extension(tmp_path, doc):
    assert project_save_path(str(tmp_path / "texture.png")) == str(tmp_path / "texture.png.itex")
    assert project_save_path(str(tmp_path / "texture")) == str(tmp_path / "texture.itex")
    assert project_save_path(str(tmp_path / "t.ITEX")) == str(tmp_path / "t.ITEX")
    # The project file a document came from keeps its name when saved again.
    assert project_save_path(str(tmp_path / "old.json"), doc, str(tmp_path / "old.json")) == str(tmp_path / "old.json")


def test_a_project_is_never_saved_over_the_document_s_inputs(tmp_path):
    (tmp_path / "wood.itex").write_bytes(open(GRAVEL, "rb").read())  # an image with a project's name
    os.link(tmp_path / "wood.itex", tmp_path / "hard.itex")
    os.symlink(tmp_path / "wood.itex", tmp_path / "soft.itex")
    ex = ExemplarSource.from_file(str(tmp_path / "wood.itex"))
    normal = ExemplarSource.from_file(GRAVEL)
    doc = Document(ex).with_maps([("basecolor", ex), ("normal", normal)])
    for name in ("wood.itex", "hard.itex", "soft.itex", "wood"):
        with pytest.raises(ProjectError, match="exemplar, one of its inputs") as info:
            project_save_path(str(tmp_path / name), doc)
        assert "\n" not in str(info.value)
    (tmp_path / "n.itex").write_bytes(open(GRAVEL, "rb").read())
    doc = Document(normal).with_maps([("basecolor", normal), ("normal", ExemplarSource.from_file(str(tmp_path / "n.itex")))])
    with pytest.raises(ProjectError, match="normal map, one of its inputs"):
        project_save_path(str(tmp_path / "n"), doc)


class FakeDialogs:
    def __init__(self):
        self.messages, self.questions, self.path_request = [], [], None

    def message(self, title, body):
        self.messages.append((title, body))

    def ask(self, title, body, buttons):
        self.questions.append((title, body, dict(buttons)))

    def ask_path(self, title, save, filters, on_done, default=""):
        self.path_request = SimpleNamespace(native=None, on_done=on_done)


def FakeEditor(doc, project_path=None):
    """The editor's document handling (files.py) without a window."""
    from infinitex.app.player import Playback
    from infinitex.app.settings import Settings
    from infinitex.app.ui.files import Documents
    from infinitex.app.ui.prefs import Preferences
    from infinitex.app.ui.viewer import Viewer

    class Ed:  # the editor, as far as its documents read it
        view = property(lambda self: self.viewer.view)
        display = property(lambda self: self.viewer.display)
        doc = property(lambda self: self.files.doc)
        history = property(lambda self: self.files.history)
        start_path, offer_recovery, screenshot = None, False, None
    ed = Ed()
    ed.viewer = Viewer()
    ed.dialogs, ed.prefs = FakeDialogs(), Preferences(Settings())
    ed.tools = []  # (the canvas tools: none without a window)
    ed.playback = Playback()  # (its process starts only when a frame is asked for)
    ed.files = Documents(ed, Autosave())
    ed.files.history, ed.files.project_path = History(doc), project_path
    ed.files.remember = lambda path: setattr(ed, "remembered", path)
    return ed


def test_save_as_an_image_name_writes_a_project_beside_it_and_never_over_it(state, tmp_path):
    image = tmp_path / "texture.png"
    image_bytes = noise_png(image, 32, 5)
    ed = FakeEditor(Document(ExemplarSource.from_file(GRAVEL), seed=4))
    ed.history.current = replace(ed.doc, seed=8)
    ed.files.save_as()
    ed.dialogs.path_request.on_done(str(image))  # "Save as texture.png"
    assert image.read_bytes() == image_bytes
    assert load_project(str(tmp_path / "texture.png.itex")).document.seed == 8
    assert ed.files.project_path == str(tmp_path / "texture.png.itex") and not ed.history.dirty


def test_save_as_asks_before_replacing_an_existing_file(state, tmp_path):
    other = tmp_path / "other.itex"
    other.write_text("someone's project")
    ed = FakeEditor(Document(ExemplarSource.from_file(GRAVEL), seed=4))
    ed.files.save_chosen(str(other))  # the in-window chooser or path box asked nothing
    title, body, buttons = ed.dialogs.questions[-1]
    assert title == "Replace file" and "other.itex" in body and list(buttons) == ["Replace", "Cancel"]
    assert other.read_text() == "someone's project"  # nothing written before the answer
    buttons["Replace"]()
    assert load_project(str(other)).document.seed == 4
    # The system's dialog asked about that very file: not asked twice.
    ed.dialogs.questions.clear()
    ed.files.save_chosen(str(tmp_path / "other.itex"), asked=True)
    assert ed.dialogs.questions == []
    # ...but it asked about "notes", not about "notes.itex", which the save would replace.
    (tmp_path / "notes.itex").write_text("notes")
    ed.files.save_chosen(str(tmp_path / "notes"), asked=True)
    assert ed.dialogs.questions and (tmp_path / "notes.itex").read_text() == "notes"


def test_save_as_refuses_the_document_s_own_exemplar(state, tmp_path):
    image = tmp_path / "wood.itex"
    image.write_bytes(open(GRAVEL, "rb").read())
    ed = FakeEditor(Document(ExemplarSource.from_file(str(image))))
    ed.files.save_chosen(str(image), asked=True)
    assert image.read_bytes() == open(GRAVEL, "rb").read()
    assert ed.dialogs.messages and ed.dialogs.messages[-1][0] == "Save failed"
    assert "one of its inputs" in ed.dialogs.messages[-1][1] and ed.files.project_path is None


def test_recovering_moves_the_work_into_this_editor_s_autosave(state, doc):
    from infinitex.app.ui.files import recovery_question
    w1, p1 = start_writer(state, seed=31, wait=False)
    w2, p2 = start_writer(state, seed=32, wait=False)
    w1.wait()
    w2.wait()
    ed = FakeEditor(doc)
    found = ed.files.autosave.pending_all()
    assert len(found) == 2 and "gravel.png" in recovery_question(found[0], 0, 2)
    rec = next(r for r in found if r.path == p1)
    ed.files.pending = ("recovered", rec.project.document, rec.project, rec.path)  # what Recover starts
    ed.files.finish_load(SimpleNamespace(error=None, cancelled=False))
    assert ed.doc.seed == 31 and ed.history.dirty
    assert load_project(ed.files.autosave.path).document.seed == 31  # kept by this editor now
    assert not os.path.exists(p1) and load_project(p2).document.seed == 32  # the other one stays
    assert [r.path for r in ed.files.autosave.pending_all()] == [p2]


def test_autosave_names_are_per_process(state):
    a, b = Autosave(), Autosave()
    assert a.path != b.path and str(os.getpid()) in os.path.basename(a.path)
    t0 = time.monotonic()
    for _ in range(3):
        assert Autosave().pending_all() == []
    assert time.monotonic() - t0 < 30


def test_a_background_autosave_writes_beside_the_frames_and_reports_its_error(state, doc, monkeypatch):
    """The editor's autosave writes in a thread: the tick returns at once, the
    file is there once it ends, a forced write (exit) waits for it, clearing
    never races it, and a failed write is the next tick's ProjectError."""
    import threading
    a = Autosave(background=True, interval=0.0)
    gate = threading.Event()
    real = fmt.save_project

    def slow(*args, **kw):
        gate.wait(10)
        return real(*args, **kw)
    monkeypatch.setattr("infinitex.project.autosave.save_project", slow)
    t0 = time.monotonic()
    assert a.tick(Project(replace(doc, seed=1)), True)
    assert time.monotonic() - t0 < 1.0 and not os.path.exists(a.path)  # under way, not waited for
    assert not a.tick(Project(replace(doc, seed=2)), True)  # one write at a time
    gate.set()
    a.tick(Project(replace(doc, seed=3)), True, force=True)  # waits for the first, then writes
    assert load_project(a.path).document.seed == 3
    a.clear()
    assert not os.path.exists(a.path)

    def broken(*args, **kw):
        raise ProjectError("The disk is full.")
    monkeypatch.setattr("infinitex.project.autosave.save_project", broken)
    assert a.tick(Project(replace(doc, seed=4)), True)
    a._join()
    with pytest.raises(ProjectError, match="disk is full"):
        a.tick(Project(replace(doc, seed=5)), True)
    a.release()
