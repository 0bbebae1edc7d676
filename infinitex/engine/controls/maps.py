"""Painted-randomness maps and avoid masks read from image files (the
``--randomness-exemplar``, ``--randomness-canvas`` and ``--avoid-exemplar``
arguments), with the same safeguards as exemplars."""
from __future__ import annotations

import os

import numpy as np
from PIL import Image

from ..exemplar import MAX_FILE_BYTES, ExemplarError, crop_box, decoding, open_image
from ..safeio import ReadError, printable, read_limited


def load_field_map(path: str, what: str = "randomness map") -> np.ndarray:
    """A grayscale randomness map as uint16 field values (1/32768ths): 8-bit
    M = value / 128 (0 calm, 128 neutral, 255 almost 2), 16-bit M = value / 32768.
    Color images are read as their luminance. Same safeguards as exemplars."""
    name = f"The {what} {printable(os.path.basename(path) or path)}"
    try:
        data = read_limited(path, MAX_FILE_BYTES, "image")
    except ReadError as exc:
        raise ExemplarError(f"The {what}: {exc}") from None
    with decoding(name), open_image(data, name) as img:
        img.load()
        if img.mode.startswith("I;16") or img.mode == "I":
            return np.clip(np.asarray(img).astype(np.int64), 0, 65535).astype(np.uint16)
        if img.mode in ("LAB", "HSV", "CMYK", "YCbCr"):
            img = img.convert("RGB")
        g = img if img.mode == "L" else img.convert("L")
        return np.ascontiguousarray((np.asarray(g).astype(np.uint32) * 256).astype(np.uint16))


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
