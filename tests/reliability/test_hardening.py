"""Regression tests for the untrusted-input defects of issue 13: each one is a
reproducer generated here (no binary corpora) and the promise that fixes it."""
import io
import json
import os
import signal
import stat
import subprocess
import sys
import textwrap
import time

import fuzzing as F
import numpy as np
import pytest
from PIL import Image

from bench.import_memory import measure_import
from infinitex.engine.exemplar import (
    DECODERS,
    HIRES_MAX,
    IMPORT_BUDGET,
    ExemplarError,
    import_cost,
    load_exemplar,
    load_exemplar_bytes,
)
from infinitex.engine.safeio import (
    TMP_SUFFIX,
    ReadError,
    WriteError,
    atomic_write,
    check_output,
    printable,
    read_limited,
)
from infinitex.project import (
    Autosave,
    Document,
    ExemplarOutside,
    ExemplarSource,
    Project,
    ProjectError,
    load_project,
    project_to_json,
    save_project,
)

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
GRAVEL = os.path.join(ROOT, "infinitex", "assets", "gravel.png")


def encoded(img: Image.Image, fmt: str, **kw) -> bytes:
    buf = io.BytesIO()
    img.save(buf, fmt, **kw)
    return buf.getvalue()


def rgb64(seed: int = 1) -> Image.Image:
    return F.make_image("RGB", 64, 64, seed)


# -- decoders ------------------------------------------------------------------


def test_every_allowed_decoder_reads_its_format():
    for fmt in DECODERS:
        ex = load_exemplar_bytes(encoded(rgb64(), fmt), name=f"x.{fmt.lower()}")
        assert ex.size == 64 and ex.channels in (1, 3), fmt


@pytest.mark.parametrize("make", [
    lambda: F.EPS_LOOP,                                     # hangs Ghostscript forever
    lambda: b"\xc5\xd0\xd3\xc6" + bytes(28) + F.EPS_LOOP,   # DOS EPS header
    lambda: encoded(rgb64(), "EPS"),                        # a valid EPS
    lambda: encoded(rgb64(), "PDF"),
    lambda: encoded(rgb64(), "DDS"),
    lambda: encoded(rgb64(), "DDS")[:40] + b"\xff" * 90,    # malformed DDS (was NotImplementedError)
    lambda: b"BLP1" + bytes(12) + b"\xff" * 64,             # malformed BLP (was NotImplementedError)
    lambda: b"BLP2\x01\x09\x08\x00" + bytes(200),
])
def test_formats_that_run_programs_or_are_not_pure_decoders_are_refused(make):
    t0 = time.monotonic()
    with F.watch() as violations:
        with pytest.raises(ExemplarError, match="not an image format Infinitex reads"):
            load_exemplar_bytes(make(), name="x.eps")
    assert not violations
    assert time.monotonic() - t0 < 5


def test_damaged_files_of_allowed_formats_give_one_sentence():
    for fmt in ("PNG", "JPEG", "TIFF", "WEBP", "GIF", "BMP"):
        data = encoded(rgb64(), fmt)
        for cut in (len(data) // 3, len(data) - 7):
            try:
                load_exemplar_bytes(data[:cut], name="cut")
            except ExemplarError as exc:
                assert "\n" not in str(exc)


def test_lab_tiff_is_three_color_channels_not_rgba():
    lab = Image.merge("LAB", [Image.fromarray(np.full((64, 64), v, np.uint8)) for v in (60, 150, 90)])
    ex = load_exemplar_bytes(encoded(lab, "TIFF"), name="lab.tif")
    assert ex.channels == 3
    want = np.asarray(lab.convert("RGB"), dtype=np.float32)[0, 0] / 255.0
    assert np.allclose(ex.pixels[0, 0], want)


def test_large_jpeg_is_decoded_at_reduced_scale_with_a_capped_hires():
    img = Image.new("RGB", (4200, 4100), (120, 80, 40))
    ex = load_exemplar_bytes(encoded(img, "JPEG", quality=80), name="big.jpg")
    assert ex.size == 512 and ex.original_size == (4200, 4100)
    assert ex.hires.shape == (HIRES_MAX, HIRES_MAX, 3)


@pytest.mark.slow
def test_import_memory_is_bounded(tmp_path):
    # A tiny JPEG whose header says 8000 x 8000 (libjpeg fills the missing
    # blocks): accepted at 2.3 GB before; now decoded at 1/2 scale.
    liar = bytearray(encoded(Image.new("RGB", (16, 16), (90, 120, 30)), "JPEG"))
    sof = liar.find(b"\xff\xc0")
    liar[sof + 5:sof + 9] = (8000).to_bytes(2, "big") * 2
    (tmp_path / "liar.jpg").write_bytes(bytes(liar))
    r = measure_import(str(tmp_path / "liar.jpg"))
    assert len(liar) < 1024 and r["outcome"] == "accepted"
    assert r["used"] < 400 * 2 ** 20
    # 8192^2 RGBA PNG (peaked at 2.9-3.6 GB): within the budget, and the cost
    # computed from the header bounds what the import really used.
    img = Image.new("RGBA", (8192, 8192), (10, 20, 30, 255))
    img.paste((200, 100, 50, 255), (0, 0, 8192, 4096))
    img.save(tmp_path / "big.png", compress_level=1)
    r = measure_import(str(tmp_path / "big.png"))
    assert r["outcome"] == "accepted"
    used = r["used"]
    assert used < IMPORT_BUDGET
    assert used <= import_cost(8192, 8192, "RGBA", os.path.getsize(tmp_path / "big.png"), "resize", "PNG")


def test_webp_over_the_budget_is_refused_from_its_header(tmp_path):
    img = Image.new("RGB", (8192, 8192), (1, 2, 3))
    path = tmp_path / "big.webp"
    img.save(path, lossless=True, quality=0, method=0)
    t0 = time.monotonic()
    with pytest.raises(ExemplarError, match="MB allowed"):
        load_exemplar(path)
    assert time.monotonic() - t0 < 5


# -- project files ---------------------------------------------------------------


@pytest.fixture
def good_project():
    return project_to_json(Project(Document(ExemplarSource.from_bytes(F.tiny_exemplar(), "tiny.png"))), embed=True)


@pytest.mark.parametrize("where, token", [
    (("view", "x"), "1" + "0" * 309), (("synthesis", "kappa"), "1" + "0" * 309),
    (("synthesis", "jitter"), "[1" + "0" * 309 + "]"), (("view", "zoom"), "9" * 5000),
    (("view", "y"), "1e999"), (("synthesis", "kappa"), "NaN"), (("view", "x"), "-Infinity"),
    (("display",), "[" * 100000 + "]" * 100000), (("view",), '{"x":' * 20 + "1" + "}" * 20),
])
def test_hostile_numbers_and_nesting_are_project_errors(tmp_path, good_project, where, token):
    d = good_project
    parent = d
    for k in where[:-1]:
        parent = parent[k]
    parent[where[-1]] = "@@TOKEN@@"
    p = tmp_path / "p.itex"
    p.write_text(json.dumps(d).replace('"@@TOKEN@@"', token))
    with pytest.raises(ProjectError):
        load_project(str(p))
    # The same file as an autosave: set aside, start-up goes on.
    auto = tmp_path / "state" / "autosave.itex"
    auto.parent.mkdir(exist_ok=True)
    auto.write_bytes(p.read_bytes())
    a = Autosave(str(auto))
    assert a.pending() is None
    assert not auto.exists() and a.set_aside is not None
    assert os.path.basename(a.set_aside[0]).startswith("autosave-broken-")
    assert (tmp_path / "state" / os.path.basename(a.set_aside[0])).read_bytes() == p.read_bytes()


def _referencing(tmp_path, good_project, ref: str, data: bytes) -> str:
    import hashlib
    d = good_project
    d["exemplar"].update(embedded=None, path=ref, sha256=hashlib.sha256(data).hexdigest())
    folder = tmp_path / "project"
    folder.mkdir(exist_ok=True)
    p = folder / "p.itex"
    p.write_text(json.dumps(d))
    return str(p)


def test_referenced_exemplars_outside_the_project_folder_need_consent(tmp_path, good_project):
    passwd = "/etc/passwd"
    data = open(passwd, "rb").read()
    p = _referencing(tmp_path, good_project, passwd, data)
    with pytest.raises(ExemplarOutside) as info:
        load_project(p)
    assert info.value.path == os.path.realpath(passwd)
    assert load_project(p, allow_outside={os.path.realpath(passwd)}).document.exemplar.data == data
    # ../ and a symbolic link out of the folder are outside too.
    (tmp_path / "out.png").write_bytes(F.tiny_exemplar())
    p = _referencing(tmp_path, good_project, "../out.png", F.tiny_exemplar())
    with pytest.raises(ExemplarOutside):
        load_project(p)
    os.symlink(tmp_path / "out.png", tmp_path / "project" / "link.png")
    p = _referencing(tmp_path, good_project, "link.png", F.tiny_exemplar())
    with pytest.raises(ExemplarOutside):
        load_project(p)
    # Inside the folder: read.
    (tmp_path / "project" / "in.png").write_bytes(F.tiny_exemplar())
    assert load_project(_referencing(tmp_path, good_project, "in.png", F.tiny_exemplar()))


def test_referenced_exemplars_must_be_regular_files_of_bounded_size(tmp_path, good_project, monkeypatch):
    folder = tmp_path / "project"
    folder.mkdir()
    with open(folder / "huge.png", "wb") as f:
        f.truncate(30 * 2 ** 30)  # sparse 30 GB: refused before a byte is read
    os.mkfifo(folder / "fifo.png")
    for ref, words in [("huge.png", "larger than"), ("fifo.png", "not a regular file"),
                       ("/proc/self/mem", "cannot be read|not a regular"), ("/dev/zero", "not a regular")]:
        p = _referencing(tmp_path, good_project, ref, b"x")
        t0 = time.monotonic()
        with pytest.raises(ProjectError, match=words):
            load_project(p, allow_outside=True)
        assert time.monotonic() - t0 < 2
    # No fallback to the current folder: a name found only there is not read.
    monkeypatch.chdir(tmp_path)
    (tmp_path / "cwd-only.png").write_bytes(F.tiny_exemplar())
    with pytest.raises(ProjectError, match="cannot be found"):
        load_project(_referencing(tmp_path, good_project, "cwd-only.png", F.tiny_exemplar()))


# -- writes ----------------------------------------------------------------------


def test_atomic_write_refuses_devices_fifos_and_folders(tmp_path):
    fifo = tmp_path / "out.png"
    os.mkfifo(fifo)
    for target in (str(fifo), "/dev/null", str(tmp_path)):
        with pytest.raises(WriteError):
            atomic_write(target, b"data")
        with pytest.raises(WriteError):
            check_output(target, (".png",))
    assert stat.S_ISFIFO(os.lstat(fifo).st_mode) and stat.S_ISCHR(os.stat("/dev/null").st_mode)
    assert [p.name for p in tmp_path.iterdir()] == ["out.png"]


def test_atomic_write_gives_ordinary_permissions_and_follows_links(tmp_path, monkeypatch):
    import infinitex.engine.safeio as sio
    old = os.umask(0o027)
    try:
        assert sio.read_umask() == 0o027  # read without changing it
        monkeypatch.setattr(sio, "_UMASK", 0o027)  # it is read once, at import
        atomic_write(str(tmp_path / "new.png"), b"a")
        assert stat.S_IMODE(os.stat(tmp_path / "new.png").st_mode) == 0o640
    finally:
        os.umask(old)
    keep = tmp_path / "keep.png"
    keep.write_bytes(b"old")
    os.chmod(keep, 0o604)
    atomic_write(str(keep), b"new")
    assert stat.S_IMODE(os.stat(keep).st_mode) == 0o604 and keep.read_bytes() == b"new"
    os.symlink(keep, tmp_path / "link.png")  # an output's name that is a link: replaced, never written through
    atomic_write(str(tmp_path / "link.png"), b"new file")
    assert not os.path.islink(tmp_path / "link.png") and (tmp_path / "link.png").read_bytes() == b"new file"
    assert keep.read_bytes() == b"new"
    os.symlink(tmp_path / "gone.png", tmp_path / "dangling.png")  # no file appears where a dangling link points
    atomic_write(str(tmp_path / "dangling.png"), b"x")
    assert not (tmp_path / "gone.png").exists() and (tmp_path / "dangling.png").read_bytes() == b"x"
    os.symlink(keep, tmp_path / "linked.itex")  # a file the user linked on purpose (a project): written through
    atomic_write(str(tmp_path / "linked.itex"), b"through", follow_links=True)
    assert os.path.islink(tmp_path / "linked.itex") and keep.read_bytes() == b"through"


def test_failed_writer_leaves_the_old_file_and_no_temporary(tmp_path):
    target = tmp_path / "o.png"
    target.write_bytes(b"old")

    def boom(f):
        f.write(b"partial")
        raise ValueError("encoder failed")
    with pytest.raises(ValueError):
        atomic_write(str(target), writer=boom)
    assert target.read_bytes() == b"old"
    assert [p.name for p in tmp_path.iterdir()] == ["o.png"]


def test_killed_writes_keep_the_old_file_and_their_temporaries_are_cleaned(tmp_path):
    target = tmp_path / "o.png"
    target.write_bytes(b"old")
    code = textwrap.dedent(f"""
        import sys, time
        sys.path.insert(0, {ROOT!r})
        from infinitex.engine.safeio import atomic_write
        def slow(f):
            f.write(b"half"); f.flush(); print("writing", flush=True); time.sleep(60)
        atomic_write({str(target)!r}, writer=slow)
    """)
    for _ in range(3):
        proc = subprocess.Popen([sys.executable, "-c", code], stdout=subprocess.PIPE, text=True)
        assert proc.stdout.readline().strip() == "writing"
        proc.send_signal(signal.SIGKILL)
        proc.wait()
    assert target.read_bytes() == b"old"
    # Each write cleaned the temporaries of the killed ones before it: one is left.
    assert len([p for p in tmp_path.iterdir() if p.name.endswith(TMP_SUFFIX)]) == 1
    atomic_write(str(target), b"new")  # the next write to the folder cleans it
    assert sorted(p.name for p in tmp_path.iterdir()) == ["o.png"] and target.read_bytes() == b"new"


def test_project_save_uses_the_same_helper(tmp_path):
    p = tmp_path / "p.itex"
    save_project(str(p), Project(Document(ExemplarSource.from_bytes(F.tiny_exemplar(), "t.png"))))
    assert stat.S_IMODE(os.stat(p).st_mode) == 0o666 & ~_umask()
    os.mkfifo(tmp_path / "f.itex")
    with pytest.raises(ProjectError, match="not a regular file"):
        save_project(str(tmp_path / "f.itex"), load_project(str(p)))


def _umask() -> int:
    m = os.umask(0)
    os.umask(m)
    return m


def test_reads_refuse_what_is_not_a_regular_file(tmp_path):
    os.mkfifo(tmp_path / "fifo")
    for path, words in [(tmp_path / "fifo", "not a regular"), ("/dev/zero", "not a regular"),
                        (tmp_path, "folder"), (tmp_path / "none", "No such file")]:
        with pytest.raises(ReadError, match=words):
            read_limited(str(path), 1000)
    (tmp_path / "big").write_bytes(b"x" * 2000)
    with pytest.raises(ReadError, match="larger than"):
        read_limited(str(tmp_path / "big"), 1000)
    with pytest.raises(ReadError):
        read_limited("/proc/self/mem", 1 << 20)


def test_printable_keeps_names_on_one_line():
    assert printable("a\nb\r\x1b[31m\udcffé") == "a\\nb\\r\\x1b[31m\\udcffé"
    assert len(printable("x" * 1000)) == 300


# -- command lines -----------------------------------------------------------------


def cli(*args, cache=None, timeout=120):
    env = dict(os.environ)
    if cache:
        env["INFINITEX_CACHE"] = str(cache)
    return subprocess.run([sys.executable, os.path.join(ROOT, "main.py"), *args], capture_output=True,
                          text=True, timeout=timeout, env=env)


@pytest.mark.parametrize("out, words", [("o.xyz", "must end in .png"), ("noext", "no extension"),
                                         ("DIR", "is a folder"), ("FIFO", "not a regular file")])
def test_synth_checks_its_output_before_any_work(tmp_path, out, words):
    (tmp_path / "DIR").mkdir()
    os.mkfifo(tmp_path / "FIFO")
    cache = tmp_path / "cache"
    r = cli("synth", GRAVEL, "-o", str(tmp_path / out), "-q", cache=cache)
    assert r.returncode == 2 and words in r.stderr and len(r.stderr.splitlines()) == 1
    assert not cache.exists()  # no analysis was run
    assert stat.S_ISFIFO(os.lstat(tmp_path / "FIFO").st_mode)


def test_synth_coords_size_cap_and_names(tmp_path):
    (tmp_path / "DIR").mkdir()
    r = cli("synth", GRAVEL, "-o", str(tmp_path / "o.png"), "--coords", str(tmp_path / "DIR"), "-q")
    assert r.returncode == 2 and ".npy" in r.stderr and not (tmp_path / "DIR.npy").exists()
    r = cli("synth", GRAVEL, "-o", str(tmp_path / "o.png"), "--size", "16384", "16384", "-q")
    assert r.returncode == 2 and "64 Mpixels" in r.stderr
    r = cli("synth", str(tmp_path / "no\nsuch.png"), "-o", str(tmp_path / "bad\nname.xyz"), "-q")
    assert r.returncode == 2 and len(r.stderr.splitlines()) == 1 and "bad\\nname.xyz" in r.stderr
    r = cli("synth", str(tmp_path / "no\nsuch.png"), "-o", str(tmp_path / "o.png"), "-q")
    assert r.returncode == 3 and len(r.stderr.splitlines()) == 1 and "no\\nsuch.png" in r.stderr


def test_synth_killed_keeps_the_previous_output(tmp_path):
    out = tmp_path / "o.png"
    out.write_bytes(encoded(rgb64(), "PNG"))
    before = out.read_bytes()
    for delay in (0.3, 0.8, 1.5):
        proc = subprocess.Popen([sys.executable, os.path.join(ROOT, "main.py"), "synth", GRAVEL, "-o", str(out),
                                 "--size", "2048", "2048", "-q"])
        time.sleep(delay)
        proc.kill()
        proc.wait()
        data = out.read_bytes()
        assert data == before or Image.open(io.BytesIO(data)).size == (2048, 2048)
        before = data


def test_export_validates_before_work(tmp_path):
    os.mkfifo(tmp_path / "FIFO.png")
    r = cli("export", GRAVEL, "-o", str(tmp_path / "FIFO.png"), "-q")
    assert r.returncode == 2 and "not a regular file" in r.stderr
    assert stat.S_ISFIFO(os.lstat(tmp_path / "FIFO.png").st_mode)
    r = cli("export", GRAVEL, "-o", str(tmp_path / "t.png"), "--toroidal", "0", "-q")
    assert r.returncode == 2 and "power-of-two" in r.stderr and not (tmp_path / "t.png").exists()
    t0 = time.monotonic()
    r = cli("export", "/dev/zero", "-o", str(tmp_path / "z.png"), "-q")
    assert r.returncode == 3 and "not a regular file" in r.stderr and time.monotonic() - t0 < 20
    r = cli("export", GRAVEL, "-o", str(tmp_path / "x.png"), "--bogus")
    assert r.returncode == 2 and len(r.stderr.splitlines()) == 1


def test_export_reads_an_outside_exemplar_only_with_the_flag(tmp_path, good_project):
    p = _referencing(tmp_path, good_project, GRAVEL, open(GRAVEL, "rb").read())
    out = tmp_path / "o.png"
    r = cli("export", p, "-o", str(out), "--size", "64", "48", "-q")
    assert r.returncode == 3 and "--allow-outside-exemplar" in r.stderr and not out.exists()
    r = cli("export", p, "-o", str(out), "--size", "64", "48", "--allow-outside-exemplar", "-q")
    assert r.returncode == 0, r.stderr
    assert Image.open(out).size == (64, 48)


# -- the editor without usable GL ----------------------------------------------------


@pytest.mark.parametrize("how", ["no-glx", "no-display"])
def test_editor_without_gl_says_so_in_one_line(tmp_path, how):
    import shutil
    env = dict(os.environ, INFINITEX_STATE=str(tmp_path))
    cmd = [sys.executable, os.path.join(ROOT, "main.py"), "--screenshot", str(tmp_path / "s.png")]
    if how == "no-glx":
        xvfb = shutil.which("xvfb-run")
        assert xvfb, "xvfb-run is missing: run scripts/setup.sh"
        cmd = [xvfb, "-a", "-s", "-screen 0 640x480x24 -extension GLX", *cmd]
    else:
        env.pop("DISPLAY", None)
        env.pop("WAYLAND_DISPLAY", None)
    r = subprocess.run(cmd, capture_output=True, text=True, timeout=120, env=env)
    assert r.returncode == 4
    lines = [ln for ln in r.stderr.splitlines() if ln.strip()]
    assert len(lines) == 1 and "OpenGL 3.3" in lines[0] and "Traceback" not in r.stderr
