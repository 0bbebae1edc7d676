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
finished file with its size and keyed hash, appended as tiles finish, so it costs
the same per tile at any export size). Running the same export again keeps the
files that verify and renders the rest; the final TIFF is written atomically
once every tile is there, and the files of the parts folder removed.

The parts folder and everything in it are untrusted (:mod:`.workdir`: files
reached relative to the folder's descriptor, never through a link; a parts
folder that is a link or another user's is refused; a new one is ``0700``).
The manifest is bounded and strict (plain tile names only); a file is kept
only if it is a regular file of the size and keyed hash listed (HMAC-SHA-256
with a secret of the user's, over the export's key, the file's name and bytes:
a manifest cannot vouch for a file this user's exports did not write) *and* decodes to
a tile of this export (the compressed TIFF tile to ``tile x tile x channels``
bytes, the PNG to the tile's size and a mode of the texture), else it is
rendered again. Only what the export wrote or verified is removed at the end;
anything else is left in place, with a note (``notes``).

Workers (``workers`` > 0: spawned processes; ``scheduler``: a Dask cluster)
receive the project (a picklable ``worker_init`` that builds a Synthesizer
with its own headless GL context), never engine objects, and return the
encoded tile bytes; this process writes them. A worker that dies has its tiles
rendered again elsewhere.
"""
from __future__ import annotations

import hashlib
import hmac
import io
import json
import os
import re
import stat
import threading
import zlib
from dataclasses import dataclass

import numpy as np

from infinitex.engine.imagefile import PIL_MODES
from infinitex.engine.pyramid import Rect
from infinitex.engine.safeio import WriteError, name_of, printable

from .errors import ExportInterrupted
from .formats import encode_tile, udim_name
from .workdir import Folder, manifest_key, open_folder_of, open_parts
from .workers import run_dask, run_pool
from .zarr_store import ZarrLevels

FORMATS = ("tiles", "tiff", "zarr")
TILE_SIZES = (256, 512, 1024, 2048, 4096, 8192)
MAX_SIDE = 1 << 20
MANIFEST = "manifest.jsonl"
MANIFEST_MAX = 1 << 30  # about 100 bytes a file: room for the 2^20 tiles of the largest export
LINE_MAX = 200          # a manifest line: ["NAME", SIZE, "HMAC-SHA-256"] is about 100 bytes
ZLIB_LEVEL = 6
# The names the export gives its files in the manifest: "COL,ROW" (and
# "COL,ROW_coords"), "LEVEL/COL,ROW" for zarr. Nothing else is trusted.
_TILE_NAME = re.compile(r"(0|[1-9][0-9]{0,6}),(0|[1-9][0-9]{0,6})(_coords)?")
MANIFEST_NAMES = {"tiles": _TILE_NAME, "tiff": _TILE_NAME,
                  "zarr": re.compile(r"(0|[1-9][0-9]?)/(0|[1-9][0-9]{0,6}),(0|[1-9][0-9]{0,6})")}
_SHA256 = re.compile(r"[0-9a-f]{64}")
_MODES = {mode: c for c, mode in PIL_MODES.items()}


def zz_limit(tile: int) -> int:
    """The largest compressed TIFF tile: zlib never grows data by more than this."""
    n = tile * tile * 4
    return n + (n >> 8) + 1024


def png_limit(r: Rect) -> int:
    """The largest PNG tile of ``r``: 4 channels, filter bytes, zlib and chunk overhead."""
    n = r.w * r.h * 4 + r.h
    return n + (n >> 6) + (1 << 16)


def zz_channels(chunks, tile: int) -> int | None:
    """The channels of a compressed TIFF tile given in pieces, or None if it
    does not decompress to exactly ``tile x tile x channels`` bytes (1 to 4)."""
    d = zlib.decompressobj()
    cap = tile * tile * 4
    n = 0
    try:
        for piece in chunks:
            n += len(d.decompress(piece, cap + 1 - n))
            if d.unconsumed_tail or n > cap:
                return None
        n += len(d.flush())
    except zlib.error:
        return None
    if not d.eof or d.unused_data or n % (tile * tile):
        return None
    c = n // (tile * tile)
    return c if 1 <= c <= 4 else None


def png_channels(data: bytes, w: int, h: int) -> int | None:
    """The channels of a PNG tile of ``w x h`` px in one of the modes an export
    writes, whole (every chunk's CRC, up to IEND) and fully decoded, or None."""
    from PIL import Image
    try:
        with Image.open(io.BytesIO(data), formats=["PNG"]) as im:
            if im.size != (w, h) or im.mode not in _MODES:
                return None
            im.verify()
        with Image.open(io.BytesIO(data), formats=["PNG"]) as im:
            im.load()
            return _MODES[im.mode]
    except Exception:  # noqa: BLE001 - any failure to decode: not a tile of ours
        return None


def _json_line(line: bytes):
    def no_constants(t):
        raise ValueError(t)
    if len(line) > LINE_MAX:
        return None
    try:
        return json.loads(line.decode("utf-8"), parse_constant=no_constants)
    except ValueError:
        return None


def parse_manifest(raw: bytes, key: str, names: re.Pattern, max_lines: int, max_size: int) -> dict:
    """The files {name: [size, keyed hash]} an untrusted manifest lists: at most
    ``max_lines`` lines of strict JSON, the export's ``key`` first, then
    ``[NAME, SIZE, HASH]`` lines (64 hex digits) with names the export itself gives. A
    foreign key or any damaged line keeps nothing; only what follows the last
    newline (a line torn by a kill) is dropped."""
    lines = raw.split(b"\n")[:-1]
    if not lines or len(lines) > max_lines or _json_line(lines[0]) != {"key": key}:
        return {}
    files = {}
    for line in lines[1:]:
        entry = _json_line(line)
        if not (isinstance(entry, list) and len(entry) == 3):
            return {}
        name, size, sha = entry
        if not (isinstance(name, str) and names.fullmatch(name) and type(size) is int
                and 0 < size <= max_size and isinstance(sha, str) and _SHA256.fullmatch(sha)):
            return {}
        files[name] = [size, sha]
    return files


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
        self.notes: list[str] = []  # what the user should know of a finished export (a parts folder left)
        self.cancel_event = threading.Event()  # set (from any thread) to stop after the tiles being rendered
        self._out_dir: Folder | None = None
        self._parts: Folder | None = None
        self._key: bytes | None = None  # this user's manifest key (workdir.manifest_key)

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
        """Every tile of the export: (manifest names, file names, rect, synthesis level or None)."""
        for k in range(len(self.levels)):
            for col, row, r in self.tiles(k):
                if self.fmt == "zarr":
                    yield [f"{k}/{col},{row}"], [None], r, self.L - k
                else:
                    yield [f"{col},{row}{m}" for m in self.maps], self.tile_names(col, row), r, None

    def tile_names(self, col: int, row: int) -> list[str]:
        """The files of one tile, one per map: PNGs beside the output (tiles),
        compressed TIFF tiles in the parts folder (tiff)."""
        if self.fmt == "tiles":
            base = os.path.splitext(os.path.basename(self.out))[0]
            return [udim_name(base + m, col, row, self.cols) for m in self.maps]
        return [f"{col}_{row}{m}.zz" for m in self.maps]

    def tile_paths(self, col: int, row: int) -> list[str]:
        """The files of one tile as paths."""
        folder = os.path.dirname(self.out) if self.fmt == "tiles" else self.parts
        return [os.path.join(folder, n) for n in self.tile_names(col, row)]

    def export_key(self) -> str:
        r = self.rect
        return hashlib.sha256(json.dumps([self.key, self.fmt, self.tile, r.x0, r.y0, r.x1, r.y1,
                                          self.coords]).encode()).hexdigest()

    def signer(self, name: str):
        """The keyed hash of a file as the manifest lists it: HMAC-SHA-256 with
        this user's secret (:func:`.workdir.manifest_key`) of the export's key,
        the file's manifest name and its bytes (``update`` them, then ``hexdigest``).
        A manifest can then vouch only for what this user's exports wrote, each
        file under its own name."""
        if self._key is None:
            self._key = manifest_key()
        return hmac.new(self._key, f"{self.export_key()}\0{name}\0".encode(), hashlib.sha256)

    def sign(self, name: str, data: bytes) -> str:
        h = self.signer(name)
        h.update(data)
        return h.hexdigest()

    # -- manifest -------------------------------------------------------------------

    def _load_manifest(self) -> dict:
        """Finished files {name: [size, keyed hash]} of an earlier run of this export (see :func:`parse_manifest`)."""
        max_lines = 2 * self.total * len(self.maps) + 2
        raw = self._parts.read(MANIFEST, min(MANIFEST_MAX, max_lines * LINE_MAX))
        return parse_manifest(raw or b"", self.export_key(), MANIFEST_NAMES[self.fmt], max_lines, self._file_limit())

    def _file_limit(self) -> int:
        t = self.tile
        return png_limit(Rect(0, 0, t, t)) if self.fmt == "tiles" else zz_limit(t) if self.fmt == "tiff" else t * t * 4

    def _start_manifest(self, done: dict) -> None:
        """A fresh manifest for this run holding the files kept."""
        lines = [json.dumps({"key": self.export_key()})] + [json.dumps([k, *v]) for k, v in done.items()]
        self.guard(lambda: self._parts.write(MANIFEST, ("\n".join(lines) + "\n").encode()))

    def _append_manifest(self, lines: list[str]) -> None:
        def append():
            if self._manifest is None:
                self._manifest = self._parts.append(MANIFEST)
            self._manifest.write("".join(lines).encode())
            self._manifest.flush()
            os.fsync(self._manifest.fileno())
        self.guard(append)

    def guard(self, write, what: str | None = None) -> None:
        """A failed write (disk full, permissions) as one sentence that names
        the file (``what``, default the parts folder) and says the work is kept."""
        try:
            write()
        except OSError as exc:
            why = (str(exc) if isinstance(exc, WriteError)
                   else f"Writing {what or name_of(self.parts)} failed: {exc.strerror or exc}.")
            raise WriteError(f"{why.rstrip('.')}. The finished tiles are kept: run the same export again "
                             f"to continue.") from None

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
        process boundary). The files are the same bytes in every case.

        The parts folder is checked before any work: a symbolic link, a file
        or another user's folder there is refused (WriteError), as is a
        folder where the export writes a file."""
        self._out_dir = open_folder_of(self.out)
        self._manifest = None
        try:
            self._parts, _ = open_parts(self._out_dir, os.path.basename(self.parts), printable(self.parts))
            self._run(progress, workers, worker_init, scheduler)
        finally:
            if self._manifest is not None:
                self._manifest.close()
            for folder in (self._parts, self._out_dir):
                if folder is not None:
                    folder.close()
            self._parts = self._out_dir = self._manifest = None

    def _run(self, progress, workers: int, worker_init, scheduler: str | None) -> None:
        self._parts.remove_stale_temporaries()
        if self.fmt == "tiles":
            self._out_dir.remove_stale_temporaries()
        self._refuse_folders_in_the_way()
        kept = self._load_manifest()
        self.zarr = ZarrLevels(self, self._parts, self._out_dir) if self.fmt == "zarr" else None
        store = self.zarr.open(fresh=not kept) if self.zarr else None  # a store not of this export: refused
        self._start_manifest(kept)
        # The channels of each map: learned from the first tile rendered (or
        # kept); kept tiles must agree. A tile rendered after kept ones that
        # disagree proves them wrong: a second pass renders those again.
        self._channels: dict[str, int | None] = dict.fromkeys(self.maps)
        self._rendered_channels: dict[str, int | None] = dict.fromkeys(self.maps)
        self.kept = self.rendered = 0
        self._pass(kept, store, progress, workers, worker_init, scheduler)
        wrong = {m for m in self.maps if self._rendered_channels[m] not in (None, self._channels[m])}
        if wrong:
            first = self.rendered
            self._channels.update({m: self._rendered_channels[m] for m in wrong})
            self.kept = 0
            self._pass(self._load_manifest(), store, progress, workers, worker_init, scheduler)
            self.kept = max(0, self.kept - first)
        if self.fmt == "tiff":
            for i, out in enumerate(self.outputs()):
                self._assemble_tiff(i, out)
        elif self.fmt == "zarr":
            self.zarr.finish()
        self._clean_up()

    def _refuse_folders_in_the_way(self) -> None:
        """A folder where the export writes a file cannot be replaced: refused before any work."""
        names = [(self._parts, MANIFEST)] + [(self._parts, f"assembling{m}.tif") for m in self.maps]
        if self.fmt != "zarr":
            folder = self._out_dir if self.fmt == "tiles" else self._parts
            names = names + [(folder, n) for col, row, _ in self.tiles() for n in self.tile_names(col, row)]
        for folder, name in names:
            st = folder.lstat(name)
            if st is not None and stat.S_ISDIR(st.st_mode):
                raise WriteError(f"{folder.show(name)} is a folder where this export writes a file; it is left as "
                                 f"it is: remove it and run the export again.")

    def _pass(self, kept: dict, store, progress, workers: int, worker_init, scheduler: str | None) -> None:
        """Render every tile not kept: verified ones count as done at once."""
        total = self.total
        count = [0]

        def todo():
            """The tiles still to render, found lazily (memory does not grow
            with the tile count); verified tiles count as done at once."""
            for item in self.work():
                names, files, r, level = item
                if all(self._verify(store, n, f, r, level, kept.get(n)) for n, f in zip(names, files)):
                    self.kept += 1
                    count[0] += 1
                    if progress is not None:
                        progress(count[0], total)
                    continue
                yield item

        def finished(item, blobs: list[bytes]) -> None:
            names, files, r, level = item
            lines = []
            for name, file, data, m in zip(names, files, blobs, self.maps):
                self._learn_channels(m, data, r)
                if store is not None:
                    self.guard(lambda: self.zarr.write(store, name, r, data))
                elif self.fmt == "tiles":
                    self.guard(lambda: self._out_dir.write(file, data, self._out_dir.output_mode(file)),
                               printable(file))
                else:
                    self.guard(lambda: self._parts.write(file, data))
                lines.append(json.dumps([name, len(data), self.sign(name, data)]) + "\n")
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

    def _learn_channels(self, m: str, data: bytes, r: Rect) -> None:
        """The channels of a map, from the first tile this run rendered of it."""
        if self._rendered_channels[m] is not None:
            return
        if self.fmt == "tiff":
            c = zz_channels([data], self.tile)
        elif self.fmt == "tiles":
            c = png_channels(data, r.w, r.h)
        else:
            c = len(data) // max(1, r.w * r.h)
        self._rendered_channels[m] = c
        if self._channels[m] is None:
            self._channels[m] = c

    def _verify(self, store, name: str, file: str | None, r: Rect, level: int | None, listed) -> bool:
        """Whether a file of an earlier run is kept: listed in the manifest,
        a regular file of the size and keyed hash listed (:meth:`signer`), and
        decoding to a tile of this export (the size, and the channels of its map)."""
        if not (isinstance(listed, list) and len(listed) == 2):
            return False
        size, sha = listed
        m = "_coords" if name.endswith("_coords") else ""
        if store is not None:
            try:
                data = self.zarr.read(store, name, r)
            except Exception:  # noqa: BLE001 - a damaged or missing chunk: render it again
                return False
            return len(data) == size and hmac.compare_digest(self.sign(name, data), sha)
        h = self.signer(name)
        if self.fmt == "tiles":
            data = self._out_dir.read(file, png_limit(r), size)
            if data is None:
                return False
            h.update(data)
            c = png_channels(data, r.w, r.h) if hmac.compare_digest(h.hexdigest(), sha) else None
        else:
            pieces: list[bytes] = []
            if not self._parts.stream(file, zz_limit(self.tile), pieces.append, size):
                return False
            for p in pieces:
                h.update(p)
            c = zz_channels(pieces, self.tile) if hmac.compare_digest(h.hexdigest(), sha) else None
        if c is None or (m == "_coords" and c != 3) or self._channels[m] not in (None, c):
            return False
        self._channels[m] = c
        return True

    def _assemble_tiff(self, index: int, out: str) -> None:
        """The TIFF from its compressed tiles: written as ``assembling.tif`` in
        the parts folder (created there, never through a link), then renamed
        onto the output. A failure names the output."""
        import tifffile
        t = self.tile
        m = self.maps[index]
        channels = self._channels[m]
        parts = self._parts

        def tiles():
            for col, row, _ in self.tiles():
                name = self.tile_names(col, row)[index]
                data = parts.read(name, zz_limit(t))
                if data is None:
                    raise WriteError(f"{parts.show(name)} went missing while the export ran")
                yield data

        shape = (self.rect.h, self.rect.w) if channels == 1 else (self.rect.h, self.rect.w, channels)
        photometric = "minisblack" if channels in (1, 2) else "rgb"
        extra = {"extrasamples": [2]} if channels in (2, 4) else {}
        name = os.path.basename(out)

        def write():
            tmp, f = parts.create_new(f"assembling{m}.tif")
            try:
                with tifffile.TiffWriter(f, bigtiff=True) as tw:
                    tw.write(tiles(), shape=shape, dtype=np.uint8, tile=(t, t), compression="zlib",
                             predictor="horizontal", photometric=photometric, **extra)
            except BaseException:
                parts.discard(tmp, f)
                raise
            parts.commit(tmp, f, name, into=self._out_dir, mode=self._out_dir.output_mode(name))
        self.guard(write, printable(out))

    def _clean_up(self) -> None:
        """Remove what this export wrote or verified in its parts folder, by
        name, then the folder; anything else stays, with a note."""
        parts = self._parts
        if self.fmt == "tiff":
            for col, row, _ in self.tiles():
                for name in self.tile_names(col, row):
                    parts.remove_file(name)
        if self._manifest is not None:
            self._manifest.close()
            self._manifest = None
        parts.remove_file(MANIFEST)
        if self._out_dir.rmdir(os.path.basename(self.parts)):
            self._out_dir.sync()
            return
        try:
            left = parts.names()
        except OSError:
            left = []
        if left:
            shown = ", ".join(printable(n, 60) for n in left[:3]) + (", ..." if len(left) > 3 else "")
            self.notes.append(f"{printable(self.parts)} was left in place: it holds {len(left)} file(s) this "
                              f"export did not write ({shown}).")
