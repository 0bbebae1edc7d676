"""The files of exports: PNG and TIFF tile encodings, UDIM tile names, the
exact exemplar-coordinate map (``encode_coords``), the rendering of one tile
(``encode_tile``) and checks of output paths."""
from __future__ import annotations

import io
import os
import zlib

import numpy as np

from infinitex.engine.imagefile import PIL_MODES, to_u8
from infinitex.engine.pyramid import Rect
from infinitex.engine.safeio import WriteError, check_output, printable

ZLIB_LEVEL = 6


def udim_name(base: str, col: int, row: int, cols: int) -> str:
    """The file of tile (col, row): ``BASE.1001.png`` style, or ``BASE_u1_v1.png`` past 10 columns."""
    if cols <= 10:
        return f"{base}.{1001 + col + 10 * row}.png"
    return f"{base}_u{col + 1}_v{row + 1}.png"


def encode_coords(coords: np.ndarray) -> np.ndarray:
    """Exemplar coordinates as an exact RGB8 image: R = x mod 256, G = y mod 256,
    B = (x >> 8) + 16 * (y >> 8). Decode: x = R + 256 * (B & 15), y = G + 256 * (B >> 4)."""
    x, y = coords[..., 0], coords[..., 1]
    return np.stack([x & 255, y & 255, (x >> 8) + 16 * (y >> 8)], axis=-1).astype(np.uint8)


def decode_coords(rgb: np.ndarray) -> np.ndarray:
    rgb = rgb.astype(np.int32)
    return np.stack([rgb[..., 0] + 256 * (rgb[..., 2] & 15), rgb[..., 1] + 256 * (rgb[..., 2] >> 4)], axis=-1)


def png_bytes(pixels: np.ndarray) -> bytes:
    """uint8 (H, W, C) pixels as PNG file bytes."""
    from PIL import Image
    arr = pixels[..., 0] if pixels.shape[2] == 1 else pixels
    buf = io.BytesIO()
    Image.fromarray(np.ascontiguousarray(arr), mode=PIL_MODES[pixels.shape[2]]).save(buf, format="PNG")
    return buf.getvalue()


def tiff_tile_bytes(pixels: np.ndarray, tile: int) -> bytes:
    """One TIFF tile as stored: padded to ``tile x tile``, horizontal
    predictor (TIFF predictor 2: each sample minus its left neighbour, mod
    256), zlib-compressed."""
    h, w, c = pixels.shape
    a = np.zeros((tile, tile, c), dtype=np.uint8)
    a[:h, :w] = pixels
    d = a.copy()
    d[:, 1:] -= a[:, :-1]
    return zlib.compress(d.tobytes(), ZLIB_LEVEL)


def check_zarr_output(path: str) -> str:
    """A Zarr store's path before any work (a folder ``NAME.zarr``): its parent
    exists and is writable; an existing one must be a Zarr store (it is
    replaced when the new one is complete). Raises WriteError with a sentence."""
    shown = printable(path)
    real = os.path.realpath(path)
    if os.path.splitext(path)[1].lower() != ".zarr":
        raise WriteError(f"The Zarr store {shown} must end in .zarr.")
    if os.path.lexists(real):
        if not (os.path.isdir(real) and os.path.isfile(os.path.join(real, ".zgroup"))):
            raise WriteError(f"{shown} exists and is not a Zarr store; it is not overwritten.")
        return path
    check_output(path, (".zarr",), "Zarr store")
    return path


def encode_tile(synth, fmt: str, tile: int, r: Rect, coords: bool = False, level: int | None = None) -> list[bytes]:
    """Render one tile (``r`` in the pixels of synthesis ``level``, default the
    finest): the bytes of its texture file (and coordinate map); for zarr the
    raw (H, W, C) uint8 pixels, which this process writes into the store."""
    c = synth.window(r, level)
    colors = synth.colors(c, level)
    if synth.normals and synth.controls.directed:  # a normal map turns with the texture
        from infinitex.engine.subpixel import turn_normals
        lv = synth.L if level is None else level
        jac = synth.controls.direction.region(synth.L - lv, r.x0, r.y0, r.w, r.h, synth.params.period)
        colors = colors if jac is None else turn_normals(colors, jac)
    maps = [to_u8(colors)]
    if coords:
        maps.append(encode_coords(c))
    if fmt == "zarr":
        return [np.ascontiguousarray(m).tobytes() for m in maps]
    return [png_bytes(m) if fmt == "tiles" else tiff_tile_bytes(m, tile) for m in maps]


def read_tiles(out: str, rect_w: int, rect_h: int, tile: int, channels: int) -> np.ndarray:
    """A tile set written by TiledExport, put back together (tests, small sets)."""
    cols, rows = -(-rect_w // tile), -(-rect_h // tile)
    base = os.path.splitext(out)[0]
    img = np.zeros((rect_h, rect_w, channels), dtype=np.uint8)
    from PIL import Image
    for row in range(rows):
        for col in range(cols):
            a = np.asarray(Image.open(udim_name(base, col, row, cols)))
            a = a[..., None] if a.ndim == 2 else a
            img[row * tile:row * tile + a.shape[0], col * tile:col * tile + a.shape[1]] = a
    return img
