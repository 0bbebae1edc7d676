"""Tile-set exports (``wang.py``) of a loaded document: the windows
synthesized piece by piece within a time budget per step (so the editor
stays live), the set composed, then every map's atlas, the JSON description,
the preview of a random arrangement and, on request, one file per tile,
written atomically."""
from __future__ import annotations

import json
import os
import threading
import time
from dataclasses import replace

import numpy as np

from infinitex.engine.imagefile import encode_image
from infinitex.engine.pyramid import Pyramid, Rect, SynthesisError
from infinitex.engine.safeio import StagedFiles

from .engines import ENGINES, EngineFiles, engine_files, write_engine_files
from .loaded import LoadedDocument
from .window import export_outputs
from .wang import TileSetBuilder, TileSetError, TileSetPlan, assemble

PREVIEW_TILES = 8       # the preview: a random valid arrangement of 8 x 8 tiles
PREVIEW_SIDE = 4096     # at most this many pixels a side (halved until it fits)
PIECE = (2048, 1 << 20)  # windows are synthesized in pieces at most this wide and of at most this many
                         # pixels (pieces of 128 px made a 512 px window 2.3-2.6x slower: each is padded)
STEP_S = 0.1            # and each piece in steps of about this long (the pyramid's pacer cuts its draws)
PACE_S = 0.05           # seconds of GPU work a cut draw aims at (the editor's 6 ms would waste the GPU's queue)


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


def _beside(out_path: str):
    """Paths as the JSON beside ``out_path`` names them (relative to its folder)."""
    base = os.path.dirname(out_path) or os.curdir
    return lambda path: os.path.relpath(path, base)


def set_description(plan: TileSetPlan, out_path: str, maps: dict[str, str], preview: str, engines: EngineFiles,
                    tiles: list[dict]) -> dict:
    """A set's JSON description (the editor's, the command line's and the API's)."""
    cols, rows = plan.grid
    rel = _beside(out_path)
    return {
        "format": "infinitex-tile-set", "version": 1,
        "kind": "corner-wang" if plan.colors > 1 else "variants",
        "colors": plan.colors if plan.colors > 1 else 1, "tile": plan.tile, "count": plan.count,
        "columns": cols, "rows": rows,
        # the atlas of a corner set is itself a valid arrangement (a packing): it tiles too
        "atlas_tiles": plan.colors > 1,
        "maps": {role: rel(path) for role, path in maps.items()},
        "preview": rel(preview),
        "engines": engines.describe(rel),
        "tiles": tiles,
    }


class Mender:
    """The mend of a set made outside a TileSetJob (the API, the bench): a
    finest-level corrector of the synthesis ``synth`` (periodic for variants
    of an N px tile), called as TileSetBuilder's ``correct``; ``release`` it."""

    def __init__(self, synth, L: int, period: int = 0):
        params = replace(synth.params, period=period) if period else synth.params
        self.L = L
        self.pyramid = Pyramid(synth.gpu, synth.gan, params, scrolling=False, controls=synth.controls)

    def __call__(self, padded: np.ndarray, q: int, origin: tuple[int, int]) -> np.ndarray:
        return correct_tile(self.pyramid, self.L, padded, q, origin)

    def release(self) -> None:
        self.pyramid.release()


def correct_tile(pyr: Pyramid, L: int, padded: np.ndarray, q: int, origin: tuple[int, int]) -> np.ndarray:
    """The finest level's correction of a composed N x N tile of coordinates
    (``padded``: with q px around it), placed at ``origin`` of the canvas: (N, N, 2)."""
    n = padded.shape[0] - 2 * q
    rect = Rect(origin[0], origin[1], origin[0] + n, origin[1] + n)
    region = pyr.padded(L, rect)
    ys = np.clip(np.arange(region.y0, region.y1) - rect.y0 + q, 0, n + 2 * q - 1)
    xs = np.clip(np.arange(region.x0, region.x1) - rect.x0 + q, 0, n + 2 * q - 1)
    return pyr.correct(L, rect, padded[ys[:, None], xs[None, :]])


class TileSetJob:
    """Make a tile set, a piece of work per ``step`` within a time budget
    (editor) or to the end (``run``: CLI); ``built`` once the set is made
    (``atlas``: its coordinates). With an output (``set_output``, or
    ``out_path`` here) it is then written: in a thread of its own by
    ``step`` (the editor stays live), at once by ``run``. ``outputs``: the
    maps' atlases [(role, path, depth)]; ``writes``: every file written."""

    def __init__(self, session: LoadedDocument, plan: TileSetPlan, out_path: str | None = None, *,
                 maps: list[str] | None = None, depth: int | None = None, per_tile: bool = False,
                 preview_seed: int = 0, engines: tuple[str, ...] = ENGINES):
        if session.synth is None:
            raise SynthesisError("Nothing to export yet: the exemplar is still being analyzed.")
        if session.controls.directed:
            raise SynthesisError("A tile set follows no direction field: its tiles meet in any order. "
                                 "Turn the direction field off to export one.")
        plan.validate()
        self.session, self.plan, self.material = session, plan, session.material
        self.out_path: str | None = None
        self.outputs: list[tuple[str, str, int]] = []
        if out_path is not None:
            self.set_output(out_path, maps=maps, depth=depth, per_tile=per_tile, preview_seed=preview_seed,
                            engines=engines)
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
                                      lambda: self._render(self.periodic, Rect(0, 0, plan.tile, plan.tile)),
                                      self._correct)
        self._work = self.builder.build()
        self._piece = 0.0  # fraction of the current request (a row of builder.making windows) done
        self._pace(STEP_S)
        self.atlas: np.ndarray | None = None
        self._pixels: dict[str, np.ndarray] = {}
        self._writer: threading.Thread | None = None
        self.built = False
        self.done = False
        self.cancelled = False
        self.error: str | None = None
        self.started = time.monotonic()

    def set_output(self, out_path: str, *, maps: list[str] | None = None, depth: int | None = None,
                   per_tile: bool = False, preview_seed: int = 0, engines: tuple[str, ...] = ENGINES) -> None:
        """Where (and how) the set is written: every map's atlas at ``out_path``
        (``OUT_ROLE.png`` for a material), its description and preview beside it,
        and the ``engines``' resources (``engines.py``: Tiled, Godot)."""
        self.outputs = export_outputs(self.material, out_path, maps, depth)
        self.engines = engine_files(out_path, self.outputs, self.material.primary, tuple(engines))
        self.out_path, self.per_tile, self.preview_seed = out_path, per_tile, preview_seed
        self.paths = set_paths(out_path)
        cols, rows = self.plan.grid
        self.out_rect = Rect(0, 0, cols * self.plan.tile, rows * self.plan.tile)
        self.coords_path = None

    @property
    def writes(self) -> list[str]:
        files = [p for _, p, _ in self.outputs] + [self.paths["json"], self.paths["preview"]] + self.engines.files
        if self.per_tile:
            files += [tile_file(p, t) for _, p, _ in self.outputs for t in self.plan.tiles()]
        return files

    def summary(self) -> str:
        """What was written, for the editor's notice."""
        p = self.plan
        kind = f"corner Wang, {p.colors} colours" if p.colors > 1 else "variants"
        others = ", ".join(os.path.basename(f) for f in [self.paths["json"], self.paths["preview"]] + self.engines.files)
        return (f"Exported {p.count} tiles of {p.tile} px ({kind}) to {os.path.abspath(self.out_path)} "
                f"(and {others})")

    @property
    def progress(self) -> float:
        b = self.builder
        part = min(1.0, (b.work_done + max(1, b.making) * self._piece) / max(1, b.work_total))
        return part if not self.outputs else part * 0.85 + (0.15 if self.done else 0.0)

    def _correct(self, padded: np.ndarray, q: int, origin: tuple[int, int]) -> np.ndarray:
        return correct_tile(self.periodic or self.pyramid, self.L, padded, q, origin)

    def _appearance(self, coords: np.ndarray) -> np.ndarray:
        return self.material.lookup(self.material.primary, coords)

    def _render(self, pyr: Pyramid, rect: Rect):
        out = np.zeros((rect.h, rect.w, 2), np.int32)
        pw = min(rect.w, PIECE[0])
        ph = max(1, min(rect.h, PIECE[1] // pw))
        pieces = [Rect(x, y, min(x + pw, rect.x1), min(y + ph, rect.y1))
                  for y in range(rect.y0, rect.y1, ph) for x in range(rect.x0, rect.x1, pw)]
        for i, t in enumerate(pieces):
            # A piece's request spread over steps of about STEP_S (one draw of a level at fidelity 4 under load
            # took seconds: the progress bar and Cancel wait for a step, never for a whole piece).
            pyr.requests.start(self.L, t)
            while not pyr.requests.advance(time.perf_counter() + self._step_s):
                self._piece = (i + min(0.99, pyr.requests.pixels / max(1, pyr.requests.total))) / len(pieces)
                yield
            out[t.y0 - rect.y0:t.y1 - rect.y0, t.x0 - rect.x0:t.x1 - rect.x0] = pyr.read(self.L, t, False)
            self._piece = (i + 1) / len(pieces)
            yield
        self._piece = 0.0
        return out

    def _pace(self, step_s: float) -> None:
        """Steps of about ``step_s`` (the editor's frame budget, or STEP_S),
        their draws cut to at most PACE_S."""
        self._step_s = step_s
        for pyr in (self.pyramid, self.periodic):
            if pyr is not None:
                pyr.pacer.piece_s = min(PACE_S, step_s / 2)

    def cancel(self) -> None:
        self.cancelled = True
        self._close()

    def step(self, budget_s: float = 0.03) -> bool:
        """Do some work; True when finished: built (without an output),
        written, failed or cancelled. The writing runs in a thread."""
        if self.done or self.cancelled:
            return True
        try:
            if not self.built:
                self._pace(budget_s)
                t0 = time.perf_counter()
                while not self._advance():
                    if time.perf_counter() - t0 > budget_s:
                        return False
            if not self.outputs:
                return True
            if self._writer is None:
                self._writer = threading.Thread(target=self._write_safely, name="tile-set-writer", daemon=True)
                self._writer.start()
            if self._writer.is_alive():
                return False
        except (OSError, SynthesisError, TileSetError, ValueError) as exc:
            self.error = str(exc)
        self.done = True
        self._close()
        return True

    def _advance(self) -> bool:
        """One piece of the build; True once built (the pyramids are then released)."""
        try:
            next(self._work)
            return False
        except StopIteration as stop:
            self.atlas = stop.value
        self.built = True
        self._close()
        return True

    def _write_safely(self) -> None:
        try:
            self.write()
        except (OSError, SynthesisError, ValueError) as exc:
            self.error = str(exc)

    def run(self, progress=None) -> None:
        """Build and write to the end (CLI); ``progress(fraction)`` may raise to cancel."""
        self._pace(STEP_S)
        while not self.built:
            t0 = time.perf_counter()
            while not self._advance() and time.perf_counter() - t0 < 0.25:
                pass
            if progress:
                progress(self.progress)
        if self.outputs:
            self.write()
        self.done = True
        if progress:
            progress(1.0)

    def map_pixels(self, role: str) -> np.ndarray:
        """One map's atlas, float32 (H, W, C) in [0, 1]."""
        px = self._pixels.get(role)
        if px is None:
            px = self._pixels[role] = self.material.lookup(role, self.atlas)
        return px

    def arranged(self, seed: int = 0, tiles: int = PREVIEW_TILES, role: str | None = None) -> np.ndarray:
        """A random valid arrangement of ``tiles`` x ``tiles`` of one map
        (default: the first), float32, at most PREVIEW_SIDE px a side."""
        role = role or self.material.primary
        out = assemble(self.map_pixels(role), self.plan, self.plan.arrangement(tiles, tiles, seed))
        while max(out.shape[:2]) > PREVIEW_SIDE:
            h, w = out.shape[0] // 2 * 2, out.shape[1] // 2 * 2
            out = out[:h, :w].reshape(h // 2, 2, w // 2, 2, -1).mean(axis=(1, 3))
        return out

    def description(self) -> dict:
        tiles = self.plan.tiles()
        if self.per_tile:
            rel = _beside(self.out_path)
            for t in tiles:
                t["files"] = {role: rel(tile_file(path, t)) for role, path, _ in self.outputs}
        return set_description(self.plan, self.out_path, {role: path for role, path, _ in self.outputs},
                               self.paths["preview"], self.engines, tiles)

    def write(self) -> None:
        """Write every map's atlas (and each tile's file), the preview, the
        engines' files and the description, as one unit (safeio.StagedFiles:
        all written beside their names first, then renamed; a failure or a
        kill before then leaves the old set whole)."""
        p = self.plan
        StagedFiles.check(self.writes)
        with StagedFiles() as stage:
            for role, path, depth in self.outputs:
                px = self.map_pixels(role)
                rng = self.material.maps[role].exemplar.value_range
                stage.write(path, encode_image(px, depth, rng))
                if self.per_tile:
                    for t in p.tiles():
                        stage.write(tile_file(path, t),
                                    encode_image(px[t["y"]:t["y"] + p.tile, t["x"]:t["x"] + p.tile], depth, rng))
            primary = self.material.primary
            stage.write(self.paths["preview"], encode_image(self.arranged(self.preview_seed, role=primary), 8,
                                                            self.material.maps[primary].exemplar.value_range))
            if self.engines.files:
                cols, rows = p.grid
                size = (cols * p.tile, rows * p.tile)
                write_engine_files(p, self.engines, {role: (path, size) for role, path, _ in self.outputs}, primary,
                                   p.arrangement(PREVIEW_TILES, PREVIEW_TILES, self.preview_seed), stage.write)
            stage.write(self.paths["json"], (json.dumps(self.description(), indent=1) + "\n").encode())
            stage.commit()

    def _close(self) -> None:
        for name in ("pyramid", "periodic"):
            pyr = getattr(self, name, None)
            if pyr is not None:
                pyr.release()
                setattr(self, name, None)
