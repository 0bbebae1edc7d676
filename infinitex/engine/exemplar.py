"""Exemplar import: any image Pillow reads, brought to a power-of-two square.

The synthesis needs an ``m x m`` exemplar with ``m = 2^L`` between 32 and 2048
(docs/algorithm.md section 1). Images that already are such squares (up to the
rule's limit) are used as they are. Anything else is brought there by one of
two rules, chosen by the user and never applied silently, each up to 512 px
(``"resize"``, ``"crop"``) or up to 2048 px (``"resize-2048"``,
``"crop-2048"``: large photos, analyzed with the random-walk search):

``"resize"`` (default)
    Center-crop the largest square (so the aspect ratio is never distorted),
    then resample it (Lanczos) to the power of two nearest to its side in
    log scale, clamped to 32..512 (or 2048). The square before resampling is kept as
    ``hires`` when it was larger, for synthesis magnification.
``"crop"``
    Center-crop a square whose side is the largest power of two that fits,
    at most 512 (or 2048). No resampling: pixels stay as they were.

Pixel values become float32 in [0, 1] with 1 (L), 2 (LA), 3 (RGB) or 4 (RGBA)
channels; 16-bit and float images keep their precision up to that point.

Image files are untrusted input. Only the raster decoders in :data:`DECODERS`
are given to Pillow (none of them starts a program: no EPS/Ghostscript), files
are read only if they are regular files of at most :data:`MAX_FILE_BYTES`, the
cost of an import is computed from the header and refused above
:data:`IMPORT_BUDGET` (JPEGs far larger than needed are decoded at 1/2 to 1/8
scale instead), the image is cropped before it is converted to floats, and
then converted one channel at a time. Every failure is an :class:`ExemplarError`.
"""
from __future__ import annotations

import contextlib
import hashlib
import io
import math
import os
from dataclasses import dataclass, field

import numpy as np
from PIL import Image, UnidentifiedImageError

from .imagefile import PNG_MIN_CHUNK, fragmented_png, png_bit_depth, to_u8
from .safeio import ReadError, printable, read_limited
from .tiffinfo import MAX_BLOCKS, block_bytes, block_count, is_tiff, loses_precision, quiet_libtiff, quiet_pillow_logs
from .wrap import guess_toroidal, seams_like_an_edge

MIN_SIZE = 32
SMALL_MIN = 4                        # seamless patterns from this size up are repeated to MIN_SIZE
MAX_SIZE = 2048                      # the largest exemplar side (the "-2048" fit rules)
DEFAULT_MAX = 512                    # the largest side the plain fit rules make
MAX_INPUT_PIXELS = 64 * 1024 * 1024  # 8192^2: bigger inputs are refused up front
MAX_FILE_BYTES = 512 * 1024 * 1024   # image files larger than this are not read
IMPORT_BUDGET = 1024 * 1024 * 1024   # bytes an import may use at its peak (file + decoded + floats)
HIRES_MAX = 2048                     # side of the full-resolution copy kept for magnification
FULL_MAX_PIXELS = 16 * 1024 * 1024   # a whole image kept unfitted (a lattice's input): 4096^2
# Pillow's pure raster decoders we accept (Pillow format IDs). Nothing that runs
# a program (EPS runs Ghostscript) or is a container of other formats.
DECODERS = ("PNG", "JPEG", "BMP", "TIFF", "WEBP", "TGA", "GIF", "PPM", "QOI", "SGI", "PCX")
FORMAT_NAMES = "PNG, JPEG, BMP, TIFF, WebP, TGA, GIF, PNM, QOI, SGI or PCX"
FIT_MODES = ("resize", "crop", "resize-2048", "crop-2048")


quiet_libtiff()
quiet_pillow_logs()


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
    depth: int = 8                     # the source's precision: 8, 16 (integer) or 32 (float) bits
    value_range: tuple[float, float] = (0.0, 1.0)  # pixel 0 and 1 in the source's units (float images)

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


def fit_rule(fit: str) -> tuple[str, int]:
    """("resize" or "crop", the largest side it makes) of a fit mode: the plain
    rules stop at DEFAULT_MAX (fast to analyze and synthesize), the "-2048" ones
    keep up to MAX_SIZE of a large photo."""
    if fit not in FIT_MODES:
        raise ExemplarError(f"Unknown fit rule {fit!r}; use one of {', '.join(FIT_MODES)}.")
    rule, _, limit = fit.partition("-")
    return rule, int(limit) if limit else DEFAULT_MAX


def _nearest_pow2(n: int, limit: int = DEFAULT_MAX) -> int:
    k = int(round(np.log2(max(n, 1))))
    return int(min(max(2 ** k, MIN_SIZE), limit))


def crop_box(w: int, h: int, fit: str) -> tuple[int, int, int]:
    """(x0, y0, side) of the square the fit rule starts from."""
    rule, limit = fit_rule(fit)
    if h == w and _is_pow2(w) and MIN_SIZE <= w <= limit:
        return 0, 0, w
    side = min(h, w)
    if rule == "crop":
        side = min(limit, 1 << (side.bit_length() - 1))
    return (w - side) // 2, (h - side) // 2, side


_U8_TO_FLOAT = [float(np.float32(i) / np.float32(255.0)) for i in range(256)]  # = float32(i) / 255


def _f_image(plane: np.ndarray) -> Image.Image:
    """A float32 (h, w) array as a Pillow "F" image (a copy)."""
    plane = np.ascontiguousarray(plane, dtype=np.float32)
    return Image.frombuffer("F", (plane.shape[1], plane.shape[0]), plane, "raw", "F", 0, 1)


def _lanczos(plane: Image.Image, size: int) -> np.ndarray:
    return np.clip(np.asarray(plane.resize((size, size), Image.LANCZOS)), 0.0, 1.0).astype(np.float32)


def _fit_planes(planes, side: int, fit: str) -> tuple[np.ndarray, np.ndarray | None]:
    """Apply the resample part of the fit rule one channel at a time.

    ``planes`` yields Pillow "F" images (side x side) in [0, 1]; returns the
    exemplar (m, m, C) and the hires copy (at most HIRES_MAX a side) or None.
    """
    rule, limit = fit_rule(fit)
    target = _nearest_pow2(side, limit) if rule == "resize" else side
    out, hires = [], []
    for plane in planes:
        if target == side:
            out.append(np.asarray(plane, dtype=np.float32))
            continue
        out.append(_lanczos(plane, target))
        if side > target:
            hires.append(np.asarray(plane, dtype=np.float32) if side <= HIRES_MAX else _lanczos(plane, HIRES_MAX))
        del plane
    px = np.ascontiguousarray(np.stack(out, axis=2), dtype=np.float32)
    hi = np.ascontiguousarray(np.stack(hires, axis=2), dtype=np.float32) if hires else None
    return px, hi


def fit_square(arr: np.ndarray, fit: str) -> tuple[np.ndarray, np.ndarray | None]:
    """Apply the documented fit rule; returns (exemplar, hires or None)."""
    h, w = arr.shape[:2]
    x0, y0, side = crop_box(w, h, fit)
    sq = arr[y0:y0 + side, x0:x0 + side]
    return _fit_planes((_f_image(sq[:, :, c]) for c in range(sq.shape[2])), side, fit)


def _finish(px: np.ndarray, hires, fit: str, toroidal: bool | None, source: str,
            size: tuple[int, int], depth: int = 8, value_range: tuple[float, float] = (0.0, 1.0)) -> Exemplar:
    if not np.all(np.isfinite(px)):
        raise ExemplarError("The exemplar holds values that are not numbers (NaN or infinity).")
    guess = guess_toroidal(px)
    return Exemplar(pixels=px, toroidal=guess if toroidal is None else bool(toroidal),
                    toroidal_guess=guess, source=source, fit=fit, original_size=size, hires=hires,
                    depth=depth, value_range=value_range)


def small_pattern(px: np.ndarray, toroidal: bool | None) -> np.ndarray:
    """A pattern smaller than MIN_SIZE that tiles seamlessly (its wrap-around
    seams match, or look like one of its own edges, or ``toroidal`` says so), repeated to the smallest square of
    whole periods that is at least MIN_SIZE: nothing is lost, the result tiles.
    Anything else smaller than MIN_SIZE is an ExemplarError."""
    h, w = px.shape[:2]
    tiles = toroidal if toroidal is not None else (min(h, w) >= 2 and (guess_toroidal(px) or seams_like_an_edge(px)))
    side = math.lcm(w, h)
    if not tiles:
        raise ExemplarError(f"The exemplar is {w}x{h} px; it must be at least {MIN_SIZE}x{MIN_SIZE} px (a smaller "
                            "pattern is accepted when it tiles seamlessly; Toroidal: yes forces that).")
    if min(w, h) < SMALL_MIN or side > DEFAULT_MAX:
        raise ExemplarError(f"The pattern is {w}x{h} px; a seamless pattern must be at least {SMALL_MIN}x{SMALL_MIN} "
                            f"px, and its repeat ({side} px) at most {DEFAULT_MAX} px.")
    side *= -(-MIN_SIZE // side)
    sq = np.tile(px, (side // h, side // w, 1))
    m = _nearest_pow2(side)
    if m == side:
        return np.ascontiguousarray(sq, dtype=np.float32)
    # Resample periodically: the 3 x 3 repetition resized, its middle kept (no seam).
    big = np.tile(sq, (3, 3, 1))
    planes = [np.asarray(_f_image(big[:, :, c]).resize((3 * m, 3 * m), Image.LANCZOS))[m:2 * m, m:2 * m]
              for c in range(big.shape[2])]
    return np.ascontiguousarray(np.clip(np.stack(planes, axis=2), 0.0, 1.0), dtype=np.float32)


def unit_values(arr) -> np.ndarray:
    """An image array as float32 in [0, 1]: unsigned integers are read on
    their type's full range (uint8 / 255, uint16 / 65535), floats as they are
    (values a little outside [0, 1] are clipped later). Floats far outside
    [0, 1], usually 8-bit values in a float array, raise ExemplarError rather
    than come out white."""
    a = np.asarray(arr)
    if a.dtype == np.bool_ or (a.dtype.kind == "i" and a.size and (a.min() < 0 or a.max() > 1)):
        raise ExemplarError(f"An exemplar array of {a.dtype} is ambiguous: pass uint8 (0-255), uint16 "
                            "(0-65535) or floats in [0, 1].")
    if a.dtype.kind == "u":
        return (a.astype(np.float64) / np.iinfo(a.dtype).max).astype(np.float32)
    a = a.astype(np.float32)
    finite = a[np.isfinite(a)]
    if finite.size and (finite.max() > 1.5 or finite.min() < -0.5):
        raise ExemplarError(f"An exemplar array of floats must hold values in [0, 1]; this one goes from "
                            f"{finite.min():g} to {finite.max():g} (8-bit values? divide by 255 or pass uint8).")
    return a


def from_array(arr: np.ndarray, *, fit: str = "resize", toroidal: bool | None = None,
               source: str = "<array>") -> Exemplar:
    """Build an exemplar from an array (H, W) or (H, W, C): floats in [0, 1],
    or unsigned integers on their type's range (:func:`unit_values`)."""
    arr = unit_values(arr)
    if arr.ndim == 2:
        arr = arr[:, :, None]
    if arr.ndim != 3 or arr.shape[2] not in (1, 2, 3, 4):
        raise ExemplarError(f"An exemplar needs 1 to 4 channels; this one has shape {arr.shape}.")
    h, w = arr.shape[:2]
    if h == 0 or w == 0:
        raise ExemplarError("The exemplar image is empty (0 pixels).")
    if not np.all(np.isfinite(arr)):
        raise ExemplarError("The exemplar holds values that are not numbers (NaN or infinity).")
    arr = np.clip(arr, 0.0, 1.0)
    if min(h, w) < MIN_SIZE:
        arr = small_pattern(arr, toroidal)
        toroidal = True if toroidal is None else toroidal
    px, hires = fit_square(arr, fit)
    return _finish(px, hires, fit, toroidal, source, (w, h))


def load_exemplar(path: str | os.PathLike, *, fit: str = "resize",
                  toroidal: bool | None = None) -> Exemplar:
    """Read an image file as an exemplar, or raise :class:`ExemplarError`."""
    path = os.fspath(path)
    name = printable(os.path.basename(path) or path)
    try:
        data = read_limited(path, MAX_FILE_BYTES, "image")
    except ReadError as exc:
        raise ExemplarError(str(exc)) from None
    if not data:
        raise ExemplarError(f"{name} is empty (0 bytes).")
    return _decode(data, name, fit, toroidal, path)


def load_exemplar_bytes(data: bytes, *, name: str = "exemplar", fit: str = "resize",
                        toroidal: bool | None = None) -> Exemplar:
    """Decode an image held in memory (e.g. embedded in a project file)."""
    name = printable(name)
    if not data:
        raise ExemplarError(f"{name} is empty (0 bytes).")
    if len(data) > MAX_FILE_BYTES:
        raise ExemplarError(f"{name} is larger than the {MAX_FILE_BYTES // 2**20} MB an image may be.")
    return _decode(data, name, fit, toroidal, name)


# Pillow modes -> the mode the channels are read in.
_CANONICAL = {"1": "L", "P": None, "PA": "RGBA", "La": "LA", "RGBa": "RGBA", "RGBX": "RGB",
              "CMYK": "RGB", "YCbCr": "RGB", "LAB": "RGB", "HSV": "RGB"}
_CHANNELS = {"L": 1, "LA": 2, "RGB": 3, "RGBA": 4, "I": 1, "F": 1}


def _pixel_bytes(mode: str) -> int:
    """Bytes per pixel Pillow uses in memory for ``mode`` (multi-band modes use 4)."""
    if mode in ("1", "L", "P"):
        return 1
    if mode.startswith("I;16"):
        return 2
    return 4


# Peak memory of a decoder relative to the decoded image (measured): Pillow's
# WebP decoder holds libwebp's canvas and a copy of each frame besides the image.
_DECODE_FACTOR = {"WEBP": 4}


def import_cost(w: int, h: int, mode: str, file_bytes: int, fit: str, fmt: str = "") -> int:
    """An upper bound of the bytes an import of a w x h image needs at its peak:
    the file, the decoder's peak, the cropped square and its mode conversion, one channel (8/16-bit and
    float), Lanczos' intermediate and the hires copy."""
    _x0, _y0, side = crop_box(w, h, fit)
    pb = _pixel_bytes(mode)
    sq = side * side
    decode = w * h * pb * _DECODE_FACTOR.get(fmt, 1)
    crop = sq * pb if (side, side) != (w, h) else 0
    convert = sq * 4 if mode in _CANONICAL else 0
    channel = sq * (2 + 4)
    rule, limit = fit_rule(fit)
    target = _nearest_pow2(side, limit) if rule == "resize" else side
    keep = min(side, HIRES_MAX)
    resample = side * max(target, keep) * 4 if target != side else 0
    hires = 4 * 4 * keep * keep if target != side else 0
    return file_bytes + decode + crop + convert + channel + resample + hires + (16 << 20)


def _normalization(img: Image.Image) -> tuple[float, float] | None:
    """(offset, scale) mapping a 32-bit or 16-bit integer or float image to [0, 1],
    from the whole image (before any crop); None for 8-bit modes."""
    mode = img.mode
    if mode == "F":
        lo, hi = math.inf, -math.inf
        for _y, rows in _row_chunks(img):
            if not np.all(np.isfinite(rows)):
                raise ExemplarError("The exemplar holds values that are not numbers (NaN or infinity).")
            lo, hi = min(lo, float(rows.min())), max(hi, float(rows.max()))
        return lo, (hi - lo if hi > lo else 1.0)
    if mode.startswith("I;16"):
        return 0.0, 65535.0
    if mode == "I":
        hi = img.getextrema()[1]
        return 0.0, 65535.0 if hi <= 65535 else float(hi)
    return None


def _row_chunks(img: Image.Image, chunk_bytes: int = 1 << 22):
    """(y, array) of bands of rows of a one-band image, about ``chunk_bytes`` each."""
    w, h = img.size
    step = max(1, chunk_bytes // (4 * max(1, w)))
    for y in range(0, h, step):
        yield y, np.asarray(img.crop((0, y, w, min(h, y + step))))


def _planes(img: Image.Image, norm: tuple[float, float] | None):
    """The channels of an image in a canonical mode as Pillow "F" images in
    [0, 1], one at a time (8-bit: x / 255 in float32 through a lookup table)."""
    mode = img.mode
    if norm is None:
        for band in range(len(mode)):
            yield img.getchannel(band).point(_U8_TO_FLOAT, "F")
        return
    lo, scale = norm
    out = Image.new("F", img.size)
    for y, rows in _row_chunks(img):
        r = rows.astype(np.float64)
        if mode != "F":
            r = np.clip(r, 0, scale)
        out.paste(_f_image(((r - lo) / scale).astype(np.float32)), (0, y))
    yield out


@contextlib.contextmanager
def decoding(name: str):
    """Every failure inside a decoder becomes one ExemplarError sentence naming ``name``."""
    try:
        yield
    except ExemplarError:
        raise
    except MemoryError:
        raise ExemplarError(f"Not enough memory to import {name}.") from None
    except Image.DecompressionBombError:
        raise ExemplarError(f"{name} is too large to import safely.") from None
    except UnidentifiedImageError:
        raise ExemplarError(f"{name} is not an image format Infinitex reads ({FORMAT_NAMES}).") from None
    except Exception as exc:  # any other failure inside a decoder: the file is damaged
        detail = printable(exc, 160) or type(exc).__name__
        raise ExemplarError(f"{name} could not be read: the file looks damaged ({detail}).") from None


def open_image(data: bytes, name: str) -> Image.Image:
    """The image in ``data``, opened with the allow-listed decoders only and its
    size checked from the header (nothing decoded yet). Use inside decoding."""
    most = fragmented_png(data)
    if most:
        raise ExemplarError(f"{name} is cut into more than {most} PNG chunks (under {PNG_MIN_CHUNK} bytes each "
                            "on average): too fragmented to decode in reasonable time; save it again.")
    img = Image.open(io.BytesIO(data), formats=DECODERS)
    w, h = img.size
    if w * h > MAX_INPUT_PIXELS:
        img.close()
        raise ExemplarError(f"{name} is {w}x{h} px, too large to import (at most {MAX_INPUT_PIXELS // 2**20} Mpixels).")
    if w <= 0 or h <= 0:
        img.close()
        raise ExemplarError(f"{name} has no pixels.")
    if img.format == "TIFF":
        try:
            check_tiff_blocks(img.tag_v2, name, len(data) + w * h * _pixel_bytes(img.mode))
        except ExemplarError:
            img.close()
            raise
    return img


def check_tiff_blocks(tags, name: str, other: int = 0) -> None:
    """Refuse a TIFF whose tiles or strips (from its header, before any
    decoding) would make the decoder allocate, with ``other`` bytes already
    counted, more than IMPORT_BUDGET."""
    block, what = block_bytes(tags)
    if block_count(tags) > MAX_BLOCKS:
        raise ExemplarError(f"{name} is cut into {block_count(tags):,} {what}; at most {MAX_BLOCKS:,} are read (save "
                            "it with larger tiles or strips).")
    if block + other > IMPORT_BUDGET:
        raise ExemplarError(f"{name} claims {what}, so decoding it would need about {(block + other) // 2**20} MB, "
                            f"more than the {IMPORT_BUDGET // 2**20} MB an import may use; it is not read.")


def _decode(data: bytes, name: str, fit: str, toroidal: bool | None, source: str) -> Exemplar:
    fit_rule(fit)
    info: dict = {}
    px, hires, size = _decode_pixels(data, name, fit, toroidal, info)
    if min(size) < MIN_SIZE and toroidal is None:
        toroidal = True  # a small pattern is accepted only when it tiles, and repeated it still does
    return _finish(px, hires, fit, toroidal, source, size, info.get("depth", 8), info.get("range", (0.0, 1.0)))


def decode_full(data: bytes, name: str = "image") -> np.ndarray:
    """The whole image (float32 (H, W, C) in [0, 1]), not fitted: the input of
    a lattice (whose vectors are in its pixels). Same safeguards as exemplars;
    at most FULL_MAX_PIXELS."""
    name = printable(name)
    if not data:
        raise ExemplarError(f"{name} is empty (0 bytes).")
    px, _, _ = _decode_pixels(data, name, "full")
    if not np.all(np.isfinite(px)):
        raise ExemplarError("The image holds values that are not numbers (NaN or infinity).")
    return px


def load_full(path: str | os.PathLike) -> np.ndarray:
    """:func:`decode_full` of an image file."""
    path = os.fspath(path)
    try:
        data = read_limited(path, MAX_FILE_BYTES, "image")
    except ReadError as exc:
        raise ExemplarError(str(exc)) from None
    return decode_full(data, os.path.basename(path) or path)


def _fit_decoded(px: np.ndarray, fit: str, toroidal: bool | None, size: tuple[int, int]):
    """(pixels, hires or None, size) of a whole decoded image by the fit rule
    ("full": as it is; a small seamless pattern is repeated first)."""
    if fit == "full":
        return px, None, size
    if min(size) < MIN_SIZE:
        px = small_pattern(px, toroidal)
    out, hires = fit_square(px, fit)
    return out, hires, size


def _decode_png16(data: bytes, name: str, fit: str, toroidal: bool | None, w: int, h: int, info: dict):
    """A 16-bit color PNG, which Pillow would read as 8 bits, decoded at full
    precision by imagecodecs (the README says why it is a dependency)."""
    import imagecodecs
    cost = len(data) + w * h * 4 * (2 + 4 + 4) + (16 << 20)
    if cost > IMPORT_BUDGET:
        raise ExemplarError(f"{name} ({w}x{h} px, 16-bit color) would need about {cost // 2**20} MB to import, "
                            f"more than the {IMPORT_BUDGET // 2**20} MB allowed; reduce it first.")
    a = imagecodecs.png_decode(data)
    if a.ndim == 2:
        a = a[:, :, None]
    if a.shape[:2] != (h, w) or a.dtype != np.uint16:
        raise ExemplarError(f"{name} could not be read: the file looks damaged (its header and pixels disagree).")
    info.update(depth=16, range=(0.0, 1.0))
    px = np.empty(a.shape, dtype=np.float32)
    for c in range(a.shape[2]):
        px[:, :, c] = a[:, :, c] / np.float32(65535.0)
    del a
    return _fit_decoded(px, fit, toroidal, (w, h))


def _decode_tiff_multi(data: bytes, name: str, fit: str, toroidal: bool | None, info: dict):
    """A TIFF Pillow cannot read or would read as 8 bits (2 to 4 channels of
    16-bit integers or floats: normal maps, float heights...) through tifffile
    at full precision, with the same size and memory limits."""
    import tifffile
    with tifffile.TiffFile(io.BytesIO(data)) as tif:
        page = tif.pages.first
        shape, dtype = tuple(page.shape), np.dtype(page.dtype)
        planar = len(shape) == 3 and int(page.planarconfig) == 2
        if planar:  # (samples, h, w)
            shape = (*shape[1:], shape[0])
        elif len(shape) == 3 and shape[0] <= 4 < shape[2]:
            raise ExemplarError(f"{name}: planar (channel-first) TIFFs are not supported; save it interleaved.")
        if len(shape) not in (2, 3) or (len(shape) == 3 and not 1 <= shape[2] <= 4) \
                or dtype.kind not in "uf" or dtype.itemsize > 8:
            raise ExemplarError(f"{name}: this TIFF layout ({'x'.join(map(str, shape))} {dtype}) is not supported.")
        h, w = shape[:2]
        if w * h > MAX_INPUT_PIXELS:
            raise ExemplarError(f"{name} is {w}x{h} px, too large to import (at most {MAX_INPUT_PIXELS // 2**20} Mpixels).")
        c = shape[2] if len(shape) == 3 else 1
        cost = len(data) + w * h * c * (dtype.itemsize + 8 + 4) + (16 << 20)
        check_tiff_blocks({t.code: t.value for t in page.tags.values()}, name, cost)
        if cost > IMPORT_BUDGET:
            raise ExemplarError(f"{name} ({w}x{h} px, {c} x {dtype}) would need about {cost // 2**20} MB to import, "
                                f"more than the {IMPORT_BUDGET // 2**20} MB allowed; reduce it first.")
        bits = int(page.bitspersample)
        a = page.asarray()
    a = (np.moveaxis(a.reshape(c, h, w), 0, -1) if planar else a).reshape(h, w, c)
    if dtype.kind == "f":
        if not np.all(np.isfinite(a)):
            raise ExemplarError("The exemplar holds values that are not numbers (NaN or infinity).")
        lo, hi = float(a.min()), float(a.max())
        scale = hi - lo if hi > lo else 1.0
        px = ((a.astype(np.float64) - lo) / scale).astype(np.float32)
        info.update(depth=32, range=(lo, lo + scale))
    else:
        top = float((1 << bits) - 1) if 8 < bits < 8 * dtype.itemsize or dtype.itemsize <= 2 \
            else max(1.0, float(a.max()))
        px = np.minimum(a / top, 1.0).astype(np.float32)
        info.update(depth=8 if dtype.itemsize == 1 else 16, range=(0.0, 1.0))
    del a
    return _fit_decoded(px, fit, toroidal, (w, h))


def _decode_pixels(data: bytes, name: str, fit: str, toroidal: bool | None = None, info: dict | None = None):
    """(pixels, hires or None, original size) by a fit rule, or "full". ``info``
    receives the source's "depth" (8, 16, 32) and "range" (pixel 0 and 1 in its units)."""
    full = fit == "full"
    info = {} if info is None else info
    with decoding(name):
        try:
            im0 = open_image(data, name)
        except UnidentifiedImageError:
            if is_tiff(data):  # a TIFF Pillow cannot read: 2 to 4 channels of 16-bit integers or floats
                return _decode_tiff_multi(data, name, fit, toroidal, info)
            raise
        with im0:
            if im0.format == "TIFF" and loses_precision(im0.tag_v2):  # 16-bit RGB...: Pillow reads 8 bits
                im0.close()
                return _decode_tiff_multi(data, name, fit, toroidal, info)
            if im0.format == "PNG" and im0.mode in ("RGB", "RGBA", "LA") and png_bit_depth(data) == 16:
                w, h = im0.size
                im0.close()
                return _decode_png16(data, name, fit, toroidal, w, h, info)
            w, h = im0.size
            small = min(w, h) < MIN_SIZE and not full  # a small seamless pattern: repeated (small_pattern)
            size = (w, h)
            side = min(w, h)
            if full and w * h > FULL_MAX_PIXELS:
                raise ExemplarError(f"{name} is {w}x{h} px; a lattice image may have at most "
                                    f"{FULL_MAX_PIXELS // 2**20} Mpixels (reduce it first).")
            if not full and fit_rule(fit)[0] == "resize" and im0.format == "JPEG" and side >= 2 * HIRES_MAX:
                # Far more pixels than we keep: let libjpeg decode at 1/2..1/8 scale.
                im0.draft(im0.mode, (max(1, w * HIRES_MAX // side), max(1, h * HIRES_MAX // side)))
                w, h = im0.size
            cost = import_cost(w, h, im0.mode, len(data), "crop" if full else fit, im0.format or "")
            if full:
                cost += 4 * 4 * w * h  # every channel kept at full size
            if cost > IMPORT_BUDGET:
                raise ExemplarError(f"{name} ({w}x{h} px, mode {im0.mode}) would need about "
                                    f"{cost // 2**20} MB to import, more than the "
                                    f"{IMPORT_BUDGET // 2**20} MB allowed; reduce it first.")
            im0.load()
            norm = _normalization(im0)
            if norm is not None:
                info.update(depth=32 if im0.mode == "F" else 16,
                            range=(norm[0], norm[0] + norm[1]) if im0.mode == "F" else (0.0, 1.0))
            x0, y0, side = (0, 0, 0) if full or small else crop_box(w, h, fit)
            img = im0 if full or small or (side, side) == (w, h) else im0.crop((x0, y0, x0 + side, y0 + side))
        del im0
        mode = img.mode
        if mode in _CANONICAL:
            target = _CANONICAL[mode] or ("RGBA" if "transparency" in img.info else "RGB")
            img = img.convert(target)
        elif not (mode in _CHANNELS or mode.startswith("I;16")):
            raise ExemplarError(f"{name}: images in Pillow mode {printable(mode)!r} are not supported.")
        if full or small:
            px = np.ascontiguousarray(np.stack([np.asarray(p, dtype=np.float32) for p in _planes(img, norm)],
                                               axis=2))
            return _fit_decoded(px, fit, toroidal, size)
        px, hires = _fit_planes(_planes(img, norm), side, fit)
        del img
    return px, hires, size
