"""The document model: what decides the texture, and what a project holds.

A :class:`Document` is an immutable value holding everything that decides the
texture: the exemplar file (its bytes and content hash), the import and
analysis settings, the synthesis parameters and every painted or placed
control. Edits make new documents (:mod:`.history` keeps them for undo/redo).
The view and display settings are saved with a project but are not edits
(panning is not undone). The file format is :mod:`.format`.

This package imports neither GL nor imgui: it is tested without any window.
"""
from __future__ import annotations

import hashlib
import math
import os
from dataclasses import dataclass, field, replace

from infinitex.engine.analysis import MODELS
from infinitex.engine.controls import (
    MAX_LABELS,
    CanvasField,
    CanvasLabels,
    DirectionField,
    Controls,
    ExemplarField,
    ExemplarLabels,
    ExemplarMask,
    Feature,
    fit_features,
)
from infinitex.engine.controls.labels import LABEL_COLORS
from infinitex.engine.controls.lattice import Lattice, LatticeError
from infinitex.engine.exemplar import FIT_MODES, MAX_FILE_BYTES
from infinitex.engine.material import IMAGE, ROLES
from infinitex.engine.palette import cell_labels
from infinitex.engine.params import DEFAULT_JITTER, DEFAULT_STRUCTURE, STRUCTURE_LEVELS, SynthParams, structure_params
from infinitex.engine.safeio import (
    read_limited,
)

MAX_LEVELS = 13                 # jitter / corrected lists hold at most one entry per level
MIN_ZOOM, MAX_ZOOM = 1.0 / 64.0, 16.0
DISPLAY_MODES = ("color", "coords", "patches", "level", "relief", "lit")
MAGNIFY_FILTERS = ("hires", "bilinear", "nearest")
GEOMETRIES = ("original", "rectified")


class ProjectError(ValueError):
    """A project file could not be read or written; the message is for the user."""


@dataclass(frozen=True)
class ExemplarSource:
    """The exemplar as the user gave it: the original file's bytes and name."""

    name: str
    data: bytes = field(repr=False, compare=False)  # equality is by content hash
    sha256: str = ""
    path: str | None = field(default=None, compare=False)  # where it was loaded from, if anywhere

    @classmethod
    def from_bytes(cls, data: bytes, name: str, path: str | None = None) -> ExemplarSource:
        return cls(name=name, data=bytes(data), sha256=hashlib.sha256(data).hexdigest(), path=path)

    @classmethod
    def from_file(cls, path: str) -> ExemplarSource:
        """Read an image file (a regular file of at most MAX_FILE_BYTES; else ReadError)."""
        data = read_limited(path, MAX_FILE_BYTES, "image")
        return cls.from_bytes(data, os.path.basename(path), os.path.abspath(path))


def _from_finest(stored: tuple, L: int, fill) -> list:
    """Per-level values for levels 0..L from ``stored`` (finest LAST), matched
    from the finest level down (by feature size); levels not stored get ``fill``."""
    out = [fill] * (L + 1)
    for i, v in enumerate(reversed(stored[-(L + 1):])):
        out[L - i] = v
    return out


@dataclass(frozen=True)
class LabelMaps:
    """Texture by numbers (engine/controls/labels.py): the exemplar's label map
    (label ids over the exemplar as fitted), a display color (and a name) per
    label, the labels painted on the canvas and how strongly synthesis follows them."""

    exemplar: ExemplarLabels
    colors: tuple[tuple[int, int, int], ...]
    names: tuple[str, ...] = ()
    canvas: CanvasLabels = field(default_factory=CanvasLabels)
    strength: float = 1.0

    def name(self, label: int) -> str:
        return self.names[label] if label < len(self.names) and self.names[label] else f"Label {label + 1}"

    def validate(self) -> None:
        if not 1 <= len(self.colors) <= MAX_LABELS or len(self.names) > MAX_LABELS:
            raise ProjectError(f"A label map has 1 to {MAX_LABELS} labels, each with a color.")
        if any(len(c) != 3 or any(not (isinstance(v, int) and 0 <= v <= 255) for v in c) for c in self.colors):
            raise ProjectError("Label colors are three integers from 0 to 255.")
        if any(not isinstance(n, str) or len(n) > 64 for n in self.names):
            raise ProjectError("Label names are texts of at most 64 characters.")
        if max(self.exemplar.present) >= len(self.colors):
            raise ProjectError("The exemplar's label map uses a label without a color.")
        if self.canvas.used and max(self.canvas.used) >= len(self.colors):
            raise ProjectError("The canvas labels use a label without a color.")
        missing = sorted(set(self.canvas.used) - set(self.exemplar.present))
        if missing:
            raise ProjectError(f"The canvas uses {self.name(missing[0])}, which the exemplar's labels do not have "
                               "(any more); give the exemplar some of it, or erase it from the canvas.")
        if not (is_number(self.strength) and 0.0 <= self.strength <= 8.0):
            raise ProjectError("The label strength must be a number from 0 to 8.")


@dataclass(frozen=True)
class PlaneControls:
    """What was painted and placed on the plane (the infinite canvas), set
    aside while a model is open: the model's own live in its atlas's texels in
    the same fields, and closing the model brings these back exactly."""

    randomness_canvas: CanvasField | None = None
    features: tuple = ()
    direction: DirectionField | None = None
    lattice: Lattice | None = None

    @property
    def empty(self) -> bool:
        return ((self.randomness_canvas is None or self.randomness_canvas.neutral) and not self.features
                and (self.direction is None or self.direction.identity) and self.lattice is None)


@dataclass(frozen=True)
class Document:
    """Everything that decides the texture. Immutable: edits make new ones."""

    exemplar: ExemplarSource
    fit: str = "resize"
    toroidal: bool | None = None       # None: use the guess from the seam test
    make_tileable: bool = False        # re-synthesize the borders so the image wraps (engine/tileable.py)
    model: str = "appearance"
    k: int = 2
    feature_weight: float = 0.0        # LH06 feature-distance channel (appearance model); 0: off
    jitter: tuple[float, ...] = ()     # finest level LAST; empty = default everywhere
    seed: int = 0
    passes: int = 2
    level_passes: tuple[int, ...] = ()  # passes per level, finest LAST (0: not corrected); empty: `passes`
                                        # on the `corrected` levels
    subgrid: int = 2
    kappa: float = 0.5
    corrected: tuple[int, ...] | None = None
    structure: int = DEFAULT_STRUCTURE  # Structure / Variety preset (engine/params.py STRUCTURE_NAMES)
    randomness_exemplar: ExemplarField | None = None   # painted over the exemplar (m x m)
    avoid_exemplar: ExemplarMask | None = None         # exemplar regions the synthesis does not copy (m x m)
    randomness_canvas: CanvasField | None = None       # painted over the canvas (sparse tiles)
    features: tuple[Feature, ...] = ()                 # placed exemplar features, later ones win
    lattice: Lattice | None = None                     # near-regular mode: synthesize this lattice's block
    # A material: every map as (role, file), the first being ``exemplar``; () for a single image.
    maps: tuple[tuple[str, ExemplarSource], ...] = ()
    weights: tuple[tuple[str, float], ...] | None = None  # maps feeding the analysis; None: the default
    labels: LabelMaps | None = None                    # texture by numbers
    # A palette (engine/palette.py): the exemplars after the first (this
    # document's exemplar or material), each as its maps [(role, file)], one
    # label each; () for one exemplar.
    palette: tuple[tuple[tuple[str, ExemplarSource], ...], ...] = ()
    direction: DirectionField | None = None            # direction and scale over the canvas (sparse tiles)
    surface: object | None = None                      # a model to texture (project/surface.py SurfaceSettings)
    plane: PlaneControls | None = None                 # with a model: the plane's controls, set aside
    motion: object | None = None                       # texture in motion (project/flow_json.py Motion)

    def with_model(self, settings) -> Document:
        """This document texturing a model: what is painted and placed on the
        plane is set aside (the model's is painted in its atlas), a model
        already open is replaced (the plane's stay aside)."""
        if self.surface is not None:
            return replace(self, surface=settings, randomness_canvas=None, features=(), direction=None)
        plane = PlaneControls(self.randomness_canvas, tuple(self.features), self.direction, self.lattice)
        return replace(self, surface=settings, plane=None if plane.empty else plane, randomness_canvas=None,
                       features=(), direction=None, lattice=None)

    def without_model(self) -> Document:
        """The model closed: the plane's controls back as they were when it opened."""
        p = self.plane or PlaneControls()
        return replace(self, surface=None, plane=None, randomness_canvas=p.randomness_canvas,
                       features=tuple(p.features), direction=p.direction, lattice=p.lattice)

    def analysis_key(self) -> tuple:
        """What the exemplar analysis depends on (a lattice's geometry: its
        rectified block is the exemplar; not its number of lattice levels;
        a material's maps and analysis weights)."""
        lat = None if self.lattice is None else replace(self.lattice, levels=None)
        mat = tuple((r, s.sha256) for r, s in self.maps)
        pal = tuple(tuple((r, s.sha256) for r, s in entry) for entry in self.palette)
        return (self.exemplar.sha256, self.fit, self.toroidal, self.model, self.k, lat, mat, self.weights,
                self.feature_weight, self.make_tileable) + ((pal,) if pal else ())

    @property
    def is_material(self) -> bool:
        return bool(self.maps)

    def sources(self) -> tuple[tuple[str, ExemplarSource], ...]:
        """Every map as (role, file): a single image is the one map "image"."""
        return self.maps or ((IMAGE, self.exemplar),)

    def input_paths(self) -> list[str]:
        """The files this document was read from (its exemplar, every map),
        where it knows them: what no export of it may replace. An embedded
        file has none (its bytes are in the project)."""
        return [src.path for entry in self.entries() for _, src in entry if src.path]

    def entries(self) -> tuple[tuple[tuple[str, ExemplarSource], ...], ...]:
        """Every exemplar of the palette as its maps [(role, file)] (one entry without a palette)."""
        return (self.sources(),) + self.palette

    def with_palette(self, entries) -> Document:
        """This document synthesizing from a palette of ``entries`` (each its
        maps [(role, file)], 2 to 16, the same roles): the first becomes the
        exemplar, each one label named after its file (labels already painted
        on the canvas are kept where their label remains). One entry: no palette."""
        entries = [canonical_maps(e) for e in entries]
        first = self.with_maps(entries[0])
        if len(entries) == 1:
            return replace(first, palette=(), labels=None)
        names = tuple(entry[0][1].name[:64] for entry in entries)
        old = self.labels
        canvas = old.canvas if old is not None and all(i < len(entries) for i in old.canvas.used) else CanvasLabels()
        labels = LabelMaps(ExemplarLabels(cell_labels(len(entries))), tuple(LABEL_COLORS[:len(entries)]), names,
                           canvas, old.strength if old is not None else 1.0)
        return replace(first, palette=tuple(entries[1:]), labels=labels, lattice=None, make_tileable=False)

    def weight_dict(self) -> dict[str, float] | None:
        return None if self.weights is None else dict(self.weights)

    def with_maps(self, maps) -> Document:
        """This document with another set of maps ([(role, source)]; one "image" map: a single image).
        The analysis weights of maps that remain are kept."""
        maps = canonical_maps(maps)
        single = len(maps) == 1 and maps[0][0] == IMAGE
        w = self.weights
        if w is not None:
            roles = {r for r, _ in maps}
            w = tuple((r, v) for r, v in w if r in roles) or None
        return replace(self, exemplar=maps[0][1], maps=() if single else maps, weights=None if single else w)

    def jitter_for(self, L: int) -> tuple[float, ...]:
        """r_l for levels 0..L. Stored values are matched from the finest level
        down (by feature size), so a document survives an exemplar of another size."""
        return tuple(float(r) for r in _from_finest(self.jitter, L, DEFAULT_JITTER))

    def passes_for(self, L: int) -> tuple[int, ...]:
        """Correction passes of levels 0..L, what the synthesis does: the stored
        per-level counts matched from the finest level down (levels coarser than
        those stored get 0), or ``passes`` on the corrected levels."""
        if self.level_passes:
            return tuple(int(c) for c in _from_finest(self.level_passes, L, 0))
        corrected = self.params(L).corrected_levels()
        return tuple(self.passes if l in corrected else 0 for l in range(L + 1))

    def with_level_passes(self, L: int, level: int, count: int) -> Document:
        """This document with ``count`` correction passes on ``level`` (the others as they are)."""
        c = list(self.passes_for(L))
        c[level] = max(0, min(8, int(count)))
        return replace(self, level_passes=tuple(c))

    def controls(self, m: int) -> Controls:
        """The engine input of everything painted, for an m x m exemplar (an
        exemplar field painted at another size is scaled to m, nearest). Made
        once per document: the session compares it every frame."""
        cached = self.__dict__.get("_controls")
        if cached is not None and cached[0] == m:
            return cached[1]
        e = None if self.randomness_exemplar is None else self.randomness_exemplar.scaled(m)
        a = None if self.avoid_exemplar is None else self.avoid_exemplar.scaled(m)
        lab = self.labels
        canvas = None if lab is None else lab.canvas
        if canvas is not None and self.palette:  # what is not painted is the first exemplar's (label 1)
            canvas = replace(canvas, background=1)
        controls = Controls(e, self.randomness_canvas, fit_features(self.features, m), self.lattice, a,
                            None if lab is None else lab.exemplar.scaled(m), canvas,
                            1.0 if lab is None else float(lab.strength), self.direction).normalized()
        object.__setattr__(self, "_controls", (m, controls))  # a cache, not a field (frozen dataclass)
        return controls

    def params(self, L: int) -> SynthParams:
        corrected = None if self.corrected is None else tuple(l for l in self.corrected if l <= L)
        level_passes = self.passes_for(L) if self.level_passes else None
        base = SynthParams(jitter=self.jitter_for(L), seed=self.seed, passes=self.passes,
                           subgrid=self.subgrid, kappa=self.kappa, corrected=corrected, level_passes=level_passes)
        return structure_params(base, self.structure)

    def with_jitter(self, L: int, level: int, value: float) -> Document:
        j = list(self.jitter_for(L))
        j[level] = _clamp01(value)
        return replace(self, jitter=tuple(j))

    def with_all_jitter(self, L: int, value: float) -> Document:
        return replace(self, jitter=(_clamp01(value),) * (L + 1))

    def validate(self) -> None:
        """Raise ProjectError with a sentence if any setting is out of range."""
        if self.fit not in FIT_MODES:
            raise ProjectError(f"Unknown import fit {self.fit!r} (use {', '.join(FIT_MODES)}).")
        if self.model not in MODELS:
            raise ProjectError(f"Unknown neighborhood model {self.model!r} (use {' or '.join(MODELS)}).")
        if not 0 <= self.k <= 4:
            raise ProjectError("k (similarity-set size) must be between 0 (random-walk search) and 4.")
        if not 0.0 <= self.feature_weight <= 4.0:
            raise ProjectError("The feature-distance weight must be between 0 and 4.")
        if self.k == 0 and self.lattice is not None:
            raise ProjectError("A lattice needs similarity sets: set Similar spots to 1 or more.")
        if any(not (0.0 <= r <= 1.0) for r in self.jitter):
            raise ProjectError("Randomness values must lie between 0 and 1.")
        if self.avoid_exemplar is not None and self.avoid_exemplar.full:
            raise ProjectError("The avoided regions cover the whole exemplar: leave some of it usable.")
        if not 0 <= self.structure < STRUCTURE_LEVELS:
            raise ProjectError(f"Structure must be a preset from 0 to {STRUCTURE_LEVELS - 1}.")
        if len(self.level_passes) > MAX_LEVELS or any(not 0 <= c <= 8 for c in self.level_passes):
            raise ProjectError(f"Correction passes per level must be at most {MAX_LEVELS} counts from 0 to 8.")
        try:
            SynthParams(jitter=(0.0,) * 10, seed=self.seed, passes=self.passes, subgrid=self.subgrid,
                        kappa=self.kappa, corrected=None).validate(9)
        except ValueError as exc:
            raise ProjectError(str(exc)) from None
        if self.corrected is not None and any(not 0 <= l <= 12 for l in self.corrected):
            raise ProjectError("Corrected levels must be level numbers from 0 to 12.")
        if self.lattice is not None:
            try:
                self.lattice.check_shape()
            except LatticeError as exc:
                raise ProjectError(f"The project's lattice: {exc}") from None
            if self.direction is not None and not self.direction.identity:
                raise ProjectError("A direction field does not work on a lattice; turn one of them off.")
        if self.maps:
            roles = [r for r, _ in self.maps]
            if any(r not in ROLES for r in roles) or len(set(roles)) != len(roles):
                raise ProjectError("Each map of a material has one of the roles "
                                   f"{', '.join(ROLES)}, and each role is used once.")
            if self.maps[0][1].sha256 != self.exemplar.sha256:
                raise ProjectError("The material's first map must be its exemplar.")
            if self.lattice is not None:
                raise ProjectError("A lattice works on a single image, not on a material.")
        if self.labels is not None:
            self.labels.validate()
            if self.lattice is not None:
                raise ProjectError("Texture by numbers does not work on a lattice; remove one of them.")
            if self.make_tileable:
                raise ProjectError("Texture by numbers does not work with Make tileable yet; turn one of them off.")
        if self.palette:
            roles = [r for r, _ in self.sources()]
            if len(self.palette) >= MAX_LABELS or any([r for r, _ in e] != roles for e in self.palette):
                raise ProjectError(f"A palette has 2 to {MAX_LABELS} exemplars, each with the same maps.")
            if self.lattice is not None or self.make_tileable:
                raise ProjectError("A palette works without a lattice and without Make tileable.")
            if self.labels is None:
                raise ProjectError("A palette's exemplars are its labels; the project has no label map.")
        if self.plane is not None and self.surface is None:
            raise ProjectError("The plane's set-aside controls belong with a model; the project has none.")
        if self.surface is not None:
            self.surface.validate()
            if self.lattice is not None:  # (a direction field is combed over the model: its atlas texels)
                raise ProjectError("Texture on a model does not work with a lattice; turn one of them off.")
        if self.motion is not None:
            self.motion.validate()
            if self.lattice is not None:
                raise ProjectError("Texture in motion does not work on a lattice (a flow would bend its grid).")
        if self.weights is not None:
            roles = {r for r, _ in self.sources()}
            if any(r not in roles or not (is_number(v) and 0.0 <= v <= 4.0) for r, v in self.weights) \
                    or not any(v > 0 for _, v in self.weights):
                raise ProjectError("Analysis weights are numbers from 0 to 4 for the material's own maps, "
                                   "at least one above 0.")


def canonical_maps(maps) -> tuple:
    """A document's maps [(role, file)] in role order (a single image's one map "image" first)."""
    return tuple(sorted(maps, key=lambda rs: -1 if rs[0] == IMAGE else ROLES.index(rs[0])))


def is_number(v: object) -> bool:
    """A finite int or float (not a bool): what a numeric field may hold."""
    return isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v)


def _clamp01(v: float) -> float:
    return float(min(1.0, max(0.0, v)))


@dataclass(frozen=True)
class View:
    """Where the canvas looks: center in finest-level canvas pixels, and zoom
    (screen pixels per canvas pixel, 1/64 .. 16)."""

    x: float = 0.0
    y: float = 0.0
    zoom: float = 1.0

    def clamped(self) -> View:
        lim = 2.0 ** 30
        return View(min(lim, max(-lim, self.x)), min(lim, max(-lim, self.y)),
                    min(MAX_ZOOM, max(MIN_ZOOM, self.zoom)))

    def top_left(self, w: int, h: int) -> tuple[float, float]:
        """Canvas position of the top-left corner of a w x h screen canvas.
        At zoom 2^-k it is snapped to whole level L-k texels, so screen pixels
        and texels align exactly."""
        x, y = self.x - w / (2 * self.zoom), self.y - h / (2 * self.zoom)
        if self.zoom <= 1.0 and math.log2(self.zoom).is_integer():
            s = round(1.0 / self.zoom)  # texels of level L - log2(s) are whole screen pixels
            x, y = math.floor(x / s + 0.5) * s, math.floor(y / s + 0.5) * s
        return x, y

    def zoom_at(self, factor: float, sx: float, sy: float, w: int, h: int) -> View:
        """Zoom by ``factor`` keeping the canvas point under screen (sx, sy) fixed."""
        z1 = min(MAX_ZOOM, max(MIN_ZOOM, self.zoom * factor))
        # Snap to powers of two when close, so 1:1 and exact mip levels are easy to hit.
        lz = math.log2(z1)
        if abs(lz - round(lz)) < 0.02:
            z1 = 2.0 ** round(lz)
        x0, y0 = self.x - w / (2 * self.zoom), self.y - h / (2 * self.zoom)
        px, py = x0 + sx / self.zoom, y0 + sy / self.zoom
        nx0, ny0 = px - sx / z1, py - sy / z1
        return View(nx0 + w / (2 * z1), ny0 + h / (2 * z1), z1).clamped()

    def panned(self, dx_screen: float, dy_screen: float) -> View:
        return View(self.x - dx_screen / self.zoom, self.y - dy_screen / self.zoom, self.zoom).clamped()


@dataclass(frozen=True)
class Display:
    """How the canvas is drawn (saved with a project, not part of undo)."""

    mode: str = "color"
    level: int = -1          # pyramid level shown in "level" mode; -1 = finest
    magnify: str = "hires"   # zoomed-in filter: "hires" (synthesis magnification), "bilinear", "nearest"
    geometry: str = "original"  # with a lattice: "original" (the input's geometry) or "rectified"
    map: str = ""            # a material's map shown in "color" and "level" modes; "": its first map
    light_azimuth: float = 135.0    # "lit" mode: the light's direction, degrees (0: from the right, 90: from above)
    light_elevation: float = 40.0   # degrees above the surface, 5 to 90
    relief: float = 1.0             # "lit" mode: height map strength (relief of the full height range, x 1/8 of m)


@dataclass(frozen=True)
class Project:
    document: Document
    view: View = View()
    display: Display = Display()
    origin: str | None = None  # autosaves: the project file the unsaved work belongs to
