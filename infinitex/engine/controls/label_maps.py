"""Label maps read from image files (texture by numbers: the
``--labels-exemplar`` and ``--labels-canvas`` arguments, the editor's import),
with the same safeguards as exemplars.

Each distinct color is a label (pure black too); the same color means the same
label in both maps. The exemplar's map gives the labels (at most 16, ordered
by color value); the canvas map may use only those colors, and its fully
transparent pixels are free (no constraint). An exemplar map with more than
16 colors (anti-aliased or resized smoothly) is refused with a sentence that
says why; a few stray in-between colors would become labels of their own
(the editor lists them).
"""
from __future__ import annotations

import numpy as np
from PIL import Image

from ..exemplar import ExemplarError, crop_box
from .labels import MAX_LABELS
from .maps import opened_map

Color = tuple[int, int, int]


def load_label_image(path: str, what: str) -> np.ndarray:
    """An image file as RGBA uint8 (H, W, 4), read like an exemplar: regular
    files only, size and decoding cost checked before decoding."""
    # RGBA, the color keys, their sort and inverse
    with opened_map(path, what, lambda w, h, mode, file_bytes: file_bytes + w * h * 48 + (16 << 20)) as (name, img):
        if img.mode.startswith("I") or img.mode == "F":
            raise ExemplarError(f"{name} is a 16-bit or float image; a label map has 8-bit colors (an indexed "
                                "PNG or distinct flat colors).")
        return np.ascontiguousarray(np.asarray(img.convert("RGBA"), dtype=np.uint8))


def _keys(rgb: np.ndarray) -> np.ndarray:
    return (rgb[..., 0].astype(np.uint32) << 16) | (rgb[..., 1].astype(np.uint32) << 8) | rgb[..., 2]


def _hex(key: int) -> str:
    return f"#{key:06x}"


def exemplar_labels_from_colors(rgba: np.ndarray, name: str = "exemplar label map") -> tuple[np.ndarray, list[Color]]:
    """(label ids uint8 (H, W), the palette: one color per label, ascending)."""
    keys = _keys(rgba[..., :3])
    colors, ids = np.unique(keys, return_inverse=True)
    if len(colors) > MAX_LABELS:
        raise ExemplarError(f"The {name} has {len(colors)} colors; at most {MAX_LABELS} labels are possible. "
                            "In-between colors come from smoothing (anti-aliasing, a smooth resize): paint it "
                            "with hard edges or save it as an indexed PNG.")
    palette = [((int(c) >> 16) & 255, (int(c) >> 8) & 255, int(c) & 255) for c in colors]
    return ids.reshape(keys.shape).astype(np.uint8), palette


def canvas_labels_from_colors(rgba: np.ndarray, palette: list[Color], name: str = "canvas label map") -> np.ndarray:
    """Canvas label values uint8 (H, W): 0 where fully transparent (free), else
    1 + the label of its color in ``palette``; a color the palette lacks is
    refused (the first one found, with its position)."""
    keys = _keys(rgba[..., :3])
    known = np.array([(r << 16) | (g << 8) | b for r, g, b in palette], np.uint32)
    order = np.argsort(known)
    pos = np.searchsorted(known[order], keys)
    pos = np.minimum(pos, len(known) - 1)
    ids = order[pos]
    free = rgba[..., 3] == 0
    bad = (known[ids] != keys) & ~free
    if bad.any():
        y, x = (int(v[0]) for v in np.nonzero(bad))
        raise ExemplarError(f"The {name} has the color {_hex(int(keys[y, x]))} at ({x}, {y}), which the exemplar's "
                            f"label map does not have ({', '.join(_hex(int(k)) for k in known)}); transparent "
                            "pixels are free.")
    return np.where(free, 0, ids + 1).astype(np.uint8)


def fit_label_map(ids: np.ndarray, fit: str, m: int, original: tuple[int, int], name: str) -> np.ndarray:
    """An exemplar label map (the size of the exemplar's image, ``original``
    = (w, h)) brought to the exemplar's m x m by its fit rule: the same center
    crop, resampled by nearest neighbor (labels never mix)."""
    h, w = ids.shape
    if (w, h) != tuple(original):
        raise ExemplarError(f"The {name} is {w}x{h} px but the exemplar is {original[0]}x{original[1]} px; "
                            "a label map covers the exemplar pixel for pixel.")
    if (h, w) == (m, m):
        return np.ascontiguousarray(ids)
    x0, y0, side = crop_box(w, h, fit)
    sq = Image.fromarray(np.ascontiguousarray(ids[y0:y0 + side, x0:x0 + side]))
    return np.asarray(sq.resize((m, m), Image.NEAREST), dtype=np.uint8)
