"""Window exports: a rectangle (or a toroidal tile) of a loaded document,
synthesized tile by tile within a time budget per step (so the editor stays
live), then every map written atomically as PNG or TIFF at 8, 16 or 32 bits,
optionally magnified (LH05 synthesis magnification) or in a lattice's
original geometry; and what an export writes, checked against what it reads
(no output may replace one of its own inputs)."""
from __future__ import annotations

import os
import re
import time
from collections.abc import Iterable
from dataclasses import dataclass, field, replace

import numpy as np

from infinitex.engine.controls.lattice import original_geometry_box, render_original
from infinitex.engine.imagefile import write_image, write_png
from infinitex.engine.material import MaterialError, export_depths, output_paths
from infinitex.engine.pyramid import Pyramid, Rect, SynthesisError
from infinitex.engine.safeio import printable
from infinitex.engine.synth import MAX_WINDOW_PIXELS as MAX_EXPORT_PIXELS
from infinitex.engine.subpixel import sample, turn_normals
from infinitex.engine.synth import MAX_WINDOW_SIDE as MAX_EXPORT_SIDE

from .formats import encode_coords
from .loaded import LoadedDocument

MAGNIFY_FACTORS = (1, 2, 4, 8)  # exports: output pixels per synthesized texel (synthesis magnification)


def colors_u8(stack: np.ndarray, coords: np.ndarray, level: int, wrap: bool = True) -> np.ndarray:
    """uint8 (H, W, C) colors of exemplar coordinates (H, W, 2) at ``level``
    ((H, W, 4) with sub-pixel remainders: bilinear, wrapped or clamped)."""
    return sample(stack[level], coords, wrap)


def export_outputs(material, out_path: str, maps: list[str] | None, depth: int | None) -> list[tuple[str, str, int]]:
    """[(role, path, depth)] an export of ``maps`` (default every map) to
    ``out_path`` writes; SynthesisError (one sentence) when it cannot."""
    roles = material.roles if maps is None else maps
    try:
        return output_paths(out_path, roles, export_depths(material, roles, depth, out_path))
    except MaterialError as exc:
        raise SynthesisError(str(exc)) from None


class ExportJob:
    """Synthesize a rectangle (or a toroidal tile) tile by tile, within a time
    budget per ``step`` so the editor stays live; then write PNGs atomically.

    The result does not depend on the tile size or order (the engine is
    order-independent), so the UI and the CLI produce the same file.
    """

    def __init__(self, session: LoadedDocument, rect: Rect, out_path: str, *, toroidal: int = 0,
                 coords_path: str | None = None, tile: int = 128, geometry: str = "rectified",
                 maps: list[str] | None = None, depth: int | None = None, magnify: int = 1):
        if session.synth is None:
            raise SynthesisError("Nothing to export yet: the exemplar is still being analyzed.")
        if rect.empty:
            raise SynthesisError("The export rectangle is empty.")
        if magnify not in MAGNIFY_FACTORS:
            raise SynthesisError(f"Magnification is one of {', '.join(map(str, MAGNIFY_FACTORS))}, not {magnify}.")
        self.magnify = magnify
        mat = session.material
        self.outputs = export_outputs(mat, out_path, maps, depth)
        if magnify > 1:
            if coords_path:
                raise SynthesisError("The coordinate map is exported at 1:1 (without magnification).")
            if rect.w * magnify > MAX_EXPORT_SIDE or rect.h * magnify > MAX_EXPORT_SIDE \
                    or rect.w * rect.h * magnify * magnify > MAX_EXPORT_PIXELS:
                raise SynthesisError(f"Magnified {magnify}x, {rect.w}x{rect.h} is {rect.w * magnify}x{rect.h * magnify}, "
                                     f"more than the {MAX_EXPORT_SIDE} px a side and "
                                     f"{MAX_EXPORT_PIXELS // 2**20} Mpixels an export may be.")
        if rect.w > MAX_EXPORT_SIDE or rect.h > MAX_EXPORT_SIDE or rect.w * rect.h > MAX_EXPORT_PIXELS:
            raise SynthesisError(f"Exports are limited to {MAX_EXPORT_SIDE} px a side and "
                                 f"{MAX_EXPORT_PIXELS // 2**20} Mpixels; {rect.w}x{rect.h} is too large.")
        self.session = session
        self.out_rect = rect
        self.out_path = out_path
        self.coords_path = coords_path
        an = session.analysis
        # With a lattice shown in the input's geometry, ``rect`` is in input
        # pixels: the rectified texels it reads are synthesized, then mapped back.
        self.lattice = session.controls.lattice if geometry == "original" and not toroidal else None
        if self.lattice is not None:
            if coords_path:
                raise SynthesisError("The coordinate map is exported in the rectified geometry only "
                                     "(each pixel of the original geometry blends four texels).")
            if magnify > 1:
                raise SynthesisError("A lattice in its original geometry is exported at 1:1 (without magnification).")
            rect = Rect(*original_geometry_box(self.lattice, an.size, rect.x0, rect.y0, rect.w, rect.h))
            if rect.w > MAX_EXPORT_SIDE or rect.h > MAX_EXPORT_SIDE or rect.w * rect.h > MAX_EXPORT_PIXELS:
                raise SynthesisError(f"This export reads {rect.w}x{rect.h} rectified texels, more than the "
                                     f"{MAX_EXPORT_SIDE} px a side and {MAX_EXPORT_PIXELS // 2**20} Mpixels allowed.")
        if magnify > 1:  # synthesis magnification blends each pixel's 4 nearest texels: one more on every side
            rect = Rect(rect.x0 - 1, rect.y0 - 1, rect.x1 + 1, rect.y1 + 1)
        self.rect = rect
        params = session.params
        if toroidal:
            params = replace(params, period=int(toroidal))
            params.validate(an.L)
            lat = session.controls.lattice
            if lat is not None:
                cx, cy = lat.cell(an.size)
                if toroidal % cx or toroidal % cy:
                    raise SynthesisError(f"A toroidal tile of whole cells needs a size that the lattice cell "
                                         f"({cx}x{cy} px) divides: {max(cx, cy, 32)} px or more.")
        self.period = params.period  # the toroidal tile's, or 0
        self.pyramid = Pyramid(session.gpu, session.synth.gan, params, scrolling=True, prefetch=0, chunk=16,
                               controls=session.controls)
        # What the files are made from, fixed now (the editor may install another analysis meanwhile).
        self.material, self.exemplar = session.material, session.exemplar
        self.stacks = {role: session.display_stack(role) for role, _, depth in self.outputs
                       if depth == 8 and self.lattice is None and magnify == 1}
        self.L = an.L
        self.directed = session.controls.directed
        self.direction = session.controls.direction  # fixed now, like the material (the editor may change it)
        self.coords = np.zeros((rect.h, rect.w, 4 if self.directed else 2), dtype=np.int32)
        self.tiles = [Rect(x, y, min(x + tile, rect.x1), min(y + tile, rect.y1))
                      for y in range(rect.y0, rect.y1, tile) for x in range(rect.x0, rect.x1, tile)]
        self.index = 0
        self.done = False
        self.cancelled = False
        self.error: str | None = None
        self.started = time.monotonic()

    @property
    def progress(self) -> float:
        return self.index / max(1, len(self.tiles))

    def cancel(self) -> None:
        self.cancelled = True
        self._close()

    def step(self, budget_s: float = 0.03) -> bool:
        """Do some tiles; True when finished (written, failed or cancelled)."""
        if self.done or self.cancelled:
            return True
        t0 = time.perf_counter()
        try:
            while self.index < len(self.tiles):
                t = self.tiles[self.index]
                self.pyramid.request(self.L, t)
                c = self.pyramid.read(self.L, t, self.directed)
                self.coords[t.y0 - self.rect.y0:t.y1 - self.rect.y0, t.x0 - self.rect.x0:t.x1 - self.rect.x0] = c
                self.index += 1
                if time.perf_counter() - t0 > budget_s:
                    return False
            self._write()
        except (OSError, SynthesisError, ValueError) as exc:
            self.error = str(exc)
        self.done = True
        self._close()
        return True

    def run(self, progress=None) -> None:
        """Run to the end (CLI); ``progress(fraction)`` may raise to cancel."""
        while not self.step(0.25):
            if progress:
                progress(self.progress)
        if progress and not self.cancelled:
            progress(1.0)
        if self.error:
            raise SynthesisError(self.error)

    def pixels(self, role: str) -> np.ndarray:
        """One map of the export, float32 (H, W, C) in [0, 1]."""
        if self.lattice is not None:
            ex, r = self.exemplar, self.out_rect
            source = ex.hires if ex.hires is not None else ex.pixels
            box = (self.rect.x0, self.rect.y0, self.rect.x1, self.rect.y1)
            return render_original(self.coords, box, self.lattice, ex.size, source, r.x0, r.y0, r.w, r.h)
        jac = None
        if self.directed:  # J per synthesized texel
            r = self.rect
            jac = self.direction.region(0, r.x0, r.y0, r.w, r.h, self.period)
        if self.magnify > 1:
            out = self.material.magnified(role, self.coords, self.magnify, jac)
            if jac is not None:
                jac = np.repeat(np.repeat(jac[1:-1, 1:-1], self.magnify, axis=0), self.magnify, axis=1)
        else:
            out = self.material.lookup(role, self.coords)
        if role == "normal" and jac is not None:  # normals turn with the texture
            out = turn_normals(out, jac)
        return out

    def _write(self) -> None:
        for role, path, depth in self.outputs:
            if role in self.stacks and not (role == "normal" and self.directed):  # pixels() turns normals
                # 8 bits at 1:1: looked up in the uint8 stack (a quarter of the memory)
                write_png(path, colors_u8(self.stacks[role], self.coords, self.L, self.material.toroidal))
            else:
                write_image(path, self.pixels(role), depth, self.material.maps[role].exemplar.value_range)
        if self.coords_path:
            write_png(self.coords_path, encode_coords(self.coords))

    def _close(self) -> None:
        if self.pyramid is not None:
            self.pyramid.release()
            self.pyramid = None


# -- an export's writes and its own inputs -----------------------------------------


class OwnInputError(ValueError):
    """An export would write over (or remove) one of the files it reads; the
    message is one sentence naming it."""


MAX_SCANNED = 100_000  # folder entries looked at for hard links to an input under a tile's name


@dataclass
class Writes:
    """Everything an export writes: files (written or replaced), folders
    (a Zarr store, a parts folder: replaced or removed, so nothing inside may
    be an input) and tile sets ``(base, cols, rows)``: the files
    ``BASE.<UDIM>.png`` (or ``BASE_u<U>_v<V>.png``) of every tile."""

    files: list[str] = field(default_factory=list)
    folders: list[str] = field(default_factory=list)
    tile_sets: list[tuple[str, int, int]] = field(default_factory=list)

    def add(self, other: Writes) -> Writes:
        self.files += other.files
        self.folders += other.folders
        self.tile_sets += other.tile_sets
        return self


def streamed_writes(out: str, fmt: str, w: int, h: int, tile: int, coords: bool = False) -> Writes:
    """What a streamed export (:class:`~infinitex.export.TiledExport`) of a
    ``w`` x ``h`` rectangle into ``out`` writes: its files or tile sets, and
    its parts folder ``OUT.parts`` (removed once the export is complete)."""
    base = os.path.splitext(out)[0]
    maps = ("", "_coords") if coords and fmt != "zarr" else ("",)
    wr = Writes(folders=[out + ".parts"])
    if fmt == "zarr":
        wr.folders.append(out)
    elif fmt == "tiff":
        wr.files += [out if not m else f"{base}{m}.tif" for m in maps]
    else:
        cols, rows = -(-w // tile), -(-h // tile)
        wr.tile_sets += [(base + m, cols, rows) for m in maps]
    return wr


def _stat(path: str) -> os.stat_result | None:
    try:
        return os.stat(path)
    except (OSError, ValueError):
        return None


def same_file(a: str, b: str) -> bool:
    """Do two paths name one file: the same real path (a symbolic link to
    it counts), or, both existing, the same device and inode (a hard link)?"""
    try:
        if os.path.realpath(a) == os.path.realpath(b):
            return True
    except (OSError, ValueError):
        return False
    sa = _stat(a)
    sb = _stat(b) if sa is not None else None
    return sb is not None and os.path.samestat(sa, sb)


def _inside(path: str, folder: str) -> bool:
    try:
        real, top = os.path.realpath(path), os.path.realpath(folder)
    except (OSError, ValueError):  # a name no file can have
        return False
    return real == top or real.startswith(top.rstrip(os.sep) + os.sep)


def _same_folder(a: str, b: str) -> bool:
    return same_file(a or os.curdir, b or os.curdir)


def is_tile_name(name: str, stem: str, cols: int, rows: int) -> bool:
    """Is ``name`` the file of one tile of a ``cols`` x ``rows`` set named
    ``stem`` (formats.udim_name: ``STEM.1001.png``..., past 10 columns
    ``STEM_u1_v1.png``...)?"""
    if cols <= 10:
        m = re.fullmatch(re.escape(stem) + r"\.([0-9]{4,9})\.png", name)
        if not m:
            return False
        n = int(m.group(1)) - 1001
        return n >= 0 and n % 10 < cols and n // 10 < rows and m.group(1) == str(n + 1001)
    m = re.fullmatch(re.escape(stem) + r"_u([0-9]{1,9})_v([0-9]{1,9})\.png", name)
    if not m:
        return False
    u, v = int(m.group(1)), int(m.group(2))
    return 1 <= u <= cols and 1 <= v <= rows and m.group(0) == f"{stem}_u{u}_v{v}.png"


def _in_tile_set(path: str, base: str, cols: int, rows: int) -> bool:
    """Is ``path`` (or the file it links to) one of the set's tiles?"""
    folder, stem = os.path.split(base)
    try:
        names = {path, os.path.realpath(path)}
    except (OSError, ValueError):
        return False
    for p in names:
        d, name = os.path.split(p)
        if is_tile_name(name, stem, cols, rows) and _same_folder(d, folder):
            return True
    return False


def _linked_tiles(base: str, cols: int, rows: int, inputs: dict[tuple[int, int], str]) -> str | None:
    """An input that an existing file under one of the set's tile names is
    (a symbolic or hard link to it), looked for among the first MAX_SCANNED
    entries of the set's folder; the input's path, or None."""
    folder, stem = os.path.split(base)
    try:
        with os.scandir(folder or os.curdir) as it:
            for i, e in enumerate(it):
                if i >= MAX_SCANNED:
                    break
                if is_tile_name(e.name, stem, cols, rows):
                    st = _stat(e.path)
                    if st is not None and (st.st_dev, st.st_ino) in inputs:
                        return inputs[(st.st_dev, st.st_ino)]
    except (OSError, ValueError):
        pass
    return None


def check_own_inputs(writes: Writes, inputs: Iterable[str | None]) -> None:
    """Refuse (:class:`OwnInputError`, one sentence naming the file) an export
    that would replace or remove one of its own inputs: an output that is an
    input (the same real path, or a link to it), an input a tile set's names
    would produce (or a file under such a name that is a link to an input),
    or an input inside a folder the export replaces or removes. Reads nothing
    but names and file metadata: call it before any work."""
    inputs = [os.fspath(p) for p in inputs if p]
    if not inputs:
        return

    def refuse(out: str, inp: str, how: str = "") -> None:
        name, other = os.path.basename(out), os.path.basename(inp)
        if how:
            msg = f"{printable(other)} is an input of this export, {how}; choose another output name."
        elif name == other:
            msg = f"{printable(name)} is an input of this export; choose another output name."
        else:
            msg = (f"{printable(name)} is the file {printable(inp)}, an input of this export; "
                   "choose another output name.")
        raise OwnInputError(msg)
    for out in writes.files:
        for inp in inputs:
            if same_file(out, inp):
                refuse(out, inp)
    for folder in writes.folders:
        for inp in inputs:
            if _inside(inp, folder):
                refuse(folder, inp, f"inside {printable(folder)}, which the export replaces or removes")
    identities = {(st.st_dev, st.st_ino): p for p in inputs if (st := _stat(p)) is not None}
    for base, cols, rows in writes.tile_sets:
        shown = f"{printable(os.path.basename(base))}.<UDIM>.png" if cols <= 10 else \
            f"{printable(os.path.basename(base))}_u<U>_v<V>.png"
        for inp in inputs:
            if _in_tile_set(inp, base, cols, rows):
                refuse(base, inp, f"and one of the tiles {shown} would replace it")
        hit = _linked_tiles(base, cols, rows, identities)
        if hit is not None:
            refuse(base, hit, f"and one of the tiles {shown} is a link to it")
