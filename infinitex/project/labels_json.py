"""Texture by numbers in project files (format version 8): the exemplar's
label map and the canvas labels as 8-bit grayscale PNGs (base64, tiles like
the canvas randomness field), the colors, names and strength. Untrusted data,
validated like the rest of a project: a damaged entry is one sentence."""
from __future__ import annotations

import base64
import io

import numpy as np

from infinitex.engine.controls import MAX_LABELS, TILE, CanvasLabels, ExemplarLabels
from infinitex.engine.exemplar import MAX_SIZE
from infinitex.engine.material import IMAGE, ROLES

from .document import LabelMaps, ProjectError, is_number

MAX_LABEL_TILES = 65536
_TILE_LIMIT = 2 ** 31 // TILE


def _png8(a: np.ndarray) -> str:
    from PIL import Image
    buf = io.BytesIO()
    Image.fromarray(np.ascontiguousarray(a, dtype=np.uint8)).save(buf, "PNG")
    return base64.b64encode(buf.getvalue()).decode("ascii")


def _unpng8(text: object, shape: tuple[int, int] | None, what: str, limit: int) -> np.ndarray:
    """An 8-bit grayscale PNG (base64) as uint8 with values <= limit; ProjectError otherwise."""
    from PIL import Image
    bad = ProjectError(f"The project's {what} is damaged.")
    if not isinstance(text, str) or len(text) > 8 * 2 ** 20:
        raise bad
    try:
        data = base64.b64decode(text, validate=True)
        with Image.open(io.BytesIO(data), formats=["PNG"]) as img:
            if img.size[0] * img.size[1] > MAX_SIZE * MAX_SIZE or img.mode != "L":
                raise ValueError
            a = np.asarray(img, dtype=np.uint8)
    except Exception:
        raise bad from None
    if int(a.max(initial=0)) > limit or (shape is not None and a.shape != shape):
        raise bad
    return a


def tiles_from_json(c: object, what: str, entry: str, decode, limit: int) -> dict:
    """Sparse TILE x TILE tiles from a project's {"tile", "tiles": [{"x", "y",
    ``entry``}]} (the canvas randomness field, the canvas labels), each decoded
    by ``decode(text)``; at most ``limit`` tiles, unique positions; all or nothing."""
    bad = ProjectError(f"The project's {what} is damaged.")
    if not isinstance(c, dict) or c.get("tile") != TILE or not isinstance(c.get("tiles"), list) \
            or len(c["tiles"]) > limit:
        raise bad
    tiles = {}
    for t in c["tiles"]:
        if not isinstance(t, dict):
            raise bad
        tx, ty = t.get("x"), t.get("y")
        if not all(isinstance(q, int) and not isinstance(q, bool) and -_TILE_LIMIT <= q < _TILE_LIMIT
                   for q in (tx, ty)) or (tx, ty) in tiles:
            raise bad
        tiles[(tx, ty)] = decode(t.get(entry))
    return tiles


def labels_to_json(lab: LabelMaps) -> dict:
    return {
        "exemplar": _png8(lab.exemplar.values),
        "colors": [list(c) for c in lab.colors],
        "names": list(lab.names),
        "strength": lab.strength,
        "canvas": {"tile": TILE, "tiles": [{"x": tx, "y": ty, "png8": _png8(t)}
                                           for (tx, ty), t in sorted(lab.canvas.tiles.items())]},
    }


def labels_from_json(d: object) -> LabelMaps | None:
    """The project's texture by numbers, or None; all or nothing."""
    if d is None:
        return None
    bad = ProjectError("The project's labels are damaged.")
    if not isinstance(d, dict):
        raise bad
    v = _unpng8(d.get("exemplar"), None, "exemplar label map", MAX_LABELS - 1)
    n = v.shape[0]
    if v.ndim != 2 or v.shape[1] != n or n & (n - 1) or not 1 <= n <= MAX_SIZE:
        raise bad
    colors, names, strength = d.get("colors"), d.get("names", []), d.get("strength", 1.0)
    if not (isinstance(colors, list) and 1 <= len(colors) <= MAX_LABELS and all(
            isinstance(c, list) and len(c) == 3 and all(isinstance(x, int) and not isinstance(x, bool)
                                                        and 0 <= x <= 255 for x in c) for c in colors)):
        raise bad
    if not (isinstance(names, list) and len(names) <= MAX_LABELS
            and all(isinstance(s, str) and len(s) <= 64 for s in names)) or not is_number(strength):
        raise bad
    tiles = tiles_from_json(d.get("canvas"), "canvas labels", "png8",
                            lambda text: _unpng8(text, (TILE, TILE), "canvas labels", MAX_LABELS), MAX_LABEL_TILES)
    lab = LabelMaps(ExemplarLabels(v), tuple(tuple(x) for x in colors), tuple(names), CanvasLabels(tiles),
                    float(strength))
    lab.validate()
    return lab


def palette_to_json(doc, entry_json) -> list:
    """A palette's exemplars after the first: per exemplar, its maps as
    {"role", "name", "sha256", "embedded", "path"} (``entry_json(source)``
    gives all but the role)."""
    return [[{"role": role, **entry_json(src)} for role, src in entry] for entry in doc.palette]


def palette_from_json(p: object, read) -> tuple:
    """The palette's exemplars after the first (none: ()); ``read(entry,
    where)`` reads one file entry like the exemplar's (embedded or referenced,
    hash-checked)."""
    if p is None:
        return ()
    bad = ProjectError("The project's palette is damaged.")
    if not isinstance(p, list) or not 1 <= len(p) < MAX_LABELS:
        raise bad
    out = []
    for i, entry in enumerate(p):
        if not isinstance(entry, list) or not 1 <= len(entry) <= len(ROLES) or any(
                not isinstance(e, dict) or (e.get("role") != IMAGE and e.get("role") not in ROLES) for e in entry):
            raise bad
        out.append(tuple((e["role"], read(e, f"palette[{i}][{j}]")) for j, e in enumerate(entry)))
    return tuple(out)
