"""The engine side of an open document: analysis in the background, the view's
synthesis pyramid refined progressively under a time budget, and exports.

A :class:`Session` lives on one GL context (the editor's window, or a headless
EGL context for the CLI and tests). It never imports imgui; it turns a
:class:`~app.document.Document` into engine objects and keeps them in step
with it (``sync``), so undo/redo, opening a project and editing a slider all
go through the same path.
"""
from __future__ import annotations

import math
import threading
import time
from dataclasses import dataclass, replace

import numpy as np

from infinitex.engine.analysis import Analysis, AnalysisCancelled, AnalysisSettings, analyze
from infinitex.engine.controls import NO_CONTROLS, Controls
from infinitex.engine.exemplar import (
    Exemplar,
    ExemplarError,
    decode_full,
    load_exemplar_bytes,
    to_u8,
    write_image,
    write_png,
)
from infinitex.engine.gpu import Gpu
from infinitex.engine.material import (
    IMAGE,
    Material,
    MaterialError,
    export_depths,
    load_material,
    output_paths,
    single,
)
from infinitex.engine.lattice import LatticeError, original_geometry_box, rectified_exemplar, render_original
from infinitex.engine.params import SynthParams
from infinitex.engine.pyramid import Pyramid, Rect, SynthesisError
from infinitex.engine.synth import MAX_WINDOW_PIXELS as MAX_EXPORT_PIXELS
from infinitex.engine.synth import MAX_WINDOW_SIDE as MAX_EXPORT_SIDE
from infinitex.engine.synth import Synthesizer
from infinitex.engine.tiled_export import decode_coords, encode_coords  # noqa: F401  (re-exported)

from .document import Document, View

MAGNIFY_FACTORS = (1, 2, 4, 8)  # exports: output pixels per synthesized texel (synthesis magnification)
MIN_BAND = 32  # rows: thinner bands cost more in correction margins than they save


def colors_u8(stack: np.ndarray, coords: np.ndarray, level: int) -> np.ndarray:
    """uint8 (H, W, C) colors of exemplar coordinates (H, W, 2) at ``level``."""
    return stack[level][coords[..., 1], coords[..., 0]]


# -- analysis in the background ----------------------------------------------


class AnalysisJob:
    """Decode the exemplar and analyze it on a worker thread (numpy and scipy
    release the GIL for the heavy parts); poll ``done``; ``cancel()`` stops it."""

    def __init__(self, doc: Document, cache_dir: str | None = None):
        self.doc = doc
        self.key = doc.analysis_key()
        self.cache_dir = cache_dir
        self.progress = 0.0
        self.message = "Reading the exemplar"
        self.exemplar: Exemplar | None = None
        self.analysis: Analysis | None = None
        self.material: Material | None = None
        self.error: str | None = None
        self.cancelled = False
        self.started = time.monotonic()
        self._cancel = threading.Event()
        self._thread = threading.Thread(target=self._run, name="analysis", daemon=True)
        self._thread.start()

    @property
    def done(self) -> bool:
        return not self._thread.is_alive()

    def wait(self, timeout: float | None = None) -> bool:
        self._thread.join(timeout)
        return self.done

    def cancel(self) -> None:
        self._cancel.set()

    def _progress(self, frac: float, msg: str) -> None:
        if self._cancel.is_set():
            raise AnalysisCancelled()
        self.progress = 0.05 + 0.95 * float(frac)
        self.message = msg

    def _run(self) -> None:
        d = self.doc
        try:
            material = material_for(d) if d.maps else None
            ex, settings = exemplar_for(d, material=material)
            self._progress(0.0, "Analyzing")
            an = analyze(ex, settings, cache_dir=self.cache_dir, progress=self._progress)
            if material is None:
                material = single(ex, [lv.stack for lv in an.levels])  # the same Gaussian stack
            for role in material.roles:  # every map's stack, off the GUI thread
                self.message = f"Filtering the {role} map"
                material.stack(role)
            self.exemplar, self.analysis, self.material = ex, an, material
        except AnalysisCancelled:
            self.cancelled = True
        except (ExemplarError, LatticeError) as exc:
            self.error = str(exc)
        except MemoryError:
            self.error = f"Not enough memory to analyze {d.exemplar.name}."
        except Exception as exc:
            self.error = f"Analyzing {d.exemplar.name} failed: {exc}"


@dataclass
class ProjectSynthesizer:
    """Makes, in another process, the Synthesizer of a project: what export
    workers receive (the project as JSON with its exemplar embedded, not
    pickled engine objects). Each worker has its own headless GL context."""

    project_json: str
    period: int = 0
    role: str = ""  # a material's map the tiles show ("": the first map)

    def __call__(self) -> Synthesizer:
        from .document import parse_project_json, project_from_json
        doc = project_from_json(parse_project_json(self.project_json.encode("utf-8"))).document
        material = material_for(doc) if doc.maps else None
        ex, settings = exemplar_for(doc, material=material)
        an = analyze(ex, settings)  # the disk cache holds it: the parent analyzed it already
        params = doc.params(an.L)
        if self.period:
            params = replace(params, period=self.period)
        synth = Synthesizer(an, params, controls=doc.controls(an.size))
        if material is not None:
            synth.palette = material.stack(self.role or material.primary)
        return synth


def material_for(doc: Document) -> Material:
    """The maps of a material document, decoded and fitted (all or nothing)."""
    return load_material([(role, src.name, src.data) for role, src in doc.maps], fit=doc.fit, toroidal=doc.toroidal)


def exemplar_for(doc: Document, image: np.ndarray | None = None,
                 material: Material | None = None) -> tuple[Exemplar, AnalysisSettings]:
    """The exemplar a document synthesizes from (a lattice's rectified block,
    the image by its fit rule, or a material's analysis maps side by side)
    and the analysis settings for it. ``image``: the exemplar file already
    decoded whole (decode_full), if at hand; ``material``: the document's
    material, if already loaded."""
    if doc.maps:
        material = material or material_for(doc)
        ex = material.guide(doc.weight_dict())
        if doc.model == "color" and ex.channels > 4:
            raise MaterialError(f"The color model compares at most 4 channels, and this material's analysis maps "
                                f"have {ex.channels}; use the appearance model or fewer analysis maps.")
        return ex, AnalysisSettings(model=doc.model, k=doc.k, feature_weight=doc.feature_weight)
    if doc.lattice is not None:
        if image is None:
            image = decode_full(doc.exemplar.data, doc.exemplar.name)
        ex = rectified_exemplar(image, doc.lattice, source=doc.exemplar.name)
        grid = (doc.lattice.nx, doc.lattice.ny)
    else:
        ex = load_exemplar_bytes(doc.exemplar.data, name=doc.exemplar.name, fit=doc.fit, toroidal=doc.toroidal)
        grid = (0, 0)
    return ex, AnalysisSettings(model=doc.model, k=doc.k, lattice=grid, feature_weight=doc.feature_weight)


# -- progressive refinement --------------------------------------------------


@dataclass
class Frame:
    """What the canvas needs this frame: the level shown and the texels it covers."""

    level: int            # display level ld
    want: Rect            # level-ld texels covering the canvas (plus a 1-texel border)


def frame_for(view: View, w: int, h: int, L: int, level: int | None = None,
              geom: np.ndarray | None = None) -> Frame:
    """The display level for the view's zoom (coarser levels when zoomed out:
    the pyramid is the mipmap) and the rectangle of it the canvas covers.

    ``geom`` (2x2), when the canvas shows a lattice in the input's geometry,
    maps view positions to synthesized (rectified) canvas positions."""
    tlx, tly = view.top_left(w, h)
    brx, bry = tlx + w / view.zoom, tly + h / view.zoom
    zoom = view.zoom
    if geom is not None:
        corners = np.array([[tlx, tly], [brx, tly], [tlx, bry], [brx, bry]]) @ np.asarray(geom).T
        tlx, tly = corners.min(axis=0)
        brx, bry = corners.max(axis=0)
        zoom = view.zoom / float(np.linalg.norm(geom, 2))  # screen px per rectified px, at least
    k = 0 if zoom >= 1.0 else min(L, int(round(-math.log2(zoom))))
    ld = L - k
    if level is not None:
        ld = max(0, min(ld, level))
    k = L - ld
    s = 1 << k
    want = Rect(math.floor(tlx / s) - 1, math.floor(tly / s) - 1, math.floor(brx / s) + 2, math.floor(bry / s) + 2)
    return Frame(ld, want)


def level_rect(want: Rect, from_level: int, to_level: int) -> Rect:
    r = want
    for _ in range(from_level - to_level):
        r = r.half()
    return r.pad(1, 1, 1, 1) if to_level < from_level else r


class Refiner:
    """Brings a scrolling pyramid to a frame coarse level first, within a time
    budget per call; a level too big for the budget grows in row bands.

    Every level is refined to ``plan[l]``: everything the frame's level will
    read, so refining that level band by band never sends a coarser one back
    for more."""

    def __init__(self, pyramid: Pyramid, gpu: Gpu):
        self.pyramid = pyramid
        self.gpu = gpu
        L = pyramid.an.L
        self.cost = [2e-6] * (L + 1)  # seconds per synthesized pixel, learned per level
        self.last_pixels = 0
        self.last_ms = 0.0
        self.version = 0  # bumps whenever pixels were synthesized
        self.extra_pixels = 0  # synthesized outside step/preview (local updates), reported with the next

    def _valid(self, level: int) -> Rect | None:
        buf = self.pyramid.buffers[level]
        return buf.valid if buf is not None else None

    def holds(self, level: int, rect: Rect) -> bool:
        valid = self._valid(level)
        return valid is not None and valid.contains(rect)

    def _missing(self, level: int, want: Rect) -> int:
        """Pixels of ``want`` the level does not hold yet."""
        valid = self._valid(level)
        have = want.intersect(valid) if valid is not None else Rect(0, 0, 0, 0)
        return want.w * want.h - (0 if have.empty else have.w * have.h)

    def _request(self, level: int, rect: Rect) -> int:
        """Synthesize, wait for the GPU, and learn the level's cost per pixel."""
        t = time.perf_counter()
        n = self.pyramid.request(level, rect)
        self.gpu.ctx.finish()
        if n > 256:
            self.cost[level] = 0.5 * self.cost[level] + 0.5 * (time.perf_counter() - t) / n
        return n

    def _done(self, t0: float, pixels: int) -> None:
        self.last_pixels = pixels + self.extra_pixels
        self.extra_pixels = 0
        self.version += bool(pixels)
        self.last_ms = (time.perf_counter() - t0) * 1000.0

    def preview(self, frame: Frame, budget_s: float, min_level: int = 2) -> int:
        """While the user drags a control: complete whole levels, coarse to fine,
        as long as the next one fits in the budget (no bands: a preview is
        consistent everywhere). Returns the finest complete level."""
        t0 = time.perf_counter()
        plan = self.pyramid.plan(frame.level, frame.want)
        pixels = 0
        done = -1
        for l, want in enumerate(plan):
            if not self.holds(l, want):
                spent = time.perf_counter() - t0
                if l > min_level and spent + self._missing(l, want) * self.cost[l] > budget_s:
                    break
                pixels += self._request(l, want)
            done = l
        self._done(t0, pixels)
        return done

    def step(self, frame: Frame, budget_s: float) -> bool:
        """Synthesize for at most about ``budget_s``; True when the frame is exact."""
        t0 = time.perf_counter()
        pixels = 0
        finished = True
        for l, want in enumerate(self.pyramid.plan(frame.level, frame.want)):
            if self.holds(l, want):
                continue
            remaining = budget_s - (time.perf_counter() - t0)
            cost = self._missing(l, want) * self.cost[l]
            if pixels and cost > remaining:
                finished = False  # do not start a big piece late in the frame
                break
            rect = want
            if cost > max(remaining, 0.25 * budget_s) and want.h > 16:
                valid = self._valid(l)
                grow = (valid is not None and valid.x0 <= want.x0 and valid.x1 >= want.x1
                        and valid.y0 <= want.y0 < valid.y1)
                start = valid.y1 if grow else want.y0
                rows = int(max(remaining, 0.25 * budget_s) / (self.cost[l] * (want.w + 24)))
                rect = Rect(want.x0, want.y0, want.x1, min(want.y1, start + max(MIN_BAND, rows)))
            pixels += self._request(l, rect)
            if rect != want:
                finished = False
                break
        self._done(t0, pixels)
        return finished


# -- the session -------------------------------------------------------------


class Session:
    """The engine objects realizing one document on one GL context."""

    def __init__(self, gpu: Gpu, cache_dir: str | None = None):
        self.gpu = gpu
        self.cache_dir = cache_dir
        self.key: tuple | None = None          # analysis key installed
        self.exemplar: Exemplar | None = None
        self.analysis: Analysis | None = None
        self.material: Material | None = None  # every map (a single image: its one map)
        self._display: dict[str, np.ndarray] = {}  # uint8 stacks of the maps shown so far
        self.synth: Synthesizer | None = None
        self.pyramid: Pyramid | None = None
        self.refiner: Refiner | None = None
        self.stack: np.ndarray | None = None   # uint8 (L+1, m, m, C)
        self.job: AnalysisJob | None = None
        self.generation = 0                    # bumps when a new analysis is installed
        self.params: SynthParams | None = None
        self.period = 0  # tile mode: the canvas shows the periodic texture a toroidal export of this size makes
        self.controls: Controls = NO_CONTROLS
        self.failed: dict[tuple, str] = {}     # analysis keys that could not be loaded

    @property
    def ready(self) -> bool:
        return self.synth is not None

    @property
    def L(self) -> int:
        return self.analysis.L if self.analysis else 0

    # -- documents ----------------------------------------------------------

    def load(self, doc: Document) -> AnalysisJob:
        """Start analyzing ``doc``'s exemplar (cancelling a job for another key)."""
        key = doc.analysis_key()
        if self.job is not None and not self.job.done:
            if self.job.key == key:
                return self.job
            self.job.cancel()
        self.job = AnalysisJob(doc, self.cache_dir)
        return self.job

    def sync(self, doc: Document) -> None:
        """Keep the engine in step with ``doc``: new analysis key -> analyze;
        new parameters -> the pyramid drops only the levels they change."""
        key = doc.analysis_key()
        if key != self.key:
            if (self.job is None or self.job.key != key) and key not in self.failed:
                self.load(doc)
            return
        params = self.doc_params(doc)
        controls = doc.controls(self.analysis.size)
        if params != self.params:
            self.params, self.controls = params, controls
            self.synth.set_params(params, controls)
            self.pyramid.set_params(params, controls)
        elif controls != self.controls:
            # Paint on the canvas, placed features: re-synthesized in place where
            # they reach (a change of the exemplar field refines everything).
            self.controls = controls
            self.synth.set_params(params, controls)
            self.pyramid.update_controls(controls)
            self.refiner.version += 1
            self.refiner.extra_pixels += self.pyramid.pixels_synthesized

    def doc_params(self, doc: Document, L: int | None = None) -> SynthParams:
        """The document's parameters, periodic in tile mode."""
        params = doc.params(self.L if L is None else L)
        return replace(params, period=self.period) if self.period else params

    def poll(self) -> AnalysisJob | None:
        """Install a finished job; returns it once when it ends (success or not)."""
        job = self.job
        if job is None or not job.done:
            return None
        self.job = None
        if job.analysis is not None:
            self.install(job.doc, job.exemplar, job.analysis, job.material)
        elif job.error:
            self.failed[job.key] = job.error
        return job

    def install(self, doc: Document, ex: Exemplar, an: Analysis, material: Material | None = None) -> None:
        if material is None:
            material = material_for(doc) if doc.maps else single(ex, [lv.stack for lv in an.levels])
        self.release_synthesis()
        self.exemplar, self.analysis, self.material = ex, an, material
        self._display = {}
        self.params = self.doc_params(doc, an.L)
        self.controls = doc.controls(an.size)
        self.synth = Synthesizer(an, self.params, self.gpu, controls=self.controls)
        self.pyramid = Pyramid(self.gpu, self.synth.gan, self.params, scrolling=True, prefetch=16,
                               controls=self.controls)
        self.refiner = Refiner(self.pyramid, self.gpu)
        self.stack = self.display_stack(material.primary)
        self.key = doc.analysis_key()
        self.generation += 1

    def shown_map(self, role: str) -> str:
        """The map the canvas shows for a display setting ("": the first map)."""
        mat = self.material
        return role if mat is not None and role in mat.maps else (mat.primary if mat else IMAGE)

    def display_stack(self, role: str) -> np.ndarray:
        """A map's Gaussian stack as uint8 (L+1, m, m, C), as the canvas shows it."""
        role = self.shown_map(role)
        st = self._display.get(role)
        if st is None:
            st = self._display[role] = np.stack([to_u8(lv) for lv in self.material.stack(role)])
        return st

    def shape_map(self) -> tuple[str, str]:
        """(kind, map) that shapes the lit preview: the normal map, else the
        height map, else the first map's luminance read as height ("luma")."""
        maps = self.material.maps
        if "normal" in maps:
            return "normal", "normal"
        if "height" in maps:
            return "height", "height"
        return "height", "luma"

    def shape_stack(self, role: str) -> list[np.ndarray]:
        """The float stack of a lit preview's shaping map ("luma": the first map's luminance)."""
        if role != "luma":
            return self.material.stack(role)
        from infinitex.engine.material import luma
        return [luma(lv) for lv in self.material.stack(self.material.primary)]

    def load_now(self, doc: Document) -> None:
        """Analyze and install synchronously (CLI, tests); raises on failure."""
        job = self.load(doc)
        job.wait()
        self.poll()
        if job.error:
            raise ExemplarError(job.error)
        if job.cancelled:
            raise AnalysisCancelled()

    # -- synthesis ----------------------------------------------------------

    def refine(self, frame: Frame, budget_s: float) -> bool:
        if self.refiner is None:
            return False
        return self.refiner.step(frame, budget_s)

    def release_synthesis(self) -> None:
        if self.pyramid is not None:
            self.pyramid.release()
        if self.synth is not None:
            self.synth.release()
        self.synth = self.pyramid = self.refiner = None

    def release(self) -> None:
        if self.job is not None:
            self.job.cancel()
        self.release_synthesis()


# -- exports -----------------------------------------------------------------


class ExportCancelled(Exception):
    pass


class ExportJob:
    """Synthesize a rectangle (or a toroidal tile) tile by tile, within a time
    budget per ``step`` so the editor stays live; then write PNGs atomically.

    The result does not depend on the tile size or order (the engine is
    order-independent), so the UI and the CLI produce the same file.
    """

    def __init__(self, session: Session, rect: Rect, out_path: str, *, toroidal: int = 0,
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
        roles = mat.roles if maps is None else maps
        try:
            self.outputs = output_paths(out_path, roles, export_depths(mat, roles, depth, out_path))
        except MaterialError as exc:
            raise SynthesisError(str(exc)) from None
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
        self.pyramid = Pyramid(session.gpu, session.synth.gan, params, scrolling=True, prefetch=0, chunk=16,
                               controls=session.controls)
        # What the files are made from, fixed now (the editor may install another analysis meanwhile).
        self.material, self.exemplar = session.material, session.exemplar
        self.stacks = {role: session.display_stack(role) for role, _, depth in self.outputs
                       if depth == 8 and self.lattice is None and magnify == 1}
        self.L = an.L
        self.coords = np.zeros((rect.h, rect.w, 2), dtype=np.int32)
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
                c = self.pyramid.read(self.L, t)
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
        if self.magnify > 1:
            return self.material.magnified(role, self.coords, self.magnify)
        return self.material.lookup(role, self.coords)

    def _write(self) -> None:
        for role, path, depth in self.outputs:
            if role in self.stacks:  # 8 bits at 1:1: looked up in the uint8 stack (a quarter of the memory)
                write_png(path, colors_u8(self.stacks[role], self.coords, self.L))
            else:
                write_image(path, self.pixels(role), depth, self.material.maps[role].exemplar.value_range)
        if self.coords_path:
            write_png(self.coords_path, encode_coords(self.coords))

    def _close(self) -> None:
        if self.pyramid is not None:
            self.pyramid.release()
            self.pyramid = None


# -- streamed exports (tile sets, BigTIFF) --------------------------------------


def export_key(doc: Document, params: SynthParams, role: str = "") -> str:
    """What decides a streamed export's pixels: the whole document (exemplar
    embedded) and the parameters. The editor and the CLI compute the same key,
    so either resumes what the other left."""
    import hashlib
    import json

    from .document import Project, project_to_json
    return hashlib.sha256(json.dumps([project_to_json(Project(doc), embed=True), repr(params)]
                                     + ([role] if role else []), sort_keys=True).encode()).hexdigest()


def project_synthesizer(doc: Document, period: int = 0, role: str = "") -> ProjectSynthesizer:
    import json

    from .document import Project, project_to_json
    return ProjectSynthesizer(json.dumps(project_to_json(Project(doc), embed=True)), period, role)


class StreamedExport:
    """A streamed export (``engine.tiled_export``) run from the editor: worker
    processes (their own GL contexts) render the tiles, a thread of this
    process writes them, and the UI polls ``progress``, ``rate`` and
    ``finished``; ``cancel`` stops after the tiles being rendered, keeping
    the finished ones for a later run (the same export resumes)."""

    def __init__(self, doc: Document, L: int, rect: Rect, out_path: str, fmt: str, tile: int,
                 workers: int, coords: bool = False, role: str = ""):
        from infinitex.engine.tiled_export import TiledExport
        params = doc.params(L)
        self.job = TiledExport(None, rect, out_path, fmt, tile, key=export_key(doc, params, role), coords=coords, L=L)
        self.init = project_synthesizer(doc, role=role)
        self.out_path, self.rect, self.out_rect, self.fmt, self.workers = out_path, rect, rect, fmt, max(1, workers)
        self.done_tiles = 0
        self.started = time.monotonic()
        self._first: tuple[float, int] | None = None  # (time, tiles) when the first rendered tile came back
        self.finished = False
        self.cancelled = False
        self.cancelling = False
        self.error: str | None = None
        self.thread = threading.Thread(target=self._run, name="streamed-export", daemon=True)
        self.thread.start()

    def _progress(self, done: int, total: int) -> None:
        self.done_tiles = done
        if self._first is None and self.job.rendered:
            self._first = (time.monotonic(), self.job.rendered)

    def _run(self) -> None:
        from infinitex.engine.tiled_export import ExportFailed, ExportInterrupted
        try:
            self.job.run(self._progress, workers=self.workers, worker_init=self.init)
        except ExportInterrupted:
            self.cancelled = True
        except (OSError, ExportFailed, ValueError) as exc:
            self.error = str(exc)
        except Exception as exc:  # noqa: BLE001 - a worker's failure, reported, never a crash of the editor
            self.error = f"The export failed: {exc}"
        finally:
            self.finished = True

    @property
    def progress(self) -> float:
        return self.done_tiles / max(1, self.job.total)

    @property
    def kept(self) -> int:
        return self.job.kept

    def rate(self) -> float | None:
        """Pixels per second of the tiles rendered by this run (after the first,
        which includes the workers' start-up)."""
        if self._first is None:
            return None
        t0, n0 = self._first
        n = self.job.rendered - n0
        dt = time.monotonic() - t0
        if n <= 0 or dt <= 0:
            return None
        return n * self.job.tile ** 2 / dt

    def seconds_left(self) -> float | None:
        r = self.rate()
        if r is None:
            return None
        return (self.job.total - self.done_tiles) * self.job.tile ** 2 / r

    def cancel(self) -> None:
        self.cancelling = True
        self.job.cancel_event.set()

    def wait(self, timeout: float | None = None) -> bool:
        self.thread.join(timeout)
        return self.finished


class ExportEstimate:
    """The size and time of a streamed export, estimated before it starts:
    one worker process (as the export uses) renders and encodes a tile, in
    the background; ``result`` is (seconds per pixel, bytes per pixel) once
    measured. The process is started and awaited by a thread of its own, as
    for StreamedExport: the GUI thread never spawns or joins processes."""

    def __init__(self, doc: Document, fmt: str, tile: int):
        self.key = (doc.analysis_key(), fmt, tile)
        self.init = project_synthesizer(doc)
        self.result: tuple[float, float] | None = None
        self.error: str | None = None
        self.pool = None
        self.closed = False
        self.finished = False
        self.thread = threading.Thread(target=self._run, name="export-estimate", daemon=True)
        self.thread.start()

    def _run(self) -> None:
        import multiprocessing
        from concurrent.futures import ProcessPoolExecutor

        from infinitex.engine.tiled_export import calibrate
        try:
            with ProcessPoolExecutor(1, mp_context=multiprocessing.get_context("spawn")) as pool:
                self.pool = pool
                if not self.closed:
                    self.result = pool.submit(calibrate, self.init, self.key[1], self.key[2]).result()
        except Exception as exc:  # noqa: BLE001 - an estimate that failed says so; the export may still work
            if not self.closed:
                self.error = str(exc) or type(exc).__name__
        finally:
            self.finished = True

    def poll(self) -> bool:
        """True once measured (or failed); the worker is then gone."""
        return self.finished

    def close(self, wait: float = 0.0) -> None:
        """Stop the measuring worker now (an estimate nobody waits for)."""
        self.closed = True
        pool = self.pool
        if pool is not None and not self.finished:
            for proc in list((getattr(pool, "_processes", None) or {}).values()):
                proc.terminate()
        if wait:
            self.thread.join(wait)

    def describe(self, w: int, h: int, workers: int, folder: str) -> tuple[str, bool]:
        """One line for the panel ("about 1.2 GB, about 25 min"), and whether the
        disk lacks room for it."""
        if self.error is not None:
            return f"No estimate ({self.error}).", False
        if self.result is None:
            return "Estimating size and time (rendering a sample tile)...", False
        s_px, b_px = self.result
        pixels = w * h
        size = pixels * b_px
        # Measured with one worker. More workers mostly overlap encoding and
        # writing: a software GL (llvmpipe) already spreads one worker over
        # every core, and one GPU is shared (bench/export.py: 2 workers 1.04x).
        seconds = pixels * s_px
        import shutil
        try:
            free = shutil.disk_usage(folder or ".").free
        except OSError:
            free = None
        need = size * (2.1 if self.key[1] == "tiff" else 1.1)  # a TIFF's parts and the file coexist a moment
        low = free is not None and need > free
        text = f"About {_bytes(size)} and {duration_text(seconds)} with {workers} worker{'s' * (workers > 1)}"
        if low:
            text += f"; only {_bytes(free)} free there"
        return text + ".", low


def _bytes(n: float) -> str:
    for unit in ("bytes", "KB", "MB", "GB", "TB"):
        if n < 1000 or unit == "TB":
            return f"{n:.0f} {unit}" if unit == "bytes" else f"{n:.1f} {unit}"
        n /= 1000
    return ""


def duration_text(s: float) -> str:
    """A duration for people: 42 s, 17 min, 3.2 h."""
    if s < 90:
        return f"{max(1, round(s))} s"
    if s < 5400:
        return f"{round(s / 60)} min"
    return f"{s / 3600:.1f} h"
