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
def watch(allowed_roots: tuple[str, ...] = (), opened: list | None = None):
    """Record subprocess starts, and with ``allowed_roots`` file opens outside them
    (``opened``: a list that gets the real path of every file opened).

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
        if (allowed_roots or opened is not None) and isinstance(path, (str, bytes, os.PathLike)):
            p = os.path.realpath(os.fsdecode(path))
            if allowed_roots and not p.startswith(allowed_roots):
                violations.append(f"opened {p}")
            if opened is not None:
                opened.append(p)
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


def rechunk_png(data: bytes, size: int) -> bytes:
    """The same PNG with its image data cut into IDAT chunks of ``size`` bytes
    (valid: decoders must join them; 1-byte chunks decode at ~10^5 a second)."""
    import struct
    import zlib
    pos, head, idat, tail = 8, [], b"", []
    while pos + 8 <= len(data):
        n, kind = struct.unpack(">I4s", data[pos:pos + 8])
        chunk = data[pos:pos + 12 + n]
        if kind == b"IDAT":
            idat += data[pos + 8:pos + 8 + n]
        else:
            (tail if idat else head).append(chunk)
        pos += 12 + n
    pieces = [idat[i:i + size] for i in range(0, len(idat), size)]
    body = [struct.pack(">I", len(p)) + b"IDAT" + p + struct.pack(">I", zlib.crc32(b"IDAT" + p)) for p in pieces]
    return data[:8] + b"".join(head) + b"".join(body) + b"".join(tail)


def tiled_tiff(img: Image.Image, compression: str) -> bytes:
    """The image as a TIFF of 16 x 16 tiles (the smallest TIFF allows)."""
    import tifffile
    buf = io.BytesIO()
    a = np.asarray(img.convert("RGB") if img.mode not in ("L", "RGB") else img)
    tifffile.imwrite(buf, a, tile=(16, 16), compression=compression)
    return buf.getvalue()


@st.composite
def image_files(draw) -> bytes:
    """Image files of many formats and modes, valid or mutated, or crafted
    bytes, or laid out in many small pieces (a PNG's data in tiny IDAT chunks,
    a TIFF of 16 x 16 tiles: what decoders walk one by one)."""
    kind = draw(st.sampled_from(["image", "image", "image", "raw", "layout"]))
    if kind == "raw":
        head = draw(st.sampled_from(MAGICS + [EPS_LOOP]))
        return head + draw(st.binary(max_size=512))
    if kind == "layout":
        w = draw(st.sampled_from([16, 33, 64, 96]))
        img = make_image(draw(st.sampled_from(["L", "RGB", "RGBA"])), w, w, draw(st.integers(0, 2 ** 16)))
        if draw(st.booleans()):
            data = rechunk_png(encode(img, "PNG", 0), draw(st.sampled_from([1, 2, 7, 255])))
        else:
            data = tiled_tiff(img, draw(st.sampled_from([None, "lzw", "zlib"])))
        return draw(mutations(data))
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


# -- export working folders (OUT.parts) ----------------------------------------------
#
# A resumable streamed export trusts nothing in its parts folder (issue 29): a
# case builds the parts folder of a small export (a complete one, a partial one
# or none) and tampers with it: links to files and folders outside the
# sandbox's export area, FIFOs, folders and garbage where files go, foreign
# files, manifest lines claiming the true size and hash of whatever their name
# now reaches, names that are not the export's. The export must then finish
# with exactly the reference output, or be refused in one line; nothing outside
# may change; and it must end within the time limit (a FIFO must not block it).

PARTS_FORMATS = ("tiff", "tiles", "zarr")
PARTS_RECT = (0, 0, 300, 280)  # 2 x 2 tiles of 256: two of them small, so a case renders fast
PARTS_TILE = 256
_PARTS = {}  # the synthesizer, the reference outputs and the complete parts folders, made once


def _parts_synth():
    if "synth" not in _PARTS:
        from infinitex.engine.analysis import analyze
        from infinitex.engine.synth import Synthesizer
        _PARTS["synth"] = Synthesizer(analyze(load_exemplar_bytes(tiny_exemplar(), name="tiny.png")))
    return _PARTS["synth"]


def _parts_job(fmt: str, folder: str):
    from infinitex.engine.pyramid import Rect
    from infinitex.export import TiledExport
    ext = {"tiff": "tif", "tiles": "png", "zarr": "zarr"}[fmt]
    return TiledExport(_parts_synth(), Rect.of(*PARTS_RECT), os.path.join(folder, f"OUT.{ext}"), fmt, PARTS_TILE,
                       key="fuzz", coords=fmt == "tiff")


def _parts_result(fmt: str, folder: str):
    """The pixels an export wrote in ``folder`` (every map, every level), as a list of arrays."""
    import tifffile
    if fmt == "tiff":
        return [tifffile.imread(os.path.join(folder, n)) for n in ("OUT.tif", "OUT_coords.tif")]
    if fmt == "tiles":
        from infinitex.export import udim_name
        out = []
        for row in range(2):
            for col in range(2):
                path = os.path.join(folder, udim_name(os.path.join(folder, "OUT"), col, row, 2))
                if os.path.islink(path):
                    raise Crash("a tile of the output is a link")
                with Image.open(path) as im:
                    out.append(np.asarray(im))
        return out
    import zarr
    g = zarr.open_group(os.path.join(folder, "OUT.zarr"), mode="r")
    return [g[k][:] for k in sorted(g.array_keys())]


def parts_sandbox() -> str:
    """``ROOT/outside`` (what must never change), ``ROOT/ref/FMT`` (reference
    exports), ``ROOT/template/FMT`` (a finished but unassembled export: every
    tile and the manifest) and ``ROOT/work`` (where cases run)."""
    from infinitex.export import ExportInterrupted
    root = tempfile.mkdtemp(prefix="infinitex-parts-fuzz-")
    far = os.path.join(root, "outside")
    os.makedirs(os.path.join(far, "data.zarr", "0"))
    os.makedirs(os.path.join(far, "folder"))
    with open(os.path.join(far, "precious.bin"), "wb") as f:
        f.write(b"the user's own bytes\n" * 500)
    with open(os.path.join(far, "manifest.jsonl"), "w") as f:
        f.write("someone else's manifest\n")
    with open(os.path.join(far, "data.zarr", ".zgroup"), "w") as f:
        f.write('{"zarr_format": 2}')
    with open(os.path.join(far, "data.zarr", "0", "0.0"), "wb") as f:
        f.write(b"\x02\x01" * 64)
    with open(os.path.join(far, "folder", "inside.txt"), "w") as f:
        f.write("inside a folder outside\n")
    for fmt in PARTS_FORMATS:
        ref = os.path.join(root, "ref", fmt)
        os.makedirs(ref)
        _parts_job(fmt, ref).run()
        _PARTS[fmt] = _parts_result(fmt, ref)
        tmpl = os.path.join(root, "template", fmt)
        os.makedirs(tmpl)
        job = _parts_job(fmt, tmpl)

        def stop(done, total, job=job):
            if done == job.total:
                raise ExportInterrupted()
        try:
            job.run(stop)
        except ExportInterrupted:
            pass
    os.makedirs(os.path.join(root, "work"))
    return root


def _snapshot(folder: str) -> dict:
    out = {}
    for dirpath, dirnames, filenames in os.walk(folder):
        for n in dirnames + filenames:
            p = os.path.join(dirpath, n)
            st = os.lstat(p)
            if stat.S_ISREG(st.st_mode):
                with open(p, "rb") as f:
                    out[p] = (hashlib.sha256(f.read()).hexdigest(), st.st_size, st.st_mtime_ns)
            else:
                out[p] = (stat.S_IFMT(st.st_mode), os.readlink(p) if stat.S_ISLNK(st.st_mode) else None)
    return out


# What goes where a file of the export should be.
PART_TAMPERS = ["keep", "keep", "keep", "keep", "keep", "delete", "link-file", "link-folder", "link-missing", "fifo",
                "folder", "garbage", "empty", "truncate", "flip", "swap", "rgb-tile"]
MANIFEST_TAMPERS = ["keep", "keep", "claim", "claim", "claim-keyed", "claim-keyed", "delete", "link-file", "fifo",
                    "folder", "garbage", "bad-names", "torn", "huge", "other-key", "nan"]
ASSEMBLY_TAMPERS = ["none", "none", "link-file", "fifo", "folder", "garbage", "link-folder"]
FOREIGN = ["none", "none", "file", "folder", "link-outside", "fifo"]
ZARR_TAMPERS = ["none", "none", "none", "store-link", "chunk-link", "chunk-fifo", "chunk-garbage",
                "bad-zarray", "no-store", "foreign-in-store"]


@st.composite
def parts_folders(draw) -> dict:
    """One tampered parts folder: the format, where it starts from, and what is done to it."""
    return {
        "fmt": draw(st.sampled_from(PARTS_FORMATS)),
        "start": draw(st.sampled_from(["complete", "complete", "partial", "none"])),
        "parts": draw(st.sampled_from(["folder"] * 20 + ["link-folder", "link-zarr", "file", "fifo"])),
        "tiles": draw(st.lists(st.sampled_from(PART_TAMPERS), min_size=8, max_size=8)),
        "folders": draw(st.booleans()),  # whether "folder" tampers stay (else: kept), so most cases run
        "manifest": draw(st.sampled_from(MANIFEST_TAMPERS)),
        "assembly": draw(st.sampled_from(ASSEMBLY_TAMPERS)),
        "foreign": draw(st.sampled_from(FOREIGN)),
        "zarr": draw(st.sampled_from(ZARR_TAMPERS)),
        "seed": draw(st.integers(0, 2 ** 16)),
    }


def _tamper_file(path: str, how: str, far: str, rng, other: str | None) -> bool:
    """Put what ``how`` says at ``path`` (an export's file); True if it makes the export refuse (a folder)."""
    exists = os.path.lexists(path)
    if how == "keep":
        return False
    if how in ("truncate", "flip") and exists and os.path.isfile(path) and not os.path.islink(path):
        with open(path, "r+b") as f:
            data = bytearray(f.read())
            if how == "truncate":
                f.truncate(rng.integers(0, max(1, len(data))))
            elif data:
                i = int(rng.integers(0, len(data)))
                data[i] ^= 1 << int(rng.integers(0, 8))
                f.seek(0)
                f.write(data)
        return False
    if how == "swap" and other and os.path.isfile(other) and not os.path.islink(other) and exists:
        with open(other, "rb") as f:  # another tile's bytes (the manifest may list them as this one's)
            data = f.read()
        os.unlink(path) if not os.path.isdir(path) or os.path.islink(path) else shutil.rmtree(path)
        with open(path, "wb") as f:
            f.write(data)
        return False
    if exists:
        if os.path.isdir(path) and not os.path.islink(path):
            shutil.rmtree(path)
        else:
            os.unlink(path)
    if how == "link-file":
        os.symlink(os.path.join(far, "precious.bin"), path)
    elif how == "link-folder":
        os.symlink(os.path.join(far, "folder"), path)
    elif how == "link-missing":
        os.symlink(os.path.join(far, "created-through-a-link"), path)
    elif how == "fifo":
        os.mkfifo(path)
    elif how == "folder":
        os.mkdir(path)
        return True
    elif how == "garbage":
        with open(path, "wb") as f:
            f.write(rng.bytes(int(rng.integers(1, 3000))))
    elif how == "empty":
        open(path, "wb").close()
    elif how == "rgb-tile":
        from infinitex.export.formats import png_bytes, tiff_tile_bytes
        px = rng.integers(0, 256, (PARTS_TILE, PARTS_TILE, 3), dtype=np.uint8)
        with open(path, "wb") as f:
            f.write(png_bytes(px) if path.endswith(".png") else tiff_tile_bytes(px, PARTS_TILE))
    return False


def _claimed(path: str, sign=None) -> tuple[int, str]:
    """The size and hash an attacker would list for ``path``: of whatever it
    reaches now (links followed); the plain SHA-256, or ``sign(data)`` (an
    attacker who has the user's manifest key)."""
    try:
        fd = os.open(path, os.O_RDONLY | os.O_NONBLOCK)
        try:
            if not stat.S_ISREG(os.fstat(fd).st_mode):
                raise OSError
            data = b""
            while chunk := os.read(fd, 1 << 20):
                data += chunk
        finally:
            os.close(fd)
    except OSError:
        data = b"x"
    return len(data), sign(data) if sign else hashlib.sha256(data).hexdigest()


def _build_parts(case: dict, root: str) -> tuple[object, bool]:
    """The tampered working folder of one case in ROOT/work; (the export, whether it must be refused).
    Without the key, claims are plain hashes; "claim-keyed" signs whatever
    lies at each name with the user's key (see run_parts for what is promised then)."""
    fmt, rng = case["fmt"], np.random.default_rng(case["seed"])
    work, far = os.path.join(root, "work"), os.path.join(root, "outside")
    shutil.rmtree(work)
    tmpl = os.path.join(root, "template", fmt)
    if case["start"] == "none":
        os.makedirs(work)
    else:
        shutil.copytree(tmpl, work, symlinks=True)
    job = _parts_job(fmt, work)
    parts = job.parts
    refuse = False
    if case["start"] == "partial":  # a run killed half-way: some files and manifest lines are missing
        names = sorted(os.listdir(parts))
        for n in names[: len(names) // 2]:
            p = os.path.join(parts, n)
            shutil.rmtree(p) if os.path.isdir(p) else os.unlink(p)
    if case["parts"] != "folder":
        if os.path.lexists(parts):
            shutil.rmtree(parts)
        if case["parts"] == "link-folder":
            os.symlink(far, parts)
        elif case["parts"] == "link-zarr":
            os.symlink(os.path.join(far, "data.zarr"), parts)
        elif case["parts"] == "file":
            with open(parts, "wb") as f:
                f.write(b"not a folder")
        else:
            os.mkfifo(parts)
        return job, True
    os.makedirs(parts, mode=0o700, exist_ok=True)
    files = []
    if fmt != "zarr":
        folder = work if fmt == "tiles" else parts
        files = [os.path.join(folder, n) for col, row, _ in job.tiles() for n in job.tile_names(col, row)]
    for i, path in enumerate(files):
        how = case["tiles"][i % len(case["tiles"])]
        how = "keep" if how == "folder" and not case.get("folders", True) else how
        refuse |= _tamper_file(path, how, far, rng, files[(i + 1) % len(files)])
    if fmt == "zarr":
        refuse |= _tamper_zarr(os.path.join(parts, "data.zarr"), case["zarr"], far, rng)
    manifest = os.path.join(parts, "manifest.jsonl")
    how = case["manifest"]
    if how in ("claim", "claim-keyed", "bad-names", "torn", "huge", "other-key", "nan"):
        lines = [json.dumps({"key": job.export_key() if how != "other-key" else "0" * 64})]
        for names, paths, _, _ in job.work():
            for n, p in zip(names, paths):
                where = os.path.join(work if fmt == "tiles" else parts, p) if p else os.path.join(far, "precious.bin")
                size, sha = _claimed(where, (lambda data, n=n: job.sign(n, data)) if how != "claim" else None)
                lines.append(json.dumps([n, size, sha]))
        if how == "bad-names":
            lines += [json.dumps(n) for n in (["../precious.bin", 10, "a" * 64], ["/etc/passwd", 1, "b" * 64],
                                              ["0,0/../../x", 2, "c" * 64])]
        elif how == "torn":
            lines[-1] = lines[-1][: len(lines[-1]) // 2]
        elif how == "huge":
            lines += [lines[-1]] * 5000
        elif how == "nan":
            lines.insert(1, '["0,0", NaN, "' + "d" * 64 + '"]')
        if os.path.lexists(manifest):
            os.unlink(manifest)
        with open(manifest, "w") as f:
            f.write("\n".join(lines) + ("" if how == "torn" else "\n"))
    elif how != "keep":
        refuse |= _tamper_file(manifest, how, far, rng, None)
    for m in ("", "_coords"):
        refuse |= _tamper_file(os.path.join(parts, f"assembling{m}.tif"), case["assembly"], far, rng, None) \
            if case["assembly"] != "none" else False
    foreign = case["foreign"]
    if foreign == "file":
        with open(os.path.join(parts, "notes.txt"), "w") as f:
            f.write("the user's notes\n")
    elif foreign == "folder":
        os.makedirs(os.path.join(parts, "sub", "deeper"))
    elif foreign == "link-outside":
        os.symlink(os.path.join(far, "folder"), os.path.join(parts, "elsewhere"))
    elif foreign == "fifo":
        os.mkfifo(os.path.join(parts, "pipe"))
    return job, refuse


def _tamper_zarr(store: str, how: str, far: str, rng) -> bool:
    """Tamper with an earlier run's Zarr store; True if the export must refuse it (not a plain store)."""
    chunk = os.path.join(store, "0", "0.0")
    if how == "none" or (how != "store-link" and not os.path.isdir(store)):
        return False
    if how == "store-link":
        if os.path.lexists(store):
            shutil.rmtree(store)
        os.symlink(os.path.join(far, "data.zarr"), store)
        return True
    if how == "no-store":
        shutil.rmtree(store)
        return False
    if how == "bad-zarray":
        meta = os.path.join(store, "0", ".zarray")
        if os.path.isfile(meta):
            with open(meta) as f:
                d = json.load(f)
            d["chunks"] = [512] * len(d["chunks"])
            with open(meta, "w") as f:
                json.dump(d, f)
        return False
    if how == "foreign-in-store":
        with open(os.path.join(store, "README"), "w") as f:
            f.write("not a store's file\n")
        return True
    if os.path.lexists(chunk):
        os.unlink(chunk)
    if how == "chunk-link":
        os.symlink(os.path.join(far, "data.zarr", "0", "0.0"), chunk)
        return True
    if how == "chunk-fifo":
        os.mkfifo(chunk)
        return True
    with open(chunk, "wb") as f:
        f.write(rng.bytes(200))
    return False


def run_parts(case: dict, root: str, timeout: float = 60.0) -> str:
    """Run the export of one tampered parts folder (see parts_folders)."""
    from infinitex.engine.safeio import WriteError
    from infinitex.export import ExportFailed
    job, must_refuse = _build_parts(case, root)
    far = os.path.join(root, "outside")
    before = _snapshot(far)
    with watch() as violations, time_limit(timeout):
        try:
            job.run()
            outcome = "accepted"
        except (WriteError, ExportFailed) as exc:
            if "\n" in str(exc) or not str(exc).strip():
                raise Crash(f"the refusal is not one line: {str(exc)[:300]!r}") from None
            outcome = "refused"
        except Exception as exc:
            raise Crash(f"{type(exc).__name__}: {str(exc)[:200]}") from exc
    if violations:
        raise Crash("; ".join(violations))
    if _snapshot(far) != before:
        raise Crash("a file outside the export's folder changed")
    work = os.path.join(root, "work")
    if must_refuse != (outcome == "refused"):
        raise Crash(f"{'accepted' if must_refuse else 'refused'} a parts folder it should have "
                    f"{'refused' if must_refuse else 'accepted'}")
    if outcome == "refused":
        if case["fmt"] != "tiles" and any(n.startswith("OUT.") and not n.endswith(".parts") for n in os.listdir(work)):
            raise Crash("a refused export left an output")
        return outcome
    got, ref = _parts_result(case["fmt"], work), _PARTS[case["fmt"]]
    if len(got) != len(ref) or any(a.shape != b.shape or a.dtype != b.dtype for a, b in zip(got, ref)):
        raise Crash("the output is not an export of this size and type")
    # Files signed with the user's own key that decode to valid tiles (another
    # tile's, one of random pixels) may be kept: only then may pixels differ.
    if case["manifest"] != "claim-keyed" and any(not np.array_equal(a, b) for a, b in zip(got, ref)):
        raise Crash("the output differs from the reference export")
    if os.path.lexists(job.parts) != bool(job.notes):
        raise Crash("the parts folder was left without a note (or a note without it)")
    return outcome
