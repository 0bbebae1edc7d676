"""Exemplar import: any image Pillow reads, brought to a power-of-two square.

The synthesis needs an ``m x m`` exemplar with ``m = 2^L`` between 32 and 512
(ALGORITHM.md section 1). Images that already are such squares are used as
they are. Anything else is brought there by one of two rules, chosen by the
user and never applied silently:

``"resize"`` (default)
    Center-crop the largest square (so the aspect ratio is never distorted),
    then resample it (Lanczos) to the power of two nearest to its side in
    log scale, clamped to 32..512. The square before resampling is kept as
    ``hires`` when it was larger, for synthesis magnification.
``"crop"``
    Center-crop a square whose side is the largest power of two that fits,
    at most 512. No resampling: pixels stay as they were.

Pixel values become float32 in [0, 1] with 1 (L), 2 (LA), 3 (RGB) or 4 (RGBA)
channels; 16-bit and float images keep their precision up to that point.
"""
from __future__ import annotations

import hashlib
import io
import os
from dataclasses import dataclass, field

import numpy as np
from PIL import Image, UnidentifiedImageError

MIN_SIZE = 32
MAX_SIZE = 512
MAX_INPUT_PIXELS = 64 * 1024 * 1024  # 8192^2: bigger inputs are refused up front
FIT_MODES = ("resize", "crop")
PIL_MODES = {1: "L", 2: "LA", 3: "RGB", 4: "RGBA"}  # channels -> Pillow mode


def to_u8(a: np.ndarray) -> np.ndarray:
    """[0, 1] floats to uint8, rounded: the one quantization used for display and export."""
    return np.clip(np.rint(a * 255.0), 0, 255).astype(np.uint8)


class ExemplarError(ValueError):
    """An exemplar could not be used; the message is a sentence for the user."""


@dataclass
class Exemplar:
    """An ``m x m`` exemplar, ready for analysis.

    ``pixels`` is float32 ``(m, m, C)`` in [0, 1]; ``toroidal`` says whether it
    tiles (its wrap-around seam looks like its interior); ``toroidal_guess`` is
    what the seam test found, kept so a UI can show it beside an override.
    """

    pixels: np.ndarray
    toroidal: bool
    toroidal_guess: bool
    source: str = ""
    fit: str = "resize"
    original_size: tuple[int, int] = (0, 0)
    hires: np.ndarray | None = field(default=None, repr=False)

    @property
    def size(self) -> int:
        return int(self.pixels.shape[0])

    @property
    def channels(self) -> int:
        return int(self.pixels.shape[2])

    @property
    def levels(self) -> int:
        """L, the finest level index: m = 2^L."""
        return int(self.size).bit_length() - 1

    def content_hash(self) -> str:
        """Hash of the pixels and the toroidal flag: the analysis cache key."""
        h = hashlib.sha256()
        h.update(np.ascontiguousarray(self.pixels, dtype=np.float32).tobytes())
        h.update(repr((self.pixels.shape, bool(self.toroidal))).encode())
        return h.hexdigest()

    def to_uint8(self) -> np.ndarray:
        return to_u8(self.pixels)


def _is_pow2(n: int) -> bool:
    return n > 0 and (n & (n - 1)) == 0


def _to_float(img: Image.Image) -> np.ndarray:
    """Pillow image of any common mode to float32 (H, W, C) in [0, 1]."""
    mode = img.mode
    if mode == "P":
        img = img.convert("RGBA" if "transparency" in img.info else "RGB")
        mode = img.mode
    if mode in ("1", "CMYK", "YCbCr", "LAB", "HSV", "PA", "La", "RGBa", "RGBX"):
        img = img.convert("RGBA" if "A" in mode or "a" in mode else ("L" if mode == "1" else "RGB"))
        mode = img.mode
    if mode in ("L", "LA", "RGB", "RGBA"):
        arr = np.asarray(img, dtype=np.float32) / 255.0
    elif mode.startswith("I;16") or mode == "I":
        raw = np.asarray(img).astype(np.float64)
        hi = 65535.0 if (mode.startswith("I;16") or raw.max() <= 65535) else raw.max()
        arr = (np.clip(raw, 0, hi) / hi).astype(np.float32)
    elif mode == "F":
        raw = np.asarray(img, dtype=np.float64)
        lo, hi = float(np.nanmin(raw)), float(np.nanmax(raw))
        if not np.isfinite(lo) or not np.isfinite(hi):
            raise ExemplarError("The exemplar holds values that are not numbers (NaN or infinity).")
        arr = ((raw - lo) / (hi - lo if hi > lo else 1.0)).astype(np.float32)
    else:
        raise ExemplarError(f"Images in Pillow mode {mode!r} are not supported.")
    if arr.ndim == 2:
        arr = arr[:, :, None]
    return np.ascontiguousarray(arr)


def guess_toroidal(pixels: np.ndarray, tolerance: float = 1.6) -> bool:
    """True when the wrap-around seams differ no more than interior neighbors.

    Compares the mean absolute difference across the left/right and top/bottom
    seams with the mean difference between adjacent interior columns/rows.
    """
    p = pixels.astype(np.float64)
    inner_x = np.abs(np.diff(p, axis=1)).mean()
    inner_y = np.abs(np.diff(p, axis=0)).mean()
    seam_x = np.abs(p[:, 0] - p[:, -1]).mean()
    seam_y = np.abs(p[0, :] - p[-1, :]).mean()
    eps = 1e-6
    return bool(seam_x <= tolerance * inner_x + eps and seam_y <= tolerance * inner_y + eps)


def _nearest_pow2(n: int) -> int:
    k = int(round(np.log2(max(n, 1))))
    return int(min(max(2 ** k, MIN_SIZE), MAX_SIZE))


def fit_square(arr: np.ndarray, fit: str) -> tuple[np.ndarray, np.ndarray | None]:
    """Apply the documented fit rule; returns (exemplar, hires or None)."""
    if fit not in FIT_MODES:
        raise ExemplarError(f"Unknown fit rule {fit!r}; use one of {', '.join(FIT_MODES)}.")
    h, w = arr.shape[:2]
    if h == w and _is_pow2(w) and MIN_SIZE <= w <= MAX_SIZE:
        return arr, None
    side = min(h, w)
    if fit == "crop":
        target = min(MAX_SIZE, 1 << (side.bit_length() - 1))
        y0, x0 = (h - target) // 2, (w - target) // 2
        return np.ascontiguousarray(arr[y0:y0 + target, x0:x0 + target]), None
    y0, x0 = (h - side) // 2, (w - side) // 2
    square = np.ascontiguousarray(arr[y0:y0 + side, x0:x0 + side])
    target = _nearest_pow2(side)
    if target == side:
        return square, None
    resized = np.stack(
        [np.asarray(Image.fromarray(square[:, :, c], mode="F").resize((target, target), Image.LANCZOS))
         for c in range(square.shape[2])], axis=2)
    resized = np.clip(resized, 0.0, 1.0).astype(np.float32)
    return np.ascontiguousarray(resized), (square if side > target else None)


def from_array(arr: np.ndarray, *, fit: str = "resize", toroidal: bool | None = None,
               source: str = "<array>") -> Exemplar:
    """Build an exemplar from a float array (H, W) or (H, W, C) in [0, 1]."""
    arr = np.asarray(arr, dtype=np.float32)
    if arr.ndim == 2:
        arr = arr[:, :, None]
    if arr.ndim != 3 or arr.shape[2] not in (1, 2, 3, 4):
        raise ExemplarError(f"An exemplar needs 1 to 4 channels; this one has shape {arr.shape}.")
    h, w = arr.shape[:2]
    if h == 0 or w == 0:
        raise ExemplarError("The exemplar image is empty (0 pixels).")
    if min(h, w) < MIN_SIZE:
        raise ExemplarError(f"The exemplar is {w}x{h} px; it must be at least {MIN_SIZE}x{MIN_SIZE} px.")
    if not np.all(np.isfinite(arr)):
        raise ExemplarError("The exemplar holds values that are not numbers (NaN or infinity).")
    px, hires = fit_square(np.clip(arr, 0.0, 1.0), fit)
    guess = guess_toroidal(px)
    return Exemplar(pixels=px, toroidal=guess if toroidal is None else bool(toroidal),
                    toroidal_guess=guess, source=source, fit=fit, original_size=(w, h), hires=hires)


def load_exemplar(path: str | os.PathLike, *, fit: str = "resize",
                  toroidal: bool | None = None) -> Exemplar:
    """Read an image file as an exemplar, or raise :class:`ExemplarError`."""
    path = os.fspath(path)
    name = os.path.basename(path)
    if not os.path.exists(path):
        raise ExemplarError(f"No such file: {path}.")
    if os.path.isdir(path):
        raise ExemplarError(f"{path} is a folder, not an image.")
    if os.path.getsize(path) == 0:
        raise ExemplarError(f"{name} is empty (0 bytes).")
    return _decode(path, name, fit, toroidal, path)


def load_exemplar_bytes(data: bytes, *, name: str = "exemplar", fit: str = "resize",
                        toroidal: bool | None = None) -> Exemplar:
    """Decode an image held in memory (e.g. embedded in a project file)."""
    if not data:
        raise ExemplarError(f"{name} is empty (0 bytes).")
    return _decode(io.BytesIO(data), name, fit, toroidal, name)


def _decode(src, name: str, fit: str, toroidal: bool | None, source: str) -> Exemplar:
    try:
        with Image.open(src) as img:
            w, h = img.size
            if w * h > MAX_INPUT_PIXELS:
                raise ExemplarError(
                    f"{name} is {w}x{h} px, too large to import (at most {MAX_INPUT_PIXELS // 2**20} Mpixels).")
            if w == 0 or h == 0:
                raise ExemplarError(f"{name} has no pixels.")
            img.load()
            arr = _to_float(img)
    except ExemplarError:
        raise
    except Image.DecompressionBombError:
        raise ExemplarError(f"{name} is too large to import safely.") from None
    except UnidentifiedImageError:
        raise ExemplarError(f"{name} is not an image format Pillow can read.") from None
    except (OSError, SyntaxError, ValueError, EOFError) as exc:
        raise ExemplarError(f"{name} could not be read: the file looks damaged ({exc}).") from None
    return from_array(arr, fit=fit, toroidal=toroidal, source=source)
