"""What a TIFF's header says before anything is decoded (TIFF files are
untrusted input, read by :mod:`engine.exemplar` and :mod:`engine.controls.maps`).

- :func:`block_bytes`: the memory a decoder allocates for one tile or strip.
  libtiff (through Pillow) and tifffile allocate a whole tile or strip before
  reading it, and a tile's size is whatever the header claims (a 688-byte file
  can claim tiles 16,777,216 px wide): it is checked against the import budget
  before any decoding. A strip never holds more rows than the image.
- :func:`block_count`: how many tiles or strips a decoder walks (bounded:
  MAX_BLOCKS), also from the header.
- :func:`loses_precision`: a TIFF that Pillow would read as 8 bits though it
  holds more (2 to 4 samples of 16 bits: normal maps, RGB heights); such files
  are decoded through tifffile at full precision.
- :func:`quiet_libtiff`: libtiff's own warnings about damaged files are not
  printed (the import's one-line error says what matters).
"""
from __future__ import annotations

import io

WIDTH, LENGTH, BITS, PHOTOMETRIC, SAMPLES, ROWS_PER_STRIP, PLANAR, TILE_WIDTH, TILE_LENGTH = (
    256, 257, 258, 262, 277, 278, 284, 322, 323)


def quiet_pillow_logs() -> None:
    """Pillow logs some refusals (a TIFF's samples per pixel beyond its
    limit) as errors before raising them; with no logging set up, Python's
    last-resort handler printed them on stderr above our one-line message. A
    NullHandler on Pillow's logger ends that; an application that configures
    logging still receives them (they propagate)."""
    import logging
    logging.getLogger("PIL").addHandler(logging.NullHandler())


def quiet_libtiff() -> None:
    """Stop libtiff printing warnings and errors about damaged TIFFs on stderr.

    Pillow turns libtiff's failures into exceptions (which become one-line
    errors), but libtiff's default handlers also print lines of their own
    to the process's stderr. Its handlers are process-wide; clearing them needs
    the libtiff that Pillow loaded (found in /proc/self/maps, so Linux only)."""
    try:
        import ctypes

        from PIL import TiffImagePlugin  # noqa: F401  (loads libtiff with Pillow's core)
        with open("/proc/self/maps", encoding="utf-8", errors="replace") as f:
            libs = {line.split()[-1] for line in f if "libtiff" in line and ".so" in line}
        for lib in libs:
            tiff = ctypes.CDLL(lib)
            for name in ("TIFFSetWarningHandler", "TIFFSetErrorHandler"):
                fn = getattr(tiff, name)
                fn.restype = ctypes.c_void_p
                fn.argtypes = [ctypes.c_void_p]
                fn(None)
    except (OSError, AttributeError, ImportError):
        pass


def is_tiff(data: bytes) -> bool:
    return data[:4] in (b"II*\x00", b"MM\x00*", b"II+\x00", b"MM\x00+")


def _int(tags, code: int, default: int = 0) -> int:
    """A tag's value as a non-negative int (the largest of several), ``default`` if absent or not a number."""
    v = tags.get(code)
    if v is None:
        return default
    try:
        vals = [int(x) for x in v] if isinstance(v, (tuple, list)) else [int(v)]
    except (TypeError, ValueError):
        return default
    return max(0, max(vals)) if vals else default


def block_bytes(tags) -> tuple[int, str]:
    """(bytes, what) of the largest tile or strip buffer a decoder allocates
    for the image whose tags (a mapping of tag code to value: Pillow's
    ``tag_v2``, or tifffile's page tags) are given: the block's pixels in
    their samples and bytes, plus the 4-byte RGBA copy libtiff may make of it."""
    width, length = _int(tags, WIDTH), _int(tags, LENGTH)
    samples = max(1, _int(tags, SAMPLES, 1))
    nbytes = max(1, -(-_int(tags, BITS, 8) // 8))
    planes = 1 if _int(tags, PLANAR, 1) == 2 else samples
    if TILE_WIDTH in tags or TILE_LENGTH in tags:
        bw, bl = _int(tags, TILE_WIDTH), _int(tags, TILE_LENGTH)
        what = f"tiles of {bw}x{bl} px"
    else:
        bw, bl = width, min(_int(tags, ROWS_PER_STRIP, length) or length, length)
        what = f"strips of {bw}x{bl} px"
    return bw * bl * (planes * nbytes + 4), what


MAX_BLOCKS = 65_536  # tiles or strips an import decodes (each costs a decoder call: ~20 us, more under load)


def block_count(tags) -> int:
    """How many tiles or strips the image is cut into (per plane for planar
    images): a 64-Mpixel image of 16 x 16 tiles is 262,144 decoder calls."""
    width, length = _int(tags, WIDTH), _int(tags, LENGTH)
    if TILE_WIDTH in tags or TILE_LENGTH in tags:
        bw, bl = max(1, _int(tags, TILE_WIDTH)), max(1, _int(tags, TILE_LENGTH))
    else:
        bw, bl = max(1, width), max(1, min(_int(tags, ROWS_PER_STRIP, length) or length, length))
    planes = max(1, _int(tags, SAMPLES, 1)) if _int(tags, PLANAR, 1) == 2 else 1
    return -(-width // bw) * -(-length // bl) * planes


def loses_precision(tags) -> bool:
    """True for gray or RGB with 2 to 4 samples of more than 8 bits: Pillow
    reads those as 8-bit images."""
    return 2 <= _int(tags, SAMPLES, 1) <= 4 and _int(tags, BITS, 8) > 8 and _int(tags, PHOTOMETRIC, -1) in (1, 2)


def page_tags(data: bytes) -> dict:
    """{code: value} of the first image's tags, read by tifffile (no pixels decoded)."""
    import tifffile
    with tifffile.TiffFile(io.BytesIO(data)) as tif:
        return {t.code: t.value for t in tif.pages.first.tags.values()}
