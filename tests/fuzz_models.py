"""Fuzzing target for model files (OBJ with its .mtl and texture, glTF with
its buffer and image, GLB), shared by tests/reliability/test_fuzz.py and
bench/fuzz.py, built like the targets of fuzzing.py.

A case starts from a small valid model of one kind (with or without texture
coordinates), then mutates the model file's bytes, swaps numbers in its text
for hostile ones (1e38, nan, a vertex at 1e11, an index past the end, a huge
count), spells the names of the files it refers to in ways trimesh reads
(SPELLINGS: a commented ``mtllib``, a folder that does not exist, an absolute
path, ``MAP_KD``, a space, a ``data:`` URI without base64, a NUL), tampers with
the file so named (missing, a FIFO, a folder, a link out of the sandbox, a
character device, garbage), and loads it with or without ``--unwrap``
(xatlas). Each must be accepted with a valid model whose inputs include every
file read, or refused with one ModelError line, within the time limit,
reading nothing outside the sandbox but the libraries, letting no warning out.
"""
from __future__ import annotations

import os
import re
import shutil
import stat
import sys
import tempfile
import warnings

import numpy as np
from hypothesis import strategies as st

from fuzzing import Crash, mutations, time_limit, watch

KINDS = ("obj", "obj-nouv", "gltf", "glb")
HOSTILE = ["1e38", "-1e38", "nan", "inf", "-inf", "1e11", "0", "-1", "99999999", "1e308", "4294967295",
           "2147483648", "1" + "0" * 40, "0x10", ""]
TAMPERS = ["none", "none", "none", "missing", "fifo", "folder", "link-out", "garbage", "empty", "device"]
# How a model names its other files, each spelling one that once got past the checks (issue 69):
# {kind: {spelling: (rewrites of (file, old bytes, new bytes), renames {old: new}, the file it then names)}}
SPELLINGS = {
    "obj": {
        "comment": ([("model.obj", b"mtllib material.mtl", b"# was: mtllib material.mtl")], {}, "material.mtl"),
        "no-folder": ([("model.obj", b"mtllib material.mtl", b"mtllib nowhere/material.mtl")], {}, "material.mtl"),
        "absolute": ([("model.obj", b"mtllib material.mtl", b"mtllib /material.mtl")], {}, "material.mtl"),
        "upper-key": ([("material.mtl", b"map_Kd", b"MAP_KD")], {}, "material_0.png"),
        "spaced": ([("material.mtl", b"map_Kd material_0.png", b"map_Kd my texture.png")],
                   {"material_0.png": "my texture.png"}, "my texture.png"),
        "map-no-folder": ([("material.mtl", b"map_Kd material_0.png", b"map_Kd textures/material_0.png")], {},
                          "material_0.png"),
    },
    "gltf": {
        "no-folder": ([("model.gltf", b'"gltf_buffer_0.bin"', b'"nowhere/gltf_buffer_0.bin"')], {},
                      "gltf_buffer_0.bin"),
        "absolute": ([("model.gltf", b'"gltf_buffer_0.bin"', b'"/gltf_buffer_0.bin"')], {}, "gltf_buffer_0.bin"),
        "data-uri": ([("model.gltf", b'"gltf_buffer_0.bin"', b'"data:application/octet-stream,gltf_buffer_0.bin"')],
                     {}, "gltf_buffer_0.bin"),
        "nul": ([("model.gltf", b'"gltf_buffer_0.bin"', b'"gltf_buffer_0.bin\\u0000"')], {}, "gltf_buffer_0.bin"),
    },
}
_BASES: dict[str, dict[str, bytes]] = {}


def _bases() -> dict[str, dict[str, bytes]]:
    """{kind: {file name: bytes}}: a textured box of each kind, made once (trimesh)."""
    if _BASES:
        return _BASES
    import trimesh
    from PIL import Image
    box = trimesh.creation.box()
    box = trimesh.Trimesh(box.vertices, box.faces, process=False)
    uv = (box.vertices[:, :2] + 0.5).clip(0, 1)
    tex = Image.fromarray((np.indices((8, 8)).sum(0) % 2 * 255).astype(np.uint8)).convert("RGB")
    textured = trimesh.Trimesh(box.vertices, box.faces, process=False,
                               visual=trimesh.visual.TextureVisuals(uv=uv, image=tex))
    with tempfile.TemporaryDirectory() as d:
        textured.export(os.path.join(d, "model.obj"))
        _BASES["obj"] = {n: open(os.path.join(d, n), "rb").read() for n in os.listdir(d)}
    _BASES["obj-nouv"] = {"model.obj": box.export(file_type="obj").encode()}
    files = textured.export(file_type="gltf")
    _BASES["gltf"] = {("model.gltf" if n.endswith(".gltf") else n): v for n, v in files.items()}
    _BASES["glb"] = {"model.glb": textured.export(file_type="glb")}
    return _BASES


FLOATS = [1e38, -1e38, float("nan"), float("inf"), 1e11, 0.0, 3.4e38]
INTS = [0xFFFFFFFF, 0x7FFFFFFF, 65535, 12, 0]


def _swap(text: bytes, draw) -> bytes:
    """One or two numbers of a text swapped for hostile ones."""
    for _ in range(draw(st.integers(1, 2))):
        numbers = list(re.finditer(rb"-?\d+(\.\d+)?(e-?\d+)?", text))
        if not numbers:
            break
        m = numbers[draw(st.integers(0, len(numbers) - 1))]
        text = text[:m.start()] + draw(st.sampled_from(HOSTILE)).encode() + text[m.end():]
    return text


def _glb_parts(data: bytes) -> tuple[bytes, bytes]:
    import struct
    n = struct.unpack_from("<I", data, 12)[0]
    js = data[20:20 + n]
    rest = data[20 + n:]
    return js, rest[8:] if len(rest) >= 8 else b""


def _glb(js: bytes, binary: bytes) -> bytes:
    import struct
    js += b" " * (-len(js) % 4)
    binary += b"\0" * (-len(binary) % 4)
    body = struct.pack("<I4s", len(js), b"JSON") + js + struct.pack("<I4s", len(binary), b"BIN\x00") + binary
    return b"glTF" + struct.pack("<II", 2, 12 + len(body)) + body


def _poke(binary: bytes, draw) -> bytes:
    """A float32 or uint32 of a binary buffer replaced by a hostile value."""
    import struct
    if len(binary) < 4:
        return binary
    at = draw(st.integers(0, len(binary) // 4 - 1)) * 4
    if draw(st.booleans()):
        value = struct.pack("<f", np.float32(draw(st.sampled_from(FLOATS))))
    else:
        value = struct.pack("<I", draw(st.sampled_from(INTS)))
    return binary[:at] + value + binary[at + 4:]


def spelled(kind: str, spelling: str) -> tuple[dict[str, bytes], str | None]:
    """The files of a valid model of ``kind`` whose references are spelled
    one way of SPELLINGS ("plain": as written), and the file it then names."""
    files = dict(_bases()[kind])
    if spelling == "plain":
        return files, None
    rewrites, renames, victim = SPELLINGS[kind][spelling]
    for name, old, new in rewrites:
        assert old in files[name], (kind, spelling)
        files[name] = files[name].replace(old, new)
    for old, new in renames.items():
        files[new] = files.pop(old)
    return files, victim


def spelling_case(kind: str, spelling: str, tamper: str) -> dict:
    """One fixed case: a clean model, its reference spelled one way, the file
    it names tampered with."""
    files, victim = spelled(kind, spelling)
    return {"kind": kind, "main": f"model.{kind}", "files": files, "tamper": tamper, "how": "clean",
            "spelling": spelling, "victim": victim, "unwrap": False}


@st.composite
def model_cases(draw) -> dict:
    kind = draw(st.sampled_from(KINDS))
    main = next(n for n in _bases()[kind] if n.startswith("model."))
    spelling = draw(st.sampled_from(["plain", *SPELLINGS.get(kind, {})]))
    files, victim = spelled(kind, spelling)
    data = files[main]
    how = draw(st.sampled_from(["bytes", "numbers", "numbers", "poke", "poke", "clean"]))
    if how == "bytes":
        data = draw(mutations(data))
    elif kind == "glb" and how in ("numbers", "poke"):
        js, binary = _glb_parts(data)
        data = _glb(_swap(js, draw), binary) if how == "numbers" else _glb(js, _poke(binary, draw))
    elif how == "poke" and kind == "gltf":
        buf = draw(st.sampled_from(sorted(n for n in files if n.endswith(".bin"))))
        files[buf] = _poke(files[buf], draw)
    elif how in ("numbers", "poke"):
        data = _swap(data, draw)
    files[main] = data
    others = [n for n in files if n != main]
    tamper = draw(st.sampled_from(TAMPERS)) if others else "none"
    if victim is None and others:
        victim = draw(st.sampled_from(others))
    return {"kind": kind, "main": main, "files": files, "tamper": tamper, "how": how, "spelling": spelling,
            "victim": victim, "unwrap": draw(st.booleans())}


def model_sandbox() -> str:
    root = tempfile.mkdtemp(prefix="infinitex-fuzz-models-")
    _bases()
    return root


def _write_case(case: dict, folder: str, outside: str) -> str:
    for name, data in case["files"].items():
        with open(os.path.join(folder, name), "wb") as f:
            f.write(data)
    victim = case["victim"]
    if victim is not None and case["tamper"] != "none":
        path = os.path.join(folder, victim)
        os.remove(path)
        how = case["tamper"]
        if how == "fifo":
            os.mkfifo(path)
        elif how == "folder":
            os.mkdir(path)
        elif how == "link-out":
            os.symlink(outside, path)
        elif how == "garbage":
            with open(path, "wb") as f:
                f.write(os.urandom(64))
        elif how == "empty":
            open(path, "wb").close()
        elif how == "device":  # /dev/zero's numbers inside the folder (a link to it where mknod is not allowed)
            try:
                os.mknod(path, 0o666 | stat.S_IFCHR, os.makedev(1, 5))
            except OSError:
                os.symlink("/dev/zero", path)
    return os.path.join(folder, case["main"])


def check_model(m) -> None:
    p, f, uv = m.positions, m.faces, m.uvs
    if not (np.isfinite(p).all() and np.isfinite(uv).all() and len(f) and f.min() >= 0 and f.max() < len(p)):
        raise Crash("an accepted model with bad arrays")


def run_model(case: dict, root: str, timeout: float = 60.0) -> str:
    """Load one case's model; 'accepted' or 'refused' (raises Crash or Hang)."""
    from infinitex.engine.surface import ModelError, load_model
    folder = tempfile.mkdtemp(dir=root)
    outside = os.path.join(tempfile.gettempdir(), "infinitex-fuzz-outside.bin")
    if not os.path.exists(outside):
        with open(outside, "wb") as f:
            f.write(b"\0" * 64)
    try:
        path = _write_case(case, folder, outside)
        allowed = (os.path.realpath(root), os.path.realpath(sys.prefix), os.path.realpath(sys.base_prefix))
        opened: list[str] = []
        with watch(allowed, opened) as violations, time_limit(timeout), \
                warnings.catch_warnings(record=True) as said:
            warnings.simplefilter("always")
            try:
                m = load_model(path, unwrap_missing=case["unwrap"])
            except ModelError as exc:
                if "\n" in str(exc):
                    raise Crash(f"multi-line error: {str(exc)[:200]!r}") from None
                outcome = "refused"
            except Exception as exc:
                raise Crash(f"{type(exc).__name__}: {str(exc)[:200]}") from exc
            else:
                check_model(m)
                # Every file of the model's folder that was read is an input no export may replace.
                inputs = {os.path.realpath(p) for p in m.meta["files"]}
                top = os.path.realpath(folder) + os.sep
                missed = sorted({p for p in opened if p.startswith(top) and p not in inputs})
                if missed:
                    raise Crash(f"read but not an input: {[os.path.basename(p) for p in missed]}")
                outcome = "accepted"
        if violations:
            raise Crash("; ".join(violations))
        if said:  # the command line would print it under its one line
            raise Crash(f"a warning escaped: {said[0].category.__name__}: {str(said[0].message)[:160]}")
        return outcome
    finally:
        shutil.rmtree(folder, ignore_errors=True)
