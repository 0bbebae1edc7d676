"""The live view's engine side: an open document (:class:`Session`, a
:class:`~infinitex.export.loaded.LoadedDocument`) whose synthesis pyramid is
refined progressively under a time budget per frame.

A :class:`Session` lives on the editor's GL context (or a headless EGL context
in tests). It never imports imgui; it turns a
:class:`~infinitex.project.Document` into engine objects and keeps them in
step with it (``sync``), so undo/redo, opening a project and editing a slider
all go through the same path.
"""
from __future__ import annotations

import math
import time
from dataclasses import dataclass

import numpy as np

from infinitex.engine.analysis import Analysis
from infinitex.engine.exemplar import Exemplar
from infinitex.engine.gpu import Gpu
from infinitex.engine.material import Material
from infinitex.engine.pyramid import Pyramid, Rect
from infinitex.export.loaded import LoadedDocument
from infinitex.project import Document, View

from .model_session import ModelPreview
from .settings import config_dir
from .warmup import ShaderWarmup

MIN_BAND = 32  # rows: thinner bands cost more in correction margins than they save
BAND_S = 0.6  # seconds of synthesis per band of a level too big to refine at once


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
    budget per call, so the editor's frames stay short: the synthesis runs a
    piece of a draw at a time (:meth:`SpreadRequests.start`), and a level too
    big to show at once grows in row bands, the visible centre first.

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
        self._job_s = 0.0  # seconds spent on the request in progress

    @property
    def shows_texture(self) -> bool:
        """Some level holds synthesized pixels (the canvas has texture to draw)."""
        return any(buf is not None and buf.valid is not None and not buf.valid.empty
                   for buf in self.pyramid.buffers)

    def _valid(self, level: int) -> Rect | None:
        buf = self.pyramid.buffers[level]
        return buf.valid if buf is not None else None

    def holds(self, level: int, rect: Rect) -> bool:
        valid = self._valid(level)
        return valid is not None and valid.contains(rect)

    def _complete(self, plan: list[Rect]) -> int:
        """The finest level complete over ``plan`` (a frame's), with every coarser one (-1: none)."""
        return next((l - 1 for l, want in enumerate(plan) if not self.holds(l, want)), len(plan) - 1)

    def _missing(self, level: int, want: Rect) -> int:
        """Pixels of ``want`` the level does not hold yet."""
        valid = self._valid(level)
        have = want.intersect(valid) if valid is not None else Rect(0, 0, 0, 0)
        return want.w * want.h - (0 if have.empty else have.w * have.h)

    def _request(self, level: int, rect: Rect) -> int:
        """Synthesize at once, wait for the GPU, and learn the level's cost per pixel."""
        t = time.perf_counter()
        n = self.pyramid.request(level, rect)
        self.gpu.ctx.finish()
        if n > 256:
            self.cost[level] = 0.5 * self.cost[level] + 0.5 * (time.perf_counter() - t) / n
        return n

    def _done(self, t0: float, pixels: int) -> None:
        self.last_pixels = pixels
        self.last_ms = (time.perf_counter() - t0) * 1000.0

    def _band(self, l: int, want: Rect, n: int) -> Rect:
        """The next band of ``n`` rows of ``want`` to synthesize, the visible
        centre first: a band across the middle, then growing what the level
        holds up or down, toward the side that misses more. The level's
        rectangle grows by union (Pyramid._target), so each band adds only its
        own rows."""
        valid = self._valid(l)
        if (valid is None or valid.x0 > want.x0 or valid.x1 < want.x1
                or valid.y1 <= want.y0 or valid.y0 >= want.y1):
            y0 = max(want.y0, min((want.y0 + want.y1) // 2 - n // 2, want.y1 - n))
            return Rect(want.x0, y0, want.x1, min(want.y1, y0 + n))
        above, below = max(0, valid.y0 - want.y0), max(0, want.y1 - valid.y1)
        if below >= above:
            return Rect(want.x0, max(want.y0, valid.y0), want.x1, min(want.y1, valid.y1 + n))
        return Rect(want.x0, max(want.y0, valid.y0 - n), want.x1, min(want.y1, valid.y1))

    def coarse(self, frame: Frame, budget_s: float, min_level: int = 2, max_level: int | None = None) -> int:
        """While a dragged control changes: complete whole levels, coarse to fine
        (no bands: each shown level is consistent everywhere), a piece of a draw at a
        time for about ``budget_s``, carried on over frames (a level of a large
        view can cost more than a frame on a CPU). Levels up to ``min_level``
        are made at once; past ``max_level``, a whole level only when its
        estimated cost fits in what is left of the budget (a GPU: the view's
        own level every frame). Returns the finest level complete over the frame."""
        t0 = time.perf_counter()
        deadline = t0 + budget_s
        pyr = self.pyramid
        plan = pyr.plan(frame.level, frame.want)
        needs = pyr.plan(frame.level, frame.want, grown=True)  # (what a missing level is asked for)
        top = len(plan) - 1 if max_level is None else max_level
        pixels = 0
        while True:
            missing = next((l for l, want in enumerate(plan) if not self.holds(l, want)), None)
            if missing is not None and missing > top:
                # Past max_level: a whole level at once only when it fits in what is left.
                if time.perf_counter() - t0 + self._missing(missing, plan[missing]) * self.cost[missing] > budget_s:
                    break
                pixels += self._request(missing, needs[missing])  # (drops a request in progress)
                continue
            job = pyr.requests.current
            if job is not None and (missing is None or job != (missing, needs[missing])):
                pyr.requests.end()  # the view moved, or a refinement's band: whole levels here
                job = None
            if missing is None:
                break
            if job is None:
                if missing <= min_level:
                    pixels += self._request(missing, needs[missing])
                    continue
                if deadline - time.perf_counter() < 0.5 * pyr.pacer.piece_s:
                    break
                pyr.requests.start(missing, needs[missing])
                self._job_s = 0.0
            done, n = self._advance(missing, deadline)
            pixels += n
            if not done:
                break
        self._done(t0, pixels)
        return self._complete(plan) if missing is None or missing > top else missing - 1

    def _advance(self, level: int, deadline: float) -> tuple[bool, int]:
        """Carry the request in progress (of ``level``) on until ``deadline``;
        learn the level's cost per pixel when it ends. (done, pixels synthesized)."""
        pyr = self.pyramid
        t = time.perf_counter()
        before = pyr.requests.pixels
        done = pyr.requests.advance(deadline)
        self._job_s += time.perf_counter() - t
        if done and pyr.requests.pixels > 256:
            self.cost[level] = 0.5 * self.cost[level] + 0.5 * self._job_s / pyr.requests.pixels
        return done, pyr.requests.pixels - before

    def _start(self, l: int, want: Rect) -> None:
        """Start the request for level l: all it misses, or a band of about
        BAND_S seconds (at least four times its margins tall, which cost as
        much as they save) where that is much more."""
        pyr = self.pyramid
        ml, mr, mt, mb = pyr.margins[l]
        min_band = max(MIN_BAND, 4 * (mt + mb))
        rect = want
        if self._missing(l, want) * self.cost[l] > 1.5 * BAND_S and want.h > 1.5 * min_band:
            rows = int(BAND_S / (self.cost[l] * (want.w + ml + mr)))
            rect = self._band(l, want, max(min_band, rows))
        pyr.requests.start(l, rect)
        self._job_s = 0.0

    def step(self, frame: Frame, budget_s: float) -> bool:
        """Synthesize for about ``budget_s`` (a piece of a draw may overrun it a
        little); True when the frame is exact."""
        t0 = time.perf_counter()
        deadline = t0 + budget_s
        pyr = self.pyramid
        plan = pyr.plan(frame.level, frame.want)
        needs = None
        # This frame's edits shown at once as quick looks (patches) unless their
        # exact update fits in the frame (about: a coarse level's change spreads).
        work = 0.0
        if pyr.looks.wanted:
            work = sum(pyr.padded(l, r).area * self.cost[l] for l, rects in enumerate(pyr.updates.dirty) for r in rects)
        pixels = pyr.looks.look(frame.level, frame.want, skip=work < 0.5 * budget_s)
        # At least one step; then no new piece of work with less than half a
        # piece's time left (it would overrun the frame).
        first = True
        while first or deadline - time.perf_counter() > 0.5 * pyr.pacer.piece_s:
            first = False
            missing = next((l for l, want in enumerate(plan) if not self.holds(l, want)), None)
            job = pyr.requests.current
            if job is not None:
                level, rect = job
                if missing is None or level >= len(plan) or rect.intersect(plan[level]).empty:
                    pyr.requests.end()  # the view moved away from it
                    continue
                pixels += self._advance(level, deadline)[1]
                continue
            if not pyr.settled and (missing is None or pyr.updates.updating):
                # A paint dab or a feature move: shown next. When the view also
                # misses pixels (a pan meanwhile), the region in progress ends
                # first and the request shares the frame: strips synthesized
                # then are exact or get marked by the update (Pyramid.settle).
                before = pyr.pixels_synthesized
                remaining = deadline - time.perf_counter()
                if missing is None:
                    pyr.settle(remaining)
                else:
                    pyr.settle(remaining / 2, regions=1)
                pixels += pyr.pixels_synthesized - before
                continue
            if missing is None:
                break
            if needs is None:
                needs = pyr.plan(frame.level, frame.want, grown=True)
            self._start(missing, needs[missing])
        self._done(t0, pixels)
        return (pyr.settled and pyr.requests.current is None
                and all(self.holds(l, want) for l, want in enumerate(plan)))


# -- the session -------------------------------------------------------------


def _reads_alike(a, b, r: Rect) -> bool:
    """Whether two controls' canvas fields read the same over ``r`` (Session.verify_regions)."""
    from infinitex.engine.controls import CanvasField, CanvasLabels, DirectionField
    from infinitex.engine.controls.direction import IDENTITY
    from infinitex.engine.controls.fields import NEUTRAL

    def region(field, blank):
        v = field.region(0, r.x0, r.y0, r.w, r.h)
        return np.broadcast_to(np.asarray(blank), (r.h, r.w) + np.shape(blank)) if v is None else v
    fa, fb = a.randomness_canvas or CanvasField(), b.randomness_canvas or CanvasField()
    da, db = a.direction or DirectionField(), b.direction or DirectionField()
    la, lb = a.labels_canvas or CanvasLabels(), b.labels_canvas or CanvasLabels()
    xs, ys = np.arange(r.x0, r.x1), np.arange(r.y0, r.y1)
    return (np.array_equal(region(fa, NEUTRAL), region(fb, NEUTRAL))
            and np.array_equal(region(da, IDENTITY), region(db, IDENTITY))
            and np.array_equal(la.sample(xs, ys), lb.sample(xs, ys))
            and set(a.features) == set(b.features))


class Session(LoadedDocument):
    """A loaded document and the view's scrolling pyramid, refined per frame.

    Opening an image shows a texture at once: a quick analysis without
    similarity sets is installed first (``quick_analysis``), and the full one
    replaces it when it is ready (the view stays where it is)."""

    QUICK_ANALYSIS = True
    # Tests: check that the region each edit says it reached holds every change
    # the two controls show (Controls.changed_rects); what it misses is listed here.
    verify_regions = False
    missed_regions: list = []

    def __init__(self, gpu: Gpu, cache_dir: str | None = None):
        super().__init__(gpu, cache_dir)
        self.pyramid: Pyramid | None = None
        self.refiner: Refiner | None = None
        self.model = ModelPreview()  # the document's model, textured live (app/model_session.py)
        self.warmup = ShaderWarmup(config_dir())  # the shader variants of the next edits, compiled aside

    def sync(self, doc: Document, changed: tuple | None = None) -> None:
        """Keep the engine in step with ``doc``: new analysis key -> analyze;
        new parameters -> the pyramid drops only the levels they change; new
        controls -> re-synthesized where they changed: ``changed``, the
        finest-level canvas rectangles the edits since the last sync reached
        (History.changes_between), else found by comparing the controls."""
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
            if self.verify_regions and changed is not None:
                self._verify(controls, changed)
            self.controls = controls
            self.synth.set_params(params, controls)
            # The work is done a budget at a time by the refinement, so a dab
            # never holds the editor up (see Pyramid.settle).
            self.pyramid.update_controls(controls, None if changed is None else list(changed), defer=True)
        self.synced_doc = doc
        self.model.sync(self, doc)

    def poll(self):
        """Once a frame: the analysis job (LoadedDocument.poll) and the shader warm-up process."""
        self.warmup.poll()
        return super().poll()

    def _verify(self, controls, changed) -> None:
        from infinitex.engine.rect import uncovered
        if self.controls.reaches_everywhere(controls):
            return
        found = [Rect(*r) for r in self.controls.changed_rects(controls)]
        # (The boxes found hold every changed pixel, and some that are not:
        # only a pixel that changed outside ``changed`` is a miss.)
        missed = [r for r in uncovered(found, [Rect(*r) for r in changed])
                  if not _reads_alike(self.controls, controls, r)]
        if missed:
            Session.missed_regions.append((changed, missed))

    def install(self, doc: Document, ex: Exemplar, an: Analysis, material: Material | None = None,
                preview: bool = False) -> None:
        super().install(doc, ex, an, material, preview)
        self.pyramid = Pyramid(self.gpu, self.synth.gan, self.params, scrolling=True, prefetch=16,
                               controls=self.controls)
        self.refiner = Refiner(self.pyramid, self.gpu)
        if not preview and an.size <= 512:  # (larger analyses are not cached: the process would redo them)
            import json
            from infinitex.project import Project, project_to_json
            self.warmup.start(json.dumps(project_to_json(Project(doc), embed=True)), self.gpu.renderer)

    def refine(self, frame: Frame, budget_s: float) -> bool:
        if self.refiner is None:
            return False
        return self.refiner.step(frame, budget_s)

    def release(self) -> None:
        self.warmup.stop()
        super().release()

    def release_synthesis(self) -> None:
        self.model.release()
        if self.pyramid is not None:
            self.pyramid.release()
        self.pyramid = self.refiner = None
        super().release_synthesis()
