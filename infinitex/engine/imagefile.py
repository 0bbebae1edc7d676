"""Writing images: the one quantization (``to_u8``, ``to_u16``), 8/16-bit PNG
and float TIFF encodings, written atomically."""
from __future__ import annotations

import io

import numpy as np
from PIL import Image

from .safeio import atomic_write

PIL_MODES = {1: "L", 2: "LA", 3: "RGB", 4: "RGBA"}  # channels -> Pillow mode


def to_u8(a: np.ndarray) -> np.ndarray:
    """[0, 1] floats to uint8, rounded: the one quantization used for display and export."""
    return np.clip(np.rint(a * 255.0), 0, 255).astype(np.uint8)


def to_rgb8(a: np.ndarray) -> np.ndarray:
    """(H, W, C) [0, 1] floats to uint8 RGB for figures: gray repeated, alpha dropped."""
    u = to_u8(a)
    return u[..., :3] if u.shape[2] >= 3 else np.repeat(u[..., :1], 3, axis=2)


def to_u16(a: np.ndarray) -> np.ndarray:
    """[0, 1] floats to uint16, rounded (16-bit exports)."""
    return np.clip(np.rint(a * 65535.0), 0, 65535).astype(np.uint16)


DEPTHS = (8, 16, 32)


def depth_extension(depth: int) -> str:
    """The file extension a map of this depth is written with: PNG, or TIFF for float."""
    return ".tif" if depth == 32 else ".png"


def encode_image(pixels: np.ndarray, depth: int, value_range: tuple[float, float] = (0.0, 1.0)) -> bytes:
    """Float (H, W, C) pixels in [0, 1] as the bytes of a file of ``depth`` bits:
    8 or 16: PNG (Pillow; 16-bit color through imagecodecs, which Pillow cannot
    write); 32: a float32 TIFF (tifffile), in the source's units (``value_range``)."""
    if depth not in DEPTHS:
        raise ValueError(f"A bit depth is 8, 16 or 32, not {depth}.")
    c = pixels.shape[2]
    if depth == 8:
        buf = io.BytesIO()
        arr = to_u8(pixels)
        Image.fromarray(np.ascontiguousarray(arr[..., 0] if c == 1 else arr), mode=PIL_MODES[c]).save(buf, "PNG")
        return buf.getvalue()
    if depth == 16:
        arr = to_u16(pixels)
        if c == 1:
            buf = io.BytesIO()
            Image.fromarray(np.ascontiguousarray(arr[..., 0])).save(buf, "PNG")
            return buf.getvalue()
        import imagecodecs
        return bytes(imagecodecs.png_encode(np.ascontiguousarray(arr), level=6))
    import tifffile
    lo, hi = value_range
    arr = np.ascontiguousarray((lo + pixels.astype(np.float64) * (hi - lo)).astype(np.float32))
    buf = io.BytesIO()
    extra = {"extrasamples": ["unassalpha"]} if c in (2, 4) else {}
    tifffile.imwrite(buf, arr[..., 0] if c == 1 else arr, photometric="rgb" if c >= 3 else "minisblack",
                     compression="zlib", predictor=True, **extra)
    return buf.getvalue()


def write_image(path: str, pixels: np.ndarray, depth: int = 8, value_range: tuple[float, float] = (0.0, 1.0)) -> None:
    """Write float pixels as an 8/16-bit PNG or a float TIFF (``encode_image``), atomically."""
    data = encode_image(pixels, depth, value_range)
    atomic_write(path, data)


def png_writer(pixels: np.ndarray):
    """A writer (file object -> None) of uint8 (H, W, C) pixels as a PNG."""
    arr = pixels[..., 0] if pixels.shape[2] == 1 else pixels
    img = Image.fromarray(np.ascontiguousarray(arr), mode=PIL_MODES[pixels.shape[2]])
    return lambda f: img.save(f, format="PNG")


def write_png(path: str, pixels: np.ndarray) -> None:
    """Write uint8 (H, W, C) pixels as a PNG, atomically (safeio.WriteError on failure)."""
    atomic_write(path, writer=png_writer(pixels))


PNG_MIN_CHUNK = 256  # average bytes per PNG chunk below which a file is refused (encoders write 8-64 KB)


def png_bit_depth(data: bytes) -> int:
    """The bit depth in a PNG's IHDR (0 if ``data`` is not a PNG)."""
    if data[:8] != b"\x89PNG\r\n\x1a\n" or len(data) < 29 or data[12:16] != b"IHDR":
        return 0
    return data[24]


def fragmented_png(data: bytes) -> int:
    """For a PNG cut into so many chunks that decoding them one by one would
    take minutes (1-byte IDAT chunks: 10^5 a second), the chunk count it
    exceeds (``len / PNG_MIN_CHUNK``, at least 4096), counted from the chunk
    headers alone; 0 otherwise (or not a PNG)."""
    if data[:8] != b"\x89PNG\r\n\x1a\n":
        return 0
    most = max(4096, len(data) // PNG_MIN_CHUNK)
    pos, count = 8, 0
    while pos + 8 <= len(data):
        count += 1
        if count > most:
            return most
        if data[pos + 4:pos + 8] == b"IEND":
            return 0
        pos += 12 + int.from_bytes(data[pos:pos + 4], "big")
    return 0
