"""Streamed exports (infinitex.export, infinitex export --format tiles|tiff):
equal to the same rectangle rendered in one piece, resumable after a killed
process, rewriting only the missing tiles."""
import os
import signal
import subprocess
import sys
import time

import numpy as np
import pytest
from clirun import infinitex
import tifffile

from infinitex.engine.analysis import analyze
from infinitex.engine.exemplar import load_exemplar
from infinitex.engine.imagefile import to_u8
from infinitex.engine.pyramid import Rect
from infinitex.engine.synth import Synthesizer
from infinitex.export import ExportInterrupted, TiledExport, read_tiles, udim_name

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
GRAVEL = os.path.join(ROOT, "infinitex", "assets", "gravel.png")


@pytest.fixture(scope="module")
def synth(gpu):
    s = Synthesizer(analyze(load_exemplar(GRAVEL)), gpu=gpu)
    yield s


@pytest.mark.slow
def test_tiles_and_bigtiff_equal_the_one_piece_render(synth, tmp_path):
    rect = Rect.of(-1000, 30_000, 2048, 2048)  # 4 x 4 tiles of each size (UDIM 1001 to 1034)
    whole = to_u8(synth.colors(synth.window(rect)))
    TiledExport(synth, rect, str(tmp_path / "set.png"), "tiles", 512, key="k").run()
    assert os.path.isfile(tmp_path / "set.1001.png") and os.path.isfile(tmp_path / "set.1034.png")
    assert np.array_equal(read_tiles(str(tmp_path / "set.png"), 2048, 2048, 512, 1), whole)
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


@pytest.mark.slow
def test_killed_cli_export_finishes_identically_when_run_again(tmp_path):
    env = dict(os.environ, INFINITEX_CACHE=str(tmp_path / "cache"))
    args = [sys.executable, os.path.join(ROOT, "main.py"), "export", GRAVEL, "-o", str(tmp_path / "k.tif"),
            "--format", "tiff", "--rect", "0", "0", "2048", "2048", "--tile", "256", "--fidelity", "variety", "-q"]
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


@pytest.mark.slow
def test_cli_refuses_bad_tiled_arguments(tmp_path):
    def run(*a):
        return infinitex("export", GRAVEL, *a)  # in this process (tests/clirun.py)
    r = run("-o", str(tmp_path / "x.png"), "--format", "tiles", "--tile", "300")
    assert r.returncode == 2 and "--tile must be one of" in r.stderr
    r = run("-o", str(tmp_path / "x.png"), "--format", "tiff")
    assert r.returncode == 2 and "must end in .tif" in r.stderr
    r = run("-o", str(tmp_path / "x.png"), "--format", "tiles", "--rect", "0", "0", str(2 ** 20 + 1), "10")
    assert r.returncode == 2 and "1048576" in r.stderr
    r = run("-o", str(tmp_path / "x.png"), "--scheduler")
    assert r.returncode == 2 and "--scheduler goes with --format tiles, tiff or zarr" in r.stderr
    r = run("-o", str(tmp_path / "x.zarr"), "--format", "zarr", "--coords")
    assert r.returncode == 2 and "--coords goes with --format png, tiles or tiff" in r.stderr
    (tmp_path / "notzarr.zarr").mkdir()
    r = run("-o", str(tmp_path / "notzarr.zarr"), "--format", "zarr")
    assert r.returncode == 2 and "is not a Zarr store; it is not overwritten" in r.stderr
    (tmp_path / "notzarr.zarr").rmdir()
    assert not list(tmp_path.iterdir())
    r = run("-o", str(tmp_path / "x.png"), "--format", "tiles", "--scheduler", "tcp://127.0.0.1:9",
            "--rect", "0", "0", "64", "64", "-q")
    assert r.returncode == 3 and r.stderr.startswith("error: Cannot reach the Dask scheduler at tcp://127.0.0.1:9")
    assert len(r.stderr.strip().splitlines()) == 1



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


@pytest.mark.slow
def test_worker_processes_give_the_same_bytes_and_survive_a_killed_worker(tmp_path):
    env = dict(os.environ, INFINITEX_CACHE=str(tmp_path / "cache"))
    base = [sys.executable, os.path.join(ROOT, "main.py"), "export", GRAVEL, "--format", "tiles",
            "--rect", "-500", "300", "1536", "1536", "--tile", "256", "--fidelity", "variety", "-q"]
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


def test_streamed_coordinate_map_is_the_synthesis_coordinates(synth, tmp_path):
    from infinitex.export import decode_coords
    rect = Rect.of(-300, 2**30 - 200, 700, 500)
    TiledExport(synth, rect, str(tmp_path / "c.tif"), "tiff", 256, key="k", coords=True).run()
    TiledExport(synth, rect, str(tmp_path / "c.png"), "tiles", 256, key="k", coords=True).run()
    coords = synth.window(rect)
    assert np.array_equal(decode_coords(tifffile.imread(tmp_path / "c_coords.tif")), coords)
    assert np.array_equal(decode_coords(read_tiles(str(tmp_path / "c_coords.png"), 700, 500, 256, 3)), coords)
    assert np.array_equal(tifffile.imread(tmp_path / "c.tif"), to_u8(synth.colors(coords))[..., 0])


def test_cancel_event_stops_a_pool_export_promptly_and_keeps_its_tiles(tmp_path):
    import json
    import threading

    from infinitex.export.workers import ProjectSynthesizer
    from infinitex.project import Document, ExemplarSource, Project, project_to_json
    init = ProjectSynthesizer(json.dumps(project_to_json(Project(Document(ExemplarSource.from_file(GRAVEL))),
                                                         embed=True)))
    job = TiledExport(None, Rect.of(0, 0, 4096, 4096), str(tmp_path / "c.png"), "tiles", 256, key="k")
    seen = []

    def progress(done, total):
        seen.append(done)
        if done == 3:
            threading.Thread(target=job.cancel_event.set).start()
    with pytest.raises(ExportInterrupted):
        job.run(progress, workers=2, worker_init=init)
    assert 3 <= job.rendered <= 8  # the 256 tiles queued were dropped, not rendered
    # The tiles it kept are whole and right: the same bytes as another export's first tile.
    other = TiledExport(None, Rect.of(0, 0, 512, 512), str(tmp_path / "d.png"), "tiles", 256, key="k")
    other.run(workers=1, worker_init=init)
    assert (tmp_path / "d.1001.png").read_bytes() == (tmp_path / "c_u1_v1.png").read_bytes()


@pytest.mark.slow
def test_a_failed_write_is_one_sentence_and_the_export_resumes(tmp_path):
    import resource
    env = dict(os.environ, INFINITEX_CACHE=str(tmp_path / "cache"))
    args = [sys.executable, os.path.join(ROOT, "main.py"), "export", GRAVEL, "-o", str(tmp_path / "f.tif"),
            "--format", "tiff", "--rect", "0", "0", "1024", "1024", "--tile", "256", "--fidelity", "variety", "-q"]

    def small_files():  # no file above 400 kB: the tiles fit, the assembled TIFF does not
        resource.setrlimit(resource.RLIMIT_FSIZE, (400_000, 400_000))
    r = subprocess.run(args, env=env, capture_output=True, text=True, timeout=300, preexec_fn=small_files)
    assert r.returncode == 3, r.stderr[-2000:]
    line = r.stderr.strip().splitlines()[-1]
    assert line.startswith("error: ") and "f.tif" in line and "The finished tiles are kept" in line, line
    assert "Traceback" not in r.stderr and not os.path.exists(tmp_path / "f.tif")
    again = subprocess.run(args[:-1], env=env, capture_output=True, text=True, timeout=300)
    assert again.returncode == 0 and "(16 kept from an earlier run)" in again.stderr, again.stderr[-2000:]
    assert tifffile.imread(tmp_path / "f.tif").shape == (1024, 1024)


def _dask_workers(pid: int) -> list[int]:
    out = []
    for child in _children(pid):
        try:
            with open(f"/proc/{child}/cmdline", "rb") as f:
                if b"spawn_main" in f.read():
                    out.append(child)
        except OSError:
            pass
    return out


@pytest.mark.slow
def test_dask_local_cluster_gives_the_same_bytes_and_survives_a_killed_worker(synth, tmp_path):
    env = dict(os.environ, INFINITEX_CACHE=str(tmp_path / "cache"))
    rect = Rect.of(-2048, 1000, 2048, 2048)
    args = [sys.executable, os.path.join(ROOT, "main.py"), "export", GRAVEL, "--format", "tiff",
            "--rect", str(rect.x0), str(rect.y0), "2048", "2048", "--tile", "256",
            "--scheduler", "--workers", "2", "--fidelity", "variety", "-o", str(tmp_path / "d.tif")]  # as `synth`
    proc = subprocess.Popen(args, env=env, stderr=subprocess.PIPE)
    manifest = tmp_path / "d.tif.parts" / "manifest.jsonl"
    killed = None
    deadline = time.monotonic() + 400
    while proc.poll() is None and time.monotonic() < deadline and killed is None:
        try:
            started = _finished(manifest) >= 4
        except (OSError, ValueError, KeyError):
            started = False
        workers = _dask_workers(proc.pid)
        if started and len(workers) >= 2:
            killed = workers[0]
            os.kill(killed, signal.SIGKILL)  # a Dask worker dies mid-export
        time.sleep(0.02)
    err = proc.stderr.read().decode()
    assert proc.wait(600) == 0, err[-2000:]
    assert killed is not None and "on a Dask LocalCluster" in err
    assert np.array_equal(tifffile.imread(tmp_path / "d.tif"), to_u8(synth.colors(synth.window(rect)))[..., 0])


def _peak_rss_kb(args, env) -> int:
    proc = subprocess.Popen(args, env=env, stderr=subprocess.PIPE)
    _, status, usage = os.wait4(proc.pid, 0)
    proc.returncode = os.waitstatus_to_exitcode(status)
    assert proc.returncode == 0, proc.stderr.read().decode()[-2000:]
    return usage.ru_maxrss


@pytest.mark.slow
def test_peak_memory_does_not_grow_with_the_export_size(tmp_path):
    env = dict(os.environ, INFINITEX_CACHE=str(tmp_path / "cache"))

    def args(n):
        return [sys.executable, os.path.join(ROOT, "main.py"), "export", GRAVEL, "--format", "tiff",
                "--rect", "0", "0", str(n), str(n), "--tile", "256", "--fidelity", "variety", "-q",
                "-o", str(tmp_path / f"m{n}.tif")]
    small = _peak_rss_kb(args(512), env)
    large = _peak_rss_kb(args(4096), env)  # 64 times the pixels (16 MB as one uint8 image)
    assert large < small * 1.15 + 20_000, (small, large)


@pytest.mark.slow
def test_zarr_multiscale_levels_are_the_synthesis_levels(synth, tmp_path):
    import json

    import zarr
    rect = Rect.of(-700, 2**30 - 900, 1500, 1100)
    out = str(tmp_path / "m.zarr")
    job = TiledExport(synth, rect, out, "zarr", 256, key="k")
    job.run()
    assert not os.path.exists(out + ".parts")
    g = zarr.open_group(out, mode="r")
    ms = g.attrs["multiscales"][0]
    assert ms["version"] == "0.4" and [a["name"] for a in ms["axes"]] == ["y", "x"]
    assert [d["path"] for d in ms["datasets"]] == [str(k) for k in range(len(job.levels))] and len(job.levels) == 4
    # Level 0 is the one-piece render; level k is synthesis level L - k over the reduced box (the mipmap).
    assert np.array_equal(g["0"][:], to_u8(synth.colors(synth.window(rect)))[..., 0])
    for k in range(1, len(job.levels)):
        r = Rect(rect.x0 >> k, rect.y0 >> k, -((-rect.x1) >> k), -((-rect.y1) >> k))
        level = synth.L - k
        assert g[str(k)].shape == (r.h, r.w)
        assert np.array_equal(g[str(k)][:], to_u8(synth.colors(synth.window(r, level), level))[..., 0]), k
        assert ms["datasets"][k]["coordinateTransformations"][0]["scale"] == [2.0 ** k] * 2
    assert max(g[str(len(job.levels) - 1)].shape) <= 256
    json.dumps(dict(g.attrs))  # plain JSON metadata


@pytest.mark.slow
def test_zarr_export_resumes_and_replaces_atomically(synth, tmp_path):
    import zarr
    rect = Rect.of(0, 0, 1024, 768)
    out = str(tmp_path / "r.zarr")
    calls = []

    def stop(done, total):
        calls.append(done)
        if len(calls) == 5:
            raise ExportInterrupted()
    first = TiledExport(synth, rect, out, "zarr", 256, key="k")
    with pytest.raises(ExportInterrupted):
        first.run(stop)
    assert not os.path.exists(out) and os.path.isdir(out + ".parts")
    again = TiledExport(synth, rect, out, "zarr", 256, key="k")
    again.run()
    assert again.kept == 5 and again.rendered == again.total - 5
    whole = to_u8(synth.colors(synth.window(rect)))[..., 0]
    assert np.array_equal(zarr.open_group(out, mode="r")["0"][:], whole)
    # Exporting again over it (another rectangle) replaces the store only once complete.
    TiledExport(synth, Rect.of(1, 0, 1024, 768), out, "zarr", 256, key="k").run()
    assert np.array_equal(zarr.open_group(out, mode="r")["0"][:, :-1], whole[:, 1:])
