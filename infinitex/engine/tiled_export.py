"""Huge exports in bounded memory: a rectangle of the infinite texture rendered
tile by tile and written as it goes, resumable after an interruption.

Formats:

``tiles``
    One PNG per tile with the UDIM numbering texture tools read:
    ``NAME.<UDIM>.png``, UDIM = 1001 + column + 10 x row (columns 0-9, rows
    from the top), so at most 10 tiles per row; wider sets use
    ``NAME_u<U>_v<V>.png`` (1-based, the Mudbox/ZBrush "uvtile" names).
``tiff``
    One tiled, zlib-compressed BigTIFF (tifffile, the well-kept library for
    it), which GIS and terrain tools open; written from the finished tiles.

Every tile is independent of every other (spatial determinism), so the result
does not depend on the tile size used to render or on interruptions: a
folder ``OUT.parts`` beside the output holds a manifest (``manifest.jsonl``:
the export's key on the first line, then one line per finished tile with its
size and SHA-256, appended as tiles finish, so it costs the same per tile at
any export size). Running the same export
again keeps the tiles that verify and renders the rest; the final TIFF is
written atomically once every tile is there, and the parts folder removed.
"""
from __future__ import annotations

import hashlib
import json
import os
import shutil
from dataclasses import dataclass

import numpy as np

from .exemplar import to_u8
from .pyramid import Rect
from .safeio import atomic_write, read_limited

FORMATS = ("tiles", "tiff")
TILE_SIZES = (256, 512, 1024, 2048, 4096, 8192)
MAX_SIDE = 1 << 20
MANIFEST = "manifest.jsonl"
MANIFEST_MAX = 1 << 30  # about 100 bytes a tile: room for the 2^20 tiles of the largest export


class ExportInterrupted(Exception):
    """Raised by a progress callback to stop; the finished tiles are kept."""


def udim_name(base: str, col: int, row: int, cols: int) -> str:
    """The file of tile (col, row): ``BASE.1001.png`` style, or ``BASE_u1_v1.png`` past 10 columns."""
    if cols <= 10:
        return f"{base}.{1001 + col + 10 * row}.png"
    return f"{base}_u{col + 1}_v{row + 1}.png"


@dataclass
class TiledExport:
    """Render ``rect`` of ``synth`` (an engine Synthesizer with its parameters
    and controls) tile by tile into ``out`` (``NAME.png`` for ``tiles``: the
    tiles are ``NAME.1001.png``...; ``NAME.tif`` for ``tiff``)."""

    synth: object
    rect: Rect
    out: str
    fmt: str = "tiles"
    tile: int = 1024
    key: str = ""           # what decides the pixels (document, parameters): a changed key restarts

    def __post_init__(self):
        if self.fmt not in FORMATS:
            raise ValueError(f"Unknown tiled format {self.fmt!r}; use tiles or tiff.")
        if self.tile not in TILE_SIZES:
            raise ValueError(f"The tile size must be one of {', '.join(map(str, TILE_SIZES))}, not {self.tile}.")
        if self.rect.empty or self.rect.w > MAX_SIDE or self.rect.h > MAX_SIDE:
            raise ValueError(f"A tiled export is 1 to {MAX_SIDE} px a side, not {self.rect.w}x{self.rect.h}.")
        self.cols = -(-self.rect.w // self.tile)
        self.rows = -(-self.rect.h // self.tile)
        self.parts = self.out + ".parts"
        self.manifest_path = os.path.join(self.parts, MANIFEST)
        self.rendered = 0   # tiles rendered by this run (the others were kept)

    # -- plan ---------------------------------------------------------------------

    def tiles(self):
        for row in range(self.rows):
            for col in range(self.cols):
                x0 = self.rect.x0 + col * self.tile
                y0 = self.rect.y0 + row * self.tile
                yield col, row, Rect(x0, y0, min(x0 + self.tile, self.rect.x1), min(y0 + self.tile, self.rect.y1))

    def tile_path(self, col: int, row: int) -> str:
        if self.fmt == "tiles":
            base = os.path.splitext(self.out)[0]
            return udim_name(base, col, row, self.cols)
        return os.path.join(self.parts, f"{col}_{row}.npy")

    def _export_key(self) -> str:
        r = self.rect
        return hashlib.sha256(json.dumps([self.key, self.fmt, self.tile, r.x0, r.y0, r.x1, r.y1]).encode()).hexdigest()

    # -- manifest -------------------------------------------------------------------

    def _load_manifest(self) -> dict:
        """Finished tiles {name: [size, sha256]} of an earlier run of this same
        export; a foreign key, damage or a torn last line keep nothing or less."""
        try:
            raw = read_limited(self.manifest_path, MANIFEST_MAX, "export manifest")
        except OSError:
            return {}
        lines = raw.decode("utf-8", "replace").split("\n")
        try:
            if json.loads(lines[0]).get("key") != self._export_key():
                return {}
        except (ValueError, AttributeError):
            return {}
        tiles = {}
        for line in lines[1:]:
            try:
                name, size, sha = json.loads(line) if len(line) < 200 else (None, None, None)
            except (ValueError, TypeError):
                continue  # a line torn by a kill
            if isinstance(name, str) and isinstance(size, int) and isinstance(sha, str):
                tiles[name] = [size, sha]
        return tiles

    def _start_manifest(self, done: dict) -> None:
        """A fresh manifest for this run holding the tiles kept."""
        lines = [json.dumps({"key": self._export_key()})] + [json.dumps([k, *v]) for k, v in done.items()]
        atomic_write(self.manifest_path, ("\n".join(lines) + "\n").encode())

    def _append_manifest(self, name: str, entry: list) -> None:
        with open(self.manifest_path, "a", encoding="utf-8") as f:
            f.write(json.dumps([name, *entry]) + "\n")
            f.flush()
            os.fsync(f.fileno())

    @staticmethod
    def _digest(path: str) -> tuple[int, str] | None:
        try:
            with open(path, "rb") as f:
                data = f.read()
        except OSError:
            return None
        return len(data), hashlib.sha256(data).hexdigest()

    # -- run --------------------------------------------------------------------------

    def run(self, progress=None, workers: int = 0, worker_init=None) -> None:
        """Render what is missing, then assemble. ``progress(done, total)`` is
        called after each tile; it may raise ExportInterrupted (or anything)
        to stop, keeping the finished tiles for the next run.

        With ``workers`` > 0 the tiles are rendered by that many processes,
        each with its own headless GL context, made by ``worker_init`` (a
        picklable callable returning the worker's Synthesizer; the project,
        not engine objects, crosses the process boundary). A worker that dies
        has its tiles given to a fresh pool. The files are the same bytes."""
        os.makedirs(self.parts, exist_ok=True)
        kept = self._load_manifest()
        done: dict = {}
        todo = []
        total = self.rows * self.cols
        for col, row, r in self.tiles():
            name = f"{col},{row}"
            path = self.tile_path(col, row)
            entry = kept.get(name)
            if isinstance(entry, list) and len(entry) == 2 and self._digest(path) == tuple(entry):
                done[name] = entry
            else:
                todo.append((name, path, r))
        self._start_manifest(done)
        if progress is not None and done:
            progress(len(done), total)

        def finished(name: str, path: str) -> None:
            size, sha = self._digest(path)
            done[name] = [size, sha]
            self.rendered += 1
            self._append_manifest(name, done[name])
            if progress is not None:
                progress(len(done), total)
        if workers > 0 and todo:
            self._run_pool(todo, workers, worker_init, finished)
        else:
            for name, path, r in todo:
                render_tile(self.synth, self.fmt, path, r)
                finished(name, path)
        if self.fmt == "tiff":
            self._assemble_tiff()
        shutil.rmtree(self.parts, ignore_errors=True)

    def _run_pool(self, todo, workers: int, worker_init, finished) -> None:
        import multiprocessing
        from concurrent.futures import FIRST_COMPLETED, ProcessPoolExecutor, wait
        from concurrent.futures.process import BrokenProcessPool
        ctx = multiprocessing.get_context("spawn")  # a fresh interpreter: no inherited GL state
        pending = list(todo)
        restarts = 0
        while pending:
            with ProcessPoolExecutor(max_workers=workers, mp_context=ctx, initializer=_worker_start,
                                     initargs=(worker_init,)) as pool:
                futures = {pool.submit(_worker_tile, self.fmt, path, (r.x0, r.y0, r.x1, r.y1)): (name, path, r)
                           for name, path, r in pending}
                broken = False
                while futures:
                    ready, _ = wait(futures, return_when=FIRST_COMPLETED)
                    for fut in ready:
                        item = futures.pop(fut)
                        try:
                            fut.result()
                        except BrokenProcessPool:
                            broken = True
                            continue
                        pending.remove(item)
                        finished(item[0], item[1])
                    if broken:
                        break
            if broken:
                restarts += 1
                if restarts > 3 * workers + 3:
                    raise RuntimeError("export workers keep dying; the finished tiles are kept")

    def _assemble_tiff(self) -> None:
        import tifffile
        t = self.tile
        first = np.load(self.tile_path(0, 0), allow_pickle=False)
        channels = first.shape[2]

        def tiles():
            for col, row, r in self.tiles():
                a = np.load(self.tile_path(col, row), allow_pickle=False)
                if a.shape[:2] != (t, t):  # edge tiles are padded to the TIFF tile size
                    pad = np.zeros((t, t, channels), dtype=np.uint8)
                    pad[:a.shape[0], :a.shape[1]] = a
                    a = pad
                yield a[..., 0] if channels == 1 else a

        shape = (self.rect.h, self.rect.w) if channels == 1 else (self.rect.h, self.rect.w, channels)
        photometric = "minisblack" if channels in (1, 2) else "rgb"
        extra = {"extrasamples": [2]} if channels in (2, 4) else {}

        # Written beside the output (the parts folder), then renamed over it: atomic.
        tmp = os.path.join(self.parts, "assembling.tif")
        with tifffile.TiffWriter(tmp, bigtiff=True) as tw:
            tw.write(tiles(), shape=shape, dtype=np.uint8, tile=(t, t), compression="zlib",
                     photometric=photometric, **extra)
        with open(tmp, "rb") as f:
            os.fsync(f.fileno())
        os.replace(tmp, self.out)


def render_tile(synth, fmt: str, path: str, r: Rect) -> None:
    """Render one tile and write it atomically (a PNG, or raw .npy for the TIFF)."""
    img = to_u8(synth.colors(synth.window(r)))
    if fmt == "tiles":
        from .exemplar import write_png
        write_png(path, img)
    else:
        atomic_write(path, writer=lambda f: np.save(f, img, allow_pickle=False))


_WORKER: dict = {}


def _worker_start(worker_init) -> None:
    _WORKER["synth"] = worker_init()


def _worker_tile(fmt: str, path: str, box: tuple[int, int, int, int]) -> str:
    render_tile(_WORKER["synth"], fmt, path, Rect(*box))
    return path


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



