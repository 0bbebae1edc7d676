"""A tile set's files are written as one unit (safeio.StagedFiles): every
file is written beside its name first and renamed only once all are
written, so a failure part way (a name that cannot be written, a full disk,
a kill) leaves the old set whole; a name that is a symbolic link is
replaced, never written through."""
from __future__ import annotations

import json
import os

import numpy as np
import pytest

import infinitex as itx
import infinitex.engine.safeio as safeio
from infinitex.engine.safeio import TMP_SUFFIX, StagedFiles, WriteError
from infinitex.export.wang import TileSetPlan


def _set(seed: int, colors: int = 2, n: int = 64):
    plan = TileSetPlan(colors, n)
    cols, rows = plan.grid
    atlas = np.random.default_rng(seed).integers(0, 256, (rows * n, cols * n, 3), dtype=np.uint8)
    return atlas, {"kind": "corner-wang", "colors": colors, "tile": n, "count": plan.count, "columns": cols,
                   "rows": rows, "tiles": plan.tiles()}


def _snapshot(folder) -> dict[str, bytes]:
    return {f: open(os.path.join(folder, f), "rb").read() for f in sorted(os.listdir(folder))
            if os.path.isfile(os.path.join(folder, f))}


@pytest.fixture
def old_set(tmp_path):
    out = tmp_path / "set.png"
    written = itx.save_tile_set(*_set(1), out)
    assert len(written) == 6
    return out, _snapshot(tmp_path)


@pytest.mark.parametrize("blocker", ["folder", "fifo", "long name"])
def test_a_side_file_that_cannot_be_written_leaves_the_old_set_whole(old_set, blocker):
    out, before = old_set
    folder = out.parent
    if blocker == "folder":
        os.remove(folder / "set.tres")
        (folder / "set.tres").mkdir()
        del before["set.tres"]
    elif blocker == "fifo":
        os.remove(folder / "set.tmx")
        os.mkfifo(folder / "set.tmx")
        del before["set.tmx"]
    else:
        out = folder / ("s" * 251 + ".png")  # its .json and _preview.png names are too long
    with pytest.raises(WriteError) as err:
        itx.save_tile_set(*_set(2), out)
    assert "\n" not in str(err.value)
    assert _snapshot(folder) == before  # nothing replaced, no temporary left


def test_a_failure_while_staging_leaves_the_old_set_and_no_temporaries(old_set, monkeypatch):
    out, before = old_set
    real = safeio._write_temporary
    calls = []

    def failing(*args, **kw):
        calls.append(args[1])
        if len(calls) == 4:  # the disk fills up at the fourth file
            raise WriteError("Saving set.tmx failed: No space left on device.")
        return real(*args, **kw)
    monkeypatch.setattr(safeio, "_write_temporary", failing)
    with pytest.raises(WriteError, match="No space left"):
        itx.save_tile_set(*_set(2), out)
    assert _snapshot(out.parent) == before
    assert not [f for f in os.listdir(out.parent) if f.endswith(TMP_SUFFIX)]


def test_nothing_is_renamed_before_every_file_is_written(old_set, monkeypatch):
    """A kill at any point before the renames leaves the old set: the renames
    (microseconds) come only after the last file is written in full."""
    out, before = old_set
    events = []
    real_write, real_replace = safeio._write_temporary, os.replace
    monkeypatch.setattr(safeio, "_write_temporary", lambda *a, **k: events.append("write") or real_write(*a, **k))
    monkeypatch.setattr(safeio.os, "replace", lambda a, b: events.append("rename") or real_replace(a, b))
    itx.save_tile_set(*_set(2), out)
    assert events == ["write"] * 6 + ["rename"] * 6
    after = _snapshot(out.parent)
    assert set(after) == set(before) and all(after[f] != before[f] for f in ("set.png", "set_preview.png"))
    assert json.loads(after["set.json"])["engines"]["godot"] == {"tileset": "set.tres"}


def test_links_are_replaced_not_written_through(tmp_path):
    outside = tmp_path / "outside"
    outside.mkdir()
    (outside / "precious.json").write_text("keep me")
    here = tmp_path / "here"
    here.mkdir()
    os.symlink(outside / "precious.json", here / "set.json")
    os.symlink(outside / "gone.tsx", here / "set.tsx")  # dangling: no file may appear outside
    itx.save_tile_set(*_set(3), here / "set.png")
    assert (outside / "precious.json").read_text() == "keep me"
    assert sorted(os.listdir(outside)) == ["precious.json"]
    for name in ("set.json", "set.tsx"):
        assert not os.path.islink(here / name) and os.path.isfile(here / name)


def test_staged_files_check_refuses_before_writing(tmp_path):
    (tmp_path / "dir.png").mkdir()
    with pytest.raises(WriteError, match="not a regular file"):
        StagedFiles.check([str(tmp_path / "a.png"), str(tmp_path / "dir.png")])
    with StagedFiles() as stage:
        stage.write(str(tmp_path / "a.txt"), b"a")
    assert not os.path.exists(tmp_path / "a.txt")  # never committed: discarded
    assert not [f for f in os.listdir(tmp_path) if f.endswith(TMP_SUFFIX)]


def test_the_api_checks_what_it_is_given(tmp_path):
    """tile_set refuses a direction field as the command line does (before any
    analysis); arrange and save_tile_set check the description against the atlas."""
    from infinitex.engine.controls import NO_CONTROLS
    atlas, desc = _set(4)
    directed = type("Directed", (), {"directed": True})()
    with pytest.raises(ValueError, match="no direction field"):
        itx.tile_set("never-read.png", controls=directed)
    with pytest.raises(ValueError, match="2 or 3 corner colours"):
        itx.tile_set("never-read.png", colors=5, controls=NO_CONTROLS)
    assert itx.arrange(atlas, desc, 3, 2).shape == (128, 192, 3)
    for bad_atlas, bad_desc, says in ((atlas[:64], desc, "atlas of this set"),
                                      (atlas, {**desc, "tile": 100}, "Not the description"),
                                      (atlas, {"colors": 2}, "Not the description"),
                                      (atlas.tolist(), desc, "atlas of this set")):
        with pytest.raises(ValueError, match=says):
            itx.arrange(bad_atlas, bad_desc, 2, 2)
        with pytest.raises(ValueError, match=says):
            itx.save_tile_set(bad_atlas, bad_desc, tmp_path / "x.png")
    with pytest.raises(ValueError, match="1 to 4096 tiles"):
        itx.arrange(atlas, desc, 0, 2)
    assert not os.listdir(tmp_path)
