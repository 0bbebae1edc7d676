"""Regular textures right by default: an image that shows a lattice is
synthesized on it without being asked (synth, export, the API, an image opened
as a document), exactly as with --lattice auto; --lattice none (lattice=None)
turns it off; a stochastic image gets none."""
import os
import tempfile

import numpy as np
import pytest
from clirun import infinitex
from lattice_gen import bricks
from PIL import Image

import infinitex as itx
from infinitex.project.document import Document, ExemplarSource
from infinitex.project.realize import AnalysisJob

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
GRAVEL = os.path.join(ROOT, "infinitex", "assets", "gravel.png")


@pytest.fixture(scope="module")
def brick_png(tmp_path_factory):
    img, _, _ = bricks(np.random.default_rng(3), side=128, bw=32.0, bh=16.0)
    path = str(tmp_path_factory.mktemp("bricks") / "bricks.png")
    Image.fromarray((img * 255).astype(np.uint8)).save(path)
    return path


def _lattice_line(stdout: str) -> str | None:
    lines = [ln for ln in stdout.splitlines() if ln.startswith("lattice: ")]
    return lines[0][len("lattice: "):] if lines else None


def test_synth_finds_the_lattice_unasked(brick_png, tmp_path):
    outs = {}
    for name, extra in (("default", []), ("auto", ["--lattice", "auto"]), ("none", ["--lattice", "none"])):
        out = str(tmp_path / f"{name}.png")
        r = infinitex("synth", brick_png, "-o", out, "--size", "96", "96", *extra)
        assert r.returncode == 0, r.stderr
        outs[name] = (np.asarray(Image.open(out)), _lattice_line(r.stdout), r.stderr)
    found = outs["default"][1]
    assert found is not None and found != "none" and found == outs["auto"][1]
    assert "a lattice was found in the exemplar" in outs["default"][2] and "--lattice none" in outs["default"][2]
    assert np.array_equal(outs["default"][0], outs["auto"][0])
    assert outs["none"][1] == "none" and not np.array_equal(outs["default"][0], outs["none"][0])


def test_a_stochastic_image_gets_no_lattice(tmp_path):
    out = str(tmp_path / "g.png")
    r = infinitex("synth", GRAVEL, "-o", out, "--size", "64", "64")
    assert r.returncode == 0, r.stderr
    assert _lattice_line(r.stdout) is None and "lattice" not in r.stderr


def test_export_finds_the_lattice_unasked(brick_png, tmp_path):
    r = infinitex("export", brick_png, "-o", str(tmp_path / "e.png"), "--size", "64", "64")
    assert r.returncode == 0, r.stderr
    assert _lattice_line(r.stdout) not in (None, "none")


def test_the_api_default_is_auto(brick_png):
    img = np.asarray(Image.open(brick_png), np.float32) / 255.0
    default = itx.synthesize(img, size=(64, 64))
    assert np.array_equal(default, itx.synthesize(img, size=(64, 64), lattice="auto"))
    assert not np.array_equal(default, itx.synthesize(img, size=(64, 64), lattice=None))
    assert np.array_equal(itx.synthesize(GRAVEL, size=(48, 48)), itx.synthesize(GRAVEL, size=(48, 48), lattice=None))


def test_the_api_reads_8_bit_arrays_on_their_range(brick_png):
    # An 8-bit array is what Pillow gives: it must not be clipped to white.
    u8 = np.asarray(Image.open(brick_png))
    unit = u8.astype(np.float32) / 255.0
    for lattice in ("auto", None):
        got = itx.synthesize(u8, size=(48, 48), lattice=lattice)
        assert np.array_equal(got, itx.synthesize(unit, size=(48, 48), lattice=lattice))
        assert got.std() > 10
    with pytest.raises(ValueError, match="divide by 255"):
        itx.synthesize(u8.astype(np.float32), size=(48, 48))
    with pytest.raises(ValueError, match="ambiguous"):
        itx.synthesize(u8.astype(np.int64) - 1, size=(48, 48), lattice=None)


def test_an_opened_image_gets_its_lattice(brick_png):
    doc = Document(ExemplarSource.from_file(brick_png))
    job = AnalysisJob(doc, find_lattice=True)
    assert job.wait(120) and job.error is None
    assert job.doc.lattice is not None and job.found.confidence >= 0.3
    assert job.asked_key == doc.analysis_key() and job.key == job.doc.analysis_key() != job.asked_key
    assert job.analysis is not None and job.exemplar.fit == "lattice"
    # With a quick preview (the editor's), the first texture does not wait for the search: the preview is the
    # image as given, and the lattice found after it is the job's document, for the editor to adopt.
    with tempfile.TemporaryDirectory() as cache:
        quick = AnalysisJob(doc, cache_dir=cache, preview=True, find_lattice=True)
        assert quick.wait(120) and quick.error is None
    shown, ex, an, _ = quick.take_preview()
    assert shown is doc and shown.lattice is None and ex.fit != "lattice" and an.size == ex.size
    assert quick.doc.lattice == job.doc.lattice and quick.key == job.key and quick.exemplar.fit == "lattice"
    # Not where a lattice does not go (Make tileable), nor on a stochastic image.
    tileable = AnalysisJob(Document(ExemplarSource.from_file(brick_png), make_tileable=True), find_lattice=True)
    gravel = AnalysisJob(Document(ExemplarSource.from_file(GRAVEL)), find_lattice=True)
    assert tileable.wait(120) and gravel.wait(120)
    assert tileable.doc.lattice is None and tileable.found is None
    assert gravel.doc.lattice is None and gravel.found is not None and gravel.found.lattice is None


@pytest.mark.slow
def test_an_image_too_large_to_search_whole_is_synthesized_without_a_lattice(tmp_path):
    """Over 16 Mpixels (what the lattice search decodes whole), the search is
    skipped and --lattice none decodes nothing whole: synth and export accept
    what synthesis accepts (up to 64 Mpixels), as they did below the limit."""
    big = tmp_path / "big.png"  # 4224^2 = 17.8 Mpixels, of one colour: its analysis is quick
    Image.new("RGB", (4224, 4224), (120, 90, 60)).save(big)
    for args in (["synth", big, "-o", tmp_path / "a.png", "--size", "64", "64"],
                 ["export", big, "-o", tmp_path / "d.png", "--size", "64", "64", "--lattice", "none"]):
        r = infinitex(*args)
        assert r.returncode == 0, r.stderr
        assert "Mpixels" not in r.stderr and _lattice_line(r.stdout) in (None, "none")
    r = infinitex("synth", big, "-o", tmp_path / "e.png", "--lattice", "auto")  # asked for: refused in one line
    assert r.returncode != 0 and "at most 16 Mpixels" in r.stderr
