"""Direction fields in project files (format version 10): the canvas's sparse
tiles of Q12 Jacobians (engine/controls/direction.py), each as little-endian
int16 (TILE, TILE, 4) bytes, zlib-compressed and base64-encoded. Untrusted
data: size-limited, decompressed with a bound, every Jacobian checked (no
mirror, no stretch beyond the limits); a damaged entry is one sentence."""
from __future__ import annotations

import base64
import zlib

import numpy as np

from infinitex.engine.controls import TILE
from infinitex.engine.controls.direction import MAX_DIRECTION_TILES, DirectionField, valid_jacobians

from .document import ProjectError
from .labels_json import tiles_from_json

_TILE_BYTES = TILE * TILE * 4 * 2


def _pack(t: np.ndarray) -> str:
    return base64.b64encode(zlib.compress(np.ascontiguousarray(t, dtype="<i2").tobytes(), 6)).decode("ascii")


def _unpack(text: object) -> np.ndarray:
    bad = ProjectError("The project's direction field is damaged.")
    if not isinstance(text, str) or len(text) > 4 * _TILE_BYTES:
        raise bad
    try:
        d = zlib.decompressobj()
        raw = d.decompress(base64.b64decode(text, validate=True), _TILE_BYTES + 1)
    except Exception:
        raise bad from None
    if len(raw) != _TILE_BYTES or d.unconsumed_tail:
        raise bad
    t = np.frombuffer(raw, dtype="<i2").astype(np.int16).reshape(TILE, TILE, 4)
    if not valid_jacobians(t):
        raise bad
    return t


def direction_to_json(field: DirectionField) -> dict:
    return {"tile": TILE, "tiles": [{"x": tx, "y": ty, "j16": _pack(t)} for (tx, ty), t in sorted(field.tiles.items())]}


def direction_from_json(d: object) -> DirectionField | None:
    """The project's direction field, or None; all or nothing."""
    if d is None:
        return None
    return DirectionField(tiles_from_json(d, "direction field", "j16", _unpack, MAX_DIRECTION_TILES))
