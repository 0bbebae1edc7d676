"""The document model: what a project is, its file format, undo/redo and autosave.

A :class:`Document` is an immutable value holding everything that decides the
texture: the exemplar file (its bytes and content hash), the import and
analysis settings, and the synthesis parameters. Edits make new documents;
:class:`History` keeps them for undo/redo. The view and display settings are
saved with a project but are not edits (panning is not undone).

This module imports neither GL nor imgui: it is tested without any window.
"""
from __future__ import annotations

import base64
import hashlib
import json
import math
import os
import tempfile
import time
from dataclasses import asdict, dataclass, field, replace

from engine.analysis import MODELS
from engine.exemplar import FIT_MODES
from engine.params import DEFAULT_JITTER, SynthParams

FORMAT = "infinitex-project"
VERSION = 1
PROJECT_SUFFIX = ".itex"
EMBED_LIMIT = 16 * 1024 * 1024  # exemplar files up to this size are embedded
MIN_ZOOM, MAX_ZOOM = 1.0 / 64.0, 16.0
DISPLAY_MODES = ("color", "coords", "patches", "level", "relief")
MAGNIFY_FILTERS = ("hires", "bilinear", "nearest")


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
        with open(path, "rb") as f:
            data = f.read()
        return cls.from_bytes(data, os.path.basename(path), os.path.abspath(path))


@dataclass(frozen=True)
class Document:
    """Everything that decides the texture. Immutable: edits make new ones."""

    exemplar: ExemplarSource
    fit: str = "resize"
    toroidal: bool | None = None       # None: use the guess from the seam test
    model: str = "appearance"
    k: int = 2
    jitter: tuple[float, ...] = ()     # finest level LAST; empty = default everywhere
    seed: int = 0
    passes: int = 2
    subgrid: int = 2
    kappa: float = 0.5
    corrected: tuple[int, ...] | None = None

    def analysis_key(self) -> tuple:
        """What the exemplar analysis depends on."""
        return (self.exemplar.sha256, self.fit, self.toroidal, self.model, self.k)

    def jitter_for(self, L: int) -> tuple[float, ...]:
        """r_l for levels 0..L. Stored values are matched from the finest level
        down (by feature size), so a document survives an exemplar of another size."""
        out = [DEFAULT_JITTER] * (L + 1)
        for i, r in enumerate(reversed(self.jitter)):
            if i > L:
                break
            out[L - i] = float(r)
        return tuple(out)

    def params(self, L: int) -> SynthParams:
        corrected = None if self.corrected is None else tuple(l for l in self.corrected if l <= L)
        return SynthParams(jitter=self.jitter_for(L), seed=self.seed, passes=self.passes,
                           subgrid=self.subgrid, kappa=self.kappa, corrected=corrected)

    def with_jitter(self, L: int, level: int, value: float) -> Document:
        j = list(self.jitter_for(L))
        j[level] = _clamp01(value)
        return replace(self, jitter=tuple(j))

    def with_all_jitter(self, L: int, value: float) -> Document:
        return replace(self, jitter=(_clamp01(value),) * (L + 1))

    def validate(self) -> None:
        """Raise ProjectError with a sentence if any setting is out of range."""
        if self.fit not in FIT_MODES:
            raise ProjectError(f"Unknown import fit {self.fit!r} (use {' or '.join(FIT_MODES)}).")
        if self.model not in MODELS:
            raise ProjectError(f"Unknown neighborhood model {self.model!r} (use {' or '.join(MODELS)}).")
        if not 1 <= self.k <= 4:
            raise ProjectError("k (similarity-set size) must be between 1 and 4.")
        if any(not (0.0 <= r <= 1.0) for r in self.jitter):
            raise ProjectError("Randomness values must lie between 0 and 1.")
        try:
            SynthParams(jitter=(0.0,) * 10, seed=self.seed, passes=self.passes, subgrid=self.subgrid,
                        kappa=self.kappa, corrected=None).validate(9)
        except ValueError as exc:
            raise ProjectError(str(exc)) from None
        if self.corrected is not None and any(not 0 <= l <= 12 for l in self.corrected):
            raise ProjectError("Corrected levels must be level numbers from 0 to 12.")


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


@dataclass(frozen=True)
class Project:
    document: Document
    view: View = View()
    display: Display = Display()


# -- undo / redo -------------------------------------------------------------


class History:
    """Undo/redo over immutable documents.

    ``apply(doc, label, group=g)`` with the same non-None ``g`` as the previous
    call replaces the current document without a new undo step: a slider drag
    is one step. ``end_group()`` closes the group (on mouse release).
    """

    def __init__(self, doc: Document, limit: int = 500):
        self.current = doc
        self.undo_stack: list[tuple[Document, str]] = []
        self.redo_stack: list[tuple[Document, str]] = []
        self.limit = limit
        self._group: object = None
        self.saved: Document | None = doc

    @property
    def dirty(self) -> bool:
        return self.current != self.saved

    def apply(self, doc: Document, label: str, group: object = None) -> bool:
        if doc == self.current:
            return False
        doc.validate()
        if group is None or group != self._group:
            self.undo_stack.append((self.current, label))
            del self.undo_stack[:-self.limit]
        self._group = group
        self.redo_stack.clear()
        self.current = doc
        return True

    def end_group(self) -> None:
        self._group = None

    def can_undo(self) -> bool:
        return bool(self.undo_stack)

    def can_redo(self) -> bool:
        return bool(self.redo_stack)

    def undo_label(self) -> str:
        return self.undo_stack[-1][1] if self.undo_stack else ""

    def redo_label(self) -> str:
        return self.redo_stack[-1][1] if self.redo_stack else ""

    def undo(self) -> bool:
        if not self.undo_stack:
            return False
        doc, label = self.undo_stack.pop()
        self.redo_stack.append((self.current, label))
        self.current = doc
        self._group = None
        return True

    def redo(self) -> bool:
        if not self.redo_stack:
            return False
        doc, label = self.redo_stack.pop()
        self.undo_stack.append((self.current, label))
        self.current = doc
        self._group = None
        return True

    def mark_saved(self) -> None:
        self.saved = self.current


# -- project files -----------------------------------------------------------


def project_to_json(project: Project, path: str | None = None, embed: bool | None = None) -> dict:
    """The project as a JSON-ready dict. The exemplar is embedded when small
    enough (or when ``embed``), else referenced by path and content hash."""
    doc = project.document
    ex = doc.exemplar
    embed = len(ex.data) <= EMBED_LIMIT if embed is None else embed
    ref_path = None
    if not embed:
        if not ex.path:
            raise ProjectError(f"{ex.name} is too large to embed and has no file to refer to.")
        ref_path = ex.path
        if path:
            try:
                ref_path = os.path.relpath(ex.path, os.path.dirname(os.path.abspath(path)))
            except ValueError:  # another drive on Windows
                ref_path = ex.path
    return {
        "format": FORMAT,
        "version": VERSION,
        "exemplar": {
            "name": ex.name,
            "sha256": ex.sha256,
            "embedded": base64.b64encode(ex.data).decode("ascii") if embed else None,
            "path": ref_path,
            "fit": doc.fit,
            "toroidal": doc.toroidal,
        },
        "analysis": {"model": doc.model, "k": doc.k},
        "synthesis": {
            "jitter": list(doc.jitter), "seed": doc.seed, "passes": doc.passes,
            "subgrid": doc.subgrid, "kappa": doc.kappa,
            "corrected": None if doc.corrected is None else list(doc.corrected),
        },
        "view": asdict(project.view),
        "display": asdict(project.display),
    }


def save_project(path: str, project: Project, embed: bool | None = None) -> None:
    """Write atomically: a temporary file in the same folder, then a rename."""
    text = json.dumps(project_to_json(project, path, embed), indent=1)
    atomic_write(path, text.encode("utf-8"))


def atomic_write(path: str, data: bytes) -> None:
    folder = os.path.dirname(os.path.abspath(path))
    try:
        fd, tmp = tempfile.mkstemp(prefix=".tmp-", suffix=os.path.basename(path), dir=folder)
    except OSError as exc:
        raise ProjectError(f"Cannot write in {folder}: {exc.strerror or exc}.") from None
    try:
        with os.fdopen(fd, "wb") as f:
            f.write(data)
            f.flush()
            os.fsync(f.fileno())
        os.replace(tmp, path)
    except OSError as exc:
        try:
            os.unlink(tmp)
        except OSError:
            pass
        raise ProjectError(f"Saving {os.path.basename(path)} failed: {exc.strerror or exc}.") from None


def _get(d: dict, key: str, types, where: str, optional: bool = False):
    if key not in d:
        if optional:
            return None
        raise ProjectError(f"The project file lacks {where}.{key}.")
    v = d[key]
    if v is None and optional:
        return None
    if isinstance(v, bool) and bool not in (types if isinstance(types, tuple) else (types,)):
        raise ProjectError(f"{where}.{key} has the wrong type.")
    if not isinstance(v, types):
        raise ProjectError(f"{where}.{key} has the wrong type.")
    return v


def project_from_json(d: object, path: str | None = None) -> Project:
    """Parse and check a project dict; raise ProjectError with a clear sentence."""
    if not isinstance(d, dict) or d.get("format") != FORMAT:
        raise ProjectError("This is not an Infinitex project file.")
    version = d.get("version")
    if not isinstance(version, int) or version > VERSION:
        raise ProjectError(f"This project was written by a newer version (format {version}); "
                           "update Infinitex to open it.")
    e = _get(d, "exemplar", dict, "project")
    name = _get(e, "name", str, "exemplar")
    sha = _get(e, "sha256", str, "exemplar")
    embedded = _get(e, "embedded", str, "exemplar", optional=True)
    ref = _get(e, "path", str, "exemplar", optional=True)
    if embedded is not None:
        try:
            data = base64.b64decode(embedded, validate=True)
        except ValueError:
            raise ProjectError("The exemplar embedded in the project is damaged.") from None
        src_path = None
    elif ref is not None:
        candidates = [ref]
        if path and not os.path.isabs(ref):
            candidates.insert(0, os.path.join(os.path.dirname(os.path.abspath(path)), ref))
        found = next((c for c in candidates if os.path.isfile(c)), None)
        if found is None:
            raise ProjectError(f"The project refers to exemplar {ref}, which cannot be found.")
        with open(found, "rb") as f:
            data = f.read()
        src_path = os.path.abspath(found)
    else:
        raise ProjectError("The project holds neither an embedded exemplar nor a path to one.")
    if hashlib.sha256(data).hexdigest() != sha:
        raise ProjectError(f"The exemplar {name} does not match the project (its content changed), "
                           "so the texture could not be reproduced.")
    source = ExemplarSource(name=name, data=data, sha256=sha, path=src_path)

    a = _get(d, "analysis", dict, "project")
    s = _get(d, "synthesis", dict, "project")
    jitter = _get(s, "jitter", list, "synthesis")
    if not all(isinstance(r, (int, float)) and not isinstance(r, bool) and math.isfinite(r) for r in jitter):
        raise ProjectError("synthesis.jitter must be a list of numbers.")
    corrected = _get(s, "corrected", list, "synthesis", optional=True)
    if corrected is not None and not all(isinstance(c, int) and not isinstance(c, bool) for c in corrected):
        raise ProjectError("synthesis.corrected must be a list of level numbers.")
    toroidal = _get(e, "toroidal", bool, "exemplar", optional=True)
    doc = Document(
        exemplar=source,
        fit=_get(e, "fit", str, "exemplar"),
        toroidal=toroidal,
        model=_get(a, "model", str, "analysis"),
        k=_get(a, "k", int, "analysis"),
        jitter=tuple(float(r) for r in jitter),
        seed=_get(s, "seed", int, "synthesis"),
        passes=_get(s, "passes", int, "synthesis"),
        subgrid=_get(s, "subgrid", int, "synthesis"),
        kappa=float(_get(s, "kappa", (int, float), "synthesis")),
        corrected=None if corrected is None else tuple(corrected),
    )
    doc.validate()
    view, display = View(), Display()
    v = d.get("view")
    if isinstance(v, dict):
        try:
            view = View(float(v["x"]), float(v["y"]), float(v["zoom"]))
            if not all(math.isfinite(c) for c in (view.x, view.y, view.zoom)):
                raise ValueError
            view = view.clamped()
        except (KeyError, TypeError, ValueError):
            raise ProjectError("The project's view is damaged.") from None
    g = d.get("display")
    if isinstance(g, dict):
        mode, level, mag = g.get("mode", "color"), g.get("level", -1), g.get("magnify", "hires")
        if mode not in DISPLAY_MODES or mag not in MAGNIFY_FILTERS or not isinstance(level, int):
            raise ProjectError("The project's display settings are damaged.")
        display = Display(mode, level, mag)
    return Project(doc, view, display)


def load_project(path: str) -> Project:
    name = os.path.basename(path)
    try:
        with open(path, "rb") as f:
            raw = f.read()
    except FileNotFoundError:
        raise ProjectError(f"No such file: {path}.") from None
    except IsADirectoryError:
        raise ProjectError(f"{path} is a folder, not a project.") from None
    except OSError as exc:
        raise ProjectError(f"{name} could not be read: {exc.strerror or exc}.") from None
    try:
        d = json.loads(raw.decode("utf-8"))
    except (UnicodeDecodeError, json.JSONDecodeError):
        raise ProjectError(f"{name} is not an Infinitex project (not readable as JSON).") from None
    return project_from_json(d, path)


def is_project_file(path: str) -> bool:
    """True when the file starts like a project (JSON with our format tag)."""
    if path.lower().endswith(PROJECT_SUFFIX):
        return True
    try:
        with open(path, "rb") as f:
            head = f.read(64).lstrip()
    except OSError:
        return False
    return head.startswith(b"{") and FORMAT.encode() in head


# -- autosave ----------------------------------------------------------------


def state_dir() -> str:
    d = os.environ.get("INFINITEX_STATE") or os.path.join(
        os.environ.get("XDG_STATE_HOME") or os.path.join(os.path.expanduser("~"), ".local", "state"), "infinitex")
    return d


def autosave_path() -> str:
    return os.path.join(state_dir(), "autosave" + PROJECT_SUFFIX)


class Autosave:
    """Writes the open project every ``interval`` seconds while it has unsaved
    edits; the file is removed on a clean exit, so finding one at start-up
    means the last session did not end cleanly."""

    def __init__(self, path: str | None = None, interval: float = 10.0):
        self.path = path or autosave_path()
        self.interval = interval
        self._last = time.monotonic()
        self._written: Document | None = None

    def pending(self) -> Project | None:
        if not os.path.isfile(self.path):
            return None
        try:
            return load_project(self.path)
        except ProjectError:
            return None

    def pending_time(self) -> float | None:
        try:
            return os.path.getmtime(self.path)
        except OSError:
            return None

    def tick(self, project: Project, dirty: bool, force: bool = False) -> bool:
        """Write when due; returns True when written."""
        now = time.monotonic()
        if not force and (now - self._last < self.interval):
            return False
        self._last = now
        if not dirty or project.document == self._written:
            return False
        os.makedirs(os.path.dirname(self.path), exist_ok=True)
        save_project(self.path, project, embed=True)
        self._written = project.document
        return True

    def clear(self) -> None:
        self._written = None
        try:
            os.unlink(self.path)
        except OSError:
            pass
