"""Infinitex: infinite, controllable, example-based textures.

The engine synthesizes *exemplar coordinates* for any window of an infinite
canvas, on the GPU (OpenGL 3.3 core, headless through EGL), bit for bit the
same whatever the window, its order or the machine. One call::

    import infinitex as itx

    img = itx.synthesize("gravel.png", size=(512, 512), origin=(10_000, -3_000), seed=7)
    itx.write_png("gravel-512.png", img)           # uint8 (H, W, C)
    tile = itx.tile("gravel.png", 256)              # a seamless 256 x 256 tile
    bricks = itx.synthesize("bricks.png", size=(512, 512))  # its lattice found: rows kept

``synthesize(exemplar, size=(W, H), origin=(X, Y), *, seed=0, randomness=None,
controls=NO_CONTROLS, lattice="auto", geometry="original", structure="balanced",
labels=None, label_strength=1.0)``
    ``exemplar`` is an image path, a float array in [0, 1] or an ``Exemplar``.
    ``randomness``: r for every level, or one per level coarse to fine
    (default 0.6). ``controls``: painted randomness and placed features
    (``Controls``). ``lattice``: ``"auto"`` (an image showing a lattice,
    found with confidence, is synthesized on it), a ``Lattice``, or None.
    ``structure``: the Structure / Variety preset, 0-4 or "variety" ... "maximum".
    ``labels``: texture by numbers, (exemplar label map, canvas label map[,
    origin]): paths or color images (each distinct color a label,
    transparent = free on the canvas) or arrays of label ids.
``tile(exemplar, n=256, *, seed=0, randomness=None, controls=NO_CONTROLS, lattice="auto", structure="balanced")``
    An n x n toroidal tile (n a power of two, 32 to 4096).
``tile_set(exemplar, colors=2, n=256, *, variants=0, ...)``
    A tile set for game engines: (atlas, description). A corner Wang set
    (2 colours: 16 tiles, 3: 81) whose tiles meet without a seam wherever
    their corner colours agree, or (colors=1, variants=K) K tiles with the
    borders of one toroidal tile. ``arrange(atlas, description, cols, rows,
    seed=0)`` lays them out at random, as an engine would;
    ``save_tile_set(atlas, description, "set.png")`` writes it as the command
    line does, with Tiled's .tsx/.tmx and Godot's .tres.

Step by step (an analysis and a GL context made once, many windows)::

    ex = itx.load_exemplar("gravel.png")            # fit "resize" (or "crop", "resize-2048", "crop-2048")
    an = itx.analyze(ex)                            # CPU, cached on disk (INFINITEX_CACHE)
    params = itx.SynthParams.default(an.L, seed=7)  # jitter per level, passes, kappa, period...
    params = itx.structure_params(params, 2)        # the Balanced preset (synthesize's default)
    with itx.Synthesizer(an, params) as s:
        coords = s.window(itx.Rect.of(0, 0, 256, 256))   # int32 (H, W, 2): exemplar (x, y)
        colors = s.colors(coords)                        # float32 (H, W, C) in [0, 1]
        seamless = s.toroidal(256)                       # coordinates of a toroidal tile

Huge exports, tile by tile in bounded memory and resumable (``TiledExport``)::

    with itx.Synthesizer(an) as s:
        itx.TiledExport(s, itx.Rect.of(0, 0, 65536, 65536), "terrain.tif", "tiff", tile=1024).run()
        itx.TiledExport(s, itx.Rect.of(0, 0, 8192, 8192), "set.png", "tiles", tile=2048).run()  # set.1001.png...
        itx.TiledExport(s, itx.Rect.of(0, 0, 8192, 8192), "set.zarr", "zarr").run()  # multiscale (OME-NGFF)

    ``run(workers=N, worker_init=...)`` renders in N processes and
    ``run(scheduler="local" | "tcp://HOST:8786", worker_init=...)`` on a Dask
    cluster; ``worker_init`` makes a worker's Synthesizer from the project
    (``infinitex.export.jobs.project_synthesizer(document)``).

Materials: aligned maps (base color, normal, height, roughness...) that one
synthesis drives, each looked up through the same coordinates::

    mat = itx.open_material("wood_basecolor.png")   # its siblings wood_normal.png... come along
    with itx.Synthesizer(itx.analyze(mat.guide())) as s:   # guide: base color + height
        coords = s.window(itx.Rect.of(0, 0, 512, 512))
        height = mat.lookup("height", coords)              # float32 (H, W, 1), 16-bit precision kept
        itx.write_image("wood_height.png", height, depth=16)  # 8, 16 (PNG) or 32 (float TIFF)

Controls (one engine input, ``Controls``): ``CanvasField`` and
``ExemplarField`` (painted randomness, uint16, 32768 = neutral; ``painted()``
adds a dab), ``Feature`` (an exemplar spot placed on the canvas), ``Lattice``
(``detect_lattice(image)``, ``rectified_exemplar(image, lattice)``; analyze
with ``AnalysisSettings(lattice=(nx, ny))``), ``ExemplarLabels`` and
``CanvasLabels`` (texture by numbers; ``label_controls(exemplar, maps...)``
builds them from label images; ``palette(exemplars)`` packs several
exemplars into one, one label each), ``DirectionField`` (the texture turns,
grows and stretches over the canvas; ``direction_field(map)`` reads a flow or
angle map, ``DirectionField.uniform`` / ``from_jacobians`` / ``painted`` build
one, ``jacobian(degrees, scale, aspect)`` gives its values). Models:
``texture_model(model, exemplar, size)`` synthesizes in a model's atlas,
seamless across its UV seams (``load_model``, ``Model``, ``AtlasDomain``).
Texture in motion: ``animate(exemplar, frames, velocity=(vx, vy), size=..., toroidal=n, loop=True,
velocity_map=...)`` gives the frames of the texture flowing along a velocity field (LH06 7), uint8
(N, H, W, C); ``write_animation(path, frames, fps)`` writes a folder, a flipbook atlas, WebP, APNG or MP4.
Projects: ``load_project``,
``save_project``; the editor's exports: ``infinitex export``. Runnable
examples of each capability are in ``examples/`` of the source tree.

Command line: ``infinitex`` (the editor), ``infinitex synth``, ``infinitex
export``, ``infinitex surface``, ``infinitex animate``, ``infinitex --version``.
"""
from __future__ import annotations

import os as _os

__version__ = "0.5.0"
ASSETS = _os.path.join(_os.path.dirname(_os.path.abspath(__file__)), "assets")  # bundled CC0 exemplars

# Names resolved on first use (PEP 562), so ``import infinitex`` and
# ``infinitex --version`` stay fast and need no GL.
_EXPORTS = {
    "synthesize": "api", "tile": "api", "tile_set": "api", "arrange": "api", "save_tile_set": "api", "label_controls": "api", "palette": "api",
    "PaletteLayout": "engine.palette",
    "Exemplar": "engine.exemplar", "ExemplarError": "engine.exemplar", "load_exemplar": "engine.exemplar",
    "from_array": "engine.exemplar", "load_full": "engine.exemplar", "write_png": "engine.imagefile",
    "to_u8": "engine.imagefile",
    "Analysis": "engine.analysis", "AnalysisSettings": "engine.analysis", "analyze": "engine.analysis",
    "SynthParams": "engine.params", "structure_params": "engine.params",
    "Synthesizer": "engine.synth", "Viewport": "engine.synth",
    "Rect": "engine.pyramid",
    "Controls": "engine.controls", "NO_CONTROLS": "engine.controls", "CanvasField": "engine.controls",
    "ExemplarField": "engine.controls", "Feature": "engine.controls", "NEUTRAL": "engine.controls",
    "ExemplarLabels": "engine.controls", "CanvasLabels": "engine.controls",
    "DirectionField": "engine.controls.direction", "jacobian": "engine.controls.direction",
    "direction_field": "api", "texture_model": "api", "animate": "api", "write_animation": "api",
    "Flow": "engine.controls.flow", "VelocityMap": "engine.controls.flow",
    "Model": "engine.surface", "load_model": "engine.surface", "AtlasDomain": "engine.surface",
    "Lattice": "engine.controls.lattice", "rectified_exemplar": "engine.controls.lattice", "render_original": "engine.controls.lattice",
    "original_geometry_box": "engine.controls.lattice",
    "TiledExport": "export.streamed",
    "Material": "engine.material", "open_material": "engine.material", "write_image": "engine.imagefile",
    "load_project": "project", "save_project": "project", "Document": "project",
    "Project": "project",
}
_RENAMED = {"detect_lattice": ("engine.controls.lattice_detect", "detect")}

__all__ = sorted([*_EXPORTS, *_RENAMED, "__version__", "ASSETS"])


def __getattr__(name: str):
    import importlib
    if name in _EXPORTS:
        return getattr(importlib.import_module(f".{_EXPORTS[name]}", __name__), name)
    if name in _RENAMED:
        mod, attr = _RENAMED[name]
        return getattr(importlib.import_module(f".{mod}", __name__), attr)
    raise AttributeError(f"module 'infinitex' has no attribute {name!r}")


def __dir__():
    return __all__
