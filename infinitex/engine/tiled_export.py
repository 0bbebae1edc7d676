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
import io
import json
import os
import secrets
import shutil
import threading
import time
import zlib
from dataclasses import dataclass

import numpy as np

from .exemplar import PIL_MODES, to_u8
from .pyramid import Rect
from .safeio import WriteError, atomic_write, name_of, read_limited

FORMATS = ("tiles", "tiff", "zarr")
TILE_SIZES = (256, 512, 1024, 2048, 4096, 8192)
MAX_SIDE = 1 << 20
MANIFEST = "manifest.jsonl"
MANIFEST_MAX = 1 << 30  # about 100 bytes a file: room for the 2^20 tiles of the largest export
ZLIB_LEVEL = 6


class ExportInterrupted(Exception):
    """Raised by a progress callback to stop; the finished tiles are kept."""


class ExportFailed(RuntimeError):
    """The workers could not finish (they keep dying, the cluster is out of
    reach); a sentence for the user. The finished tiles are kept."""


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
    from .safeio import check_output, printable
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
    maps = [to_u8(synth.colors(c, level))]
    if coords:
        maps.append(encode_coords(c))
    if fmt == "zarr":
        return [np.ascontiguousarray(m).tobytes() for m in maps]
    return [png_bytes(m) if fmt == "tiles" else tiff_tile_bytes(m, tile) for m in maps]


def calibrate(worker_init, fmt: str, tile: int) -> tuple[float, float]:
    """Seconds and bytes per pixel of a streamed export, measured on one tile
    (at most 1024 px; larger tiles cost about the same per pixel) rendered
    and encoded as the export does, in a worker made by ``worker_init``."""
    synth = worker_init()
    n = min(tile, 1024)
    # A first tile of the same size compiles the shaders and allocates the
    # buffers: costs an export pays once, not per pixel.
    encode_tile(synth, fmt, n, Rect(-n, 0, 0, n))
    t0 = time.perf_counter()
    blob = encode_tile(synth, fmt, n, Rect(n, 3 * n, 2 * n, 4 * n))[0]
    return (time.perf_counter() - t0) / (n * n), len(blob) / (n * n)


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

    def _export_key(self) -> str:
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
            if json.loads(lines[0]).get("key") != self._export_key():
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
        lines = [json.dumps({"key": self._export_key()})] + [json.dumps([k, *v]) for k, v in done.items()]
        self._guard(lambda: atomic_write(self.manifest_path, ("\n".join(lines) + "\n").encode()))

    def _append_manifest(self, lines: list[str]) -> None:
        def append():
            with open(self.manifest_path, "a", encoding="utf-8") as f:
                f.write("".join(lines))
                f.flush()
                os.fsync(f.fileno())
        self._guard(append)

    def _guard(self, write) -> None:
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
        self._guard(lambda: os.makedirs(self.parts, exist_ok=True))
        kept = self._load_manifest()
        self._start_manifest(kept)
        store = self._open_zarr(fresh=not kept) if self.fmt == "zarr" else None
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
                    self._guard(lambda: self._write_zarr(store, name, r, data))
                else:
                    self._guard(lambda: atomic_write(path, data))
                lines.append(json.dumps([name, len(data), hashlib.sha256(data).hexdigest()]) + "\n")
            self._append_manifest(lines)
            self.rendered += 1
            count[0] += 1
            if progress is not None:
                progress(count[0], total)
            if self.cancel_event.is_set():
                raise ExportInterrupted()

        if scheduler:
            self._run_dask(todo(), scheduler, workers, worker_init, finished)
        elif workers > 0:
            self._run_pool(todo(), workers, worker_init, finished)
        else:
            for item in todo():
                if self.cancel_event.is_set():
                    raise ExportInterrupted()
                finished(item, encode_tile(self.synth, self.fmt, self.tile, item[2], self.coords, item[3]))
        if self.fmt == "tiff":
            for i, m in enumerate(self.maps):
                self._assemble_tiff(i, self.outputs()[i])
        elif self.fmt == "zarr":
            self._finish_zarr()
        shutil.rmtree(self.parts, ignore_errors=True)

    def _verify(self, store, name: str, path: str | None, r: Rect, level: int | None):
        """(size, sha256) of a tile already written, or None."""
        if store is None:
            return self._digest(path)
        try:
            data = self._read_zarr(store, name, r)
        except Exception:  # noqa: BLE001 - a damaged or missing chunk: render it again
            return None
        return len(data), hashlib.sha256(data).hexdigest()

    def _in_flight(self, workers: int) -> int:
        return 2 * max(1, workers) + 2  # enough to keep the workers busy; a cancel drops the rest at once

    def _run_pool(self, todo, workers: int, worker_init, finished) -> None:
        import multiprocessing
        from concurrent.futures import FIRST_COMPLETED, ProcessPoolExecutor, wait
        from concurrent.futures.process import BrokenProcessPool
        ctx = multiprocessing.get_context("spawn")  # a fresh interpreter: no inherited GL state
        retry: list = []  # tiles of a pool that broke (a worker died)
        restarts = 0
        more = True
        while more or retry:
            pool = ProcessPoolExecutor(max_workers=workers, mp_context=ctx, initializer=_worker_start,
                                       initargs=(worker_init,))
            futures: dict = {}
            broken = False
            try:
                while True:
                    while len(futures) < self._in_flight(workers) and (retry or more):
                        item = retry.pop() if retry else next(todo, None)
                        if item is None:
                            more = False
                            break
                        try:
                            fut = pool.submit(_worker_tile, self.fmt, self.tile, _box(item[2]), self.coords, item[3])
                        except BrokenProcessPool:  # a worker died since the last wait: this pool is done
                            retry.append(item)
                            broken = True
                            break
                        futures[fut] = item
                    if broken:
                        retry.extend(futures.values())
                        break
                    if not futures:
                        break
                    ready, _ = wait(futures, return_when=FIRST_COMPLETED)
                    for fut in ready:
                        item = futures.pop(fut)
                        try:
                            blobs = fut.result()
                        except BrokenProcessPool:
                            broken = True
                            retry.append(item)
                            continue
                        finished(item, blobs)
                    if broken:
                        retry.extend(futures.values())
                        break
            finally:  # stopped (or done): drop the queued tiles, wait only for those being rendered
                pool.shutdown(wait=True, cancel_futures=True)
            if broken:
                restarts += 1
                if restarts > 3 * workers + 3:
                    raise ExportFailed("The export's worker processes keep dying (out of memory?); the finished "
                                       "tiles are kept: run the same export again to continue.")

    def _run_dask(self, todo, scheduler: str, workers: int, worker_init, finished) -> None:
        """Tiles as Dask tasks: the cluster reschedules those of a worker that dies."""
        import logging

        from distributed import Client, KilledWorker, LocalCluster, as_completed
        from distributed.client import FutureCancelledError
        cluster = None
        try:
            if scheduler == "local":
                cluster = LocalCluster(n_workers=workers or os.cpu_count() or 1, threads_per_worker=1,
                                       processes=True, dashboard_address=None, silence_logs=logging.ERROR)
                client = Client(cluster)
            else:
                client = Client(scheduler, timeout=10)
        except (OSError, TimeoutError, ValueError) as exc:
            if cluster is not None:
                cluster.close()
            raise ExportFailed(f"Cannot reach the Dask scheduler at {scheduler}: {exc}") from None
        try:
            init = client.scatter(worker_init, broadcast=True, hash=False)
            key = self._export_key()
            threads = sum(client.nthreads().values()) or 1
            futures: dict = {}
            serial = [0]
            run_id = secrets.token_hex(4)  # task names of this run only, on a cluster others may share

            def submit() -> bool:
                item = next(todo, None)
                if item is None:
                    return False
                serial[0] += 1
                fut = client.submit(_dask_tile, init, key, self.fmt, self.tile, _box(item[2]), self.coords, item[3],
                                    pure=False, key=f"infinitex-tile-{key[:12]}-{run_id}-{serial[0]}")
                futures[fut] = item
                queue.add(fut)
                return True
            queue = as_completed([])
            more = True
            while more and len(futures) < self._in_flight(threads):
                more = submit()
            try:
                for fut in queue:
                    item = futures.pop(fut)
                    try:
                        blobs = fut.result()
                    except FutureCancelledError:
                        continue
                    except KilledWorker:
                        raise ExportFailed("A tile killed every Dask worker it was given to (out of memory?); "
                                           "the finished tiles are kept: run the same export again to "
                                           "continue.") from None
                    finished(item, blobs)
                    while more and len(futures) < self._in_flight(threads):
                        more = submit()
            except BaseException:
                client.cancel(list(futures))
                raise
        finally:
            client.close()
            if cluster is not None:
                cluster.close()

    # -- zarr ---------------------------------------------------------------------

    def _zarr_path(self) -> str:
        return os.path.join(self.parts, "data.zarr")  # built here, moved to ``out`` when complete

    def _open_zarr(self, fresh: bool):
        """The multiscale store being built (OME-NGFF 0.4 metadata, zarr format
        2, which napari's and most viewers' readers open): arrays "0" (full
        resolution), "1" (half)... of (C, H, W) or (H, W) uint8 chunked by tile."""
        import zarr
        path = self._zarr_path()
        if not fresh:
            try:
                return zarr.open_group(path, mode="r+", zarr_format=2)
            except Exception:  # noqa: BLE001 - no usable store: start it again
                pass
        shutil.rmtree(path, ignore_errors=True)
        return self._guard_value(lambda: zarr.open_group(path, mode="w", zarr_format=2))

    def _guard_value(self, make):
        out = []
        self._guard(lambda: out.append(make()))
        return out[0]

    def _zarr_array(self, store, level: int, channels: int):
        name = str(level)
        if name in store:
            return store[name]
        r = self.levels[level]
        t = self.tile
        shape, chunks = ((r.h, r.w), (t, t)) if channels == 1 else ((channels, r.h, r.w), (channels, t, t))
        return store.create_array(name, shape=shape, chunks=chunks, dtype="uint8", fill_value=0)

    def _level_of(self, name: str) -> int:
        return int(name.split("/", 1)[0])

    def _write_zarr(self, store, name: str, r: Rect, data: bytes) -> None:
        k = self._level_of(name)
        lr = self.levels[k]
        c = len(data) // (r.w * r.h)
        a = np.frombuffer(data, dtype=np.uint8).reshape(r.h, r.w, c)
        arr = self._zarr_array(store, k, c)
        ys, xs = slice(r.y0 - lr.y0, r.y1 - lr.y0), slice(r.x0 - lr.x0, r.x1 - lr.x0)
        if c == 1:
            arr[ys, xs] = a[..., 0]
        else:
            arr[:, ys, xs] = np.moveaxis(a, 2, 0)

    def _read_zarr(self, store, name: str, r: Rect) -> bytes:
        k = self._level_of(name)
        lr = self.levels[k]
        arr = store[str(k)]
        ys, xs = slice(r.y0 - lr.y0, r.y1 - lr.y0), slice(r.x0 - lr.x0, r.x1 - lr.x0)
        a = arr[ys, xs][..., None] if arr.ndim == 2 else np.moveaxis(arr[:, ys, xs], 0, 2)
        return np.ascontiguousarray(a).tobytes()

    def _finish_zarr(self) -> None:
        """Write the multiscale metadata, then move the complete store to ``out``."""
        import zarr
        store = zarr.open_group(self._zarr_path(), mode="r+", zarr_format=2)
        color = store["0"].ndim == 3
        axes = ([{"name": "c", "type": "channel"}] if color else []) + [
            {"name": "y", "type": "space"}, {"name": "x", "type": "space"}]
        r = self.rect
        datasets = []
        for k in range(len(self.levels)):
            scale = ([1.0] if color else []) + [float(2 ** k)] * 2
            origin = ([0.0] if color else []) + [float((r.y0 >> k) << k), float((r.x0 >> k) << k)]
            datasets.append({"path": str(k), "coordinateTransformations": [
                {"type": "scale", "scale": scale}, {"type": "translation", "translation": origin}]})
        store.attrs["multiscales"] = [{
            "version": "0.4", "name": os.path.splitext(os.path.basename(self.out))[0], "axes": axes,
            "datasets": datasets, "type": "synthesis levels (LH05: the coarser levels are the mipmap)",
            "metadata": {"canvas_rect": [r.x0, r.y0, r.w, r.h], "synthesis_levels": [self.L - k for k in
                                                                                    range(len(self.levels))]}}]

        def move():
            old = os.path.join(self.parts, "replaced.zarr")
            if os.path.lexists(self.out):
                os.rename(self.out, old)  # an earlier export of the same name, removed below
            os.rename(self._zarr_path(), self.out)
        self._guard(move)

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
        self._guard(write)

    def _read_part(self, col: int, row: int, index: int) -> bytes:
        with open(self.tile_paths(col, row)[index], "rb") as f:
            return f.read()


def _box(r: Rect) -> tuple[int, int, int, int]:
    return r.x0, r.y0, r.x1, r.y1


_WORKER: dict = {}


def _worker_start(worker_init) -> None:
    _WORKER["synth"] = worker_init()


def _worker_tile(fmt: str, tile: int, box: tuple[int, int, int, int], coords: bool,
                 level: int | None = None) -> list[bytes]:
    return encode_tile(_WORKER["synth"], fmt, tile, Rect(*box), coords, level)


def _dask_tile(worker_init, key: str, fmt: str, tile: int, box: tuple[int, int, int, int],
               coords: bool, level: int | None = None) -> list[bytes]:
    """A Dask task: the worker's Synthesizer is made once per export and
    thread (a GL context is current in the thread that made it)."""
    slot = (threading.get_ident(), key)
    synth = _WORKER.get(slot)
    if synth is None:
        for old in [k for k in _WORKER if isinstance(k, tuple) and k[0] == slot[0]]:
            _WORKER.pop(old)  # one export's engine per thread at a time
        synth = _WORKER[slot] = worker_init()
    return encode_tile(synth, fmt, tile, Rect(*box), coords, level)


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
