"""The project file format (``.itex``, JSON): write, read and validate.

Project files are untrusted input: they are read only if they are regular
files of at most :data:`MAX_PROJECT_BYTES`, their JSON nesting and numbers are
bounded before and while parsing, every field is type- and range-checked, and
an exemplar they refer to by path is read only from the project's own folder
(anything else must be allowed explicitly: the editor asks, ``export`` needs
``--allow-outside-exemplar``). Every failure is a :class:`ProjectError`.
"""
from __future__ import annotations

import base64
import hashlib
import json
import os
import re
from dataclasses import asdict

import numpy as np

from infinitex.engine.controls import (
    TILE,
    CanvasField,
    ExemplarField,
    ExemplarMask,
    features_from_json,
    features_to_json,
)
from infinitex.engine.exemplar import MAX_FILE_BYTES, MAX_SIZE
from infinitex.engine.material import IMAGE, ROLES
from infinitex.engine.params import STRUCTURE_LEVELS
from infinitex.engine.safeio import (
    JSONLimitError,
    ReadError,
    WriteError,
    atomic_write,
    parse_json,
    printable,
    read_head,
    read_limited,
)

from .labels_json import labels_from_json, labels_to_json, palette_from_json, palette_to_json, tiles_from_json
from .direction_json import direction_from_json, direction_to_json
from .flow_json import motion_from_json, motion_to_json
from .lattice_json import lattice_from_json, lattice_to_json
from .surface import surface_from_json, surface_to_json
from .document import (
    DISPLAY_MODES,
    GEOMETRIES,
    MAGNIFY_FILTERS,
    MAX_LEVELS,
    Display,
    Document,
    ExemplarSource,
    PlaneControls,
    Project,
    ProjectError,
    View,
    is_number,
)

FORMAT = "infinitex-project"
VERSION = 12             # 12: texture in motion ("motion"); 11: a model ("surface"); 10: a direction field ("direction"); 9: a palette of exemplars ("palette"); 8: texture by numbers ("labels"); 2: painted randomness ("randomness") and placed features ("features"); 3: a lattice ("lattice"); 4: a material ("material"); 5: avoided exemplar regions ("avoid") or passes per level (synthesis.level_passes); 6: a Structure preset other than Variety (synthesis.structure); 7: an exemplar made tileable (exemplar.make_tileable); files without them are written as 1
PROJECT_SUFFIX = ".itex"
EMBED_LIMIT = 16 * 1024 * 1024  # exemplar files up to this size are embedded
MATERIAL_EMBED_TOTAL = 64 * 1024 * 1024  # a material's maps are embedded while their total stays under this
MAX_PROJECT_BYTES = 96 * 1024 * 1024  # 64 MB of embedded maps are 85.4 MB of base64
MAX_JSON_DEPTH = 8              # our files nest 3 deep
MAX_INT_DIGITS = 18             # no field needs more; 10^309 or 5,000 digits are refused while parsing


def _reference(src: ExemplarSource, embed: bool | None, path: str | None) -> tuple[str | None, str | None]:
    """(base64 data, None) when embedded, else (None, path relative to the project's folder);
    ``embed`` None: (None, None), to be filled in."""
    if embed is None:
        return None, None
    if embed:
        return base64.b64encode(src.data).decode("ascii"), None
    if not src.path:
        raise ProjectError(f"{src.name} is too large to embed and has no file to refer to.")
    ref_path = src.path
    if path:
        try:
            ref_path = os.path.relpath(src.path, os.path.dirname(os.path.abspath(path)))
        except ValueError:  # another drive on Windows
            ref_path = src.path
    return None, ref_path


def project_to_json(project: Project, path: str | None = None, embed: bool | None = None) -> dict:
    """The project as a JSON-ready dict. The exemplar is embedded when small
    enough (or when ``embed``), else referenced by path and content hash; a
    material's maps are embedded while each is at most EMBED_LIMIT and their
    total at most MATERIAL_EMBED_TOTAL."""
    total = 0

    def embeds(src: ExemplarSource) -> bool:
        nonlocal total
        if embed is not None:
            return embed
        ok = len(src.data) <= EMBED_LIMIT and total + len(src.data) <= MATERIAL_EMBED_TOTAL
        total += len(src.data) if ok else 0
        return ok
    return _to_json(project, path, embeds)


def fitted_project_json(project: Project, store) -> dict:
    """The project as a JSON-ready dict that save_project writes in at most
    MAX_PROJECT_BYTES (an autosave: recoverable whatever its files' sizes).
    Every file is embedded while that fits, the smallest first; each other
    one is referenced with its content hash at ``store(source)``: the name of
    a file in the folder the project is written to that now holds the
    source's bytes (so it is read back from that folder only). Each file's
    own path is kept as "source" (never read: where the file came from).
    ProjectError when even that does not fit."""
    limit = MAX_PROJECT_BYTES
    doc = project.document
    sources = [doc.exemplar] + [src for _, src in doc.maps[1:]] + [src for e in doc.palette for _, src in e]
    d = _to_json(project, None, lambda src: None)  # neither embedded nor referenced yet
    entries = [d["exemplar"]] + (d["material"]["maps"] if doc.maps else []) + [e for p in d.get("palette", ()) for e in p]
    for e, src in zip(entries, sources):
        if src.path:
            e["source"] = os.path.abspath(src.path)
        e["path"] = "x" * 200  # (a stored file's name is shorter)
    size = len(json.dumps(d, indent=1))  # ASCII: characters are bytes
    for i in sorted(range(len(sources)), key=lambda i: len(sources[i].data)):
        e = entries[i]
        grows = 4 * ((len(sources[i].data) + 2) // 3) - 2 - len(json.dumps(e["path"])) + 4  # swap null and "..."
        if size + grows > limit:
            continue
        e["embedded"], e["path"] = base64.b64encode(sources[i].data).decode("ascii"), None
        size += grows
    for e, src in zip(entries, sources):
        if e["embedded"] is None:
            e["path"] = store(src)
    size = len(json.dumps(d, indent=1))
    if size > limit:
        raise ProjectError(f"The project would be {size / 2 ** 20:.0f} MB even with its images referenced, "
                           f"more than the {limit / 2 ** 20:.0f} MB a project file may be.")
    return d


def _to_json(project: Project, path: str | None, embeds) -> dict:
    """project_to_json, with ``embeds(source)`` deciding what is embedded."""
    doc = project.document
    ex = doc.exemplar
    embedded, ref_path = _reference(ex, embeds(ex), path)

    def entry_json(src: ExemplarSource) -> dict:
        data, ref = _reference(src, embeds(src), path)
        return {"name": src.name, "sha256": src.sha256, "embedded": data, "path": ref}
    material = None
    if doc.maps:
        entries = [{"role": role, **entry_json(src)} for role, src in doc.maps[1:]]
        material = {"role": doc.maps[0][0], "maps": entries,
                    "weights": None if doc.weights is None else [[r, w] for r, w in doc.weights]}
    fields = _fields_to_json(doc)
    avoid = None if doc.avoid_exemplar is None or doc.avoid_exemplar.empty else {
        "png16": _png16(doc.avoid_exemplar.values)}
    return {
        "format": FORMAT,
        "version": 12 if doc.motion is not None else 11 if doc.surface is not None else 10 if doc.direction is not None and not doc.direction.identity else 9 if doc.palette else 8 if doc.labels else 7 if doc.make_tileable else 6 if doc.structure else 5 if avoid or doc.level_passes else 4 if material else 3 if doc.lattice else (
            2 if fields or doc.features else 1),
        "exemplar": {
            "name": ex.name,
            "sha256": ex.sha256,
            "embedded": embedded,
            "path": ref_path,
            "fit": doc.fit,
            "toroidal": doc.toroidal,
            **({"make_tileable": True} if doc.make_tileable else {}),
        },
        "analysis": {"model": doc.model, "k": doc.k,
                     **({"feature_weight": doc.feature_weight} if doc.feature_weight else {})},
        "synthesis": {
            "jitter": list(doc.jitter), "seed": doc.seed, "passes": doc.passes,
            **({"level_passes": list(doc.level_passes)} if doc.level_passes else {}),
            "subgrid": doc.subgrid, "kappa": doc.kappa,
            "corrected": None if doc.corrected is None else list(doc.corrected),
            "structure": doc.structure,
        },
        **({"randomness": fields} if fields else {}),
        **({"avoid": avoid} if avoid else {}),
        **({"features": features_to_json(doc.features)} if doc.features else {}),
        **({"lattice": lattice_to_json(doc.lattice)} if doc.lattice else {}),
        **({"labels": labels_to_json(doc.labels)} if doc.labels else {}),
        **({"material": material} if material else {}),
        **({"palette": palette_to_json(doc, entry_json)} if doc.palette else {}),
        **({"direction": direction_to_json(doc.direction)} if doc.direction and not doc.direction.identity else {}),
        **({"surface": surface_to_json(doc.surface)} if doc.surface is not None else {}),
        **({"motion": motion_to_json(doc.motion)} if doc.motion is not None else {}),
        **({"plane": _plane_to_json(doc.plane)} if doc.surface is not None and doc.plane is not None else {}),
        "view": asdict(project.view),
        "display": asdict(project.display),
        **({"autosave_of": project.origin} if project.origin else {}),
    }


def _plane_to_json(p: PlaneControls) -> dict:
    """What the plane had, set aside while a model is open (each part as the document writes its own)."""
    c = p.randomness_canvas
    return {
        **({"randomness": {"tile": TILE, "tiles": [{"x": tx, "y": ty, "png16": _png16(t)}
                                                   for (tx, ty), t in sorted(c.tiles.items())]}}
           if c is not None and not c.neutral else {}),
        **({"features": features_to_json(p.features)} if p.features else {}),
        **({"direction": direction_to_json(p.direction)} if p.direction is not None and not p.direction.identity
           else {}),
        **({"lattice": lattice_to_json(p.lattice)} if p.lattice is not None else {}),
    }


def _plane_from_json(d: object) -> PlaneControls | None:
    """The plane's set-aside controls, or None; all or nothing."""
    if d is None:
        return None
    if not isinstance(d, dict):
        raise ProjectError("The project's set-aside plane controls are damaged.")
    _, canvas = _fields_from_json({"canvas": d["randomness"]}) if "randomness" in d else (None, None)
    try:
        features = features_from_json(d.get("features", []))
    except ValueError as exc:
        raise ProjectError(f"The project's set-aside features are damaged: {exc}") from None
    return PlaneControls(canvas, tuple(features), direction_from_json(d.get("direction")),
                         lattice_from_json(d.get("lattice")))


def _png16(a: np.ndarray) -> str:
    import io

    from PIL import Image
    buf = io.BytesIO()
    Image.fromarray(np.ascontiguousarray(a, dtype=np.uint16)).save(buf, "PNG")
    return base64.b64encode(buf.getvalue()).decode("ascii")


def _unpng16(text: object, shape: tuple[int, int] | None, what: str) -> np.ndarray:
    """A 16-bit grayscale PNG (base64) as uint16; ProjectError if it is anything else."""
    import io

    from PIL import Image
    if not isinstance(text, str) or len(text) > 8 * 2 ** 20:
        raise ProjectError(f"The project's {what} is damaged.")
    try:
        data = base64.b64decode(text, validate=True)
        with Image.open(io.BytesIO(data), formats=["PNG"]) as img:
            if img.size[0] * img.size[1] > MAX_SIZE * MAX_SIZE or img.mode not in ("I;16", "I"):
                raise ValueError
            a = np.asarray(img)
    except Exception:
        raise ProjectError(f"The project's {what} is damaged.") from None
    if a.min(initial=0) < 0 or a.max(initial=0) > 65535 or (shape is not None and a.shape != shape):
        raise ProjectError(f"The project's {what} is damaged.")
    return a.astype(np.uint16)


def _fields_to_json(doc: Document) -> dict | None:
    e, c = doc.randomness_exemplar, doc.randomness_canvas
    if (e is None or e.neutral) and (c is None or c.neutral):
        return None
    return {
        "exemplar": None if e is None or e.neutral else {"png16": _png16(e.values)},
        "canvas": None if c is None or c.neutral else {
            "tile": TILE, "tiles": [{"x": tx, "y": ty, "png16": _png16(t)} for (tx, ty), t in sorted(c.tiles.items())]},
    }


MAX_FIELD_TILES = 65536


def _fields_from_json(r: object) -> tuple[ExemplarField | None, CanvasField | None]:
    """The painted fields of a project; all or nothing."""
    if r is None:
        return None, None
    if not isinstance(r, dict):
        raise ProjectError("The project's randomness fields are damaged.")
    e = r.get("exemplar")
    efield = None
    if e is not None:
        if not isinstance(e, dict):
            raise ProjectError("The project's exemplar randomness field is damaged.")
        v = _unpng16(e.get("png16"), None, "exemplar randomness field")
        n = v.shape[0]
        if v.ndim != 2 or v.shape[1] != n or n & (n - 1) or not 1 <= n <= MAX_SIZE:
            raise ProjectError("The project's exemplar randomness field is damaged.")
        efield = ExemplarField(v)
    c = r.get("canvas")
    cfield = None
    if c is not None:
        cfield = CanvasField(tiles_from_json(c, "canvas randomness field", "png16",
                                             lambda text: _unpng16(text, (TILE, TILE), "canvas randomness field"),
                                             MAX_FIELD_TILES))
    return efield, cfield


def _avoid_from_json(r: object) -> ExemplarMask | None:
    """The project's avoided exemplar regions (a 0/1 16-bit PNG), or None."""
    if r is None:
        return None
    if not isinstance(r, dict):
        raise ProjectError("The project's avoided exemplar regions are damaged.")
    v = _unpng16(r.get("png16"), None, "avoided exemplar regions")
    n = v.shape[0]
    if v.ndim != 2 or v.shape[1] != n or n & (n - 1) or not 1 <= n <= MAX_SIZE or v.max(initial=0) > 1:
        raise ProjectError("The project's avoided exemplar regions are damaged.")
    return ExemplarMask(v.astype(np.uint8))


def save_project(path: str, project: Project, embed: bool | None = None, store=None) -> None:
    """Write atomically (engine.safeio.atomic_write); failures are ProjectError.
    With ``store``: as :func:`fitted_project_json` (autosaves), else as
    :func:`project_to_json`."""
    d = fitted_project_json(project, store) if store is not None else project_to_json(project, path, embed)
    text = json.dumps(d, indent=1)
    try:
        # A project file the user linked on purpose is saved through the link; an autosave never is.
        atomic_write(path, text.encode("utf-8"), follow_links=store is None)
    except WriteError as exc:
        raise ProjectError(str(exc)) from None


def project_save_path(path: str, document: Document | None = None, current: str | None = None) -> str:
    """The file a project save writes when the user chose ``path``: with the
    project extension appended when it lacks it, so project JSON never lands
    on an image ("texture.png" is saved as "texture.png.itex"); ``current``,
    the project file the document came from, keeps its name. ProjectError
    when that file is one of ``document``'s input files (its exemplar or a
    material map): those are never replaced."""
    path = os.path.abspath(os.path.expanduser(path))
    if not (current and path == os.path.abspath(current)) and not path.lower().endswith(PROJECT_SUFFIX):
        path += PROJECT_SUFFIX
    if document is not None:
        for role, src in (rs for entry in document.entries() for rs in entry):
            if src.path and _same_file(path, src.path):
                what = "exemplar" if src is document.exemplar else f"{role} map"
                raise ProjectError(f"{printable(os.path.basename(path))} is the document's {what}, one of its "
                                   "inputs; a project is not saved over it. Choose another name.")
    return path


def _same_file(a: str, b: str) -> bool:
    try:
        return os.path.samestat(os.stat(a), os.stat(b))  # hard links too
    except OSError:
        return os.path.realpath(a) == os.path.realpath(b)


class ExemplarOutside(ProjectError):
    """The project refers to an exemplar file outside its own folder; it is read
    only when the user allows it (``load_project(..., allow_outside=...)``)."""

    def __init__(self, path: str, project_name: str):
        self.path = path
        super().__init__(f"The project {project_name} uses the exemplar file {printable(path)}, "
                         "which is outside the project's folder.")


def parse_project_json(raw: bytes, name: str = "The file") -> object:
    """Decode untrusted project JSON with bounded nesting and numbers."""
    try:
        return parse_json(raw, MAX_JSON_DEPTH, MAX_INT_DIGITS)
    except JSONLimitError as exc:
        raise ProjectError(f"{name} is not an Infinitex project ({exc}).") from None
    except ValueError:
        raise ProjectError(f"{name} is not an Infinitex project (not readable as JSON).") from None


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


def _int_in(d: dict, key: str, where: str, lo: int, hi: int) -> int:
    v = _get(d, key, int, where)
    if not lo <= v <= hi:
        raise ProjectError(f"{where}.{key} must be an integer from {lo} to {hi}.")
    return v


def _read_reference(ref: str, path: str | None, name: str, allow_outside) -> tuple[bytes, str]:
    """Bytes and real path of an exemplar referenced by ``ref`` from the project
    at ``path``: relative paths start at the project's folder; a file outside
    that folder is read only if ``allow_outside`` is True or holds its real path."""
    if not ref or "\x00" in ref or len(ref) > 4096:
        raise ProjectError("exemplar.path is not a usable file path.")
    folder = os.path.realpath(os.path.dirname(os.path.abspath(path))) if path else None
    base = folder or os.getcwd()
    real = os.path.realpath(os.path.join(base, os.path.expanduser(ref)) if not os.path.isabs(ref) else ref)
    inside = folder is not None and os.path.commonpath([real, folder]) == folder
    allowed = allow_outside is True or (allow_outside not in (None, False) and real in allow_outside)
    if not inside and not allowed:
        raise ExemplarOutside(real, name)
    if not os.path.lexists(real):
        raise ProjectError(f"The project refers to exemplar {printable(ref)}, which cannot be found.")
    try:
        return read_limited(real, MAX_FILE_BYTES, "image"), real
    except ReadError as exc:
        raise ProjectError(f"The project's exemplar cannot be read: {exc}") from None


def _source_from_json(e: dict, where: str, path: str | None, name: str, allow_outside) -> ExemplarSource:
    """One image file of a project (the exemplar or a material's map): embedded
    or referenced, and hash-checked."""
    ex_name = _get(e, "name", str, where)
    if not ex_name or len(ex_name) > 1024:
        raise ProjectError(f"{where}.name must be a file name of 1 to 1024 characters.")
    sha = _get(e, "sha256", str, where)
    if not re.fullmatch(r"[0-9a-f]{64}", sha):
        raise ProjectError(f"{where}.sha256 is not a SHA-256 digest.")
    embedded = _get(e, "embedded", str, where, optional=True)
    ref = _get(e, "path", str, where, optional=True)
    source = _get(e, "source", str, where, optional=True)  # autosaves: where the file came from (not read)
    if source is not None and not (os.path.isabs(source) and len(source) <= 4096 and "\x00" not in source):
        raise ProjectError(f"{where}.source is not a usable file path.")
    if embedded is not None:
        try:
            data = base64.b64decode(embedded, validate=True)
        except ValueError:
            raise ProjectError(f"The {where} embedded in the project is damaged.") from None
        src_path = None
    elif ref is not None:
        data, src_path = _read_reference(ref, path, name, allow_outside)
    else:
        raise ProjectError(f"The project holds neither an embedded {where} nor a path to one.")
    if hashlib.sha256(data).hexdigest() != sha:
        what = "exemplar" if where == "exemplar" else "map"
        raise ProjectError(f"The {what} {printable(ex_name)} does not match the project (its content changed), "
                           "so the texture could not be reproduced.")
    return ExemplarSource(name=ex_name, data=data, sha256=sha, path=source or src_path)


def _material_from_json(mat: object, primary: ExemplarSource, path: str | None, name: str, allow_outside):
    """(maps, weights) of a project's material section (none: a single image)."""
    if mat is None:
        return (), None
    bad = ProjectError("The project's material is damaged.")
    if not isinstance(mat, dict) or not isinstance(mat.get("maps"), list) or len(mat["maps"]) >= len(ROLES):
        raise bad
    role = mat.get("role")
    if role not in ROLES:
        raise bad
    maps = [(role, primary)]
    for i, entry in enumerate(mat["maps"]):
        if not isinstance(entry, dict) or entry.get("role") not in ROLES:
            raise bad
        maps.append((entry["role"], _source_from_json(entry, f"material.maps[{i}]", path, name, allow_outside)))
    w = mat.get("weights")
    weights = None
    if w is not None:
        if not isinstance(w, list) or len(w) > len(ROLES) or not all(
                isinstance(p, list) and len(p) == 2 and isinstance(p[0], str) and is_number(p[1]) for p in w):
            raise bad
        weights = tuple((str(r), float(v)) for r, v in w)
    return tuple(maps), weights


def project_from_json(d: object, path: str | None = None, allow_outside=False) -> Project:
    """Parse and check a project dict; raise ProjectError with a clear sentence.

    ``allow_outside``: True, or a collection of real paths, of referenced
    exemplar files outside the project's folder that may be read."""
    try:
        return _project_from_json(d, path, allow_outside)
    except ProjectError:
        raise
    except (TypeError, ValueError, OverflowError, RecursionError, KeyError, AttributeError) as exc:
        raise ProjectError(f"The project file is damaged ({type(exc).__name__}).") from None


def _project_from_json(d: object, path: str | None, allow_outside) -> Project:
    name = printable(os.path.basename(path)) if path else "project"
    if not isinstance(d, dict) or d.get("format") != FORMAT:
        raise ProjectError("This is not an Infinitex project file.")
    version = d.get("version")
    if not isinstance(version, int) or isinstance(version, bool) or version < 1:
        raise ProjectError("The project file has no valid format version.")
    if version > VERSION:
        raise ProjectError(f"This project was written by a newer version (format {version}); "
                           "update Infinitex to open it.")
    e = _get(d, "exemplar", dict, "project")
    source = _source_from_json(e, "exemplar", path, name, allow_outside)
    maps, weights = _material_from_json(d.get("material"), source, path, name, allow_outside)
    palette = palette_from_json(d.get("palette"), lambda e, where: _source_from_json(e, where, path, name, allow_outside))
    a = _get(d, "analysis", dict, "project")
    s = _get(d, "synthesis", dict, "project")
    jitter = _get(s, "jitter", list, "synthesis")
    if len(jitter) > MAX_LEVELS or not all(is_number(r) and 0.0 <= r <= 1.0 for r in jitter):
        raise ProjectError(f"synthesis.jitter must be a list of at most {MAX_LEVELS} numbers from 0 to 1.")
    corrected = _get(s, "corrected", list, "synthesis", optional=True)
    if corrected is not None and (len(corrected) > MAX_LEVELS or not all(
            isinstance(c, int) and not isinstance(c, bool) and 0 <= c <= 12 for c in corrected)):
        raise ProjectError("synthesis.corrected must be a list of level numbers from 0 to 12.")
    level_passes = _get(s, "level_passes", list, "synthesis", optional=True) or []
    if len(level_passes) > MAX_LEVELS or not all(
            isinstance(c, int) and not isinstance(c, bool) and 0 <= c <= 8 for c in level_passes):
        raise ProjectError(f"synthesis.level_passes must be a list of at most {MAX_LEVELS} integers from 0 to 8.")
    fw = a.get("feature_weight", 0.0) if isinstance(a, dict) else 0.0
    if not is_number(fw) or not 0.0 <= fw <= 4.0:
        raise ProjectError("analysis.feature_weight must be a number from 0 to 4.")
    kappa = _get(s, "kappa", (int, float), "synthesis")
    if not is_number(kappa) or not 0.0 <= kappa <= 100.0:
        raise ProjectError("synthesis.kappa must be a number from 0 to 100.")
    toroidal = _get(e, "toroidal", bool, "exemplar", optional=True)
    make_tileable = bool(_get(e, "make_tileable", bool, "exemplar", optional=True))
    fields = _fields_from_json(d.get("randomness"))
    avoid = _avoid_from_json(d.get("avoid"))
    labels = labels_from_json(d.get("labels"))
    try:
        features = features_from_json(d.get("features", []))
    except ValueError as exc:
        raise ProjectError(f"The project's features are damaged: {exc}") from None
    doc = Document(
        exemplar=source,
        fit=_get(e, "fit", str, "exemplar"),
        toroidal=toroidal,
        make_tileable=make_tileable,
        model=_get(a, "model", str, "analysis"),
        k=_int_in(a, "k", "analysis", 0, 4),
        feature_weight=float(fw),
        jitter=tuple(float(r) for r in jitter),
        seed=_int_in(s, "seed", "synthesis", 0, 2 ** 32 - 1),
        passes=_int_in(s, "passes", "synthesis", 0, 8),
        level_passes=tuple(level_passes),
        subgrid=_int_in(s, "subgrid", "synthesis", 1, 4),
        # Files from before the fidelity stage have none: they keep their texture (Variety).
        structure=_int_in(s, "structure", "synthesis", 0, STRUCTURE_LEVELS - 1) if "structure" in s else 0,
        kappa=float(kappa),
        corrected=None if corrected is None else tuple(corrected),
        randomness_exemplar=fields[0],
        avoid_exemplar=avoid,
        labels=labels,
        randomness_canvas=fields[1],
        features=features,
        lattice=lattice_from_json(d.get("lattice")),
        maps=maps,
        weights=weights,
        palette=palette,
        direction=direction_from_json(d.get("direction")),
        surface=surface_from_json(d.get("surface")),
        plane=_plane_from_json(d.get("plane")),
        motion=motion_from_json(d.get("motion")),
    )
    doc.validate()
    view, display = View(), Display()
    v = d.get("view")
    if v is not None:
        if not isinstance(v, dict) or not all(is_number(v.get(k)) for k in ("x", "y", "zoom")):
            raise ProjectError("The project's view is damaged.")
        view = View(float(v["x"]), float(v["y"]), float(v["zoom"])).clamped()
    g = d.get("display")
    if g is not None:
        if not isinstance(g, dict):
            raise ProjectError("The project's display settings are damaged.")
        mode, level, mag = g.get("mode", "color"), g.get("level", -1), g.get("magnify", "hires")
        geom = g.get("geometry", "original")
        shown = g.get("map", "")
        az, el, relief = g.get("light_azimuth", 135.0), g.get("light_elevation", 40.0), g.get("relief", 1.0)
        if (not isinstance(mode, str) or mode not in DISPLAY_MODES or not isinstance(mag, str)
                or mag not in MAGNIFY_FILTERS or not isinstance(level, int) or isinstance(level, bool)
                or not -1 <= level <= 12 or geom not in GEOMETRIES
                or shown not in ("", IMAGE, *ROLES) or not all(is_number(v) for v in (az, el, relief))
                or not (-360.0 <= az <= 360.0 and 5.0 <= el <= 90.0 and 0.0 <= relief <= 16.0)):
            raise ProjectError("The project's display settings are damaged.")
        display = Display(mode, level, mag, geom, shown, float(az), float(el), float(relief))
    origin = d.get("autosave_of")
    if origin is not None and not (isinstance(origin, str) and 0 < len(origin) <= 4096 and "\x00" not in origin):
        raise ProjectError("The project's autosave origin is damaged.")
    return Project(doc, view, display, origin)


def load_project(path: str, allow_outside=False) -> Project:
    """Read a project file (untrusted); see :func:`project_from_json` for ``allow_outside``."""
    name = printable(os.path.basename(path))
    try:
        raw = read_limited(path, MAX_PROJECT_BYTES, "project file")
    except ReadError as exc:
        raise ProjectError(str(exc)) from None
    return project_from_json(parse_project_json(raw, name), path, allow_outside)


def is_project_file(path: str) -> bool:
    """True when the file starts like a project (JSON with our format tag)."""
    if path.lower().endswith(PROJECT_SUFFIX):
        return True
    head = read_head(path, 64).lstrip()
    return head.startswith(b"{") and FORMAT.encode() in head
