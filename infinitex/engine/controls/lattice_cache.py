"""The lattice search's answers kept on disk beside the analyses
(``INFINITEX_CACHE``): an image searched once is not searched again, and a
command or an editor opening it again does not even import the search
(scipy). The key is the image's exact pixels and the search's own source
files, so a changed search never answers from an old entry; a damaged or
foreign entry is searched again and replaced."""
from __future__ import annotations

import functools
import hashlib
import json
import math
import os
import time
from dataclasses import replace

import numpy as np

from .lattice import Detection, Lattice

_HERE = os.path.dirname(os.path.abspath(__file__))
_SEARCH_FILES = ("lattice.py", "lattice_detect.py", "lattice_correlation.py", "lattice_block.py", "lattice_cache.py")
_MAX_ENTRY = 1 << 16  # bytes: an entry is a few hundred


@functools.cache
def _search_digest() -> bytes:
    """The search's own source, read once a process."""
    h = hashlib.sha256()
    for name in _SEARCH_FILES:
        with open(os.path.join(_HERE, name), "rb") as fh:
            h.update(fh.read())
    return h.digest()


def cache_key(pixels: np.ndarray) -> str:
    img = np.ascontiguousarray(pixels)
    h = hashlib.sha256(_search_digest())
    h.update(f"{img.shape}|{img.dtype.str}".encode())
    h.update(img.tobytes())
    return h.hexdigest()[:32]


def _pair(v) -> tuple[float, float] | None:
    return None if v is None else (float(v[0]), float(v[1]))


def to_json(found: Detection) -> dict:
    lat = found.lattice
    return {"lattice": None if lat is None else {"origin": _pair(lat.origin), "t1": _pair(lat.t1), "t2": _pair(lat.t2),
                                                 "nx": int(lat.nx), "ny": int(lat.ny), "levels": lat.levels},
            "confidence": float(found.confidence), "seconds": float(found.seconds),
            "t1": _pair(found.t1), "t2": _pair(found.t2)}


def _finite(x) -> bool:
    return isinstance(x, (int, float)) and not isinstance(x, bool) and math.isfinite(x)


def _finite_pair(v) -> tuple[float, float]:
    if not (isinstance(v, list) and len(v) == 2 and all(_finite(x) for x in v)):
        raise ValueError("not a pair of numbers")
    return float(v[0]), float(v[1])


def from_json(d, check: bool = True) -> Detection:
    """The Detection of an entry; ValueError for anything else (``check``: the
    lattice's shape too, as for any lattice read from a file)."""
    if not isinstance(d, dict):
        raise ValueError("not an entry")
    lat = d.get("lattice")
    if lat is not None:
        if not isinstance(lat, dict):
            raise ValueError("not a lattice")
        counts = [lat.get("nx"), lat.get("ny")]
        levels = lat.get("levels")
        if not all(type(n) is int for n in counts) or not (levels is None or type(levels) is int):
            raise ValueError("not a lattice")
        lat = Lattice(_finite_pair(lat.get("origin")), _finite_pair(lat.get("t1")), _finite_pair(lat.get("t2")),
                      counts[0], counts[1], levels)
        if check:
            lat.check_shape()
    conf, secs = d.get("confidence"), d.get("seconds")
    if not (_finite(conf) and _finite(secs)):
        raise ValueError("not a confidence")
    t1, t2 = (None if d.get(k) is None else _finite_pair(d.get(k)) for k in ("t1", "t2"))
    return Detection(lat, float(conf), float(secs), t1, t2)


def find_lattice(pixels: np.ndarray, cache_dir: str | None = None, use_cache: bool = True) -> Detection:
    """:func:`.lattice_detect.detect` of ``pixels``, answered from the cache when
    this image was searched before (``seconds``: then the time to read the
    entry). Both ways give the same Detection, field for field (an answer is
    always passed through its cache form)."""
    from ..analysis import default_cache_dir
    from ..safeio import ReadError, WriteError, atomic_write, read_limited
    t0 = time.perf_counter()
    path = None
    if use_cache:
        path = os.path.join(cache_dir or default_cache_dir(), f"lattice-{cache_key(pixels)}.json")
        try:
            found = from_json(json.loads(read_limited(path, _MAX_ENTRY, "lattice entry")))
            return replace(found, seconds=time.perf_counter() - t0)
        except (ReadError, ValueError, TypeError, OverflowError, RecursionError):
            pass  # no entry yet, or a damaged one: searched again (and replaced)
    from .lattice_detect import detect
    entry = json.dumps(to_json(detect(pixels)))
    if path is not None:
        try:
            os.makedirs(os.path.dirname(path), exist_ok=True)
            atomic_write(path, entry.encode("utf-8"))
        except (OSError, WriteError):
            pass  # a cache that cannot be written: the answer still stands
    return from_json(json.loads(entry), check=False)
