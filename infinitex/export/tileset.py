"""Tile-set exports (``wang.py``) of a loaded document: the windows
synthesized piece by piece within a time budget per step (so the editor
stays live), the set composed, then every map's atlas, the JSON description,
the preview of a random arrangement and, on request, one file per tile,
written atomically."""
from __future__ import annotations

import json
import os
import time
from dataclasses import replace

import numpy as np

from infinitex.engine.imagefile import write_image
from infinitex.engine.material import MaterialError, export_depths, output_paths
from infinitex.engine.pyramid import Pyramid, Rect, SynthesisError
from infinitex.engine.safeio import atomic_write

from .loaded import LoadedDocument
from .wang import TileSetBuilder, TileSetError, TileSetPlan, assemble

PREVIEW_TILES = 8       # the preview: a random valid arrangement of 8 x 8 tiles
PREVIEW_SIDE = 4096     # at most this many pixels a side (halved until it fits)
PIECE = 128             # windows are synthesized in pieces of this size (one per step at most)


def set_paths(out: str) -> dict[str, str]:
    """The description and preview beside an atlas ``OUT.png``: ``OUT.json``,
    ``OUT_preview.png``."""
    base = os.path.splitext(out)[0]
    return {"json": base + ".json", "preview": base + "_preview.png"}


def tile_file(path: str, tile: dict) -> str:
    """One tile's own file beside a map's atlas: ``SET_0110.png`` (its corner
    colours nw ne sw se) or ``SET_v3.png`` (a variant)."""
    base, ext = os.path.splitext(path)
    if "variant" in tile:
        return f"{base}_v{tile['variant']}{ext}"
    return f"{base}_{tile['nw']}{tile['ne']}{tile['sw']}{tile['se']}{ext}"


def plan_for(session: LoadedDocument, colors: int, tile: int, variants: int = 0,
             origin: tuple[int, int] = (0, 0)) -> TileSetPlan:
    """The plan of a set of this document: its lattice's cell, windows around ``origin``."""
    lat = session.controls.lattice
    cell = tuple(lat.cell(session.analysis.size)) if lat is not None else (1, 1)
    plan = TileSetPlan(colors, tile, variants if colors == 1 else 0, cell, origin)
    plan.validate()
    return plan


class TileSetJob:
    """Make and write a tile set, a piece of work per ``step`` within a time
    budget (editor) or to the end (``run``: CLI, API). ``outputs``: the maps'
    atlases [(role, path, depth)]; ``writes``: every file written."""

    def __init__(self, session: LoadedDocument, out_path: str, plan: TileSetPlan, *,
                 maps: list[str] | None = None, depth: int | None = None, per_tile: bool = False,
                 preview_seed: int = 0):
        if session.synth is None:
            raise SynthesisError("Nothing to export yet: the exemplar is still being analyzed.")
        if session.controls.directed:
            raise SynthesisError("A tile set follows no direction field: its tiles meet in any order. "
                                 "Turn the direction field off to export one.")
        plan.validate()
        mat = session.material
        roles = mat.roles if maps is None else maps
        try:
            self.outputs = output_paths(out_path, roles, export_depths(mat, roles, depth, out_path))
        except MaterialError as exc:
            raise SynthesisError(str(exc)) from None
        self.session, self.plan, self.out_path = session, plan, out_path
        self.per_tile, self.preview_seed = per_tile, preview_seed
        self.paths = set_paths(out_path)
        self.material = mat
        self.L = session.analysis.L
        params = session.params
        self.pyramid = Pyramid(session.gpu, session.synth.gan, params, scrolling=True, prefetch=0, chunk=16,
                               controls=session.controls)
        self.periodic: Pyramid | None = None
        if plan.colors == 1:
            periodic = replace(params, period=plan.tile)
            periodic.validate(self.L)
            self.periodic = Pyramid(session.gpu, session.synth.gan, periodic, scrolling=True, prefetch=0,
                                    chunk=16, controls=session.controls)
        self.builder = TileSetBuilder(plan, lambda r: self._render(self.pyramid, r), self._appearance,
                                      lambda: self._render(self.periodic, Rect(0, 0, plan.tile, plan.tile)))
        self._work = self.builder.build()
        self._piece = 0.0  # fraction of the current window done
        self.atlas: np.ndarray | None = None
        self.done = False
        self.cancelled = False
        self.error: str | None = None
        self.started = time.monotonic()

    @property
    def writes(self) -> list[str]:
        files = [p for _, p, _ in self.outputs] + [self.paths["json"], self.paths["preview"]]
        if self.per_tile:
            files += [tile_file(p, t) for _, p, _ in self.outputs for t in self.plan.tiles()]
        return files

    @property
    def progress(self) -> float:
        b = self.builder
        return min(1.0, (b.work_done + self._piece) / max(1, b.work_total)) * 0.95 + (0.05 if self.done else 0.0)

    def _appearance(self, coords: np.ndarray) -> np.ndarray:
        return self.material.lookup(self.material.primary, coords)

    def _render(self, pyr: Pyramid, rect: Rect):
        out = np.zeros((rect.h, rect.w, 2), np.int32)
        pieces = [Rect(x, y, min(x + PIECE, rect.x1), min(y + PIECE, rect.y1))
                  for y in range(rect.y0, rect.y1, PIECE) for x in range(rect.x0, rect.x1, PIECE)]
        for i, t in enumerate(pieces):
            pyr.request(self.L, t)
            out[t.y0 - rect.y0:t.y1 - rect.y0, t.x0 - rect.x0:t.x1 - rect.x0] = pyr.read(self.L, t, False)
            self._piece = (i + 1) / len(pieces)
            yield
        self._piece = 0.0
        return out

    def cancel(self) -> None:
        self.cancelled = True
        self._close()

    def step(self, budget_s: float = 0.03) -> bool:
        """Do some work; True when finished (written, failed or cancelled)."""
        if self.done or self.cancelled:
            return True
        t0 = time.perf_counter()
        try:
            while True:
                try:
                    next(self._work)
                except StopIteration as stop:
                    self.atlas = stop.value
                    break
                if time.perf_counter() - t0 > budget_s:
                    return False
            self._close()
            self._write()
        except (OSError, SynthesisError, TileSetError, ValueError) as exc:
            self.error = str(exc)
        self.done = True
        self._close()
        return True

    def run(self, progress=None) -> None:
        """Run to the end; ``progress(fraction)`` may raise to cancel."""
        while not self.step(0.25):
            if progress:
                progress(self.progress)
        if progress and not self.cancelled:
            progress(1.0)
        if self.error:
            raise SynthesisError(self.error)

    def map_pixels(self, role: str) -> np.ndarray:
        """One map's atlas, float32 (H, W, C) in [0, 1]."""
        return self.material.lookup(role, self.atlas)

    def description(self) -> dict:
        p = self.plan
        cols, rows = p.grid
        base = os.path.dirname(self.out_path)
        rel = lambda path: os.path.relpath(path, base or os.curdir)  # noqa: E731 - names beside the JSON
        tiles = p.tiles()
        if self.per_tile:
            for t in tiles:
                t["files"] = {role: rel(tile_file(path, t)) for role, path, _ in self.outputs}
        return {
            "format": "infinitex-tile-set", "version": 1,
            "kind": "corner-wang" if p.colors > 1 else "variants",
            "colors": p.colors if p.colors > 1 else 1, "tile": p.tile, "count": p.count,
            "columns": cols, "rows": rows,
            # the atlas of a corner set is itself a valid arrangement (a packing): it tiles too
            "atlas_tiles": p.colors > 1,
            "maps": {role: rel(path) for role, path, _ in self.outputs},
            "preview": rel(self.paths["preview"]),
            "tiles": tiles,
        }

    def _write(self) -> None:
        p = self.plan
        primary = None
        for role, path, depth in self.outputs:
            px = self.map_pixels(role)
            rng = self.material.maps[role].exemplar.value_range
            write_image(path, px, depth, rng)
            if self.per_tile:
                for t in p.tiles():
                    write_image(tile_file(path, t), px[t["y"]:t["y"] + p.tile, t["x"]:t["x"] + p.tile], depth, rng)
            if primary is None or role == self.material.primary:
                primary = (px, rng)
        layout = p.arrangement(PREVIEW_TILES, PREVIEW_TILES, self.preview_seed)
        preview = assemble(primary[0], p, layout)
        while max(preview.shape[:2]) > PREVIEW_SIDE:
            h, w = preview.shape[0] // 2 * 2, preview.shape[1] // 2 * 2
            preview = preview[:h, :w].reshape(h // 2, 2, w // 2, 2, -1).mean(axis=(1, 3))
        write_image(self.paths["preview"], preview, 8, primary[1])
        atomic_write(self.paths["json"], (json.dumps(self.description(), indent=1) + "\n").encode())

    def _close(self) -> None:
        for name in ("pyramid", "periodic"):
            pyr = getattr(self, name, None)
            if pyr is not None:
                pyr.release()
                setattr(self, name, None)
