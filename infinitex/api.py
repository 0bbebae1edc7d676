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
from .engine.controls.lattice_detect import detect
from .engine.exemplar import Exemplar, load_exemplar, load_full
from .engine.imagefile import to_u8
from .engine.params import DEFAULT_STRUCTURE, SynthParams, structure_index, structure_params
from .engine.pyramid import Rect
from .engine.synth import Synthesizer


def _exemplar(source, lattice: Lattice | str | None) -> tuple[Exemplar, Lattice | None]:
    """An exemplar from a path, an array or an Exemplar; with a lattice, its rectified block."""
    if lattice is None:
        if isinstance(source, Exemplar):
            return source, None
        if isinstance(source, (str, os.PathLike)):
            return load_exemplar(source), None
        from .engine.exemplar import from_array
        return from_array(np.asarray(source, dtype=np.float32)), None
    image = load_full(source) if isinstance(source, (str, os.PathLike)) else np.asarray(source, np.float32)
    if image.ndim == 2:
        image = image[:, :, None]
    if isinstance(lattice, str):
        if lattice != "auto":
            raise ValueError("lattice must be a Lattice, 'auto' or None.")
        lattice = detect(image).lattice
        if lattice is None:
            return _exemplar(source, None)
    return rectified_exemplar(image, lattice), lattice


def synthesize(exemplar, size: tuple[int, int] = (256, 256), origin: tuple[int, int] = (0, 0), *,
               seed: int = 0, randomness: float | tuple[float, ...] | None = None,
               controls: Controls = NO_CONTROLS, lattice: Lattice | str | None = None,
               geometry: str = "original", structure: int | str = DEFAULT_STRUCTURE) -> np.ndarray:
    """A ``size`` = (W, H) window of the exemplar's infinite texture at canvas
    position ``origin``, as uint8 (H, W, C).

    ``exemplar``: an image path, a float array (H, W[, C]) in [0, 1], or an
    :class:`~infinitex.engine.exemplar.Exemplar`. ``randomness``: one r for
    every level or one per level, coarse to fine (default 0.6). ``controls``:
    painted randomness and placed features (:class:`Controls`). ``lattice``:
    a :class:`Lattice`, ``"auto"`` (detected; no lattice mode when none is
    found) or None; with a lattice, ``geometry`` is ``"original"`` (the
    input's geometry, origin and size in input pixels) or ``"rectified"``.
    ``structure``: the Structure / Variety preset, 0 to 4 or its name
    ("variety" ... "maximum"; default "balanced", as in the editor and the
    command line). Windows of the same arguments agree bit for bit wherever
    they overlap."""
    ex, lat = _exemplar(exemplar, lattice)
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
         controls: Controls = NO_CONTROLS, lattice: Lattice | str | None = None,
         structure: int | str = DEFAULT_STRUCTURE) -> np.ndarray:
    """An n x n seamless (toroidal) tile, uint8 (n, n, C); n a power of two
    from 32 to 4096. With a lattice the tile is rectified, whole cells.
    ``structure`` as for :func:`synthesize`."""
    ex, lat = _exemplar(exemplar, lattice)
    an = analyze(ex, AnalysisSettings(lattice=(lat.nx, lat.ny) if lat else (0, 0)))
    if lat is not None:
        from dataclasses import replace
        controls = replace(controls, lattice=lat)
    with Synthesizer(an, _params(an.L, seed, randomness, structure), controls=controls) as s:
        return to_u8(s.colors(s.toroidal(n)))


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
