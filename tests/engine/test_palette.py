"""A palette of exemplars (engine/palette.py): several images or materials
packed into one exemplar, one label each; documents, projects and both
commands."""
from __future__ import annotations

import io
import json
import os

import numpy as np
import pytest
from clirun import infinitex
from PIL import Image

from infinitex import ASSETS
from infinitex.engine.exemplar import ExemplarError, from_array
from infinitex.engine.material import load_material, single
from infinitex.engine.palette import layout_for, pack_palette
from infinitex.project import Document, ExemplarSource, Project, ProjectError, load_project, save_project

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))


def _png(a: np.ndarray) -> bytes:
    buf = io.BytesIO()
    Image.fromarray(a).save(buf, "PNG")
    return buf.getvalue()


def _noise(m: int, seed: int, channels: int = 3) -> np.ndarray:
    a = np.random.default_rng(seed).integers(0, 256, (m, m, channels), dtype=np.uint8)
    return a[..., 0] if channels == 1 else a


def test_entries_are_packed_on_a_grid_and_located_back():
    imgs = [_noise(64, 1), _noise(64, 2, 1), _noise(128, 3)]  # a gray one, a larger one
    mats = [single(from_array(a.astype(np.float32) / 255, toroidal=False)) for a in imgs]
    mat, lay = pack_palette(mats, ["a.png", "b.png", "c.png"], "resize")
    px = mat.maps["image"].exemplar.pixels
    assert (lay.grid, lay.cell, lay.size) == (2, 64, 128) and px.shape == (128, 128, 3) and mat.toroidal
    ids = lay.labels()
    assert ids[0, 0] == 0 and ids[0, 64] == 1 and ids[64, 0] == 2 and ids[64, 64] == 0  # the 4th cell repeats the 1st
    assert np.array_equal(px[64:, 64:], px[:64, :64])
    # Where each exemplar pixel comes from: the entry and its pixel as fitted.
    ys, xs = np.mgrid[0:128, 0:128]
    entry, x, y = lay.locate(np.stack([xs, ys], axis=-1))
    assert np.array_equal(entry, ids)
    a = mats[0].maps["image"].pixels
    sel = entry == 0
    assert np.array_equal(px[sel], a[y[sel], x[sel]])
    gray = mats[1].maps["image"].pixels[..., 0]
    sel = entry == 1
    assert np.array_equal(px[sel][:, 1], gray[y[sel], x[sel]])  # gray replicated to RGB
    sel = entry == 2
    assert x[sel].max() == 126 and y[sel].max() == 126  # the 128 px entry was resized to the 64 px cell
    # Under a crop rule the larger entry is cropped instead: its pixels are copied exactly.
    mat, lay = pack_palette(mats, ["a.png", "b.png", "c.png"], "crop")
    px = mat.maps["image"].exemplar.pixels
    entry, x, y = lay.locate(np.stack([xs, ys], axis=-1))
    sel = entry == 2
    assert np.array_equal(px[sel], mats[2].maps["image"].pixels[y[sel], x[sel]])
    # Five to sixteen entries: a 4 x 4 grid, cells halved to stay within the fit rule's 512 px.
    lay = layout_for([f"{i}.png" for i in range(5)], [512] * 5, "resize")
    assert (lay.grid, lay.cell) == (4, 128)
    assert layout_for(["a", "b"], [2048, 2048], "resize-2048").cell == 1024
    for names, sizes in ((["a"], [64]), ([str(i) for i in range(17)], [64] * 17)):
        with pytest.raises(ExemplarError, match="2 to 16"):
            layout_for(names, sizes, "resize")


def test_a_palette_of_materials_keeps_each_map_aligned():
    def material(seed):
        base = _noise(64, seed)
        height = base[..., 0]
        return load_material([("basecolor", "b.png", _png(base)), ("height", "h.png", _png(height))])
    mats = [material(5), material(6)]
    mat, lay = pack_palette(mats, ["m1", "m2"], "resize")
    assert mat.roles == ["basecolor", "height"]
    base, height = mat.maps["basecolor"].pixels, mat.maps["height"].pixels
    assert np.array_equal(base[..., 0], height[..., 0])  # the height still equals the red channel, cell for cell
    other = load_material([("basecolor", "b.png", _png(_noise(64, 7)))])
    with pytest.raises(ExemplarError, match="the same maps"):
        pack_palette([mats[0], other], ["m1", "m3"], "resize")


def _sources(tmp_path):
    out = []
    for name in ("grass", "gravel", "brick"):
        out.append(ExemplarSource.from_file(os.path.join(ASSETS, f"{name}.png")))
    return out


def test_palette_documents_synthesize_each_label_from_its_exemplar(tmp_path, gpu):
    from infinitex.engine.analysis import analyze
    from infinitex.engine.controls import CanvasLabels
    from infinitex.engine.pyramid import Rect
    from infinitex.engine.synth import Synthesizer
    from infinitex.project.document import replace
    from infinitex.project.realize import exemplar_for, palette_for
    srcs = _sources(tmp_path)
    doc = Document(srcs[0], structure=0).with_palette([(("image", s),) for s in srcs])
    doc.validate()
    assert doc.labels.names == ("grass.png", "gravel.png", "brick.png") and doc.exemplar is srcs[0]
    assert len(doc.entries()) == 3 and doc.analysis_key() != Document(srcs[0]).analysis_key()
    # A canvas painted with one label uses only that exemplar's pixels (cells of its entry).
    canvas = np.zeros((96, 192), np.uint8)
    canvas[:, :96], canvas[:, 96:] = 2, 3  # gravel | brick
    doc = replace(doc, labels=replace(doc.labels, canvas=CanvasLabels.from_image(canvas, 1000, -500)))
    ex, settings = exemplar_for(doc)
    _, lay = palette_for(doc)
    an = analyze(ex, settings)
    with Synthesizer(an, doc.params(an.L), gpu=gpu, controls=doc.controls(an.size)) as s:
        S = s.window(Rect.of(1000, -500, 192, 96))
    entry, _, _ = lay.locate(S)
    inner = entry[8:-8]
    assert (inner[:, 8:88] == 1).mean() > 0.97 and (inner[:, 104:-8] == 2).mean() > 0.97
    # What is not painted is the first exemplar's (not a patchwork of all three).
    with Synthesizer(an, doc.params(an.L), gpu=gpu, controls=doc.controls(an.size)) as s:
        far, _, _ = lay.locate(s.window(Rect.of(-4000, 3000, 128, 96)))
    assert (far == 0).mean() > 0.97
    # One entry left: no palette, no labels.
    single_doc = doc.with_palette([doc.entries()[0]])
    assert not single_doc.palette and single_doc.labels is None


def test_projects_keep_the_palette_and_refuse_damaged_entries(tmp_path):
    srcs = _sources(tmp_path)
    doc = Document(srcs[0]).with_palette([(("image", s),) for s in srcs])
    path = tmp_path / "p.itex"
    save_project(str(path), Project(doc))
    saved = json.loads(path.read_text())
    assert saved["version"] == 9 and len(saved["palette"]) == 2 and saved["palette"][1][0]["name"] == "brick.png"
    back = load_project(str(path)).document
    assert back == doc and back.analysis_key() == doc.analysis_key() and back.labels == doc.labels
    assert sorted(doc.input_paths()) == sorted(s.path for s in srcs)  # no export may replace any of them
    good = path.read_text()
    for damage in (lambda d: d.update(palette="x"), lambda d: d["palette"][0][0].update(role="wood"),
                   lambda d: d["palette"][1][0].update(sha256="0" * 64), lambda d: d.update(palette=[[]]),
                   lambda d: d["palette"].extend([d["palette"][0]] * 15),
                   lambda d: d.pop("labels")):
        bad = json.loads(good)
        damage(bad)
        path.write_text(json.dumps(bad))
        with pytest.raises(ProjectError):
            load_project(str(path))


def test_both_commands_take_a_palette(tmp_path):
    a = os.path.join(ASSETS, "grass.png")
    pal = ",".join(os.path.join(ASSETS, f) for f in ("gravel.png", "brick.png"))
    colors = [(230, 25, 75), (60, 180, 75), (255, 225, 25)]  # the palette's labels 1, 2, 3
    canvas = np.zeros((64, 192, 3), np.uint8)
    for i in range(3):
        canvas[:, 64 * i:64 * (i + 1)] = colors[i]
    Image.fromarray(canvas).save(tmp_path / "canvas.png")

    cli = infinitex  # in this process (tests/clirun.py)
    r = cli("synth", a, "--palette", pal, "--labels-canvas", str(tmp_path / "canvas.png"), "--size", "192", "64",
            "-o", str(tmp_path / "s.png"), "--coords", str(tmp_path / "c.npy"), "--fidelity", "0", "-q")
    assert r.returncode == 0, r.stderr
    coords = np.load(tmp_path / "c.npy")
    cell = (coords[..., 1] // 128) * 2 + coords[..., 0] // 128
    entry = cell % 3
    for i in range(3):
        assert (entry[8:-8, 64 * i + 8:64 * (i + 1) - 8] == i).mean() > 0.97
    r = cli("export", a, "--palette", pal, "--labels-canvas", str(tmp_path / "canvas.png"), "--rect", "0", "0",
            "192", "64", "--fidelity", "0", "-o", str(tmp_path / "e.png"), "-q")
    assert r.returncode == 0, r.stderr
    assert np.array_equal(np.asarray(Image.open(tmp_path / "s.png")), np.asarray(Image.open(tmp_path / "e.png")))
    # Refused in one line: a label map of the exemplar with a palette, a missing file, an output over an input.
    for args, code, words in ((("--palette", pal, "--labels-exemplar", str(tmp_path / "canvas.png")), 2,
                               "--labels-exemplar"),
                              (("--palette", str(tmp_path / "none.png")), 3, "none.png"),
                              (("--palette", str(tmp_path / "x.png")), 2, "x.png")):
        r = cli("synth", a, "-o", str(tmp_path / "x.png"), "--size", "32", "32", "-q", *args)
        assert r.returncode == code and words in r.stderr and len(r.stderr.strip().splitlines()) == 1, r.stderr


def test_the_api_packs_a_palette_for_synthesize():
    import infinitex
    ex, lay = infinitex.palette([os.path.join(ASSETS, "grass.png"), os.path.join(ASSETS, "gravel.png")])
    assert lay.names == ("grass.png", "gravel.png") and ex.size == 256
    canvas = np.full((64, 64), 1)  # all gravel (label 1)
    out = infinitex.synthesize(ex, (64, 64), labels=(lay.labels(), canvas), structure=0)
    gravel = infinitex.synthesize(ex, (64, 64), labels=(lay.labels(), canvas * 0), structure=0)
    assert out.shape[:2] == (64, 64) and not np.array_equal(out, gravel)


def test_a_palette_over_the_import_budget_is_refused_before_decoding(tmp_path, monkeypatch):
    """Like a material, a palette's import (its files, the largest decode, every
    fitted map) is checked against MATERIAL_BUDGET from the headers, and by the
    command line from the files' sizes before they are read: one line each."""
    from infinitex.engine import palette as palette_module
    from infinitex.engine.material import MaterialError
    from infinitex.project.document import replace
    from infinitex.project.realize import palette_for
    srcs = _sources(tmp_path)
    doc = replace(Document(srcs[0]), palette=tuple(((("image", s),) for s in srcs[1:])))
    palette_for(doc)  # within the budget
    monkeypatch.setattr(palette_module, "MATERIAL_BUDGET", 1 << 20)
    decoded = []
    monkeypatch.setattr("infinitex.project.realize.load_exemplar_bytes", lambda *a, **k: decoded.append(1))
    with pytest.raises(MaterialError, match="palette's 3 exemplars would need"):
        palette_for(doc)
    assert not decoded
    monkeypatch.setattr("infinitex.engine.material.MATERIAL_BUDGET", 20_000)
    pal = ",".join(os.path.join(ASSETS, f) for f in ("gravel.png", "brick.png"))
    r = infinitex("synth", os.path.join(ASSETS, "grass.png"), "--palette", pal, "-o", str(tmp_path / "x.png"),
                  "--size", "32", "32", "-q")
    assert r.returncode == 3 and "palette's files come to" in r.stderr and r.stderr.count("\n") == 1, r.stderr
    # Files small enough together, images too large to decode together: refused from their first bytes, before
    # any palette file is read whole (14 files of 132 MB: 92 MB and 0.9 s for the refusal, 2.1 GB and 8 s before).
    sizes = sum(os.path.getsize(os.path.join(ASSETS, f)) for f in ("grass.png", "gravel.png", "brick.png"))
    monkeypatch.setattr("infinitex.engine.material.MATERIAL_BUDGET", sizes + 4096)
    monkeypatch.setattr(palette_module, "MATERIAL_BUDGET", sizes + 4096)
    monkeypatch.setattr(palette_module, "HEAD_BYTES", 4096)
    from infinitex.project.document import ExemplarSource
    read, from_file = [], ExemplarSource.from_file
    monkeypatch.setattr(ExemplarSource, "from_file", staticmethod(lambda p, *a, **k: read.append(p) or from_file(p)))
    r = infinitex("synth", os.path.join(ASSETS, "grass.png"), "--palette", pal, "-o", str(tmp_path / "x.png"),
                  "--size", "32", "32", "-q")
    assert r.returncode == 3 and "palette's 3 exemplars would need" in r.stderr, r.stderr
    assert not [p for p in read if "gravel" in str(p) or "brick" in str(p)], read
