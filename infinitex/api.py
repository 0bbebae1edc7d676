"""The small front door: one call from an exemplar to a texture.

:func:`synthesize` and :func:`tile` cover the common cases (a window of the
infinite texture, a seamless tile); everything they do is also reachable
step by step through the building blocks re-exported by :mod:`infinitex`
(``load_exemplar`` -> ``analyze`` -> ``Synthesizer`` -> ``colors``), which is
what pipelines that make many windows of one exemplar should use (the
analysis and the GL context are then made once).
"""
from __future__ import annotations

import os

import numpy as np

from .engine.analysis import AnalysisSettings, analyze
from .engine.controls import NO_CONTROLS, Controls
from .engine.controls.lattice import (
    Lattice,
    original_geometry_box,
    rectified_exemplar,
    render_original,
)
from .engine.controls.lattice_cache import find_lattice
from .engine.exemplar import Exemplar, from_array, load_exemplar, load_full, unit_values
from .engine.imagefile import to_u8
from .engine.palette import PaletteLayout
from .engine.params import DEFAULT_STRUCTURE, SynthParams, structure_index, structure_params
from .engine.pyramid import Rect
from .engine.synth import Synthesizer


def _exemplar(source, lattice: Lattice | str | None) -> tuple[Exemplar, Lattice | None]:
    """An exemplar from a path, an array or an Exemplar; with a lattice, its
    rectified block ("auto": the lattice detection finds, if it is confident;
    an Exemplar is taken as it is)."""
    if lattice is None or (isinstance(lattice, str) and isinstance(source, Exemplar)):
        if isinstance(source, Exemplar):
            return source, None
        if isinstance(source, (str, os.PathLike)):
            return load_exemplar(source), None
        return from_array(source), None
    image = load_full(source) if isinstance(source, (str, os.PathLike)) else unit_values(source)
    if image.ndim == 2:
        image = image[:, :, None]
    if isinstance(lattice, str):
        if lattice != "auto":
            raise ValueError("lattice must be a Lattice, 'auto' or None.")
        lattice = find_lattice(image).lattice
        if lattice is None:
            return _exemplar(source, None)
    return rectified_exemplar(image, lattice), lattice


def _whole_cells(source, lattice, controls: Controls, n: int) -> tuple[Exemplar, Lattice | None]:
    """As _exemplar, for tiles of n px: a lattice found by "auto" whose cells
    do not divide n (or beside exemplar maps in ``controls``) is not used."""
    auto = isinstance(lattice, str)
    if auto and controls is not NO_CONTROLS:
        lattice = None
    ex, lat = _exemplar(source, lattice)
    if auto and lat is not None:
        cx, cy = lat.cell(ex.size)
        if n % cx or n % cy:
            return _exemplar(source, None)
    return ex, lat


def _label_map(source, what: str) -> tuple[np.ndarray, bool]:
    """(array, colored): a path or a color image (H, W, 3|4) as RGBA uint8,
    or a 2-D integer array of label ids as it is."""
    from .engine.controls.label_maps import load_label_image
    if isinstance(source, (str, os.PathLike)):
        return load_label_image(os.fspath(source), what), True
    a = np.asarray(source)
    if a.ndim == 2:
        return a.astype(np.int64), False
    if a.ndim == 3 and a.shape[2] in (3, 4) and a.dtype == np.uint8:
        return (a if a.shape[2] == 4 else np.concatenate([a, np.full(a.shape[:2] + (1,), 255, np.uint8)], 2)), True
    raise ValueError(f"The {what} must be a path, an 8-bit color image (H, W, 3|4) or a 2-D array of label ids.")


def label_controls(ex: Exemplar, exemplar_labels, canvas_labels, origin: tuple[int, int] = (0, 0),
                   strength: float = 1.0, controls: Controls = NO_CONTROLS) -> Controls:
    """``controls`` with texture by numbers for ``ex``: ``exemplar_labels``
    over the exemplar image (a path, a color image where each distinct color
    is a label, or label ids 0..15; brought to the exemplar by its fit rule),
    ``canvas_labels`` placed at canvas ``origin`` (the same colors, transparent
    = free; or ids, negative = free), followed with ``strength`` (0 to 8)."""
    from dataclasses import replace

    from .engine.controls import CanvasLabels, ExemplarLabels
    from .engine.controls.label_maps import canvas_labels_from_colors, exemplar_labels_from_colors, fit_label_map
    emap, colored = _label_map(exemplar_labels, "exemplar label map")
    palette = None
    if colored:
        ids, palette = exemplar_labels_from_colors(emap)
    else:
        if emap.min(initial=0) < 0 or emap.max(initial=0) > 15:
            raise ValueError("Exemplar label ids are 0 to 15.")
        ids = emap.astype(np.uint8)
    ids = fit_label_map(ids, ex.fit, ex.size, ex.original_size, "exemplar label map")
    cmap, ccolored = _label_map(canvas_labels, "canvas label map")
    if ccolored:
        if palette is None:
            raise ValueError("A colored canvas label map needs a colored exemplar label map (which color is which label).")
        values = canvas_labels_from_colors(cmap, palette)
    else:
        if cmap.max(initial=0) > 15:
            raise ValueError("Canvas label ids are 0 to 15 (negative: free).")
        values = np.where(cmap < 0, 0, cmap + 1).astype(np.uint8)
    out = replace(controls, labels_exemplar=ExemplarLabels(ids),
                  labels_canvas=CanvasLabels.from_image(values, int(origin[0]), int(origin[1])),
                  label_strength=float(strength))
    out.validate(ex.size)
    return out


def direction_field(source, origin: tuple[int, int] = (0, 0), *, kind: str = "auto", y_up: bool = True,
                    scale: float = 1.0, aspect: float = 1.0):
    """A :class:`DirectionField` from a direction map placed with its top-left at
    canvas ``origin``: a file path (a flow map, or a grayscale angle map; see
    ``kind``, ``y_up`` for a flow map's green: up = OpenGL) or an array of
    angles in degrees (H, W). ``scale`` and ``aspect`` apply where the map gives
    a direction. Pass it as ``Controls(direction=...)``."""
    from .engine.controls.direction import DirectionField, jacobian
    from .engine.controls.maps import load_direction_map
    if isinstance(source, (str, os.PathLike)):
        values = load_direction_map(os.fspath(source), kind, y_up, scale, aspect)
    else:
        values = jacobian(np.asarray(source, np.float64), scale, aspect)
    return DirectionField.from_jacobians(values, int(origin[0]), int(origin[1]))


def palette(exemplars, fit: str = "resize") -> tuple[Exemplar, PaletteLayout]:
    """Several exemplars (paths, arrays in [0, 1] or Exemplars; 2 to 16) packed
    into one exemplar, each a label (engine/palette.py): returns it and its
    layout, whose ``labels()`` is the exemplar label map for :func:`synthesize`'s
    ``labels`` (label i = exemplar i) and whose ``locate(coords)`` tells which
    exemplar, and which of its pixels, each coordinate copies."""
    from .engine.material import single
    from .engine.palette import pack_palette
    exs = [load_exemplar(e, fit=fit) if isinstance(e, (str, os.PathLike)) else _exemplar(e, None)[0] for e in exemplars]
    names = [os.path.basename(os.fspath(e)) if isinstance(e, (str, os.PathLike)) else f"exemplar {i + 1}"
             for i, e in enumerate(exemplars)]
    mat, layout = pack_palette([single(ex) for ex in exs], names, fit)
    return mat.maps[mat.primary].exemplar, layout


def synthesize(exemplar, size: tuple[int, int] = (256, 256), origin: tuple[int, int] = (0, 0), *,
               seed: int = 0, randomness: float | tuple[float, ...] | None = None,
               controls: Controls = NO_CONTROLS, lattice: Lattice | str | None = "auto",
               geometry: str = "original", structure: int | str = DEFAULT_STRUCTURE,
               labels: tuple | None = None, label_strength: float = 1.0) -> np.ndarray:
    """A ``size`` = (W, H) window of the exemplar's infinite texture at canvas
    position ``origin``, as uint8 (H, W, C).

    ``exemplar``: an image path, an array (H, W[, C]) of floats in [0, 1] or
    of uint8 / uint16 (read on their full range), or an
    :class:`~infinitex.engine.exemplar.Exemplar`. ``randomness``: one r for
    every level or one per level, coarse to fine (default 0.6). ``controls``:
    painted randomness and placed features (:class:`Controls`). ``lattice``:
    ``"auto"`` (the default: an image or array showing a lattice, found with
    confidence, is synthesized on it; none is found on stochastic images), a
    :class:`Lattice`, or None (never); with a lattice, ``geometry`` is ``"original"`` (the
    input's geometry, origin and size in input pixels) or ``"rectified"``.
    ``structure``: the Structure / Variety preset, 0 to 4 or its name
    ("variety" ... "maximum"; default "balanced", as in the editor and the
    command line). ``labels``: texture by numbers, (exemplar label map,
    canvas label map) or (..., canvas origin) as for :func:`label_controls`,
    followed with ``label_strength``. Windows of the same arguments agree bit
    for bit wherever they overlap."""
    if lattice == "auto" and (labels is not None or controls is not NO_CONTROLS):
        lattice = None  # maps in the exemplar's pixels, and labels, go without a lattice
    ex, lat = _exemplar(exemplar, lattice)
    if labels is not None:
        controls = label_controls(ex, labels[0], labels[1], tuple(labels[2]) if len(labels) > 2 else (0, 0),
                                  label_strength, controls)
    an = analyze(ex, AnalysisSettings(lattice=(lat.nx, lat.ny) if lat else (0, 0)))
    params = _params(an.L, seed, randomness, structure)
    if lat is not None:
        from dataclasses import replace
        controls = replace(controls, lattice=lat)
    w, h = size
    with Synthesizer(an, params, controls=controls) as s:
        if lat is not None and geometry == "original":
            box = original_geometry_box(lat, an.size, origin[0], origin[1], w, h)
            coords = s.window(Rect(*box))
            src = ex.hires if ex.hires is not None else ex.pixels
            return to_u8(render_original(coords, box, lat, an.size, src, origin[0], origin[1], w, h))
        return to_u8(s.colors(s.window(Rect.of(origin[0], origin[1], w, h))))


def tile(exemplar, n: int = 256, *, seed: int = 0, randomness: float | tuple[float, ...] | None = None,
         controls: Controls = NO_CONTROLS, lattice: Lattice | str | None = "auto",
         structure: int | str = DEFAULT_STRUCTURE) -> np.ndarray:
    """An n x n seamless (toroidal) tile, uint8 (n, n, C); n a power of two
    from 32 to 4096. With a lattice the tile is rectified, whole cells.
    ``structure`` as for :func:`synthesize`; a lattice found by ``"auto"``
    is used only where its cells divide n."""
    ex, lat = _whole_cells(exemplar, lattice, controls, n)
    an = analyze(ex, AnalysisSettings(lattice=(lat.nx, lat.ny) if lat else (0, 0)))
    if lat is not None:
        from dataclasses import replace
        controls = replace(controls, lattice=lat)
    with Synthesizer(an, _params(an.L, seed, randomness, structure), controls=controls) as s:
        return to_u8(s.colors(s.toroidal(n)))


def tile_set(exemplar, colors: int = 2, n: int = 256, *, variants: int = 0, seed: int = 0,
             randomness: float | tuple[float, ...] | None = None, controls: Controls = NO_CONTROLS,
             lattice: Lattice | str | None = "auto", structure: int | str = DEFAULT_STRUCTURE,
             origin: tuple[int, int] = (0, 0)) -> tuple[np.ndarray, dict]:
    """A tile set for game engines: a corner Wang set of ``colors`` corner
    colours (2: 16 tiles, 3: 81) of n x n (64 to 2048, a power of two) that
    meet without a seam wherever their corner colours agree; or, with
    ``colors=1`` and ``variants=K``, K tiles with the borders of one toroidal
    tile. Returns (atlas uint8 (rows*n, cols*n, C), description): the
    description's ``tiles`` give each tile's corner colours ``nw`` ``ne``
    ``sw`` ``se`` and atlas position ``x`` ``y`` (px); a corner set's atlas is
    itself a valid arrangement. ``arrange(atlas, description, cols, rows)``
    lays tiles out at random. Other arguments as for :func:`synthesize`; the
    windows are taken from around ``origin``."""
    from dataclasses import replace

    from .export.tileset import Mender
    from .export.wang import TileSetBuilder, TileSetPlan
    if controls.directed:
        raise ValueError("A tile set follows no direction field (its tiles meet in any order): pass controls "
                         "without one.")
    TileSetPlan(colors, n, variants if colors == 1 else 0).validate()  # before any analysis
    ex, lat = _whole_cells(exemplar, lattice, controls, n)
    an = analyze(ex, AnalysisSettings(lattice=(lat.nx, lat.ny) if lat else (0, 0)))
    if lat is not None:
        controls = replace(controls, lattice=lat)
    cell = tuple(lat.cell(an.size)) if lat is not None else (1, 1)
    plan = TileSetPlan(colors, n, variants if colors == 1 else 0, cell, origin)
    with Synthesizer(an, _params(an.L, seed, randomness, structure), controls=controls) as s:
        def render(rect):
            yield
            return s.window(rect, remainder=False)

        def toroidal():
            yield
            return s.toroidal(n)[..., :2]
        mender = Mender(s, an.L, n if colors == 1 else 0)  # the cuts inside tiles mended
        work = TileSetBuilder(plan, render, s.colors, toroidal, mender).build()
        try:
            while True:
                try:
                    next(work)
                except StopIteration as stop:
                    coords = stop.value
                    break
        finally:
            mender.release()
        atlas = to_u8(s.colors(coords))
    cols, rows = plan.grid
    return atlas, {"kind": "corner-wang" if colors > 1 else "variants", "colors": colors, "tile": n,
                   "count": plan.count, "columns": cols, "rows": rows, "tiles": plan.tiles()}


def arrange(atlas: np.ndarray, description: dict, cols: int, rows: int, seed: int = 0) -> np.ndarray:
    """A random valid arrangement of a tile set's tiles (``cols`` x ``rows``), as one image."""
    from .export.wang import assemble
    plan = _described_plan(atlas, description)
    if not (1 <= cols <= 4096 and 1 <= rows <= 4096):
        raise ValueError(f"An arrangement is 1 to 4096 tiles a side, not {cols} x {rows}.")
    return assemble(atlas, plan, plan.arrangement(cols, rows, seed))


def _described_plan(atlas: np.ndarray, d: dict):
    """The plan of a set :func:`tile_set` described, checked against its atlas (ValueError, one sentence)."""
    from .export.wang import TileSetPlan
    try:
        plan = TileSetPlan(int(d["colors"]), int(d["tile"]), int(d["count"]) if int(d["colors"]) == 1 else 0)
        plan.validate()
    except (KeyError, TypeError, ValueError) as exc:
        raise ValueError(f"Not the description of a tile set made by tile_set ({exc}).") from None
    cols, rows = plan.grid
    want = (rows * plan.tile, cols * plan.tile)
    if not isinstance(atlas, np.ndarray) or atlas.ndim != 3 or atlas.shape[:2] != want:
        got = getattr(atlas, "shape", type(atlas).__name__)
        raise ValueError(f"The atlas of this set is an array of {want[1]}x{want[0]} px with channels, not {got}.")
    return plan


def save_tile_set(atlas: np.ndarray, description: dict, path, *, engines: str | tuple[str, ...] = "all",
                  seed: int = 0) -> list[str]:
    """Write a set made by :func:`tile_set` as ``infinitex export --wang``
    does: the atlas ``path`` (.png), its ``.json`` description, the preview
    (8 x 8 tiles at random by ``seed``, also the example map's layout) and
    the ``engines``' resources ("tiled", "godot", "all" or "none": the .tsx
    and .tmx, the .tres). Returns the files written."""
    import json

    from .engine.imagefile import png_writer
    from .engine.safeio import StagedFiles
    from .export.engines import engine_files, parse_engines, write_engine_files
    from .export.tileset import PREVIEW_TILES, set_description, set_paths
    from .export.wang import assemble
    path = os.fspath(path)
    if not path.lower().endswith(".png"):
        raise ValueError(f"A tile set's atlas is written as PNG: {path!r} does not end in .png.")
    d = description
    plan = _described_plan(atlas, d)
    if atlas.dtype != np.uint8:
        raise ValueError(f"A tile set's atlas is written from uint8 pixels, not {atlas.dtype}.")
    files = engine_files(path, [("image", path, 8)], "image", parse_engines(engines) if isinstance(engines, str)
                         else tuple(engines))
    side = set_paths(path)
    layout = plan.arrangement(PREVIEW_TILES, PREVIEW_TILES, seed)
    written = [path, side["preview"]] + files.files + [side["json"]]
    full = set_description(plan, path, {"image": path}, side["preview"], files, d["tiles"])
    StagedFiles.check(written)
    with StagedFiles() as stage:  # one unit: the old set stays whole until every file is written
        stage.write(path, writer=png_writer(atlas))
        stage.write(side["preview"], writer=png_writer(assemble(atlas, plan, layout)))
        write_engine_files(plan, files, {"image": (path, (atlas.shape[1], atlas.shape[0]))}, "image", layout,
                           stage.write)
        stage.write(side["json"], (json.dumps(full, indent=1) + "\n").encode())
        stage.commit()
    return written


def _params(L: int, seed: int, randomness, structure: int | str) -> SynthParams:
    return structure_params(_jitter_params(L, seed, randomness), structure_index(structure))


def _jitter_params(L: int, seed: int, randomness) -> SynthParams:
    if randomness is None:
        return SynthParams.default(L, seed=seed)
    if isinstance(randomness, (int, float)):
        return SynthParams(jitter=(float(randomness),) * (L + 1), seed=seed)
    r = tuple(float(v) for v in randomness)
    if len(r) != L + 1:
        raise ValueError(f"randomness needs one value or {L + 1} (one per level), not {len(r)}.")
    return SynthParams(jitter=r, seed=seed)


def texture_model(model, exemplar, size: int = 1024, *, repeats: float | None = None, frame: str = "up",
                  seed: int = 0, structure: int | None = None, seams: bool = True):
    """Texture a model (LH06 6): synthesis directly in its atlas, continuous
    across its UV seams. ``model``: an OBJ/glTF/GLB path or a
    :class:`~infinitex.engine.surface.Model`; ``exemplar``: a path, an array
    or an Exemplar. ``repeats``: the exemplar's width fits that many times
    across the model's largest side (default: about one exemplar pixel per
    texel); ``frame``: "up" (upright) or "uv". Returns (image float32
    (size, size, C), coordinates (size, size, 4) int32, the AtlasDomain).
    ``seams=False``: each chart on its own (for comparison)."""
    from .engine.params import DEFAULT_STRUCTURE
    from .engine.surface import AtlasDomain, Model, load_model
    from .engine.surface.bake import atlas_coords, atlas_image
    from .export.surface import plan
    m = model if isinstance(model, Model) else load_model(os.fspath(model))
    ex, _ = _exemplar(exemplar, None)
    an = analyze(ex)
    pl = plan(m, size, an.size, repeats=repeats)
    if pl.magnify != 1:
        raise ValueError(f"texture_model synthesizes up to 4096 px; use `infinitex surface` for {size} px.")
    atlas = AtlasDomain(m, size, pl.sigma, frame=frame, seams=seams)
    params = structure_params(SynthParams.default(an.L, seed=seed),
                              DEFAULT_STRUCTURE if structure is None else structure)
    with Synthesizer(an, params) as synth:
        coords = atlas_coords(synth, atlas)
    return atlas_image(an.levels[an.L].stack, coords, atlas, an.toroidal), coords, atlas


def animate(exemplar, frames: int, velocity: tuple[float, float] = (1.0, 0.0), *, size: tuple[int, int] = (256, 256),
            origin: tuple[int, int] = (0, 0), toroidal: int = 0, loop: bool = False, period: int | None = None,
            velocity_map=None, speed: float = 1.0, velocity_origin: tuple[int, int] = (0, 0), y_up: bool = True,
            start: int = 0, seed: int = 0, randomness: float | tuple[float, ...] | None = None,
            controls: Controls = NO_CONTROLS, structure: int | str = DEFAULT_STRUCTURE) -> np.ndarray:
    """Frames of the texture flowing (LH06 7, engine/advect.py), uint8 (N, H, W, C).

    ``velocity``: uniform, canvas px per frame (+x right, +y down the rows);
    ``velocity_map``: added over its rectangle (placed at ``velocity_origin``): an
    image path (red, green in [0, 1], 0.5 still, ``speed`` px per frame at 0 and
    1, green up unless ``y_up`` is False) or a float array (H, W, 2) of px per
    frame. ``toroidal=n``: frames of an n x n seamless tile (the map is then
    resized to the tile). ``loop``: frame ``frames`` is frame 0; ``period``: frames
    between renewals (default: ``Flow.suggested_period``, from the field's shear).
    ``write_animation(path, frames)`` writes them (folder, .png atlas, .webp,
    .apng, .mp4). Other arguments as for :func:`synthesize` (no lattice)."""
    from dataclasses import replace

    from .engine.advect import FlowFrames, SynthSource
    from .engine.controls.flow import Q, Flow, VelocityMap
    from .engine.controls.maps import load_velocity_map
    ex, _ = _exemplar(exemplar, None)
    flow = Flow.of(*velocity)
    if velocity_map is not None:
        at = (0, 0) if toroidal else tuple(velocity_origin)
        if isinstance(velocity_map, (str, os.PathLike)):
            vmap = load_velocity_map(os.fspath(velocity_map), speed, y_up, *at,
                                     size=(toroidal, toroidal) if toroidal else None)
        else:
            vmap = VelocityMap(np.rint(np.asarray(velocity_map, np.float64) * Q).astype(np.int32), *at)
        flow = replace(flow, map=vmap)
    flow = replace(flow, period=period or flow.suggested_period(frames if loop else 0), loop=frames if loop else 0)
    flow.validate()
    from .engine.advect import MAX_STATIC_SIDE, static_side
    w, h = (toroidal, toroidal) if toroidal else size
    if static_side(flow, w, h) > MAX_STATIC_SIDE:
        raise ValueError(f"Content travels up to {flow.reach(2 * flow.period)} px in a chain's life: with {w}x{h} "
                         f"frames one synthesis would pass {MAX_STATIC_SIDE} px a side; use a shorter period or "
                         "smaller frames.")
    an = analyze(ex)
    rect = Rect(0, 0, w, h) if toroidal else Rect.of(origin[0], origin[1], w, h)
    with Synthesizer(an, _params(an.L, seed, randomness, structure), controls=controls) as s:
        source = SynthSource(s, toroidal)
        ff = FlowFrames(source, flow, seed)
        try:
            return np.stack([to_u8(s.colors(ff.frame(start + i, rect))) for i in range(frames)])
        finally:
            ff.release()
            source.release()


def write_animation(path: str, frames: np.ndarray, fps: float = 24.0, loop: bool = False) -> list[str]:
    """Write frames (N, H, W, C) uint8 as ``path``: a folder (frame_0000.png...), a
    flipbook atlas .png with its .json, .webp, .apng or .mp4; returns the files."""
    from .export.animation import AnimationWriter, animation_format
    w = AnimationWriter(os.fspath(path), animation_format(os.fspath(path)), fps, loop)
    for f in frames:
        w.add(f)
    return w.close()
