"""Fuzzing targets shared by the test suite (tests/reliability/test_fuzz.py, a few hundred
cases) and the long runs (bench/fuzz.py, 10,000+ cases per target).

Each target is a Hypothesis strategy for one kind of untrusted input and a
``run_*`` function that feeds one generated input to the program and returns
the outcome ("accepted" or "refused"), raising :class:`Crash` when the program
broke a promise: an exception other than its own error types, a started
subprocess, a read outside what the user chose, a wrong result, a damaged file.
Hangs are caught by :func:`time_limit` (a :class:`Hang`).
"""
from __future__ import annotations

import contextlib
import hashlib
import io
import json
import os
import shutil
import signal
import stat
import subprocess
import sys
import tempfile
import traceback

import numpy as np
from hypothesis import strategies as st
from PIL import Image

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
if ROOT not in sys.path:
    sys.path.insert(0, ROOT)

from infinitex.engine.exemplar import (  # noqa: E402
    FIT_MODES,
    MAX_SIZE,
    MIN_SIZE,
    ExemplarError,
    load_exemplar_bytes,
)
from infinitex.project import (  # noqa: E402
    DISPLAY_MODES,
    MAGNIFY_FILTERS,
    MAX_ZOOM,
    MIN_ZOOM,
    Autosave,
    Document,
    ExemplarSource,
    Project,
    ProjectError,
    load_project,
    project_to_json,
)


class Crash(AssertionError):
    """The program broke a promise on this input."""


class Hang(BaseException):
    """An input ran past its time limit (BaseException: no ``except Exception`` swallows it)."""


@contextlib.contextmanager
def time_limit(seconds: float):
    """Raise Hang in the main thread after ``seconds`` (SIGALRM; main thread only)."""
    def on_alarm(_sig, _frame):
        raise Hang(f"still running after {seconds} s")
    old = signal.signal(signal.SIGALRM, on_alarm)
    signal.setitimer(signal.ITIMER_REAL, seconds)
    try:
        yield
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0)
        signal.signal(signal.SIGALRM, old)


@contextlib.contextmanager
def watch(allowed_roots: tuple[str, ...] = ()):
    """Record subprocess starts, and with ``allowed_roots`` file opens outside them.

    Yields a list of violations (strings); a started subprocess is also refused."""
    violations: list[str] = []
    real_popen_init = subprocess.Popen.__init__
    real_os_open = os.open

    def popen(self, args, *a, **k):
        # ctypes.util.find_library (run by the GL loader, whatever the input) is
        # not about the input; anything else is.
        if any(f.filename.endswith(os.path.join("ctypes", "util.py")) for f in traceback.extract_stack()):
            return real_popen_init(self, args, *a, **k)
        violations.append(f"started a subprocess: {args!r}"[:200])
        raise OSError("subprocesses are not allowed here")

    def checked_open(path, flags, *a, **k):
        if allowed_roots and isinstance(path, (str, bytes, os.PathLike)):
            p = os.path.realpath(os.fsdecode(path))
            if not p.startswith(allowed_roots):
                violations.append(f"opened {p}")
        return real_os_open(path, flags, *a, **k)

    subprocess.Popen.__init__ = popen
    os.open = checked_open
    try:
        yield violations
    finally:
        subprocess.Popen.__init__ = real_popen_init
        os.open = real_os_open


# -- images --------------------------------------------------------------------

MODES = ["1", "L", "P", "RGB", "RGBA", "LA", "PA", "I;16", "I", "F", "CMYK", "YCbCr", "LAB", "HSV", "RGBX"]
# Allowed decoders, then formats that must be refused (EPS runs Ghostscript).
FORMATS = ["PNG", "JPEG", "BMP", "TIFF", "WEBP", "TGA", "GIF", "PPM", "QOI", "SGI", "PCX",
           "EPS", "PDF", "ICO", "DDS", "BLP", "IM", "MSP", "XBM", "SPIDER", "ICNS", "JPEG2000"]
MAGICS = [b"\x89PNG\r\n\x1a\n", b"\xff\xd8\xff\xe0", b"GIF89a", b"BM", b"II*\x00", b"MM\x00*",
          b"RIFF\x00\x10\x00\x00WEBPVP8 ", b"P6\n", b"P5\n64 64\n255\n", b"qoif", b"\x01\xda\x01\x01",
          b"\x0a\x05\x01\x08", b"%!PS-Adobe-3.0 EPSF-3.0\n", b"\xc5\xd0\xd3\xc6", b"DDS |\x00\x00\x00",
          b"BLP1", b"BLP2", b"8BPS", b"%PDF-1.4\n", b"icns", b"\x00\x00\x01\x00", b"\x00\x00\x02\x00"]
EPS_LOOP = b"%!PS-Adobe-3.0 EPSF-3.0\n%%BoundingBox: 0 0 100 100\n{ } loop\n"


def make_image(mode: str, w: int, h: int, seed: int) -> Image.Image:
    rng = np.random.default_rng(seed)
    smooth = rng.random() < 0.5
    base = rng.random((h, w, 4))
    if smooth:  # some images with structure, not only noise
        base = np.cumsum(base, axis=1) / np.arange(1, w + 1)[None, :, None]
    u8 = (base * 255).astype(np.uint8)
    if mode in ("1", "L", "P"):
        return Image.fromarray(u8[:, :, 0]).convert(mode)
    if mode == "I;16":
        return Image.fromarray((base[:, :, 0] * 65535).astype(np.uint16))
    if mode == "I":
        return Image.fromarray((base[:, :, 0] * rng.choice([255, 65535, 2 ** 31 - 1])).astype(np.int32))
    if mode == "F":
        f = (base[:, :, 0] * rng.choice([1.0, 1e6, -3.0])).astype(np.float32)
        if rng.random() < 0.2:
            f[rng.integers(h), rng.integers(w)] = rng.choice([np.nan, np.inf])
        return Image.fromarray(f)
    if mode in ("LAB", "HSV"):
        return Image.merge(mode, [Image.fromarray(u8[:, :, c]) for c in range(3)])
    if mode == "LA":
        return Image.merge("LA", [Image.fromarray(u8[:, :, c]) for c in range(2)])
    if mode == "PA":
        return Image.merge("PA", [Image.fromarray(u8[:, :, 0]), Image.fromarray(u8[:, :, 1])])
    rgba = Image.fromarray(u8, "RGBA")
    return rgba if mode == "RGBA" else rgba.convert(mode)


def encode(img: Image.Image, fmt: str, option: int) -> bytes:
    """The image in ``fmt``; converted to RGB or L when the format cannot hold its mode."""
    kw = {}
    if fmt == "TIFF":
        kw["compression"] = [None, "tiff_deflate", "tiff_lzw", "packbits", "tiff_adobe_deflate"][option % 5]
    elif fmt == "JPEG":
        kw["quality"] = 5 + option % 95
    elif fmt == "WEBP":
        kw["lossless"] = bool(option % 2)
    elif fmt == "PNG":
        kw["compress_level"] = option % 10
    for target in (None, "RGB", "L"):
        buf = io.BytesIO()
        try:
            (img if target is None else img.convert(target)).save(buf, fmt, **kw)
            return buf.getvalue()
        except Exception:
            continue
    return MAGICS[option % len(MAGICS)] + bytes(range(256))


MUTATION = st.tuples(
    st.sampled_from(["flip", "truncate", "insert", "delete", "u16", "u32", "copy"]),
    st.booleans(),                      # near the start (headers) or anywhere
    st.integers(0, 2 ** 20),            # position (modulo the length)
    st.integers(0, 2 ** 16),            # a small parameter: bit, count, value index
    st.binary(min_size=1, max_size=16))  # bytes to insert


def mutate(data: bytes, plan) -> bytes:
    """Apply byte-level mutations. The plan is drawn before it is applied, so what
    Hypothesis draws never depends on the bytes (some encoders are not deterministic)."""
    b = bytearray(data)
    values = [0, 1, 8000, 32768, 65535, 2 ** 31, 2 ** 32 - 1]
    for kind, near, where, k, blob in plan:
        if not b:
            break
        pos = where % (min(len(b), 96) if near else len(b))
        if kind == "flip":
            b[pos] ^= 1 << (k % 8)
        elif kind == "truncate":
            del b[pos:]
        elif kind == "insert":
            b[pos:pos] = blob
        elif kind == "delete":
            del b[pos:pos + 1 + k % 16]
        elif kind in ("u16", "u32"):
            n = 2 if kind == "u16" else 4
            v = values[k % len(values)] % (1 << (8 * n))
            b[pos:pos + n] = v.to_bytes(n, "big" if k & 1 else "little")
        else:  # repeat a chunk (chunk-count and length confusions)
            end = min(len(b), pos + 1 + k % 64)
            b[end:end] = b[pos:end] * (1 + k % 8)
    return bytes(b)


def mutations(data: bytes):
    """0..4 byte-level mutations of ``data``, biased towards the header."""
    return st.lists(MUTATION, max_size=4).map(lambda plan: mutate(data, plan))


@st.composite
def image_files(draw) -> bytes:
    """Image files of many formats and modes, valid or mutated, or crafted bytes."""
    kind = draw(st.sampled_from(["image", "image", "image", "raw"]))
    if kind == "raw":
        head = draw(st.sampled_from(MAGICS + [EPS_LOOP]))
        return head + draw(st.binary(max_size=512))
    mode = draw(st.sampled_from(MODES))
    fmt = draw(st.sampled_from(FORMATS))
    w = draw(st.sampled_from([1, 7, 31, 32, 33, 48, 64, 65, 96]))
    h = draw(st.sampled_from([1, 7, 31, 32, 33, 48, 64, 65, 96]))
    data = encode(make_image(mode, w, h, draw(st.integers(0, 2 ** 16))), fmt, draw(st.integers(0, 99)))
    return draw(mutations(data))


def check_exemplar(ex) -> None:
    m = ex.size
    px = ex.pixels
    if not (MIN_SIZE <= m <= MAX_SIZE and m & (m - 1) == 0 and px.shape[:2] == (m, m)
            and 1 <= px.shape[2] <= 4 and px.dtype == np.float32):
        raise Crash(f"bad exemplar shape {px.shape} {px.dtype}")
    if not (np.all(np.isfinite(px)) and px.min() >= 0.0 and px.max() <= 1.0):
        raise Crash("exemplar values outside [0, 1]")
    if ex.hires is not None and (ex.hires.shape[2] != px.shape[2] or max(ex.hires.shape[:2]) > 2048):
        raise Crash(f"bad hires shape {ex.hires.shape}")


def run_import(data: bytes, timeout: float = 20.0) -> str:
    """Import ``data`` with both fit rules; 'accepted' if either worked, else 'refused'."""
    outcome = "refused"
    with watch() as violations, time_limit(timeout):
        for fit in FIT_MODES:
            try:
                ex = load_exemplar_bytes(data, name="fuzz.bin", fit=fit)
            except ExemplarError as exc:
                if "\n" in str(exc):
                    raise Crash(f"multi-line error: {str(exc)[:200]!r}") from None
                continue
            except Exception as exc:
                raise Crash(f"{type(exc).__name__}: {str(exc)[:200]}") from exc
            check_exemplar(ex)
            outcome = "accepted"
    if violations:
        raise Crash("; ".join(violations))
    return outcome


# -- projects --------------------------------------------------------------------

_TINY = None


def tiny_exemplar() -> bytes:
    """A 32x32 PNG (the exemplar of generated projects)."""
    global _TINY
    if _TINY is None:
        buf = io.BytesIO()
        make_image("RGB", 32, 32, 7).save(buf, "PNG")
        _TINY = buf.getvalue()
    return _TINY


def base_project() -> dict:
    """A valid project with both painted randomness fields and a lattice (so mutations reach them)."""
    from infinitex.engine.controls import CanvasField, ExemplarField
    from infinitex.engine.controls.lattice import Lattice
    c, _ = CanvasField().painted(10.0, 20.0, 12.0, 0)
    e = ExemplarField.blank(32).painted(8, 8, 5, 65535)
    doc = Document(ExemplarSource.from_bytes(tiny_exemplar(), "tiny.png"), randomness_canvas=c, randomness_exemplar=e,
                   lattice=Lattice((1.0, 2.0), (8.0, 0.5), (-1.0, 7.5), 2, 2, levels=2))
    return project_to_json(Project(doc), embed=True)


json_scalars = st.one_of(
    st.none(), st.booleans(), st.integers(-2 ** 70, 2 ** 70), st.floats(allow_nan=False, allow_infinity=False),
    st.sampled_from([0, 1, -1, 2 ** 31, 2 ** 32, 10 ** 18, -10 ** 19, 0.5, 1e308, -0.0, 4.0, 100.0]),
    st.text(max_size=20),
    st.sampled_from(["appearance", "color", "resize", "crop", "hires", "relief", "tiny.png", "../tiny.png",
                     "/etc/passwd", "/proc/self/mem", "/dev/zero", "~/.bashrc", "sub/../../x", "a\x00b",
                     "=" * 8, "0" * 64, "QUJD"]))
json_values = st.recursive(json_scalars, lambda inner: st.one_of(
    st.lists(inner, max_size=5), st.dictionaries(st.text(max_size=8), inner, max_size=5)), max_leaves=12)

# Raw JSON tokens no Python value serializes to: huge or long numbers, NaN, deep nesting.
RAW_TOKENS = ["1" + "0" * 309, "-1" + "0" * 400, "9" * 5000, "1e999", "-1e999", "NaN", "Infinity", "-Infinity",
              "[" * 100000 + "]" * 100000, "{\"a\":" * 50000 + "1" + "}" * 50000, "1.5e-400", "0.0000001",
              "\"\\ud800\"", "\"\\u0000\""]
PATHS = [("version",), ("exemplar",), ("exemplar", "name"), ("exemplar", "sha256"), ("exemplar", "embedded"),
         ("exemplar", "path"), ("exemplar", "fit"), ("exemplar", "toroidal"), ("analysis", "model"),
         ("analysis", "k"), ("synthesis", "jitter"), ("synthesis", "seed"), ("synthesis", "passes"),
         ("synthesis", "subgrid"), ("synthesis", "kappa"), ("synthesis", "corrected"), ("view",),
         ("view", "x"), ("view", "y"), ("view", "zoom"), ("display", "mode"), ("display", "level"),
         ("display", "magnify"), ("format",), ("synthesis",), ("randomness",), ("randomness", "canvas"),
         ("randomness", "exemplar"), ("randomness", "canvas", "tiles"), ("randomness", "canvas", "tile"),
         ("lattice",), ("lattice", "origin"), ("lattice", "t1"), ("lattice", "t2"), ("lattice", "cells"),
         ("lattice", "levels"), ("display", "geometry")]


@st.composite
def project_files(draw) -> bytes:
    """Project files: structural mutations of a valid one, raw tokens, byte-level damage."""
    d = base_project()
    raw_slots = {}
    for _ in range(draw(st.integers(0, 4))):
        path = draw(st.sampled_from(PATHS))
        parent = d
        for k in path[:-1]:
            parent = parent.get(k) if isinstance(parent, dict) else None
        if not isinstance(parent, dict):
            continue
        action = draw(st.sampled_from(["set", "set", "delete", "raw", "reference"]))
        if action == "set":
            parent[path[-1]] = draw(json_values)
        elif action == "delete":
            parent.pop(path[-1], None)
        elif action == "raw":
            slot = f"@@RAW{len(raw_slots)}@@"
            raw_slots[slot] = draw(st.sampled_from(RAW_TOKENS))
            parent[path[-1]] = slot
        else:  # refer to a file instead of embedding (maybe with a matching hash)
            ref = draw(st.sampled_from(["tiny.png", "./tiny.png", "../outside.png", "/etc/passwd", "/proc/self/mem",
                                        "/dev/zero", "sparse.png", "fifo.png", "folder", "missing.png",
                                        "link-out.png", "sub/../tiny.png"]))
            ex = d.get("exemplar")
            if isinstance(ex, dict):
                ex["embedded"] = None
                ex["path"] = ref
                if ref == "/etc/passwd" and os.path.isfile(ref):
                    with open(ref, "rb") as f:
                        ex["sha256"] = hashlib.sha256(f.read()).hexdigest()
    text = json.dumps(d, indent=draw(st.sampled_from([None, 1])))
    for slot, token in raw_slots.items():
        text = text.replace(json.dumps(slot), token)
    return draw(mutations(text.encode("utf-8"))) if draw(st.booleans()) else text.encode("utf-8")


def project_sandbox() -> str:
    """A folder holding what generated projects may refer to (and a file outside it)."""
    top = tempfile.mkdtemp(prefix="infinitex-fuzz-")
    root = os.path.join(top, "project")
    os.makedirs(os.path.join(root, "folder"))
    os.makedirs(os.path.join(root, "sub"))
    with open(os.path.join(root, "tiny.png"), "wb") as f:
        f.write(tiny_exemplar())
    with open(os.path.join(top, "outside.png"), "wb") as f:
        f.write(tiny_exemplar())
    with open(os.path.join(root, "sparse.png"), "wb") as f:
        f.truncate(30 * 2 ** 30)  # 30 GB, sparse: must be refused before reading
    os.mkfifo(os.path.join(root, "fifo.png"))
    os.symlink(os.path.join(top, "outside.png"), os.path.join(root, "link-out.png"))
    return root


def check_project(p: Project) -> None:
    p.document.validate()
    v, g = p.view, p.display
    if not (all(np.isfinite([v.x, v.y, v.zoom])) and MIN_ZOOM <= v.zoom <= MAX_ZOOM
            and abs(v.x) <= 2 ** 30 and abs(v.y) <= 2 ** 30):
        raise Crash(f"bad view {v}")
    if g.mode not in DISPLAY_MODES or g.magnify not in MAGNIFY_FILTERS or not -1 <= g.level <= 12:
        raise Crash(f"bad display {g}")
    if hashlib.sha256(p.document.exemplar.data).hexdigest() != p.document.exemplar.sha256:
        raise Crash("exemplar bytes do not match their hash")


def run_project(data: bytes, root: str, timeout: float = 20.0) -> str:
    """Load ``data`` as a project file in ``root`` and as an autosave file."""
    path = os.path.join(root, "fuzz.itex")
    with open(path, "wb") as f:
        f.write(data)
    allowed = (os.path.realpath(root) + os.sep, os.path.realpath(root))
    with watch(allowed) as violations, time_limit(timeout):
        try:
            p = load_project(path)
            outcome = "accepted"
        except ProjectError as exc:
            if "\n" in str(exc):
                raise Crash(f"multi-line error: {str(exc)[:200]!r}") from None
            outcome, p = "refused", None
        except Exception as exc:
            raise Crash(f"{type(exc).__name__}: {str(exc)[:200]}") from exc
        if p is not None:
            check_project(p)
        auto = os.path.join(root, "autosave.itex")
        shutil.copyfile(path, auto)
        a = Autosave(auto)
        try:
            rec = a.pending()
        except Exception as exc:
            raise Crash(f"autosave: {type(exc).__name__}: {str(exc)[:200]}") from exc
        if (rec is None) != (p is None):
            raise Crash("the autosave and the project loader disagree")
        if rec is None and (os.path.lexists(auto) or a.set_aside is None or not os.path.isfile(a.set_aside[0])):
            raise Crash("a broken autosave was not set aside")
        if a.set_aside:
            os.unlink(a.set_aside[0])
        if os.path.lexists(auto):
            os.unlink(auto)
    if violations:
        raise Crash("; ".join(violations))
    return outcome


# -- command lines -------------------------------------------------------------

WEIRD_INT = st.sampled_from(
    ["0", "1", "31", "33", "-1", "4097", "16385", "100000", "2147483000", "-2147483000", str(2 ** 40),
     "9" * 30, "1e3", "0x10", "", " 12", "nan", "\u0663\u0662", "1_0", "--", "-q"])
INT_TEXT = st.one_of(st.integers(-70, 300).map(str), WEIRD_INT)
# Sizes: small valid ones or invalid ones (a valid 4097^2 is legitimately slow, not a hang).
SIZE_TEXT = st.one_of(st.sampled_from(["32", "40", "64"]), st.integers(-70, 300).map(str), st.sampled_from(
    ["0", "-1", "16385", "100000", "1" + "0" * 30, "1e3", "0x10", "", " 12", "nan", "\u0663\u0662", "1_0", "--"]))
NUM_TEXT = st.one_of(st.sampled_from(["0", "0.5", "1", "4.0"]), INT_TEXT,
                     st.sampled_from(["inf", "-inf", "nan", "1e308", "4.01", "-0.0"]))
NAMES = ["OUT.png", "OUT.PNG", "out.xyz", "noext", "DIR", "DIR/", "MISSING/o.png", "new\nline.png", "FIFO",
         "bad\udcff.png", "", ".png", "c.npy", "OUT.png.npy"]


def _opt(name, values):
    return st.tuples(st.just(name), values).map(list)


synth_options = st.one_of(
    st.tuples(st.just("--size"), SIZE_TEXT, SIZE_TEXT).map(list),
    st.tuples(st.just("--origin"), INT_TEXT, INT_TEXT).map(list),
    _opt("--seed", INT_TEXT), _opt("--passes", INT_TEXT), _opt("--kappa", NUM_TEXT), _opt("--k", INT_TEXT),
    _opt("--jitter", st.one_of(NUM_TEXT, st.sampled_from(["0,0.5,1", "1,1,1,1,1,1", ",", "0.1,", "2", "a,b"]))),
    _opt("--coords", st.sampled_from(["c.npy"] + NAMES)),
    _opt("--model", st.sampled_from(["appearance", "color", "x"])),
    _opt("--fit", st.sampled_from(["resize", "crop", "stretch"])),
    _opt("--exemplar-toroidal", st.sampled_from(["auto", "yes", "no", "maybe"])),
    st.sampled_from([["--toroidal"], ["--no-cache"], ["-q"], ["--bogus"], ["-o"], ["--size"]]))
# Painted randomness maps and feature files: untrusted files too.
control_options = st.one_of(
    _opt("--features", st.sampled_from(["FEATS", "BADFEATS", "HUGEFEATS", "TEXT", "MISSING", "DEVZERO", "EPS", "DIR"])),
    _opt("--randomness-canvas", st.sampled_from(["CMAP", "TINY", "TEXT", "EPS", "MISSING", "FIFO"])),
    _opt("--randomness-exemplar", st.sampled_from(["CMAP", "TINY", "TEXT", "MISSING"])),
    st.tuples(st.just("--randomness-origin"), INT_TEXT, INT_TEXT).map(list),
    _opt("--lattice", st.sampled_from(["auto", "none", "NONE", "0,0,8,0,0,8,2,2", "1,1,8,0.5,-1,7.5,2,2",
                                       "0,0,8,0,16,0,2,2", "0,0,8,0,0,8,3,2", "0,0,100,0,0,100,2,2", "1,2,3",
                                       "nan,0,8,0,0,8,2,2", "0,0,1e300,0,0,8,2,2", "0,0,8,0,0,8,16,16", ""])),
    _opt("--lattice-levels", INT_TEXT),
    _opt("--geometry", st.sampled_from(["original", "rectified", "skewed"])))
synth_options = st.one_of(synth_options, control_options)
export_options = st.one_of(
    st.tuples(st.just("--rect"), INT_TEXT, INT_TEXT, SIZE_TEXT, SIZE_TEXT).map(list),
    st.tuples(st.just("--size"), SIZE_TEXT, SIZE_TEXT).map(list),
    _opt("--toroidal", st.one_of(st.sampled_from(["32", "64"]), INT_TEXT)),
    st.sampled_from([["--coords"], ["--allow-outside-exemplar"], ["-q"], ["--bogus"], ["--toroidal"]]),
    control_options)
INPUTS = ["TINY", "PROJECT", "OUTSIDE_PROJECT", "MISSING", "DIR", "FIFO", "DEVZERO", "TEXT", "EPS"]


@st.composite
def command_lines(draw) -> list[str]:
    """``synth`` or ``export`` argument lists with symbolic paths (see run_cli):
    about half of them well-formed, the rest with one or more bad parts."""
    cmd = draw(st.sampled_from(["synth", "export"]))
    good = draw(st.booleans())
    argv = [cmd]
    if good or draw(st.integers(0, 9)):
        argv.append(draw(st.sampled_from(["TINY", "PROJECT"] if good else INPUTS)))
    if good or draw(st.integers(0, 9)):
        argv += ["-o", "OUT.png" if good else draw(st.sampled_from(NAMES))]
    opts = synth_options if cmd == "synth" else export_options
    for o in draw(st.lists(opts, max_size=1 if good else 4)):
        argv += o
    if cmd == "export" and not any(a in argv for a in ("--rect", "--size", "--toroidal")):
        argv += ["--size", "48", "40"]  # the default 1024^2 is slow to fuzz with
    return argv


def cli_sandbox() -> str:
    root = tempfile.mkdtemp(prefix="infinitex-cli-fuzz-")
    os.makedirs(os.path.join(root, "DIR"))
    with open(os.path.join(root, "TINY.png"), "wb") as f:
        f.write(tiny_exemplar())
    with open(os.path.join(root, "TEXT.txt"), "w") as f:
        f.write("not an image\n")
    with open(os.path.join(root, "EPS.eps"), "wb") as f:
        f.write(EPS_LOOP)
    doc = Document(ExemplarSource.from_bytes(tiny_exemplar(), "tiny.png"))
    with open(os.path.join(root, "PROJECT.itex"), "w") as f:
        json.dump(project_to_json(Project(doc), embed=True), f)
    os.makedirs(os.path.join(root, "sub"))
    d = project_to_json(Project(doc), embed=True)
    d["exemplar"].update(embedded=None, path=os.path.join(root, "TINY.png"))
    with open(os.path.join(root, "sub", "OUTSIDE.itex"), "w") as f:
        json.dump(d, f)
    os.mkfifo(os.path.join(root, "FIFO"))
    with open(os.path.join(root, "FEATS.json"), "w") as f:
        json.dump([{"exemplar": [5, 6], "canvas": [10, 12], "radius": [4, 9]},
                   {"exemplar": [20, 3], "canvas": [30, -5], "radius": [2, 5], "levels": [0, 5]}], f)
    with open(os.path.join(root, "BADFEATS.json"), "w") as f:
        f.write('[{"exemplar": [1e999, "x"], "canvas": [0]}, NaN, ' + "[" * 5000)
    with open(os.path.join(root, "HUGEFEATS.json"), "w") as f:
        json.dump([{"exemplar": [1, 1], "canvas": [0, 0], "radius": [2047, 2047], "levels": [0, 12]}] * 3, f)
    Image.fromarray((np.arange(40 * 50) % 256).astype(np.uint8).reshape(40, 50)).save(os.path.join(root, "CMAP.png"))
    return root


def _resolve(arg: str, root: str) -> str:
    table = {"TINY": "TINY.png", "PROJECT": "PROJECT.itex", "OUTSIDE_PROJECT": "sub/OUTSIDE.itex",
             "MISSING": "missing.png", "TEXT": "TEXT.txt", "EPS": "EPS.eps", "FEATS": "FEATS.json",
             "BADFEATS": "BADFEATS.json", "HUGEFEATS": "HUGEFEATS.json", "CMAP": "CMAP.png", "FIFO": "FIFO"}
    if arg == "DEVZERO":
        return "/dev/zero"
    if arg in table:
        return os.path.join(root, table[arg])
    if arg in NAMES and arg not in ("", "-q"):
        return os.path.join(root, arg)
    return arg


def run_cli(argv: list[str], root: str, timeout: float = 60.0) -> str:
    """Run ``main.py`` in-process on ``argv`` (paths resolved in ``root``)."""
    from infinitex.__main__ import main
    real = [_resolve(a, root) for a in argv]
    fifo = os.path.join(root, "FIFO")
    before = {e.name for e in os.scandir(root)}
    err = io.StringIO()
    with watch() as violations, time_limit(timeout), contextlib.redirect_stderr(err), \
            contextlib.redirect_stdout(io.StringIO()):
        try:
            code = main(real)
        except SystemExit as exc:  # --help
            code = exc.code if isinstance(exc.code, int) else 2
        except Exception as exc:
            raise Crash(f"{type(exc).__name__}: {str(exc)[:200]}") from exc
    # Progress lines ("\ranalysis ..%", "\rexport ..%") are output, not errors.
    text = "\n".join(ln for ln in err.getvalue().split("\n")
                     if not ln.startswith(("\ranalysis", "\rexport", "\r")))
    if violations:
        raise Crash("; ".join(violations))
    if "Traceback" in text:
        raise Crash("a traceback on stderr")
    if code not in (0, 2, 3, 4):
        raise Crash(f"exit code {code}")
    lines = [ln for ln in text.splitlines() if ln.strip()]
    if code != 0 and (len(lines) != 1 or not lines[0].startswith("error: ")):
        raise Crash(f"error output is not one line: {text[:300]!r}")
    if not os.path.exists(fifo) or not stat.S_ISFIFO(os.lstat(fifo).st_mode):
        raise Crash("the FIFO was replaced")
    created = {e.name for e in os.scandir(root)} - before
    if any(n.endswith(".infinitex-tmp") for n in created):
        raise Crash("a temporary file was left behind")
    for n in created:
        p = os.path.join(root, n)
        if n.endswith(".png"):
            try:
                with Image.open(p) as im:
                    im.load()
            except Exception as exc:
                raise Crash(f"wrote a broken PNG {n}: {exc}") from exc
        os.unlink(p)
    return "accepted" if code == 0 else "refused"
