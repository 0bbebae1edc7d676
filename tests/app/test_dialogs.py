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


def test_the_in_window_chooser_lists_sizes_and_proposes_a_name(tmp_path, monkeypatch):
    from infinitex.app.ui.browser import FileBrowser, size_text
    monkeypatch.setenv("INFINITEX_NO_NATIVE_DIALOGS", "1")
    monkeypatch.delenv("INFINITEX_PATH_PROMPT", raising=False)
    (tmp_path / "sub").mkdir()
    (tmp_path / "b.png").write_bytes(b"x" * 2048)
    (tmp_path / "A.jpg").write_bytes(b"x" * 10)
    (tmp_path / "notes.txt").write_bytes(b"x")
    (tmp_path / ".hidden.png").write_bytes(b"x")
    d = Dialogs()
    d.last_dir = str(tmp_path)
    d.ask_path("Export view", True, ["PNG image", "*.png"], lambda p: None, default="view.png")
    br = d.path_request.browser
    assert br is not None and br.save and br.name == "view.png" and br.folder == str(tmp_path)
    # Folders first, then the files the filter shows; no sizes for folders.
    assert [(e.name, e.is_dir, e.size) for e in br.listing()] == [("sub", True, 0), ("b.png", False, 2048)]
    br.set_filter(0)
    assert size_text(2048) == "2.0 KiB" and size_text(532) == "532 B" and size_text(3 * 2**20) == "3.0 MiB"
    # Typing a folder's name enters it; a name in it is the choice.
    assert not br.accept("sub") and br.folder == str(tmp_path / "sub")
    assert br.accept("out.png") and br.result == [str(tmp_path / "sub" / "out.png")]


def test_the_in_window_chooser_opens_existing_files_only(tmp_path, monkeypatch):
    from infinitex.app.ui.browser import FileBrowser
    (tmp_path / "a.png").write_bytes(b"x")
    (tmp_path / "b.png").write_bytes(b"x")
    br = FileBrowser("Open", False, ["Images", "*.png", "All files", "*"], str(tmp_path))
    assert not br.accept("missing.png") and "does not exist" in br.error and not br.done
    assert not br.go(str(tmp_path / "a.png")) and "not a folder" in br.error
    assert br.accept("a.png") and br.result == [str(tmp_path / "a.png")]
    multi = FileBrowser("Open material", False, ["Images", "*.png"], str(tmp_path), multi=True)
    assert multi.accept("a.png; b.png") and multi.result == [str(tmp_path / "a.png"), str(tmp_path / "b.png")]
    folder = FileBrowser("Open material", False, ["Images", "*.png"], str(tmp_path), multi=True)
    assert folder.accept("") and folder.result == [str(tmp_path)]  # a material's maps: the folder
    cancelled = FileBrowser("Open", False, ["Images", "*.png"], str(tmp_path))
    cancelled.cancel()
    assert cancelled.done and cancelled.result == []
