"""Painted-randomness maps and avoid masks read from image files (the
``--randomness-exemplar``, ``--randomness-canvas`` and ``--avoid-exemplar``
arguments), with the same safeguards as exemplars."""
from __future__ import annotations

import os
from contextlib import contextmanager

import numpy as np
from PIL import Image

from ..exemplar import IMPORT_BUDGET, MAX_FILE_BYTES, ExemplarError, crop_box, decoding, open_image
from ..safeio import ReadError, printable, read_limited


def field_map_cost(w: int, h: int, mode: str, file_bytes: int) -> int:
    """An upper bound of the bytes reading a w x h map needs at its peak: the
    file, the decoded image (4 bytes a pixel at most), its conversion to one
    8-bit or 32-bit band, and the uint16 values (plus a margin)."""
    return file_bytes + w * h * (4 + 4 + 4 + 2) + (16 << 20)


@contextmanager
def opened_map(path: str, what: str, cost):
    """The decoded image of a map file (``with``: (name, image)), read like an
    exemplar: regular files only, the size and the decoder's tiles or strips
    checked from the header, and ``cost(w, h, mode, file_bytes)`` (the bytes
    reading it needs at its peak) against IMPORT_BUDGET, before decoding."""
    name = f"The {what} {printable(os.path.basename(path) or path)}"
    try:
        data = read_limited(path, MAX_FILE_BYTES, "image")
    except ReadError as exc:
        raise ExemplarError(f"The {what}: {exc}") from None
    with decoding(name), open_image(data, name) as img:
        w, h = img.size
        need = cost(w, h, img.mode, len(data))
        if need > IMPORT_BUDGET:
            raise ExemplarError(f"{name} ({w}x{h} px) would need about {need // 2**20} MB to read, more than the "
                                f"{IMPORT_BUDGET // 2**20} MB allowed; reduce it first.")
        img.load()
        yield name, img


def load_field_map(path: str, what: str = "randomness map") -> np.ndarray:
    """A grayscale randomness map as uint16 field values (1/32768ths): 8-bit
    M = value / 128 (0 calm, 128 neutral, 255 almost 2), 16-bit M = value / 32768.
    Color images are read as their luminance. Same safeguards as exemplars:
    regular files only, the size and the decoder's tiles or strips checked from
    the header, and the cost of reading it against IMPORT_BUDGET, before decoding."""
    with opened_map(path, what, field_map_cost) as (_, img):
        if img.mode.startswith("I;16") or img.mode == "I":
            a = np.asarray(img)
            if a.dtype.kind == "u" and a.dtype.itemsize == 2:
                return np.ascontiguousarray(a, dtype=np.uint16)
            return np.clip(a, 0, 65535).astype(np.uint16)
        if img.mode in ("LAB", "HSV", "CMYK", "YCbCr"):
            img = img.convert("RGB")
        g = img if img.mode == "L" else img.convert("L")
        values = np.asarray(g).astype(np.uint16)
        values *= 256
        return values


def fit_field_map(values: np.ndarray, fit: str, m: int) -> np.ndarray:
    """A map over the exemplar brought to the exemplar's m x m by its fit rule
    (the same center crop; resampled bilinearly when the sizes differ)."""
    h, w = values.shape
    if (h, w) == (m, m):
        return values
    x0, y0, side = crop_box(w, h, fit)
    sq = values[y0:y0 + side, x0:x0 + side].astype(np.float32)
    if side != m:
        sq = np.asarray(Image.fromarray(sq, mode="F").resize((m, m), Image.BILINEAR))
    return np.clip(np.rint(sq), 0, 65535).astype(np.uint16)


BAND_PIXELS = 1 << 18  # pixels of a direction map converted at a time


def direction_map_cost(w: int, h: int, mode: str, file_bytes: int) -> int:
    """Peak bytes reading a w x h direction map needs: the file, the decoded
    image (Pillow keeps 1, 2 or 4 bytes a pixel by mode), the Q12 Jacobians made
    of it (8 bytes a pixel) and one band of BAND_PIXELS in float64 (about 200
    bytes a pixel), plus a margin: an 8192 x 8192 color map fits in the import
    budget."""
    decoded = 1 if mode in ("L", "P", "1") else 2 if mode.startswith("I;16") else 4
    return file_bytes + w * h * (decoded + 8) + min(w * h, BAND_PIXELS + w) * 200 + (16 << 20)


def load_direction_map(path: str, kind: str = "auto", y_up: bool = True, scale: float = 1.0,
                       aspect: float = 1.0) -> np.ndarray:
    """A direction map as Q12 Jacobians (H, W, 4) int16 (engine/controls/direction.py):
    ``flow`` (R, G in [0, 1], 0.5 = none; ``y_up``: green points up, OpenGL, else
    down, DirectX), ``angle`` (gray 0..1 = 0..360 degrees, clockwise on screen
    from +x), or ``auto`` (grayscale files are angle maps, color ones flow maps).
    ``scale`` and ``aspect`` apply where a direction is given. Same safeguards as exemplars."""
    from .direction import angle_to_jacobians, flow_to_jacobians
    with opened_map(path, "direction map", direction_map_cost) as (name, img):
        gray = img.mode in ("L", "LA", "I", "F") or img.mode.startswith("I;16")
        if kind == "auto":
            kind = "angle" if gray else "flow"
        if kind == "flow" and gray:
            raise ExemplarError(f"{name} is grayscale; a flow map has its direction in red and green.")
        w, h = img.size
        out = np.empty((h, w, 4), np.int16)
        rows = max(1, BAND_PIXELS // max(1, w))
        for y0 in range(0, h, rows):  # a band at a time: the float arrays stay small
            band = img.crop((0, y0, w, min(h, y0 + rows)))
            if kind == "angle":
                if band.mode.startswith("I;16") or band.mode == "I":
                    a = np.asarray(band).astype(np.float64) / 65535.0
                else:
                    a = np.asarray(band.convert("L")).astype(np.float64) / 255.0
                out[y0:y0 + a.shape[0]] = angle_to_jacobians(a, scale, aspect)
            else:
                rgb = np.asarray(band.convert("RGB")).astype(np.float64) / 255.0
                out[y0:y0 + rgb.shape[0]] = flow_to_jacobians(rgb, y_up, scale, aspect)
        return out


def load_velocity_map(path: str, speed: float, y_up: bool = True, x: int = 0, y: int = 0,
                      size: tuple[int, int] | None = None):
    """A velocity map (engine/controls/flow.py): red and green in [0, 1], 0.5 still,
    ``speed`` px per frame at 0 and 1, green up unless ``y_up`` is False; placed at
    (x, y); ``size``: resized to (w, h) first (a toroidal tile's). Same safeguards
    as exemplars; a grayscale file is refused (it holds no direction)."""
    from .flow import MAX_MAP_SIDE, FlowError, VelocityMap
    with opened_map(path, "velocity map", direction_map_cost) as (name, img):
        if img.mode in ("L", "LA", "I", "F", "1") or img.mode.startswith("I;16"):
            raise ExemplarError(f"{name} is grayscale; a velocity map has its x and y in red and green.")
        if max(img.size) > MAX_MAP_SIDE:
            raise ExemplarError(f"{name} is {img.size[0]}x{img.size[1]} px; a velocity map is at most "
                                f"{MAX_MAP_SIDE} px a side.")
        img = img.convert("RGB")
        if size is not None and img.size != tuple(size):
            img = img.resize(tuple(size), Image.BILINEAR)
        rgb = np.asarray(img).astype(np.float64) / 255.0
    try:
        return VelocityMap.from_unit(rgb, speed, y_up, x, y)
    except FlowError as exc:
        raise ExemplarError(f"{name}: {exc}") from None
