"""No output may replace an input of the same run (issue 29, items 1 and 2):
the exemplar, any map of a material, the randomness, avoid and feature files,
the project; for every format and map name, by the file's identity (a
symbolic or hard link counts), in the command line (one line, exit 2, before
any work) and in the editor (a message; and a question before replacing any
existing file the file dialog did not ask about). Also: a damaged TIFF gives
one line on stderr, not tifffile's log lines before it (item 16)."""
import hashlib
import io
import os
import struct
import subprocess
import sys
from types import SimpleNamespace

import numpy as np
import pytest
import tifffile
from PIL import Image

from infinitex.cli import export as cli_export
from infinitex.cli import synth as cli_synth
from infinitex.engine.material import open_material, single
from infinitex.engine.pyramid import Rect
from infinitex.export.window import (
    OwnInputError,
    Writes,
    check_own_inputs,
    is_tile_name,
    streamed_writes,
)

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
GRAVEL = os.path.join(ROOT, "infinitex", "assets", "gravel.png")


def digest(folder) -> dict[str, str]:
    """Every file under ``folder`` and its SHA-256: what a refused run must leave as it was."""
    out = {}
    for dirpath, _, files in os.walk(folder):
        for n in files:
            p = os.path.join(dirpath, n)
            if not os.path.islink(p):
                with open(p, "rb") as f:
                    out[os.path.relpath(p, folder)] = hashlib.sha256(f.read()).hexdigest()
    return out


@pytest.fixture
def wood(tmp_path):
    """A material of three maps side by side: wood_basecolor.png, wood_normal.png, wood_height.tif (float)."""
    rng = np.random.default_rng(3)
    Image.fromarray((rng.random((64, 64, 3)) * 255).astype(np.uint8)).save(tmp_path / "wood_basecolor.png")
    Image.fromarray((rng.random((64, 64, 3)) * 255).astype(np.uint8)).save(tmp_path / "wood_normal.png")
    tifffile.imwrite(tmp_path / "wood_height.tif", rng.random((64, 64)).astype(np.float32))
    return tmp_path


def read(path) -> bytes:
    with open(path, "rb") as f:
        return f.read()


@pytest.fixture
def gravel(tmp_path):
    p = tmp_path / "gravel.png"
    p.write_bytes(read(GRAVEL))
    return p


def refused(main, argv, capsys, folder, name: str) -> str:
    """Run a command that must refuse: exit 2, one line naming ``name``, nothing changed in ``folder``."""
    before = digest(folder)
    code = main([*argv, "-q"])
    err = capsys.readouterr().err
    assert code == 2, err
    assert err.startswith("error: ") and len(err.strip().splitlines()) == 1, err
    assert f"{name} is" in err and "input of this export" in err, err
    assert digest(folder) == before  # nothing written, nothing replaced
    return err


# -- the command line ----------------------------------------------------------


def test_a_material_exported_into_its_own_name_is_refused(wood, capsys):
    err = refused(cli_export.main, [str(wood / "wood_basecolor.png"), "-o", str(wood / "wood.png")], capsys, wood,
                  "wood_basecolor.png")
    assert "choose another output name" in err
    # The folder form, and each map chosen alone: a float height is written .tif (known once decoded).
    refused(cli_export.main, [str(wood), "-o", str(wood / "wood.png"), "--maps", "normal"], capsys, wood,
            "wood_normal.png")
    refused(cli_export.main, [str(wood / "wood_normal.png"), "-o", str(wood / "wood.png"), "--maps", "height"],
            capsys, wood, "wood_height.tif")
    refused(cli_export.main, [str(wood / "wood_normal.png"), "-o", str(wood / "wood.png"), "--depth", "32",
                              "--maps", "height"], capsys, wood, "wood_height.tif")


def test_the_streamed_form_into_a_map_of_its_own_is_refused(wood, capsys):
    refused(cli_export.main, [str(wood / "wood_basecolor.png"), "-o", str(wood / "wood.tif"), "--format", "tiff",
                              "--maps", "height", "--rect", "0", "0", "64", "64", "--tile", "256"], capsys, wood,
            "wood_height.tif")


def test_an_8_bit_tiff_map_written_as_png_beside_itself_is_not_refused(wood, capsys):
    """The check is exact, not by name alone: an 8-bit height map (wood_height.tif)
    exported as -o wood.png writes wood_height.png, which replaces nothing."""
    a = np.asarray(Image.open(wood / "wood_normal.png"))[..., 0]
    tifffile.imwrite(wood / "wood_height.tif", a)
    code = cli_export.main([str(wood / "wood_normal.png"), "-o", str(wood / "wood.png"), "--maps", "height",
                            "--size", "32", "32", "-q"])
    assert code == 0, capsys.readouterr().err
    assert os.path.isfile(wood / "wood_height.png")


def test_an_exemplar_exported_or_synthesized_onto_itself_is_refused(gravel, capsys):
    folder = gravel.parent
    refused(cli_export.main, [str(gravel), "-o", str(gravel)], capsys, folder, "gravel.png")
    refused(cli_synth.main, [str(gravel), "-o", str(gravel)], capsys, folder, "gravel.png")
    (folder / "sub").mkdir()  # another spelling of the same path
    refused(cli_export.main, [str(gravel), "-o", str(folder / "sub" / ".." / "gravel.png")], capsys, folder,
            "gravel.png")


@pytest.mark.parametrize("kind", ["symlink", "hardlink"])
def test_a_link_to_the_exemplar_as_output_is_refused(gravel, capsys, kind):
    folder = gravel.parent
    link = folder / "link.png"
    (os.symlink if kind == "symlink" else os.link)(gravel, link)
    err = refused(cli_export.main, [str(gravel), "-o", str(link)], capsys, folder, "link.png")
    assert "is the file" in err and "gravel.png" in err
    refused(cli_synth.main, [str(gravel), "-o", str(link)], capsys, folder, "link.png")
    assert read(gravel) == read(GRAVEL)


def test_a_coordinate_map_onto_an_input_is_refused(tmp_path, capsys):
    ex = tmp_path / "a_coords.png"
    ex.write_bytes(read(GRAVEL))
    refused(cli_export.main, [str(ex), "-o", str(tmp_path / "a.png"), "--coords", "--size", "64", "64"], capsys,
            tmp_path, "a_coords.png")
    os.rename(ex, tmp_path / "a_coords.tif")  # the streamed BigTIFF's coordinate map is NAME_coords.tif
    refused(cli_export.main, [str(tmp_path / "a_coords.tif"), "-o", str(tmp_path / "a.tif"), "--coords", "--format",
                              "tiff", "--rect", "0", "0", "64", "64", "--tile", "256"], capsys, tmp_path,
            "a_coords.tif")
    link = tmp_path / "c.npy"  # synth --coords OUT.npy: a link to the exemplar
    os.symlink(tmp_path / "a_coords.tif", link)
    refused(cli_synth.main, [str(tmp_path / "a_coords.tif"), "-o", str(tmp_path / "o.png"), "--coords", str(link)],
            capsys, tmp_path, "c.npy")
    assert not os.path.exists(tmp_path / "o.png")


def test_a_tile_set_whose_names_hit_an_input_is_refused(tmp_path, capsys):
    ex = tmp_path / "set.1002.png"  # tile (1, 0) of a set of 2 columns
    ex.write_bytes(read(GRAVEL))
    err = refused(cli_export.main, [str(ex), "-o", str(tmp_path / "set.png"), "--format", "tiles", "--rect", "0", "0",
                                    "512", "256", "--tile", "256"], capsys, tmp_path, "set.1002.png")
    assert "set.<UDIM>.png" in err
    # Past 10 columns the tiles are NAME_u<U>_v<V>.png.
    os.rename(ex, tmp_path / "wide_u11_v1.png")
    refused(cli_export.main, [str(tmp_path / "wide_u11_v1.png"), "-o", str(tmp_path / "wide.png"), "--format",
                              "tiles", "--rect", "0", "0", str(11 * 256), "256", "--tile", "256"], capsys, tmp_path,
            "wide_u11_v1.png")


def test_tile_names_match_only_the_tiles_of_this_set(tmp_path):
    assert is_tile_name("set.1002.png", "set", 2, 1) and is_tile_name("set.1011.png", "set", 2, 2)
    assert not is_tile_name("set.1003.png", "set", 2, 1)   # a third column: not in this set
    assert not is_tile_name("set.1011.png", "set", 2, 1)   # a second row
    assert not is_tile_name("set.01002.png", "set", 2, 1) and not is_tile_name("xset.1001.png", "set", 2, 1)
    assert is_tile_name("s_u11_v2.png", "s", 11, 2) and not is_tile_name("s_u12_v1.png", "s", 11, 2)
    assert not is_tile_name("s.1001.png", "s", 11, 2)
    ex = tmp_path / "set.1005.png"
    ex.write_bytes(b"x")
    check_own_inputs(streamed_writes(str(tmp_path / "set.png"), "tiles", 512, 256, 256), [str(ex)])  # no refusal
    # A hard link to an input under one of the tiles' names is found too.
    os.link(ex, tmp_path / "set.1001.png")
    with pytest.raises(OwnInputError, match="is a link to it"):
        check_own_inputs(streamed_writes(str(tmp_path / "set.png"), "tiles", 512, 256, 256), [str(ex)])


def test_an_input_inside_a_folder_the_export_replaces_or_removes_is_refused(tmp_path, capsys):
    parts = tmp_path / "big.tif.parts"
    parts.mkdir()
    ex = parts / "gravel.png"
    ex.write_bytes(read(GRAVEL))
    err = refused(cli_export.main, [str(ex), "-o", str(tmp_path / "big.tif"), "--format", "tiff", "--rect", "0", "0",
                                    "64", "64", "--tile", "256"], capsys, tmp_path, "gravel.png")
    assert "big.tif.parts" in err
    store = tmp_path / "o.zarr"
    store.mkdir()
    (store / ".zgroup").write_text('{"zarr_format": 2}')
    os.rename(ex, store / "gravel.png")
    refused(cli_export.main, [str(store / "gravel.png"), "-o", str(store), "--format", "zarr", "--rect", "0", "0",
                              "64", "64", "--tile", "256"], capsys, tmp_path, "gravel.png")


def test_control_maps_and_features_are_inputs_too(gravel, capsys):
    folder = gravel.parent
    mask = folder / "mask.png"
    Image.fromarray(np.zeros((64, 64), np.uint8)).save(mask)
    for flag in ("--randomness-exemplar", "--randomness-canvas", "--avoid-exemplar"):
        refused(cli_export.main, [str(gravel), "-o", str(mask), flag, str(mask)], capsys, folder, "mask.png")
        refused(cli_synth.main, [str(gravel), "-o", str(mask), flag, str(mask)], capsys, folder, "mask.png")
    feats = folder / "f.png"  # a features file with an image's name: still an input
    feats.write_text("[]")
    refused(cli_synth.main, [str(gravel), "-o", str(feats), "--features", str(feats)], capsys, folder, "f.png")


def test_a_project_and_the_exemplar_it_refers_to_are_inputs(gravel, capsys):
    from infinitex.project import Document, ExemplarSource, Project, save_project
    folder = gravel.parent
    proj = folder / "p.itex"
    save_project(str(proj), Project(Document(ExemplarSource.from_file(str(gravel)))), embed=False)
    refused(cli_export.main, [str(proj), "-o", str(gravel)], capsys, folder, "gravel.png")
    as_png = folder / "p.png"  # a project named like an image (read by its content)
    os.rename(proj, as_png)
    refused(cli_export.main, [str(as_png), "-o", str(as_png)], capsys, folder, "p.png")


def test_other_names_beside_the_inputs_are_not_refused(wood):
    """No false alarm: outputs beside the inputs, under other names."""
    inputs = [str(wood / n) for n in ("wood_basecolor.png", "wood_normal.png", "wood_height.tif")]
    check_own_inputs(Writes(files=[str(wood / "wood2_basecolor.png"), str(wood / "wood_height.png")]), inputs)
    check_own_inputs(streamed_writes(str(wood / "wood_height.png"), "tiles", 64, 64, 256, coords=True), inputs)
    check_own_inputs(streamed_writes(str(wood / "x.zarr"), "zarr", 64, 64, 256), inputs)


# -- the editor ----------------------------------------------------------------


class Dialogs:
    def __init__(self, native: bool):
        self.native = native
        self.messages: list = []
        self.questions: list = []

    def message(self, title, body):
        self.messages.append((title, body))

    def ask(self, title, body, buttons):
        self.questions.append((title, body, buttons))


class Started:
    """Stands for the editor's StreamedExport (worker processes): records that one started."""

    def __init__(self, doc, L, rect, path, fmt, *args, **kw):
        self.path, self.fmt = path, fmt


@pytest.fixture
def editor(monkeypatch):
    from infinitex.app.ui import exports
    monkeypatch.setattr(exports, "StreamedExport", Started)

    def make(doc, material, native=False, project_path=None, **kw):
        class Fake:  # the editor, as far as its exports read it
            def geometry(self):
                return None

            def shown_role(self):
                return material.primary
        ed = Fake()
        ed.doc, ed.dialogs = doc, Dialogs(native)
        ed.files = SimpleNamespace(project_path=project_path)  # (the project file: an input too)
        ed.session = SimpleNamespace(material=material, synth=None, L=0, quick_analysis=False)  # not ready: a window export says so
        ed.exports = exports.Exports(ed)
        ed.exports.settings = exports.ExportSettings(stream_tile=256, workers=1)
        for k, v in kw.items():
            setattr(ed.exports.settings, k, v)
        return ed
    return make


def _single(path):
    from infinitex.engine.exemplar import load_exemplar
    from infinitex.project import Document, ExemplarSource
    return Document(ExemplarSource.from_file(str(path))), single(load_exemplar(str(path)))


def test_the_editor_refuses_an_export_over_its_inputs(editor, wood, gravel):
    from infinitex.project import Document, ExemplarSource
    files = {r: str(wood / f"wood_{r}{'.tif' if r == 'height' else '.png'}") for r in ("basecolor", "normal", "height")}
    doc = Document(ExemplarSource.from_file(files["basecolor"])).with_maps(
        [(r, ExemplarSource.from_file(p)) for r, p in files.items()])
    before = digest(wood)
    ed = editor(doc, open_material(files["basecolor"]))
    ed.exports.start(str(wood / "wood.png"), Rect.of(0, 0, 64, 64))
    assert ed.exports.job is None and not ed.dialogs.questions
    assert "wood_basecolor.png is an input of this export" in ed.dialogs.messages[-1][1]
    ed.exports.settings.format = "tiff"  # the streamed form writes the map shown: wood_basecolor.tif replaces nothing
    ed.exports.start_streamed(str(wood / "wood.tif"), Rect.of(0, 0, 64, 64))
    assert isinstance(ed.exports.job, Started) and ed.exports.job.path == str(wood / "wood_basecolor.tif")
    assert digest(wood) == before
    # A project file is an input of the editor's exports too, and so is the exemplar.
    doc, mat = _single(gravel)
    proj = gravel.parent / "proj.png"
    proj.write_bytes(b"{}")
    ed = editor(doc, mat, project_path=str(proj))
    ed.exports.start(str(proj), Rect.of(0, 0, 64, 64))
    assert "proj.png is an input of this export" in ed.dialogs.messages[-1][1] and proj.read_bytes() == b"{}"
    ed.exports.start(str(gravel), Rect.of(0, 0, 64, 64))
    assert "gravel.png is an input of this export" in ed.dialogs.messages[-1][1]
    ed.exports.settings.format = "tiles"  # a tile's name that is a link to the exemplar
    (gravel.parent / "t.1001.png").symlink_to(gravel)
    ed.exports.start_streamed(str(gravel.parent / "t.png"), Rect.of(0, 0, 64, 64))
    assert "is an input of this export" in ed.dialogs.messages[-1][1]
    assert ed.exports.job is None and not ed.dialogs.questions and read(gravel) == read(GRAVEL)


def test_the_editor_asks_before_replacing_an_existing_file(editor, gravel, tmp_path):
    doc, mat = _single(gravel)
    out = tmp_path / "view.png"
    out.write_bytes(b"mine")
    ed = editor(doc, mat)  # the in-window browser or the path box: nobody asked yet
    ed.exports.start(str(out), Rect.of(0, 0, 64, 64))
    assert ed.exports.job is None and not ed.dialogs.messages and out.read_bytes() == b"mine"
    _, body, buttons = ed.dialogs.questions[-1]
    assert "view.png already exists" in body and [b for b, _ in buttons] == ["Replace", "Cancel"]
    buttons[0][1]()  # Replace: the export goes on (here: the document is not analyzed yet, and says so)
    assert len(ed.dialogs.questions) == 1 and "Nothing to export yet" in ed.dialogs.messages[-1][1]
    # A system dialog asked about the file chosen, not about the coordinate map beside it.
    ed = editor(doc, mat, native=True)
    ed.exports.start(str(out), Rect.of(0, 0, 64, 64))
    assert not ed.dialogs.questions and "Nothing to export yet" in ed.dialogs.messages[-1][1]
    (tmp_path / "view_coords.png").write_bytes(b"coords")
    ed = editor(doc, mat, native=True, write_coords=True)
    ed.exports.start(str(out), Rect.of(0, 0, 64, 64))
    assert "view_coords.png already exists" in ed.dialogs.questions[-1][1]
    # Streamed: an existing BigTIFF is asked about; a tile set being continued (its parts folder there) is not.
    ed = editor(doc, mat, format="tiff")
    (tmp_path / "big.tif").write_bytes(b"tif")
    ed.exports.start_streamed(str(tmp_path / "big.tif"), Rect.of(0, 0, 64, 64))
    assert "big.tif already exists" in ed.dialogs.questions[-1][1] and ed.exports.job is None
    ed.dialogs.questions[-1][2][0][1]()  # Replace
    assert isinstance(ed.exports.job, Started) and (tmp_path / "big.tif").read_bytes() == b"tif"
    ed = editor(doc, mat, format="tiles")
    (tmp_path / "set.1001.png").write_bytes(b"tile")
    ed.exports.start_streamed(str(tmp_path / "set.png"), Rect.of(0, 0, 64, 64))
    assert "set.<UDIM>.png already exists" in ed.dialogs.questions[-1][1] and ed.exports.job is None
    (tmp_path / "set.png.parts").mkdir()
    ed = editor(doc, mat, format="tiles")
    ed.exports.start_streamed(str(tmp_path / "set.png"), Rect.of(0, 0, 64, 64))
    assert not ed.dialogs.questions and isinstance(ed.exports.job, Started)


# -- one line of error, whatever the decoders log -------------------------------


def damaged_tiff() -> bytes:
    """A 2-channel 16-bit TIFF (read by tifffile) whose tags have an invalid
    type: tifffile logs a line per tag before it fails."""
    a = (np.random.default_rng(0).random((64, 64, 2)) * 65535).astype(np.uint16)
    buf = io.BytesIO()
    tifffile.imwrite(buf, a, photometric="minisblack", planarconfig="contig")
    d = bytearray(buf.getvalue())
    off = struct.unpack("<I", d[4:8])[0]
    for i in range(struct.unpack("<H", d[off:off + 2])[0]):
        p = off + 2 + 12 * i
        if struct.unpack("<H", d[p:p + 2])[0] not in (256, 257, 258, 262, 277, 284):
            d[p + 2:p + 4] = struct.pack("<H", 99)
    return bytes(d)


@pytest.mark.parametrize("command", ["export", "synth"])
@pytest.mark.parametrize("quiet", [True, False])
def test_a_damaged_tiff_gives_exactly_one_line(tmp_path, command, quiet):
    bad = tmp_path / "bad.tif"
    bad.write_bytes(damaged_tiff())
    env = dict(os.environ, INFINITEX_CACHE=str(tmp_path / "cache"))
    r = subprocess.run([sys.executable, os.path.join(ROOT, "main.py"), command, str(bad), "-o",
                        str(tmp_path / "o.png"), *(["-q"] if quiet else [])],
                       check=False, capture_output=True, text=True, timeout=300, env=env)
    assert r.returncode == 3
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: bad.tif could not be read"), r.stderr
