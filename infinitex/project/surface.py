"""A document's model (texture on a surface, engine/surface): the mesh, how
the texture lies on it, and how it is stored in project files (format 11).

The mesh is kept inside the project (positions and texture coordinates as
float64, faces as int32, their counts beside; zlib, base64), so a project
reopens the same atlas bit for bit wherever it moves. Untrusted data: the
counts are limited first, the data decompressed to exactly their size, the
arrays checked by :class:`~infinitex.engine.surface.Model`.
"""
from __future__ import annotations

import base64
import zlib
from dataclasses import dataclass

import numpy as np

from infinitex.engine.surface import AtlasDomain, Model, ModelError
from infinitex.engine.surface.mesh import MAX_FACES, MAX_VERTICES, texel_density
from infinitex.engine.surface.atlas import FRAMES

from .document import ProjectError

SIZES = (256, 512, 1024, 2048, 4096)
MIN_REPEATS, MAX_REPEATS = 0.05, 500.0


@dataclass(frozen=True, eq=False)
class SurfaceSettings:
    """The model and how the texture lies on it: ``size`` atlas texels a side
    (what the editor synthesizes, and exports by default), the tangent frame
    (engine/surface/atlas.py) and the scale: the exemplar's width fits
    ``repeats`` times across the model's largest side."""

    model: Model
    size: int = 1024
    frame: str = "up"
    up: tuple[float, float, float] = (0.0, 1.0, 0.0)
    repeats: float = 4.0

    def _key(self) -> tuple:
        return (self.model.key, self.size, self.frame, tuple(float(v) for v in self.up), float(self.repeats))

    def __eq__(self, other) -> bool:
        return isinstance(other, SurfaceSettings) and self._key() == other._key()

    def __hash__(self) -> int:
        return hash(self._key())

    def validate(self, exemplar_size: int | None = None) -> None:
        if self.size not in SIZES:
            raise ProjectError(f"The model's texture size is one of {', '.join(map(str, SIZES))}.")
        if exemplar_size is not None and self.size < exemplar_size:
            raise ProjectError(f"The model's texture ({self.size} px) must be at least as large as the exemplar "
                               f"({exemplar_size} px).")
        if self.frame not in FRAMES:
            raise ProjectError(f"The model's texture frame is one of {', '.join(FRAMES)}.")
        up = np.asarray(self.up, np.float64)
        if up.shape != (3,) or not np.isfinite(up).all() or not np.any(up):
            raise ProjectError("The model's up direction is three numbers, not all zero.")
        if not (np.isfinite(self.repeats) and MIN_REPEATS <= self.repeats <= MAX_REPEATS):
            raise ProjectError(f"The model's texture scale (repeats) is from {MIN_REPEATS} to {MAX_REPEATS:g}.")

    def sigma(self, exemplar_size: int) -> float:
        """Exemplar px per world unit."""
        return exemplar_size * float(self.repeats) / self.model.extent

    def atlas(self, exemplar_size: int, size: int | None = None) -> AtlasDomain:
        return AtlasDomain(self.model, size or self.size, self.sigma(exemplar_size), frame=self.frame, up=self.up)


def default_repeats(model: Model, size: int, exemplar_size: int) -> float:
    """The scale that shows about one exemplar pixel per atlas texel (the sharpest without aliasing)."""
    rho = texel_density(model, size)
    return float(np.clip(round(rho * model.extent / exemplar_size, 2), MIN_REPEATS, MAX_REPEATS))


def _pack(model: Model) -> str:
    """Positions (V, 3) and texture coordinates (V, 2) as little-endian float64,
    faces (F, 3) as int32, one after the other; zlib, base64."""
    raw = b"".join(np.ascontiguousarray(a, dtype=t).tobytes() for a, t in
                   ((model.positions, "<f8"), (model.uvs, "<f8"), (model.faces, "<i4")))
    return base64.b64encode(zlib.compress(raw, 6)).decode("ascii")


def _unpack(text: object, name: str, vertices: object, faces: object) -> Model:
    bad = ProjectError("The project's model is damaged.")
    if not (isinstance(vertices, int) and isinstance(faces, int) and not isinstance(vertices, bool)
            and not isinstance(faces, bool) and 3 <= vertices <= MAX_VERTICES and 1 <= faces <= MAX_FACES):
        raise bad
    size = vertices * 40 + faces * 12  # known before anything is decompressed
    if not isinstance(text, str) or len(text) > 2 * size + 1024:
        raise bad
    try:
        d = zlib.decompressobj()
        raw = d.decompress(base64.b64decode(text, validate=True), size + 1)
    except Exception:
        raise bad from None
    if len(raw) != size or d.unconsumed_tail:
        raise bad
    v3 = vertices * 24
    P = np.frombuffer(raw[:v3], "<f8").reshape(vertices, 3)
    uv = np.frombuffer(raw[v3:v3 + vertices * 16], "<f8").reshape(vertices, 2)
    F = np.frombuffer(raw[v3 + vertices * 16:], "<i4").reshape(faces, 3)
    try:
        return Model(P, F, uv, name=name)
    except ModelError as exc:
        raise ProjectError(f"The project's model: {exc}") from None


def surface_to_json(s: SurfaceSettings) -> dict:
    return {"name": s.model.name, "vertices": len(s.model.positions), "faces": len(s.model.faces),
            "mesh": _pack(s.model), "sha256": s.model.key, "size": s.size,
            "frame": s.frame, "up": [float(v) for v in s.up], "repeats": float(s.repeats)}


def surface_from_json(d: object) -> SurfaceSettings | None:
    """The project's model, or None; all or nothing."""
    if d is None:
        return None
    if not isinstance(d, dict) or not isinstance(d.get("name"), str) or len(d["name"]) > 255:
        raise ProjectError("The project's model is damaged.")
    model = _unpack(d.get("mesh"), d["name"], d.get("vertices"), d.get("faces"))
    if d.get("sha256") != model.key:
        raise ProjectError("The project's model is damaged (its checksum does not match).")
    size, frame, up, repeats = d.get("size"), d.get("frame"), d.get("up"), d.get("repeats")
    if (not isinstance(size, int) or isinstance(size, bool) or not isinstance(frame, str)
            or not isinstance(up, list) or len(up) != 3
            or not all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in [*up, repeats])):
        raise ProjectError("The project's model settings are damaged.")
    s = SurfaceSettings(model, size, frame, tuple(float(v) for v in up), float(repeats))
    s.validate()
    return s
