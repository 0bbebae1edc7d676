"""The shader warm-up (app/warmup.py): a low-priority process compiles the
shader variants of the edits a document does not have yet, once."""
import json
import os

from infinitex.app.warmup import MARKER, ShaderWarmup, edits, warm_key
from infinitex.project import Document, ExemplarSource, Project, project_to_json

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))


def _doc_json(**kw) -> str:
    doc = Document(ExemplarSource.from_file(os.path.join(ROOT, "infinitex", "assets", "gravel.png")), **kw)
    return json.dumps(project_to_json(Project(doc), embed=True))


def test_every_kind_of_edit_is_warmed_and_valid(analyses):
    from infinitex.engine.controls import Controls
    an = analyses["gravel-appearance"]
    kinds = edits(Controls(), an)
    assert [k for k, _ in kinds] == ["randomness", "labels", "direction", "avoid", "features", "exemplar"]
    for _, c in kinds:
        c.validate(an.size, an.settings.lattice)
    # A kind the document has already is not warmed again.
    assert "labels" not in [k for k, _ in edits(kinds[1][1], an)]


def test_the_key_follows_the_settings_not_the_paint():
    a, b = _doc_json(), _doc_json(seed=7)
    assert warm_key(a, "r") == warm_key(a, "r") != warm_key(a, "other renderer")
    assert warm_key(a, "r") != warm_key(b, "r")


def test_the_process_runs_once_per_document_kind(tmp_path, monkeypatch):
    monkeypatch.delenv("INFINITEX_NO_WARMUP", raising=False)
    w = ShaderWarmup(str(tmp_path))
    doc = _doc_json()
    assert w.start(doc, "test renderer")
    assert not w.start(doc, "test renderer")  # one at a time
    w.proc.wait(timeout=300)
    assert w.proc.returncode == 0
    w.poll()
    assert (tmp_path / MARKER).read_text().split() == [warm_key(doc, "test renderer")]
    assert not w.start(doc, "test renderer")  # warmed already
    assert w.start(_doc_json(seed=3), "test renderer")
    w.stop()
    assert w.proc is None
    monkeypatch.setenv("INFINITEX_NO_WARMUP", "1")
    assert not ShaderWarmup(str(tmp_path / "b")).start(doc, "test renderer")
