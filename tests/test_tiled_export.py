"""Streamed exports (engine.tiled_export, infinitex export --format tiles|tiff):
equal to the same rectangle rendered in one piece, resumable after a killed
process, rewriting only the missing tiles."""
import os
import signal
import subprocess
import sys
import time

import numpy as np
import pytest
import tifffile


from infinitex.engine.analysis import analyze
from infinitex.engine.exemplar import load_exemplar, to_u8
from infinitex.engine.pyramid import Rect
from infinitex.engine.synth import Synthesizer
from infinitex.engine.tiled_export import ExportInterrupted, TiledExport, read_tiles, udim_name

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
GRAVEL = os.path.join(ROOT, "infinitex", "assets", "gravel.png")


@pytest.fixture(scope="module")
def synth(gpu):
    s = Synthesizer(analyze(load_exemplar(GRAVEL)), gpu=gpu)
    yield s


def test_4096_tiles_and_bigtiff_equal_the_one_piece_render(synth, tmp_path):
    rect = Rect.of(-1000, 30_000, 4096, 4096)
    whole = to_u8(synth.colors(synth.window(rect)))
    TiledExport(synth, rect, str(tmp_path / "set.png"), "tiles", 1024, key="k").run()
    assert os.path.isfile(tmp_path / "set.1001.png") and os.path.isfile(tmp_path / "set.1034.png")
    assert np.array_equal(read_tiles(str(tmp_path / "set.png"), 4096, 4096, 1024, 1), whole)
    TiledExport(synth, rect, str(tmp_path / "big.tif"), "tiff", 512, key="k").run()
    with tifffile.TiffFile(tmp_path / "big.tif") as tf:
        page = tf.pages[0]
        assert tf.is_bigtiff and page.is_tiled and page.tilewidth == 512
        assert np.array_equal(page.asarray(), whole[..., 0])
    assert not os.path.exists(tmp_path / "big.tif.parts")  # the parts are gone once it is complete


def test_interrupted_export_resumes_with_the_missing_tiles_only(synth, tmp_path):
    rect = Rect.of(5, 7, 1000, 600)
    out = str(tmp_path / "t.png")
    calls = []

    def stop(done, total):
        calls.append(done)
        if len(calls) == 4:
            raise ExportInterrupted()
    first = TiledExport(synth, rect, out, "tiles", 256, key="k")
    with pytest.raises(ExportInterrupted):
        first.run(stop)
    kept = {n: os.path.getmtime(tmp_path / n) for n in os.listdir(tmp_path) if n.endswith(".png")}
    assert len(kept) == 4
    # A damaged tile is not trusted: it is rendered again.
    damaged = udim_name(str(tmp_path / "t"), 1, 0, 4)
    with open(damaged, "r+b") as f:
        f.seek(60)
        f.write(b"\x00\x01\x02")
    time.sleep(0.01)
    again = TiledExport(synth, rect, out, "tiles", 256, key="k")
    again.run()
    assert again.rendered == again.rows * again.cols - 3
    for name, t in kept.items():
        if os.path.join(tmp_path, name) != damaged:
            assert os.path.getmtime(tmp_path / name) == t  # kept, not rewritten
    assert np.array_equal(read_tiles(out, 1000, 600, 256, 1), to_u8(synth.colors(synth.window(rect))))
    # Another export (another key) into the same name starts over.
    other = TiledExport(synth, Rect.of(6, 7, 1000, 600), out, "tiles", 256, key="k")
    other.run()
    assert other.rendered == other.rows * other.cols


def test_killed_cli_export_finishes_identically_when_run_again(tmp_path):
    env = dict(os.environ, INFINITEX_CACHE=str(tmp_path / "cache"))
    args = [sys.executable, os.path.join(ROOT, "main.py"), "export", GRAVEL, "-o", str(tmp_path / "k.tif"),
            "--format", "tiff", "--rect", "0", "0", "2048", "2048", "--tile", "256", "-q"]
    proc = subprocess.Popen(args, env=env, stderr=subprocess.PIPE)
    manifest = tmp_path / "k.tif.parts" / "manifest.jsonl"
    deadline = time.monotonic() + 240
    while time.monotonic() < deadline:
        try:
            if _finished(manifest) >= 10:
                break
        except (OSError, ValueError, KeyError):
            pass
        time.sleep(0.05)
    proc.send_signal(signal.SIGKILL)
    proc.wait()
    done_before = _finished(manifest)
    assert 10 <= done_before < 64 and not os.path.exists(tmp_path / "k.tif")
    again = subprocess.run(args[:-1], env=env, capture_output=True, text=True, timeout=600)
    assert again.returncode == 0, again.stderr[-2000:]
    assert f"({done_before} kept from an earlier run)" in again.stderr
    fresh = subprocess.run([*args[:5], str(tmp_path / "fresh.tif"), *args[6:]], env=env, capture_output=True,
                           text=True, timeout=600)
    assert fresh.returncode == 0, fresh.stderr[-2000:]
    assert np.array_equal(tifffile.imread(tmp_path / "k.tif"), tifffile.imread(tmp_path / "fresh.tif"))


def test_cli_refuses_bad_tiled_arguments(tmp_path):
    def run(*a):
        return subprocess.run([sys.executable, os.path.join(ROOT, "main.py"), "export", GRAVEL, *a],
                              capture_output=True, text=True, timeout=120)
    r = run("-o", str(tmp_path / "x.png"), "--format", "tiles", "--tile", "300")
    assert r.returncode == 2 and "--tile must be one of" in r.stderr
    r = run("-o", str(tmp_path / "x.png"), "--format", "tiff")
    assert r.returncode == 2 and "must end in .tif" in r.stderr
    r = run("-o", str(tmp_path / "x.png"), "--format", "tiles", "--rect", "0", "0", str(2 ** 20 + 1), "10")
    assert r.returncode == 2 and "1048576" in r.stderr
    r = run("-o", str(tmp_path / "x.png"), "--format", "tiles", "--coords")
    assert r.returncode == 2 and "--coords goes with --format png" in r.stderr
    assert not list(tmp_path.iterdir())



def _finished(manifest) -> int:
    """Tiles a running export has finished: the lines after the key in its manifest."""
    return len([ln for ln in manifest.read_text().splitlines()[1:] if ln.strip()])


def _children(pid: int) -> list[int]:
    out = []
    for task in os.listdir(f"/proc/{pid}/task"):
        try:
            with open(f"/proc/{pid}/task/{task}/children") as f:
                out += [int(c) for c in f.read().split()]
        except OSError:
            pass
    return out


def test_worker_processes_give_the_same_bytes_and_survive_a_killed_worker(tmp_path):
    env = dict(os.environ, INFINITEX_CACHE=str(tmp_path / "cache"))
    base = [sys.executable, os.path.join(ROOT, "main.py"), "export", GRAVEL, "--format", "tiles",
            "--rect", "-500", "300", "1536", "1536", "--tile", "256", "-q"]
    one = subprocess.run([*base, "-o", str(tmp_path / "one.png")], env=env, capture_output=True, text=True,
                         timeout=600)
    assert one.returncode == 0, one.stderr[-2000:]
    proc = subprocess.Popen([*base, "-o", str(tmp_path / "two.png"), "--workers", "2"], env=env,
                            stderr=subprocess.PIPE)
    manifest = tmp_path / "two.png.parts" / "manifest.jsonl"
    killed = False
    deadline = time.monotonic() + 300
    while proc.poll() is None and time.monotonic() < deadline and not killed:
        try:
            started = _finished(manifest) >= 3
        except (OSError, ValueError, KeyError):
            started = False
        if started:
            for child in _children(proc.pid):
                with open(f"/proc/{child}/cmdline", "rb") as f:
                    if b"spawn_main" in f.read():
                        os.kill(child, signal.SIGKILL)  # a worker dies mid-export
                        killed = True
                        break
        time.sleep(0.02)
    assert proc.wait(600) == 0, proc.stderr.read().decode()[-2000:]
    assert killed
    for row in range(6):
        for col in range(6):
            a = udim_name(str(tmp_path / "one"), col, row, 6)
            b = udim_name(str(tmp_path / "two"), col, row, 6)
            with open(a, "rb") as fa, open(b, "rb") as fb:
                assert fa.read() == fb.read(), (col, row)
