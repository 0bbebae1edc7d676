"""Huge exports in bounded memory: a rectangle of the infinite texture rendered
tile by tile and written as it goes, resumable after an interruption, on this
process, a pool of local worker processes or a Dask cluster.

Formats:

``tiles``
    One PNG per tile with the UDIM numbering texture tools read:
    ``NAME.<UDIM>.png``, UDIM = 1001 + column + 10 x row (columns 0-9, rows
    from the top), so at most 10 tiles per row; wider sets use
    ``NAME_u<U>_v<V>.png`` (1-based, the Mudbox/ZBrush "uvtile" names).
``tiff``
    One tiled, zlib-compressed BigTIFF (tifffile, the well-kept library for
    it), which GIS and terrain tools open. Tiles are compressed where they are
    rendered (horizontal predictor, zlib) and kept compressed until the file
    is assembled from them, so the parts take no more disk than the result.

With ``coords`` the exact exemplar-coordinate map (``encode_coords``) is
written the same way beside the texture: ``NAME_coords.<UDIM>.png`` or
``NAME_coords.tif``.

Every tile is independent of every other (spatial determinism), so the result
does not depend on the tile size used to render, on the workers or on
interruptions: a folder ``OUT.parts`` beside the output holds a manifest
(``manifest.jsonl``: the export's key on the first line, then one line per
finished file with its size and SHA-256, appended as tiles finish, so it costs
the same per tile at any export size). Running the same export again keeps the
files that verify and renders the rest; the final TIFF is written atomically
once every tile is there, and the parts folder removed.

Workers (``workers`` > 0: spawned processes; ``scheduler``: a Dask cluster)
receive the project (a picklable ``worker_init`` that builds a Synthesizer
with its own headless GL context), never engine objects, and return the
encoded tile bytes; this process writes them. A worker that dies has its tiles
rendered again elsewhere.
"""
from __future__ import annotations

import hashlib
import json
import os
import shutil
import threading
import zlib
from dataclasses import dataclass

import numpy as np

from infinitex.engine.pyramid import Rect
from infinitex.engine.safeio import WriteError, atomic_write, name_of, read_limited

from .errors import ExportInterrupted
from .formats import encode_tile, udim_name
from .workers import run_dask, run_pool
from .zarr_store import ZarrLevels

FORMATS = ("tiles", "tiff", "zarr")
TILE_SIZES = (256, 512, 1024, 2048, 4096, 8192)
MAX_SIDE = 1 << 20
MANIFEST = "manifest.jsonl"
MANIFEST_MAX = 1 << 30  # about 100 bytes a file: room for the 2^20 tiles of the largest export
ZLIB_LEVEL = 6


@dataclass
class TiledExport:
    """Render ``rect`` of ``synth`` (an engine Synthesizer with its parameters
    and controls; None when only workers render) tile by tile into ``out``
    (``NAME.png`` for ``tiles``: the tiles are ``NAME.1001.png``...;
    ``NAME.tif`` for ``tiff``)."""

    synth: object
    rect: Rect
    out: str
    fmt: str = "tiles"
    tile: int = 1024
    key: str = ""           # what decides the pixels (document, parameters): a changed key restarts
    coords: bool = False    # also the coordinate map, NAME_coords...
    L: int | None = None    # the synthesis's finest level (zarr's coarser levels); default synth.L

    def __post_init__(self):
        if self.fmt not in FORMATS:
            raise ValueError(f"Unknown tiled format {self.fmt!r}; use tiles, tiff or zarr.")
        if self.fmt == "zarr" and self.coords:
            raise ValueError("The coordinate map is written with tiles or tiff, not zarr.")
        if self.tile not in TILE_SIZES:
            raise ValueError(f"The tile size must be one of {', '.join(map(str, TILE_SIZES))}, not {self.tile}.")
        if self.rect.empty or self.rect.w > MAX_SIDE or self.rect.h > MAX_SIDE:
            raise ValueError(f"A tiled export is 1 to {MAX_SIDE} px a side, not {self.rect.w}x{self.rect.h}.")
        self.cols = -(-self.rect.w // self.tile)
        self.rows = -(-self.rect.h // self.tile)
        if self.L is None:
            self.L = getattr(self.synth, "L", 0)
        # Zarr: level k is the synthesis's level L - k over the rectangle's
        # 2^k-reduced box (the mipmap comes free), down to one tile or level 0.
        self.levels = [self.rect]
        while self.fmt == "zarr" and len(self.levels) <= self.L and max(self.levels[-1].w, self.levels[-1].h) > self.tile:
            k = len(self.levels)
            r = self.rect
            self.levels.append(Rect(r.x0 >> k, r.y0 >> k, -((-r.x1) >> k), -((-r.y1) >> k)))
        self.parts = self.out + ".parts"
        self.manifest_path = os.path.join(self.parts, MANIFEST)
        self.rendered = 0   # tiles rendered by this run (the others were kept)
        self.kept = 0       # tiles kept from an earlier run
        self.cancel_event = threading.Event()  # set (from any thread) to stop after the tiles being rendered

    # -- plan ---------------------------------------------------------------------

    @property
    def total(self) -> int:
        return sum(-(-r.w // self.tile) * -(-r.h // self.tile) for r in self.levels)

    @property
    def maps(self) -> tuple[str, ...]:
        """Suffixes of the maps written: the texture, then the coordinate map."""
        return ("", "_coords") if self.coords else ("",)

    def outputs(self) -> list[str]:
        """What the user gets, for messages: the TIFF files or the tile patterns."""
        base = os.path.splitext(self.out)[0]
        if self.fmt == "tiff":
            return [self.out if not m else f"{base}{m}.tif" for m in self.maps]
        if self.fmt == "zarr":
            return [self.out]
        return [f"{base}{m}.<UDIM>.png" for m in self.maps]

    def tiles(self, level: int = 0):
        """(col, row, rect) of every tile of a level, row by row."""
        lr = self.levels[level]
        for row in range(-(-lr.h // self.tile)):
            for col in range(-(-lr.w // self.tile)):
                x0 = lr.x0 + col * self.tile
                y0 = lr.y0 + row * self.tile
                yield col, row, Rect(x0, y0, min(x0 + self.tile, lr.x1), min(y0 + self.tile, lr.y1))

    def work(self):
        """Every tile of the export: (manifest names, files, rect, synthesis level or None)."""
        for k in range(len(self.levels)):
            for col, row, r in self.tiles(k):
                if self.fmt == "zarr":
                    yield [f"{k}/{col},{row}"], [None], r, self.L - k
                else:
                    yield [f"{col},{row}{m}" for m in self.maps], self.tile_paths(col, row), r, None

    def tile_paths(self, col: int, row: int) -> list[str]:
        """The files of one tile, one per map."""
        if self.fmt == "tiles":
            base = os.path.splitext(self.out)[0]
            return [udim_name(base + m, col, row, self.cols) for m in self.maps]
        return [os.path.join(self.parts, f"{col}_{row}{m}.zz") for m in self.maps]

    def export_key(self) -> str:
        r = self.rect
        return hashlib.sha256(json.dumps([self.key, self.fmt, self.tile, r.x0, r.y0, r.x1, r.y1,
                                          self.coords]).encode()).hexdigest()

    # -- manifest -------------------------------------------------------------------

    def _load_manifest(self) -> dict:
        """Finished files {name: [size, sha256]} of an earlier run of this same
        export; a foreign key, damage or a torn last line keep nothing or less."""
        try:
            raw = read_limited(self.manifest_path, MANIFEST_MAX, "export manifest")
        except OSError:
            return {}
        lines = raw.decode("utf-8", "replace").split("\n")
        try:
            if json.loads(lines[0]).get("key") != self.export_key():
                return {}
        except (ValueError, AttributeError):
            return {}
        files = {}
        for line in lines[1:]:
            try:
                name, size, sha = json.loads(line) if len(line) < 200 else (None, None, None)
            except (ValueError, TypeError):
                continue  # a line torn by a kill
            if isinstance(name, str) and isinstance(size, int) and isinstance(sha, str):
                files[name] = [size, sha]
        return files

    def _start_manifest(self, done: dict) -> None:
        """A fresh manifest for this run holding the files kept."""
        lines = [json.dumps({"key": self.export_key()})] + [json.dumps([k, *v]) for k, v in done.items()]
        self.guard(lambda: atomic_write(self.manifest_path, ("\n".join(lines) + "\n").encode()))

    def _append_manifest(self, lines: list[str]) -> None:
        def append():
            with open(self.manifest_path, "a", encoding="utf-8") as f:
                f.write("".join(lines))
                f.flush()
                os.fsync(f.fileno())
        self.guard(append)

    def guard(self, write) -> None:
        """A failed write (disk full, permissions) as one sentence that says the work is kept."""
        try:
            write()
        except OSError as exc:
            why = str(exc) if isinstance(exc, WriteError) else f"Writing {name_of(self.parts)} failed: {exc.strerror or exc}."
            raise WriteError(f"{why.rstrip('.')}. The finished tiles are kept: run the same export again "
                             f"to continue.") from None

    @staticmethod
    def _digest(path: str) -> tuple[int, str] | None:
        try:
            with open(path, "rb") as f:
                data = f.read()
        except OSError:
            return None
        return len(data), hashlib.sha256(data).hexdigest()

    # -- run --------------------------------------------------------------------------

    def run(self, progress=None, workers: int = 0, worker_init=None, scheduler: str | None = None) -> None:
        """Render what is missing, then assemble. ``progress(done, total)`` is
        called after each tile; it may raise ExportInterrupted (or anything)
        to stop, keeping the finished tiles for the next run; so does
        ``cancel_event.set()`` from another thread.

        With ``workers`` > 0 the tiles are rendered by that many spawned
        processes; with ``scheduler`` by a Dask cluster (``"local"``: a
        LocalCluster of ``workers`` processes, else the scheduler's address).
        Both need ``worker_init``: a picklable callable returning the
        worker's Synthesizer (the project, not engine objects, crosses the
        process boundary). The files are the same bytes in every case."""
        self.guard(lambda: os.makedirs(self.parts, exist_ok=True))
        kept = self._load_manifest()
        self._start_manifest(kept)
        self.zarr = ZarrLevels(self) if self.fmt == "zarr" else None
        store = self.zarr.open(fresh=not kept) if self.zarr else None
        total = self.total
        count = [0]
        self.kept = self.rendered = 0

        def todo():
            """The tiles still to render, found lazily (memory does not grow
            with the tile count); verified tiles count as done at once."""
            for item in self.work():
                names, paths, r, level = item
                if all(isinstance(kept.get(n), list) and len(kept[n]) == 2
                       and self._verify(store, n, p, r, level) == tuple(kept[n]) for n, p in zip(names, paths)):
                    self.kept += 1
                    count[0] += 1
                    if progress is not None:
                        progress(count[0], total)
                    continue
                yield item

        def finished(item, blobs: list[bytes]) -> None:
            names, paths, r, level = item
            lines = []
            for name, path, data in zip(names, paths, blobs):
                if store is not None:
                    self.guard(lambda: self.zarr.write(store, name, r, data))
                else:
                    self.guard(lambda: atomic_write(path, data))
                lines.append(json.dumps([name, len(data), hashlib.sha256(data).hexdigest()]) + "\n")
            self._append_manifest(lines)
            self.rendered += 1
            count[0] += 1
            if progress is not None:
                progress(count[0], total)
            if self.cancel_event.is_set():
                raise ExportInterrupted()

        if scheduler:
            run_dask(self, todo(), scheduler, workers, worker_init, finished)
        elif workers > 0:
            run_pool(self, todo(), workers, worker_init, finished)
        else:
            for item in todo():
                if self.cancel_event.is_set():
                    raise ExportInterrupted()
                finished(item, encode_tile(self.synth, self.fmt, self.tile, item[2], self.coords, item[3]))
        if self.fmt == "tiff":
            for i, m in enumerate(self.maps):
                self._assemble_tiff(i, self.outputs()[i])
        elif self.fmt == "zarr":
            self.zarr.finish()
        shutil.rmtree(self.parts, ignore_errors=True)

    def _verify(self, store, name: str, path: str | None, r: Rect, level: int | None):
        """(size, sha256) of a tile already written, or None."""
        if store is None:
            return self._digest(path)
        try:
            data = self.zarr.read(store, name, r)
        except Exception:  # noqa: BLE001 - a damaged or missing chunk: render it again
            return None
        return len(data), hashlib.sha256(data).hexdigest()

    def _assemble_tiff(self, index: int, out: str) -> None:
        import tifffile
        t = self.tile
        m = self.maps[index]
        channels = 3 if m == "_coords" else None
        if channels is None:  # the texture's channels, from the first tile's size
            raw = zlib.decompress(self._read_part(0, 0, index))
            channels = len(raw) // (t * t)

        def tiles():
            for col, row, _ in self.tiles():
                yield self._read_part(col, row, index)

        shape = (self.rect.h, self.rect.w) if channels == 1 else (self.rect.h, self.rect.w, channels)
        photometric = "minisblack" if channels in (1, 2) else "rgb"
        extra = {"extrasamples": [2]} if channels in (2, 4) else {}

        # Written beside the output (the parts folder), then renamed over it: atomic.
        tmp = os.path.join(self.parts, f"assembling{m}.tif")

        def write():
            with tifffile.TiffWriter(tmp, bigtiff=True) as tw:
                tw.write(tiles(), shape=shape, dtype=np.uint8, tile=(t, t), compression="zlib",
                         predictor="horizontal", photometric=photometric, **extra)
            with open(tmp, "rb") as f:
                os.fsync(f.fileno())
            os.replace(tmp, out)
        self.guard(write)

    def _read_part(self, col: int, row: int, index: int) -> bytes:
        with open(self.tile_paths(col, row)[index], "rb") as f:
            return f.read()
