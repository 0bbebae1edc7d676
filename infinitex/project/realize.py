"""What a document is made of for the engine (CPU only, no GL): its exemplar
(a lattice's rectified block, the image by its fit rule, or a material's
analysis maps side by side), the analysis settings, its material, and the
analysis run on a worker thread (:class:`AnalysisJob`)."""
from __future__ import annotations

import threading
import time
from dataclasses import replace
from typing import TYPE_CHECKING

import numpy as np

from infinitex.engine.analysis import (
    Analysis,
    AnalysisCancelled,
    AnalysisSettings,
    analyze,
    is_cached,
    search_k,
)
from infinitex.engine.controls.lattice import LatticeError, rectified_exemplar
from infinitex.engine.exemplar import (
    Exemplar,
    ExemplarError,
    decode_full,
    load_exemplar_bytes,
)
from infinitex.engine.material import IMAGE, Material, MaterialError, load_material, single
from infinitex.engine.palette import PaletteLayout, check_palette_budget, pack_palette
from infinitex.engine.tileable import tileable_exemplar, tileable_material

from .document import Document, ProjectError

if TYPE_CHECKING:
    from infinitex.engine.controls.lattice import Detection


def material_for(doc: Document) -> Material:
    """The maps of a material document, decoded and fitted (all or nothing),
    made tileable together when the document says so; a palette's entries
    packed into one material (engine/palette.py)."""
    if doc.palette:
        return palette_for(doc)[0]
    material = load_material([(role, src.name, src.data) for role, src in doc.maps], fit=doc.fit,
                             toroidal=doc.toroidal)
    return tileable_material(material) if doc.make_tileable else material


def material_or_none(doc: Document) -> Material | None:
    """The document's material (its maps, or its palette packed), or None for a single image."""
    return material_for(doc) if doc.maps or doc.palette else None


def palette_for(doc: Document) -> tuple[Material, PaletteLayout]:
    """A palette document's entries, each decoded and fitted, packed into one
    material (a single-image palette: the one map "image"), and the layout."""
    check_palette_budget([[(src.name, src.data) for _, src in entry] for entry in doc.entries()], doc.fit)
    entries = []
    for entry in doc.entries():
        if entry[0][0] == IMAGE:
            src = entry[0][1]
            entries.append(single(load_exemplar_bytes(src.data, name=src.name, fit=doc.fit, toroidal=doc.toroidal)))
        else:
            entries.append(load_material([(role, src.name, src.data) for role, src in entry], fit=doc.fit,
                                         toroidal=doc.toroidal))
    return pack_palette(entries, [entry[0][1].name for entry in doc.entries()], doc.fit)


def exemplar_for(doc: Document, image: np.ndarray | None = None,
                 material: Material | None = None) -> tuple[Exemplar, AnalysisSettings]:
    """The exemplar a document synthesizes from (a lattice's rectified block,
    the image by its fit rule, or a material's analysis maps side by side)
    and the analysis settings for it. ``image``: the exemplar file already
    decoded whole (decode_full), if at hand; ``material``: the document's
    material, if already loaded."""
    if doc.palette and not doc.maps:
        material = material or material_for(doc)
        return material.maps[IMAGE].exemplar, AnalysisSettings(model=doc.model, k=doc.k,
                                                               feature_weight=doc.feature_weight)
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
        if doc.make_tileable:
            ex = tileable_exemplar(ex)
        grid = (0, 0)
    return ex, AnalysisSettings(model=doc.model, k=doc.k, lattice=grid, feature_weight=doc.feature_weight)


def may_find_lattice(doc: Document) -> bool:
    """Whether :func:`with_found_lattice` looks at all (before any decoding)."""
    return not (doc.lattice is not None or doc.maps or doc.palette or doc.make_tileable or doc.k == 0
                or doc.randomness_exemplar is not None or doc.avoid_exemplar is not None or doc.features)


def with_found_lattice(doc: Document, image: np.ndarray | None = None) -> tuple[Document, Detection | None]:
    """Regular textures right by default: a single image without a lattice
    that shows one (lattice detection, confident: engine.controls.lattice's
    MIN_CONFIDENCE, chosen so that no stochastic image of the development sets
    gets one) is synthesized on it, where a lattice goes with the rest of the
    document (not with Make tileable, texture by numbers, a direction field, a
    model, a material, the random-walk search, or maps and features placed in
    the exemplar's pixels, which a rectified block would move). Returns the document (with
    the lattice, or as it was) and the detection (None when none ran).
    ``image``: the exemplar file decoded whole, if at hand."""
    if not may_find_lattice(doc):
        return doc, None
    if image is None:
        try:
            image = decode_full(doc.exemplar.data, doc.exemplar.name)
        except ExemplarError:  # too large to search whole (over FULL_MAX_PIXELS): synthesized without a lattice
            return doc, None
    from infinitex.engine.controls.lattice_cache import find_lattice
    found = find_lattice(image)
    if found.lattice is None:
        return doc, found
    on = replace(doc, lattice=found.lattice)
    try:
        on.validate()
    except ProjectError:
        return doc, found
    return on, found


class AnalysisJob:
    """Decode the exemplar and analyze it on a worker thread (numpy and scipy
    release the GIL for the heavy parts); poll ``done``; ``cancel()`` stops it."""

    def __init__(self, doc: Document, cache_dir: str | None = None, preview: bool = False,
                 find_lattice: bool = False):
        self.doc = doc
        # ``find_lattice``: an image opened as a new document (or replacing the
        # exemplar) is first searched for a lattice (with_found_lattice); then
        # ``doc`` and ``key`` become the document with it, ``asked_key`` stays
        # the key asked for, and ``found`` holds the detection.
        self.find_lattice = find_lattice
        self.found: Detection | None = None
        self.shown_doc: Document | None = None  # the document installed (by LoadedDocument.poll) when shown
        self.asked_key = doc.analysis_key()
        # ``preview``: before the full analysis, a quick one without similarity
        # sets (TBN10's random-walk search needs none: about a tenth of the
        # time), so the editor shows a texture at once. Only where the full
        # analysis would build sets and is not in the cache, for single images
        # without a lattice.
        self.want_preview = preview
        # (document, exemplar, analysis, material) of the preview: the image as
        # given, even where the lattice search then finds a lattice (``doc``
        # then changes; the preview shows while that analysis runs).
        self.preview: tuple[Document, Exemplar, Analysis, Material] | None = None
        self.preview_taken = False
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

    def _needs_preview(self, ex: Exemplar, settings: AnalysisSettings) -> bool:
        """The full analysis builds similarity sets (slow) and is not cached yet."""
        if search_k(settings, ex.size) == 0 or settings.lattice != (0, 0):
            return False
        return not is_cached(ex, settings, self.cache_dir)

    def take_preview(self) -> tuple[Document, Exemplar, Analysis, Material] | None:
        """The quick preview once it is ready, once (None otherwise)."""
        if self.preview is None or self.preview_taken:
            return None
        self.preview_taken = True
        return self.preview

    def _progress(self, frac: float, msg: str) -> None:
        if self._cancel.is_set():
            raise AnalysisCancelled()
        self.progress = 0.05 + 0.95 * float(frac)
        self.message = msg

    def _quick_preview(self, d: Document, ex: Exemplar, settings: AnalysisSettings) -> None:
        self._progress(0.0, "Quick preview (random-walk search)")
        quick = analyze(ex, replace(settings, k=0), progress=self._progress)
        self.preview = (d, ex, quick, single(ex, [lv.stack for lv in quick.levels]))

    def _run(self) -> None:
        d = self.doc
        try:
            image = None
            searching = self.find_lattice and may_find_lattice(d)
            material = material_or_none(d)
            preview = self.want_preview and (material is None or material.single)
            if searching and preview:
                # The first texture never waits for the lattice search: the image's quick preview first (shown
                # and editable), then the search; a lattice found is the editor's to adopt (one undo step).
                ex, settings = exemplar_for(d, None, material=material)
                if self._needs_preview(ex, settings):
                    self._quick_preview(d, ex, settings)
            if searching:
                self.message = "Looking for a lattice"
                image = decode_full(d.exemplar.data, d.exemplar.name)
                d, self.found = with_found_lattice(d, image)
                if d is not self.doc:
                    self.doc, self.key = d, d.analysis_key()
            if self.preview is not None and self.preview[0] is d:  # no lattice found: the preview's exemplar
                ex = self.preview[1]
            else:
                ex, settings = exemplar_for(d, image if d.lattice is not None else None, material=material)
            if self.preview is None and preview and self._needs_preview(ex, settings):
                self._quick_preview(d, ex, settings)
            if self.preview is not None:
                self._progress(0.0, "Analyzing (similarity sets, cached for next time)")
            else:
                self._progress(0.0, "Analyzing")
            # The preview's stack and neighborhoods are the full analysis's too (of the same exemplar).
            reuse = self.preview[2] if self.preview is not None and self.preview[0] is d else None
            an = analyze(ex, settings, cache_dir=self.cache_dir, progress=self._progress, reuse=reuse)
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
