"""``infinitex animate``: the texture flowing, as an image sequence, a flipbook
atlas with its description, animated WebP and PNG, and MP4; every format holds
the same frames as the engine; a material's maps flow alike; bad arguments get
one line and write nothing; a folder of other files is never replaced."""
import json
import os

import numpy as np
import pytest
from clirun import infinitex
from PIL import Image

from infinitex.engine.advect import FlowFrames, SynthSource
from infinitex.engine.analysis import analyze
from infinitex.engine.controls.flow import Flow
from infinitex.engine.exemplar import load_exemplar
from infinitex.engine.imagefile import to_u8
from infinitex.engine.params import SynthParams, structure_params
from infinitex.engine.pyramid import Rect
from infinitex.engine.synth import Synthesizer
from infinitex.export.animation import AnimationWriter, check_folder_output

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
GRAVEL = os.path.join(ROOT, "infinitex", "assets", "gravel.png")


def run(*args):
    return infinitex("animate", *args)


def cells(atlas: np.ndarray, desc: dict) -> list[np.ndarray]:
    w, h, cols = desc["frame_width"], desc["frame_height"], desc["columns"]
    return [atlas[(i // cols) * h:(i // cols + 1) * h, (i % cols) * w:(i % cols + 1) * w] for i in range(desc["frames"])]


def test_a_looping_flipbook_tile_and_its_image_sequence(tmp_path):
    atlas, folder = tmp_path / "lava.png", tmp_path / "seq"
    common = ["--frames", "8", "--loop", "--toroidal", "32", "--velocity", "1.5,-0.5", "--fps", "12", "-q"]
    r = run(GRAVEL, "-o", atlas, *common)
    assert r.returncode == 0, r.stderr
    desc = json.loads((tmp_path / "lava.json").read_text())
    assert {k: desc[k] for k in ("frame_width", "frame_height", "frames", "columns", "rows", "fps", "loop")} == \
        dict(frame_width=32, frame_height=32, frames=8, columns=4, rows=2, fps=12.0, loop=True)
    import hashlib
    assert desc["sha256"] == hashlib.sha256(atlas.read_bytes()).hexdigest() and desc["image"] == "lava.png"
    sheet = np.asarray(Image.open(atlas))
    assert sheet.shape[:2] == (64, 128)
    r = run(GRAVEL, "-o", folder, *common)
    assert r.returncode == 0, r.stderr
    names = sorted(os.listdir(folder))
    assert names == [f"frame_{i:04d}.png" for i in range(8)]
    seq = [np.asarray(Image.open(folder / n)) for n in names]
    for a, b in zip(cells(sheet, desc), seq):
        np.testing.assert_array_equal(a, b)
    # The same frames as the engine's: a uniform velocity on a tile, renewed by the loop.
    an = analyze(load_exemplar(GRAVEL))
    with Synthesizer(an, structure_params(SynthParams.default(an.L), 2)) as s:
        ff = FlowFrames(SynthSource(s, 32), Flow.of(1.5, -0.5, period=8, loop=8), seed=0)
        for t in (0, 5):
            want = to_u8(s.colors(ff.frame(t, Rect(0, 0, 32, 32))))
            np.testing.assert_array_equal(seq[t], want[..., 0] if want.shape[2] == 1 else want)
    assert any(np.any(seq[t] != seq[t + 1]) for t in range(7))
    # Written again over an earlier sequence: replaced whole.
    (folder / "frame_0007.png").unlink()
    r = run(GRAVEL, "-o", folder, *common)
    assert r.returncode == 0 and len(os.listdir(folder)) == 8


def test_animated_files_and_video(tmp_path):
    for ext in (".webp", ".apng"):
        out = tmp_path / f"a{ext}"
        r = run(GRAVEL, "-o", out, "--frames", "5", "--size", "40", "24", "--origin", "-1000", "2000", "-q")
        assert r.returncode == 0, r.stderr
        with Image.open(out) as im:
            assert im.n_frames == 5 and im.size == (40, 24)
    av = pytest.importorskip("av")
    out = tmp_path / "a.mp4"
    r = run(GRAVEL, "-o", out, "--frames", "6", "--size", "41", "23", "--fps", "30", "-q")
    assert r.returncode == 0, r.stderr
    with av.open(str(out)) as box:
        frames = [f for f in box.decode(video=0)]
    assert len(frames) == 6 and (frames[0].width, frames[0].height) == (42, 24)  # padded to even sizes


def test_a_materials_maps_flow_alike(tmp_path):
    ex = np.asarray(Image.open(GRAVEL).convert("L"))
    Image.fromarray(np.stack([ex, ex // 2, 255 - ex], -1)).save(tmp_path / "stone_basecolor.png")
    normal = np.zeros(ex.shape + (3,), np.uint8)
    normal[..., 0], normal[..., 1], normal[..., 2] = 200, 128, 230
    Image.fromarray(normal).save(tmp_path / "stone_normal.png")
    vmap = np.full((32, 32, 3), 128, np.uint8)
    vmap[..., 1] = 255  # up at --speed
    Image.fromarray(vmap).save(tmp_path / "up.png")
    r = run(tmp_path / "stone_basecolor.png", "-o", tmp_path / "o.png", "--frames", "3", "--size", "32", "32",
            "--velocity", tmp_path / "up.png", "--speed", "2", "-q")
    assert r.returncode == 0, r.stderr
    for role in ("basecolor", "normal"):
        assert json.loads((tmp_path / f"o_{role}.json").read_text())["frames"] == 3
    assert not (tmp_path / "o.png").exists()


@pytest.mark.parametrize("args, words", [
    (["--frames", "0"], "--frames is 1 to"),
    (["--frames", "4", "--velocity", "1,x"], "--velocity is VX,VY"),
    (["--frames", "4", "--velocity", "40,0"], "at most 32 px per frame"),
    (["--frames", "131", "--loop"], "divides it"),
    (["--frames", "4", "--period", "1"], "renewal period"),
    (["--frames", "4", "--toroidal", "48"], "power-of-two"),
    (["--frames", "4", "--fps", "0"], "--fps"),
])
def test_bad_arguments_get_one_line_and_write_nothing(tmp_path, args, words):
    out = tmp_path / "o.png"
    r = run(GRAVEL, "-o", out, *args)
    assert r.returncode == 2 and words in r.stderr and r.stderr.count("\n") == 1, r.stderr
    assert os.listdir(tmp_path) == []


def test_outputs_that_are_refused(tmp_path):
    r = run(GRAVEL, "-o", tmp_path / "o.gif", "--frames", "2")
    assert r.returncode == 2 and "not .gif" in r.stderr
    other = tmp_path / "photos"
    other.mkdir()
    (other / "holiday.jpg").write_bytes(b"x")
    r = run(GRAVEL, "-o", other, "--frames", "2")
    assert r.returncode == 2 and "other files" in r.stderr and os.listdir(other) == ["holiday.jpg"]
    gray = tmp_path / "gray.png"
    Image.fromarray(np.full((8, 8), 128, np.uint8)).save(gray)
    r = run(GRAVEL, "-o", tmp_path / "o.png", "--frames", "2", "--velocity", gray)
    assert r.returncode == 3 and "grayscale" in r.stderr and not (tmp_path / "o.png").exists()
    r = run(GRAVEL, "-o", GRAVEL.replace(".png", "_copy_never.png").replace(os.path.dirname(GRAVEL), str(tmp_path)),
            "--frames", "2", "--velocity", str(tmp_path / "missing.png"))
    assert r.returncode == 2 and "neither VX,VY nor an image" in r.stderr


def test_a_failed_write_leaves_what_was_there(tmp_path):
    seq = tmp_path / "seq"
    w = AnimationWriter(str(seq), "folder", 24, False)
    w.add(np.zeros((4, 4, 3), np.uint8))
    w.close()
    before = sorted(os.listdir(seq))
    w = AnimationWriter(str(seq), "folder", 24, False)
    w.add(np.zeros((4, 4, 3), np.uint8))
    w.frames.append(object())  # a frame that cannot be encoded: the write fails midway
    with pytest.raises(Exception):
        w.close()
    assert sorted(os.listdir(seq)) == before and sorted(os.listdir(tmp_path)) == ["seq"]
    check_folder_output(str(seq))


def test_a_materials_image_sequences_and_limits(tmp_path):
    ex = np.asarray(Image.open(GRAVEL).convert("L"))
    Image.fromarray(np.stack([ex, ex, ex], -1)).save(tmp_path / "stone_basecolor.png")
    Image.fromarray(ex).save(tmp_path / "stone_height.png")
    out = tmp_path / "seq"
    for _ in range(2):  # made, then replaced
        r = run(tmp_path / "stone_basecolor.png", "-o", out, "--frames", "2", "--size", "24", "16", "-q")
        assert r.returncode == 0, r.stderr
        assert sorted(os.listdir(out)) == ["basecolor", "height"]
        assert sorted(os.listdir(out / "height")) == ["frame_0000.png", "frame_0001.png"]
    # Where one synthesis could not cover a chain's travel, or WebP cannot hold the frames: one line, before work.
    r = run(GRAVEL, "-o", tmp_path / "o.png", "--frames", "2", "--velocity", "32,0", "--period", "128")
    assert r.returncode == 2 and "shorter --period" in r.stderr
    r = run(GRAVEL, "-o", tmp_path / "o.webp", "--frames", "2", "--size", "16384", "8")
    assert r.returncode == 2 and "WebP is at most" in r.stderr
    vmap = tmp_path / "v.png"
    Image.fromarray(np.full((4, 4, 3), 200, np.uint8)).save(vmap)
    r = run(GRAVEL, "-o", tmp_path / "o.png", "--frames", "2", "--velocity", vmap, "--velocity-origin", "2147483000", "0")
    assert r.returncode in (2, 3) and r.stderr.count("\n") == 1 and "outside" in r.stderr
