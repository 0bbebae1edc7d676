"""A document loaded onto one GL context: the engine objects every export
reads, and the base of the editor's live session."""
from __future__ import annotations

from dataclasses import replace

import numpy as np

from infinitex.engine.analysis import Analysis, AnalysisCancelled
from infinitex.engine.controls import NO_CONTROLS, Controls
from infinitex.engine.exemplar import Exemplar, ExemplarError
from infinitex.engine.gpu import Gpu
from infinitex.engine.imagefile import to_u8
from infinitex.engine.material import IMAGE, Material, luma, single
from infinitex.engine.params import SynthParams
from infinitex.engine.synth import Synthesizer
from infinitex.project import Document
from infinitex.project.realize import AnalysisJob, material_or_none


class LoadedDocument:
    """The engine objects realizing one document on one GL context: its
    exemplar, analysis, material (every map) and Synthesizer. What exports
    read (a headless EGL context for the command line and tests); the
    editor's live :class:`~infinitex.app.session.Session` extends it with the
    view's progressively refined pyramid."""

    # Install a quick preview analysis while the full one runs (the editor's
    # session); exports and the command line always wait for the full one.
    QUICK_ANALYSIS = False

    def __init__(self, gpu: Gpu, cache_dir: str | None = None):
        self.gpu = gpu
        self.quick_analysis = False                # the installed analysis is the quick preview
        self.cache_dir = cache_dir
        self.key: tuple | None = None          # analysis key installed
        self.exemplar: Exemplar | None = None
        self.analysis: Analysis | None = None
        self.material: Material | None = None  # every map (a single image: its one map)
        self._display: dict[str, np.ndarray] = {}  # uint8 stacks of the maps shown so far
        self.synth: Synthesizer | None = None
        self.stack: np.ndarray | None = None   # uint8 (L+1, m, m, C)
        self.job: AnalysisJob | None = None
        self.generation = 0                    # bumps when a new analysis is installed
        self.params: SynthParams | None = None
        self.period = 0  # tile mode: the canvas shows the periodic texture a toroidal export of this size makes
        self.controls: Controls = NO_CONTROLS
        self.synced_doc: Document | None = None  # the document whose parameters and controls are held
        self.failed: dict[tuple, str] = {}     # analysis keys that could not be loaded

    @property
    def ready(self) -> bool:
        return self.synth is not None

    @property
    def L(self) -> int:
        return self.analysis.L if self.analysis else 0

    # -- documents ----------------------------------------------------------

    def load(self, doc: Document, preview: bool | None = None, find_lattice: bool = False) -> AnalysisJob:
        """Start analyzing ``doc``'s exemplar (cancelling a job for another key);
        ``preview`` (default: the class's QUICK_ANALYSIS): install a quick
        preview analysis first (see ``poll``); ``find_lattice``: first look for
        a lattice in a single image (project.realize.with_found_lattice; the
        job's ``doc`` becomes the document with it)."""
        key = doc.analysis_key()
        if self.job is not None and not self.job.done:
            if self.job.asked_key == key and self.job.find_lattice == find_lattice:
                return self.job
            self.job.cancel()
        self.job = AnalysisJob(doc, self.cache_dir, preview=self.QUICK_ANALYSIS if preview is None else preview,
                               find_lattice=find_lattice)
        return self.job

    def doc_params(self, doc: Document, L: int | None = None) -> SynthParams:
        """The document's parameters, periodic in tile mode; the quick preview
        skips the fidelity stage (it is replaced soon: its refinement must leave
        the cores to the full analysis)."""
        params = doc.params(self.L if L is None else L)
        if self.quick_analysis:
            params = replace(params, fidelity=None)
        return replace(params, period=self.period) if self.period else params

    def poll(self) -> AnalysisJob | None:
        """Install a finished job; returns it once when it ends (success or not),
        and once before that when its quick preview is ready and installed
        (``quick_analysis`` stays true until the full analysis replaces it)."""
        job = self.job
        if job is None:
            return None
        if not job.done:
            preview = job.take_preview()
            if preview is None:
                return None
            self.install(*preview, preview=True)  # quick_analysis until the full analysis is installed
            job.shown_doc = preview[0]  # (the image as given: a lattice may be found after)
            return job  # the document can be shown (and edited) now
        self.job = None
        if job.analysis is not None:
            self.install(job.doc, job.exemplar, job.analysis, job.material)
            job.shown_doc = job.doc
        elif job.error:
            self.failed[job.key] = job.error
        return job

    def install(self, doc: Document, ex: Exemplar, an: Analysis, material: Material | None = None,
                preview: bool = False) -> None:
        if material is None:
            material = material_or_none(doc) or single(ex, [lv.stack for lv in an.levels])
        self.release_synthesis()
        self.quick_analysis = preview
        self.exemplar, self.analysis, self.material = ex, an, material
        self._display = {}
        self.params = self.doc_params(doc, an.L)
        self.controls = doc.controls(an.size)
        self.synced_doc = doc  # the document whose parameters and controls are held
        self.synth = Synthesizer(an, self.params, self.gpu, controls=self.controls)
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
        return [luma(lv) for lv in self.material.stack(self.material.primary)]

    def load_now(self, doc: Document) -> None:
        """Analyze and install synchronously (CLI, tests); raises on failure."""
        job = self.load(doc, preview=False)
        job.wait()
        self.poll()
        if job.error:
            raise ExemplarError(job.error)
        if job.cancelled:
            raise AnalysisCancelled()

    def release_synthesis(self) -> None:
        if self.synth is not None:
            self.synth.release()
        self.synth = None

    def release(self) -> None:
        if self.job is not None:
            self.job.cancel()
        self.release_synthesis()
