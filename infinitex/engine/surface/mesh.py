"""Models to texture: triangle meshes with texture coordinates, read from OBJ
and glTF/GLB files by trimesh (the well-kept library that reads both, scenes
included; docs/install.md), checked like every untrusted input.

A :class:`Model` is plain arrays: positions (V, 3), faces (F, 3), texture
coordinates (V, 2) in OBJ's convention (v = 0 at the image's bottom; trimesh
converts glTF's on import and back on export). Vertices are split wherever a
texture coordinate changes (a UV seam): the atlas finds the seams by welding
equal positions (engine/surface/atlas.py).
"""
from __future__ import annotations

import hashlib
import os
import signal
from dataclasses import dataclass, field
from functools import cached_property

import numpy as np

from ..safeio import printable
from .sources import ModelFiles, obj_counts, trimesh_mtllib

MAX_MODEL_BYTES = 512 * 1024 * 1024
MAX_FACES = 2_000_000
MAX_VERTICES = 3_000_000
MODEL_SUFFIXES = (".obj", ".glb", ".gltf")
MAX_UV = 64.0  # texture coordinates beyond +-64 (far outside the atlas) are refused
MAX_POSITION = 1e12  # and positions beyond +-1e12 (after the scene's transforms)


class ModelError(ValueError):
    """A model file that cannot be textured (one line, for the CLI and the editor)."""


@dataclass(frozen=True, eq=False)
class Model:
    """A triangle mesh with texture coordinates (float64 / int64 arrays)."""

    positions: np.ndarray  # (V, 3)
    faces: np.ndarray  # (F, 3) vertex indices
    uvs: np.ndarray  # (V, 2), v up (OBJ)
    name: str = "model"
    meta: dict = field(default_factory=dict)

    def __post_init__(self):
        p = np.ascontiguousarray(self.positions, dtype=np.float64)
        f = np.ascontiguousarray(self.faces, dtype=np.int64)
        uv = np.ascontiguousarray(self.uvs, dtype=np.float64)
        if p.ndim != 2 or p.shape[1] != 3 or f.ndim != 2 or f.shape[1] != 3 or uv.shape != (len(p), 2):
            raise ModelError(f"{self.name}: the mesh's arrays do not fit together (positions {p.shape}, "
                             f"faces {f.shape}, texture coordinates {uv.shape}).")
        if not len(f):
            raise ModelError(f"{self.name} has no triangles.")
        if len(f) > MAX_FACES or len(p) > MAX_VERTICES:
            raise ModelError(f"{self.name} has {len(f):,} triangles and {len(p):,} vertices; the limit is "
                             f"{MAX_FACES:,} and {MAX_VERTICES:,}.")
        if f.min() < 0 or f.max() >= len(p):
            raise ModelError(f"{self.name}: a triangle refers to a vertex that does not exist.")
        if not (np.isfinite(p).all() and np.isfinite(uv).all()):
            raise ModelError(f"{self.name} has positions or texture coordinates that are not finite numbers.")
        if np.abs(uv).max() > MAX_UV or np.abs(p).max() > MAX_POSITION:
            raise ModelError(f"{self.name} has texture coordinates or positions far out of range.")
        object.__setattr__(self, "positions", p)
        object.__setattr__(self, "faces", f)
        object.__setattr__(self, "uvs", uv)
        for a in (p, f, uv):
            a.setflags(write=False)

    @cached_property
    def key(self) -> str:
        h = hashlib.sha256()
        for a in (self.positions, self.faces, self.uvs):
            h.update(repr(a.shape).encode())
            h.update(a.tobytes())
        return h.hexdigest()

    @property
    def extent(self) -> float:
        """The largest side of the bounding box (world units)."""
        e = self.positions.max(axis=0) - self.positions.min(axis=0)
        return float(max(e.max(), 1e-12))


def _from_trimesh(mesh, name: str) -> Model:
    uv = getattr(getattr(mesh, "visual", None), "uv", None)
    if uv is None or len(uv) != len(mesh.vertices):
        raise ModelError(f"{name} has no texture coordinates (UVs): unwrap it first (e.g. Blender's Smart UV "
                         f"Project), or pass --unwrap to generate them with xatlas.")
    return Model(np.asarray(mesh.vertices), np.asarray(mesh.faces), np.asarray(uv), name=name)


THIN_AREA = 1e-10         # twice a triangle's area in the unit cube below which xatlas cannot lay it out
UNWRAP_MEMORY = 3 << 30  # bytes of address space the unwrapping process may take
UNWRAP_SECONDS = 10.0     # and seconds, plus UNWRAP_PER_FACE a triangle (158k triangles: 8.5 s here)
UNWRAP_PER_FACE = 100e-6


def unwrap(model_positions: np.ndarray, faces: np.ndarray, name: str = "model", isolated: bool = True) -> Model:
    """New texture coordinates for a mesh (xatlas, the library made for it):
    charts cut and packed into [0, 1]^2 with room between them.

    ``isolated`` (a model read from a file): xatlas runs in a child process
    with a memory and a time limit, since it cannot be interrupted (a signal
    does not stop it) and some inputs make it spin or grow without end (an
    ``inf`` coordinate, a vertex at 1e11: 6 GB); any failure is one line."""
    P, F = _unwrappable(model_positions, faces, name)
    if not isolated:
        import xatlas
        vmap, idx, uv = xatlas.parametrize(P, F)
    else:
        vmap, idx, uv = _unwrap_isolated(P, F, name)
    if not np.isfinite(uv).all():  # xatlas's, not the model's: say what made it so
        raise ModelError(f"{name}: xatlas could not lay out its texture coordinates ({int(_thin(P, F).sum()):,} of "
                         f"its {len(F):,} triangles are degenerate or too thin for the model's size); remove "
                         f"them and try again.")
    return Model(np.asarray(model_positions)[vmap], idx.astype(np.int64), uv.astype(np.float64), name=name,
                 meta={"unwrapped": True})


def _thin(P: np.ndarray, F: np.ndarray) -> np.ndarray:
    """Triangles of a mesh in the unit cube too small or thin for single
    precision (twice their area under THIN_AREA)."""
    P = P.astype(np.float64)
    return np.linalg.norm(np.cross(P[F[:, 1]] - P[F[:, 0]], P[F[:, 2]] - P[F[:, 0]]), axis=-1) < THIN_AREA


def _unwrappable(positions, faces, name: str) -> tuple[np.ndarray, np.ndarray]:
    """The mesh as xatlas gets it, checked first (xatlas cannot be stopped
    once it runs): triangles that refer to vertices that exist, finite
    positions of sane magnitude (a node scale of 1e38 spun forever), not
    every triangle degenerate or too thin for single precision once the mesh
    is moved and scaled into the unit cube (a vertex at 1e11 beside a unit
    quad took 6 GB); the unit cube's positions are what xatlas gets (the
    layout does not depend on size)."""
    P = np.asarray(positions, np.float64)
    F = np.asarray(faces)
    if P.ndim != 2 or P.shape[1] != 3 or F.ndim != 2 or F.shape[1] != 3 or not len(F):
        raise ModelError(f"{name} holds no triangle mesh to unwrap.")
    if F.min() < 0 or F.max() >= len(P):
        raise ModelError(f"{name}: a triangle refers to a vertex that does not exist.")
    if not np.isfinite(P).all():
        raise ModelError(f"{name}: its positions are not all finite numbers.")
    used = P[np.unique(F)]
    biggest = float(np.abs(used).max())
    if biggest > MAX_POSITION:
        raise ModelError(f"{name}: its positions reach {biggest:.3g} (after the scene's transforms); models "
                         f"within +-{MAX_POSITION:.0e} are read.")
    lo = used.min(axis=0)
    extent = float((used.max(axis=0) - lo).max())
    unit = (P - lo) / extent if extent > 0 else P - lo
    thin = int(_thin(unit, F).sum())
    if 2 * thin > len(F):  # (a box with one vertex at 2e9: 7 of 12, and xatlas spun)
        raise ModelError(f"{name}: {'every' if thin == len(F) else f'{thin:,} of its {len(F):,}'} triangles are "
                         f"degenerate or too thin for the model's size (a vertex far from the rest?); xatlas "
                         f"cannot lay them out.")
    return unit.astype(np.float32), F.astype(np.uint32)


def _unwrap_child(conn, P, F, limit: int) -> None:
    try:
        import resource
        _, hard = resource.getrlimit(resource.RLIMIT_AS)
        if hard != resource.RLIM_INFINITY:  # a hard limit inherited (ulimit -v): never above it
            limit = min(limit, hard)
        resource.setrlimit(resource.RLIMIT_AS, (limit, limit))
        import xatlas
        conn.send(("ok", xatlas.parametrize(P, F)))
    except MemoryError:
        conn.send(("memory", None))
    except Exception as exc:  # one line for the parent
        conn.send(("error", (str(exc).strip().splitlines() or [type(exc).__name__])[0][:160]))


def _unwrap_isolated(P: np.ndarray, F: np.ndarray, name: str):
    import multiprocessing
    ctx = multiprocessing.get_context("spawn")
    recv, send = ctx.Pipe(duplex=False)
    proc = ctx.Process(target=_unwrap_child, args=(send, P, F, UNWRAP_MEMORY), daemon=True)
    proc.start()
    send.close()
    limit = UNWRAP_SECONDS + UNWRAP_PER_FACE * len(F)
    try:
        if not recv.poll(limit):
            raise ModelError(f"{name}: generating its texture coordinates took over {limit:.0f} s; gave up.")
        kind, out = recv.recv()
    except (EOFError, OSError):
        kind, out = "died", None  # the process ended without an answer
    finally:
        if proc.is_alive():
            proc.kill()
        proc.join()
        recv.close()
    if kind == "died" and proc.exitcode is not None and proc.exitcode < 0 \
            and -proc.exitcode in (signal.SIGSEGV, signal.SIGBUS, signal.SIGABRT, signal.SIGILL, signal.SIGFPE):
        raise ModelError(f"{name}: xatlas crashed on this mesh ({signal.Signals(-proc.exitcode).name}); unwrap it "
                         f"in a modelling tool (e.g. Blender's Smart UV Project) and open it again.")
    if kind in ("memory", "died"):
        raise ModelError(f"{name}: generating its texture coordinates needed more than "
                         f"{UNWRAP_MEMORY >> 30} GB; gave up.")
    if kind != "ok":
        raise ModelError(f"{name}: xatlas could not generate texture coordinates ({out}).")
    return out


def _gltf_json(data: bytes, name: str, glb: bool) -> dict:
    """The JSON of a .gltf, or a .glb's JSON chunk (from its header)."""
    import json
    import struct
    if glb:
        if len(data) < 20 or data[:4] != b"glTF" or data[16:20] != b"JSON":
            raise ModelError(f"{name} is not a GLB file.")
        n = struct.unpack("<I", data[12:16])[0]
        if n > 64 * 1024 * 1024:
            raise ModelError(f"{name}'s scene description is {n >> 20} MB; at most 64 MB is read.")
        data = data[20:20 + n]
    elif len(data) > 64 * 1024 * 1024:
        raise ModelError(f"{name}'s scene description is {len(data) >> 20} MB; at most 64 MB is read.")
    try:
        doc = json.loads(data)
    except (ValueError, RecursionError):
        raise ModelError(f"{name} is not a glTF file (its JSON cannot be read).") from None
    if not isinstance(doc, dict):
        raise ModelError(f"{name} is not a glTF file.")
    return doc


def _check_gltf(doc: dict, name: str, files) -> None:
    """A glTF or GLB checked from its JSON before any geometry is built: the
    triangles and vertices of every mesh instance the scene's nodes place,
    at any depth (a mesh used by 12,000 nodes counts 12,000 times: the scene
    is joined), within the limits; a node tree that loops refused. The files
    its URIs name are inputs (the gate checks each one trimesh reads)."""
    for key in ("buffers", "images"):
        for entry in doc.get(key) if isinstance(doc.get(key), list) else []:
            uri = entry.get("uri") if isinstance(entry, dict) else None
            if isinstance(uri, str) and not uri.startswith("data:"):
                files.candidates(uri)
    faces, verts = _instanced_counts(doc, name)
    if faces > MAX_FACES:
        raise ModelError(f"{name} places over {MAX_FACES:,} triangles in its scene (a mesh counts once per node "
                         "that uses it); that is the limit.")
    if verts > MAX_VERTICES:
        raise ModelError(f"{name} places over {MAX_VERTICES:,} vertices in its scene (a mesh counts once per node "
                         "that uses it); that is the limit.")


def _instanced_counts(doc: dict, name: str) -> tuple[int, int]:
    """(triangles, vertices) of every mesh instance the scenes' nodes place,
    from the accessors' counts, at any depth: each node's total (its mesh and
    its children's totals) is found once, so a node shared by many parents
    costs nothing more to count; a cycle is refused. An unreadable entry
    counts as nothing (the loader then refuses the file)."""
    def items(key):
        v = doc.get(key)
        return v if isinstance(v, list) else []
    accessors, meshes, nodes = items("accessors"), items("meshes"), items("nodes")

    def count(i) -> int:
        a = accessors[i] if isinstance(i, int) and 0 <= i < len(accessors) else None
        c = a.get("count") if isinstance(a, dict) else None
        return c if isinstance(c, int) and c > 0 else 0

    per_mesh = []
    for m in meshes:
        tri = vert = 0
        for prim in (m.get("primitives") if isinstance(m, dict) else None) or []:
            if not isinstance(prim, dict):
                continue
            attrs = prim.get("attributes") if isinstance(prim.get("attributes"), dict) else {}
            v = count(attrs.get("POSITION"))
            n = count(prim["indices"]) if "indices" in prim else v
            mode = prim.get("mode", 4)
            tri += n // 3 if mode == 4 else max(0, n - 2) if mode in (5, 6) else 0
            vert += v
        per_mesh.append((tri, vert))

    def children(i: int) -> list[int]:
        c = nodes[i].get("children") if isinstance(nodes[i], dict) else None
        return [j for j in c if isinstance(j, int) and 0 <= j < len(nodes)] if isinstance(c, list) else []

    total: dict[int, tuple[int, int]] = {}
    busy: set[int] = set()

    def walk(root: int) -> tuple[int, int]:  # post-order without recursion (a chain may be any depth)
        stack = [root]
        while stack:
            i = stack[-1]
            if i in total:
                stack.pop()
                continue
            todo = [j for j in children(i) if j not in total]
            if i not in busy:
                busy.add(i)
                for j in todo:
                    if j in busy:
                        raise ModelError(f"{name}: its node tree loops back on itself (node {j}).")
                stack += todo
                continue
            m = nodes[i].get("mesh") if isinstance(nodes[i], dict) else None
            tri, vert = per_mesh[m] if isinstance(m, int) and 0 <= m < len(per_mesh) else (0, 0)
            for j in children(i):
                tri, vert = tri + total[j][0], vert + total[j][1]
            total[i] = (min(tri, 1 << 62), min(vert, 1 << 62))
            busy.discard(i)
            stack.pop()
        return total[root]

    roots = []
    for sc in items("scenes"):
        roots += [r for r in (sc.get("nodes") if isinstance(sc, dict) else None) or []
                  if isinstance(r, int) and 0 <= r < len(nodes)]
    if not items("scenes"):
        roots = list(range(len(nodes)))
    tri = vert = 0
    for r in roots:
        t, v = walk(r)
        tri, vert = tri + t, vert + v
    return tri, vert


def _check_obj(text: bytes, name: str) -> None:
    """An OBJ's triangles and vertices counted from its text before it is
    parsed, the way trimesh finds them (a 140 MB file of 10 million triangles
    took 4.3 GB before the limit was checked; ``f1/1 ...`` lines and large
    polygons count too)."""
    faces, verts, others = obj_counts(text, limit=MAX_FACES)
    if faces > MAX_FACES:
        raise ModelError(f"{name} has over {MAX_FACES:,} faces; that is the limit.")
    if max(verts, others) > MAX_VERTICES:
        raise ModelError(f"{name} has over {MAX_VERTICES:,} vertices; that is the limit.")


def load_model(path, unwrap_missing: bool = False) -> Model:
    """Read OBJ, glTF or GLB (all meshes of a scene, joined, in world space).
    ``unwrap_missing``: generate texture coordinates when the model has none.
    Raises ModelError with one line for anything it cannot use.

    Every file is read through one gate (engine/surface/sources.py): the
    model, then only what trimesh asks the gate for; ``meta["files"]`` lists
    the model's inputs (what was read and what its names could mean)."""
    name = os.path.basename(str(path))
    lower = str(path).lower()
    if not lower.endswith(MODEL_SUFFIXES):
        raise ModelError(f"{name}: models are read from OBJ, glTF or GLB files.")
    files = ModelFiles(str(path), MAX_MODEL_BYTES, ModelError)
    data = files.main()
    kind = "obj" if lower.endswith(".obj") else "glb" if lower.endswith(".glb") else "gltf"
    mtllib = None
    if kind == "obj":
        _check_obj(data, name)
        # The text as read and checked, as UTF-8 (trimesh would guess other encodings with a module we lack).
        text = data.decode("utf-8", "replace")
        mtllib = trimesh_mtllib(text)
        data = text.encode("utf-8")
    else:
        _check_gltf(_gltf_json(data, name, kind == "glb"), name, files)
    import io
    import warnings

    import trimesh
    with warnings.catch_warnings(), np.errstate(all="ignore"):  # what trimesh says of a damaged file: not ours to print
        warnings.simplefilter("ignore")
        try:
            scene = trimesh.load_scene(io.BytesIO(data), file_type=kind, process=False, resolver=files.resolver())
            files.check()
            _check_scene(scene, name)
            loaded = scene.to_mesh()
        except ModelError:
            raise
        except Exception as exc:  # trimesh raises many kinds on damaged files
            files.check()
            if files.missing:  # (a glTF's buffer, most likely)
                raise ModelError(f"{name} refers to {files.missing[0]}, which does not exist beside it.") from None
            msg = str(exc).strip().splitlines()[0][:160] if str(exc).strip() else type(exc).__name__
            raise ModelError(f"{name} is not a model trimesh can read ({printable(msg)}).") from None
    files.name_maps(mtllib)
    if not hasattr(loaded, "faces") or loaded.faces is None or len(loaded.faces) == 0:
        raise ModelError(f"{name} holds no triangle mesh.")
    if len(loaded.faces) > MAX_FACES:
        raise ModelError(f"{name} has {len(loaded.faces):,} triangles; the limit is {MAX_FACES:,}.")
    uv = getattr(getattr(loaded, "visual", None), "uv", None)
    if uv is None and unwrap_missing:
        model = unwrap(np.asarray(loaded.vertices), np.asarray(loaded.faces), name)
    else:
        model = _from_trimesh(loaded, name)
    model.meta["files"] = files.inputs()  # what no export of it may replace
    return model


def _check_scene(scene, name: str) -> None:
    """The triangles and vertices every instance of the parsed scene places,
    counted before the scene is joined into one mesh."""
    faces = verts = 0
    for node in scene.graph.nodes_geometry:
        geom = scene.geometry.get(scene.graph[node][1])
        f, v = getattr(geom, "faces", None), getattr(geom, "vertices", None)
        faces += 0 if f is None else len(f)
        verts += 0 if v is None else len(v)
        if faces > MAX_FACES or verts > MAX_VERTICES:
            raise ModelError(f"{name} places over {MAX_FACES:,} triangles or {MAX_VERTICES:,} vertices in its "
                             "scene (a mesh counts once per node that uses it); that is the limit.")


def texel_density(model: Model, size: int) -> float:
    """Atlas texels per world unit at ``size``: the area-weighted median over triangles."""
    P, f = model.positions, model.faces
    uv = model.uvs * size
    a3 = 0.5 * np.linalg.norm(np.cross(P[f[:, 1]] - P[f[:, 0]], P[f[:, 2]] - P[f[:, 0]]), axis=-1)
    d1, d2 = uv[f[:, 1]] - uv[f[:, 0]], uv[f[:, 2]] - uv[f[:, 0]]
    a2 = 0.5 * np.abs(d1[:, 0] * d2[:, 1] - d1[:, 1] * d2[:, 0])
    ok = (a3 > 0) & (a2 > 0)
    if not ok.any():
        raise ModelError(f"{model.name}: every triangle is degenerate in space or in its texture coordinates.")
    rho = np.sqrt(a2[ok] / a3[ok])
    order = np.argsort(rho)
    w = np.cumsum(a3[ok][order])
    return float(rho[order][np.searchsorted(w, 0.5 * w[-1])])
