"""Where the file choosers start (no window needed: the path-box mode)."""
import os

from infinitex.app.ui.dialogs import Dialogs


def _dialogs(monkeypatch, last_dir):
    monkeypatch.setenv("INFINITEX_NO_NATIVE_DIALOGS", "1")
    monkeypatch.setenv("INFINITEX_PATH_PROMPT", "1")
    d = Dialogs()
    d.last_dir = str(last_dir)
    return d


def test_every_chooser_starts_in_the_saved_projects_folder(tmp_path, monkeypatch):
    last, proj = tmp_path / "last", tmp_path / "project"
    last.mkdir()
    proj.mkdir()
    d = _dialogs(monkeypatch, last)
    # No saved project: the folder last used, for a save's default name and an open.
    d.ask_path("Export toroidal tile", True, ["PNG", "*.png"], lambda p: None, default="tile1024.png")
    assert d.path_request.default == str(last / "tile1024.png")
    d.ask_path("Open", False, ["PNG", "*.png"], lambda p: None)
    assert d.path_request.text == str(last) + os.sep
    # A saved project: its folder, whatever was used last.
    d.project_dir = str(proj)
    d.ask_path("Export view", True, ["PNG", "*.png"], lambda p: None, default="view.png")
    assert d.path_request.default == str(proj / "view.png")
    d.ask_paths("Open material", ["Images", "*.png"], lambda p: None)
    assert d.path_request.text == str(proj) + os.sep
    # An absolute default (Save As of a saved project) stays as it is.
    d.ask_path("Save project as", True, ["Project", "*.itex"], lambda p: None, default=str(tmp_path / "a.itex"))
    assert d.path_request.default == str(tmp_path / "a.itex")


def test_choosing_a_file_makes_its_folder_the_last_used(tmp_path, monkeypatch):
    other = tmp_path / "other"
    other.mkdir()
    d = _dialogs(monkeypatch, tmp_path)
    got = []
    d.ask_path("Open", False, ["PNG", "*.png"], got.append)
    d.path_request.on_done(str(other / "x.png"))
    assert got == [str(other / "x.png")] and d.last_dir == str(other)
    # A vanished project folder falls back to the folder last used.
    d.project_dir = str(tmp_path / "gone")
    assert d.start_dir() == str(other)
