"""Exemplar analysis (docs/algorithm.md section 2): CPU, numpy + scipy, cached on disk.

For every level ``l = 0..L`` of the Gaussian stack this computes what the
correction shaders read, all as small integers so that the GPU passes and the
numpy oracle in ``tests/`` agree bit for bit on any driver:

- ``stack[l]``: the filtered exemplar ``E_l`` (float, for display and export).
- ``feat[l]``: the per-texel feature the runtime neighborhood is built from.
  Appearance model (LH06): the appearance vector ``A_l[u]``, a Gaussian-weighted
  5x5 neighborhood of ``E_l`` at spacing ``h_l`` (plus, optionally, LH06's
  feature-distance channel), PCA-reduced to 8 dims and quantized to int8
  [-127, 127]. Color model (LH05): the colors of ``E_l`` in
  [0, 127].
- ``proj[l]``: the integer PCA matrix (taps*channels x 8) of the runtime
  neighborhood and ``shift[l]`` its fixed-point scale (see ``fixed.py``).
- ``nbhd[l]``: ``N_E(u)``, the projected exemplar neighborhood at each texel,
  computed with exactly the integer formula the shader uses for ``N_S``, so a
  perfectly coherent patch has error 0.
- ``simset[l]``: similarity sets ``C_l^i(u)``, ``i = 1..k`` as (x, y); None
  with k = 0 (and always above SIMSET_MAX = 512 px), where the correction
  searches by TBN10's random walk instead.
- ``lattice_simset[l]`` (rectified near-regular exemplars only, LH05 4.5):
  similarity sets restricted to the lattice-equivalent positions
  ``u + (i m/nx, j m/ny)``, used on the lattice levels.

Everything is built a band of rows at a time (taps copied by slices, one BLAS
product per band), so a 2048^2 exemplar is analyzed in seconds and under 2 GB.
Nearest neighbors come from ``scipy.spatial.cKDTree``, the well-kept library for
the job (the README says why scipy is a dependency).
"""
from __future__ import annotations

import io
import json
import os
import time
import zipfile
from concurrent.futures import ThreadPoolExecutor
from dataclasses import asdict, dataclass, field, replace
from typing import Callable

import numpy as np
from threadpoolctl import threadpool_limits

from . import fixed
from .controls.lattice import lattice_level_limit
from .exemplar import Exemplar
from .neighborhoods import (
    appearance_features,
    color_features,
    exemplar_neighborhoods,
    feature_distance,
    gather_exemplar_neighborhood,
    gaussian_stack,
    runtime_projection,
    sample_step,
)
from .safeio import atomic_write
from .similarity import lattice_similarity_sets, similarity_sets

ANALYSIS_VERSION = 7
MODELS = ("appearance", "color")
NDIM = fixed.NDIM

ProgressFn = Callable[[float, str], None]
# Exemplars up to this side get k-coherence similarity sets; larger ones are
# searched by TBN10's random walk (k = 0), which needs no precomputation.
SIMSET_MAX = 512


class AnalysisCancelled(Exception):
    """Raised (by a progress callback) to stop a running analysis."""


@dataclass(frozen=True)
class AnalysisSettings:
    """What the analysis depends on besides the exemplar pixels."""

    model: str = "appearance"      # "appearance" (LH06, default) or "color" (LH05)
    k: int = 2                     # similarity-set size, 1..4; 0: none (TBN10 random-walk search)
    spacing: float = 0.05          # min distance between set entries, fraction of m
    appearance_sigma: float = 1.5  # Gaussian weight of the 5x5 appearance taps, in taps
    lattice: tuple[int, int] = (0, 0)  # (nx, ny) cells of a rectified near-regular exemplar; (0, 0): none
    feature_weight: float = 0.0    # LH06 feature-distance channel's weight (appearance model); 0: none

    def validate(self) -> None:
        if self.model not in MODELS:
            raise ValueError(f"Unknown neighborhood model {self.model!r}; use 'appearance' or 'color'.")
        if not 0 <= int(self.k) <= 4:
            raise ValueError(f"k must be between 0 (random-walk search) and 4, not {self.k}.")
        if not 0.0 <= self.feature_weight <= 4.0:
            raise ValueError(f"The feature-distance weight must be in [0, 4], not {self.feature_weight}.")
        if not 0.0 <= self.spacing < 0.5:
            raise ValueError("spacing must be a fraction of the exemplar size in [0, 0.5).")
        nx, ny = self.lattice
        if (nx, ny) != (0, 0) and int(self.k) == 0:
            raise ValueError("A lattice needs similarity sets: use k of 1 or more.")
        if (nx, ny) != (0, 0) and not all(n >= 1 and n & (n - 1) == 0 and n <= 16 for n in (nx, ny)):
            raise ValueError(f"Lattice cell counts must be powers of two up to 16, not {nx}x{ny}.")


@dataclass
class LevelData:
    stack: np.ndarray      # float32 (m, m, C): E_l
    feat: np.ndarray       # int8 (m, m, F): A_l (F=8) or colors (F=C)
    proj: np.ndarray       # int32 (T*F, 8): runtime neighborhood PCA, fixed point
    shift: int             # right shift applied to the projection
    nbhd: np.ndarray       # int16 (m, m, 8): N_E(u)
    simset: np.ndarray | None  # int16 (m, m, k, 2): C^i(u) as (x, y); None when k = 0
    lattice_simset: np.ndarray | None = None  # int16 (m, m, k, 2): restricted to u + cells, or None


@dataclass
class Analysis:
    """Everything synthesis needs about one exemplar under one setting."""

    size: int
    channels: int
    toroidal: bool
    settings: AnalysisSettings
    levels: list[LevelData] = field(repr=False)
    key: str = ""
    seconds: float = 0.0

    @property
    def L(self) -> int:
        return self.size.bit_length() - 1

    def h(self, level: int) -> int:
        """Exemplar-coordinate spacing h_l = 2^(L-l) of level ``level``."""
        return 1 << (self.L - level)

    @property
    def model(self) -> str:
        return self.settings.model

    @property
    def k(self) -> int:
        """Similarity-set size in use; 0: none, the correction searches by random walk."""
        return search_k(self.settings, self.size)


def search_k(settings: AnalysisSettings, m: int) -> int:
    """The similarity-set size an m x m exemplar gets: ``settings.k``, or 0 (random-walk
    search, no sets) above SIMSET_MAX, where building the sets would take minutes."""
    return int(settings.k) if m <= SIMSET_MAX else 0


# ----------------------------------------------------------------------------
# Driver and cache


def analysis_key(ex: Exemplar, settings: AnalysisSettings) -> str:
    import hashlib
    h = hashlib.sha256()
    h.update(ex.content_hash().encode())
    h.update(json.dumps(asdict(settings), sort_keys=True).encode())
    h.update(f"v{ANALYSIS_VERSION}".encode())
    return h.hexdigest()[:32]


def default_cache_dir() -> str:
    env = os.environ.get("INFINITEX_CACHE")
    if env:
        return env
    base = os.environ.get("XDG_CACHE_HOME") or os.path.join(os.path.expanduser("~"), ".cache")
    return os.path.join(base, "infinitex", "analysis")


def _level_features(stack: np.ndarray, fstack: np.ndarray | None, h: int, m: int,
                    settings: AnalysisSettings, toroidal: bool):
    """One level's features, runtime projection and exemplar neighborhoods."""
    if settings.model == "appearance":
        guide = stack if fstack is None else np.concatenate([stack, fstack], axis=2)
        feat = appearance_features(guide, h, settings.appearance_sigma, toroidal)
    else:
        feat = color_features(stack)
    sampled = gather_exemplar_neighborhood(feat, h, settings.model, sample_step(m))
    proj, shift = runtime_projection(sampled, int(np.abs(feat).max()), settings.model)
    del sampled
    return stack, feat, proj, shift, exemplar_neighborhoods(feat, h, settings.model, proj, shift)


def _compute(ex: Exemplar, settings: AnalysisSettings, progress: ProgressFn | None,
             reuse: list[LevelData] | None = None) -> list[LevelData]:
    """Every level's data; ``reuse``: the levels of an analysis of the same
    exemplar with the same settings but the search (k), whose stack, features
    and neighborhoods are taken as they are (only the similarity sets differ).
    Levels are independent: their features are computed two at a time (numpy
    releases the GIL for the copies and products), each with the same
    operations as one at a time, so the result does not depend on it."""
    m, L = ex.size, ex.levels
    k = search_k(settings, m)
    report = progress or (lambda f, msg: None)
    report(0.0, "Gaussian stack")
    pool = blas = None
    if reuse is None:
        stack = gaussian_stack(ex.pixels, ex.toroidal)
        fstack = None
        if settings.model == "appearance" and settings.feature_weight > 0:
            fstack = gaussian_stack(settings.feature_weight * feature_distance(ex.pixels, ex.toroidal), ex.toroidal)
        # OpenBLAS's own threads on these small products cost more than they
        # give (1.7x slower at 512 px with two levels at once): one each.
        blas = threadpool_limits(limits=1, user_api="blas")
        pool = ThreadPoolExecutor(max_workers=2, thread_name_prefix="analysis")
        pending = [pool.submit(_level_features, stack[level], None if fstack is None else fstack[level],
                               1 << (L - level), m, settings, ex.toroidal) for level in range(L + 1)]
        del stack, fstack
    levels: list[LevelData] = []
    try:
        # Work per level is roughly equal; the stack took ~5%.
        for level in range(L + 1):
            h = 1 << (L - level)
            base = 0.05 + 0.95 * level / (L + 1)
            step = 0.95 / (L + 1)
            report(base, f"level {level}/{L}: neighborhoods")
            if reuse is not None:
                lv = reuse[level]
                level_stack, feat, proj, shift, nbhd = lv.stack, lv.feat, lv.proj, lv.shift, lv.nbhd
            else:
                level_stack, feat, proj, shift, nbhd = pending[level].result()
                pending[level] = None
            report(base + 0.3 * step, f"level {level}/{L}: similarity sets")
            if k == 0:
                sims = None
            elif level == 0:
                ys, xs = np.mgrid[0:m, 0:m]
                ident = np.stack([xs, ys], axis=-1)[:, :, None, :]
                sims = np.repeat(ident, k, axis=2).astype(np.int16)
            else:
                sims = similarity_sets(nbhd, m, h, k, ex.toroidal, settings.spacing)
            lsims = None
            if settings.lattice != (0, 0) and 0 < level <= lattice_level_limit(m, *settings.lattice):
                report(base + 0.7 * step, f"level {level}/{L}: lattice similarity sets")
                lsims = lattice_similarity_sets(nbhd, k, *settings.lattice)
            levels.append(LevelData(stack=level_stack, feat=feat, proj=proj, shift=int(shift),
                                    nbhd=nbhd, simset=sims, lattice_simset=lsims))
    finally:
        if pool is not None:
            pool.shutdown(wait=True, cancel_futures=True)  # a cancelled analysis stops at the level in progress
            blas.restore_original_limits()
    report(1.0, "done")
    return levels


def save_analysis(path: str, an: Analysis) -> None:
    arrays = {}
    for i, lv in enumerate(an.levels):
        for name in ("stack", "feat", "proj", "nbhd"):
            arrays[f"{name}{i}"] = getattr(lv, name)
        if lv.simset is not None:
            arrays[f"simset{i}"] = lv.simset
        arrays[f"shift{i}"] = np.array(lv.shift)
        if lv.lattice_simset is not None:
            arrays[f"lattice_simset{i}"] = lv.lattice_simset
    meta = dict(size=an.size, channels=an.channels, toroidal=an.toroidal,
                settings=asdict(an.settings), version=ANALYSIS_VERSION, key=an.key)
    arrays["meta"] = np.frombuffer(json.dumps(meta).encode(), dtype=np.uint8)
    os.makedirs(os.path.dirname(path), exist_ok=True)
    atomic_write(path, writer=lambda f: np.savez(f, **arrays))


def load_analysis(path: str, key: str, settings: AnalysisSettings, ex: Exemplar) -> Analysis | None:
    """The cached analysis, or None if missing, foreign or damaged."""
    if not os.path.exists(path):
        return None
    try:
        with np.load(path, allow_pickle=False) as z:
            meta = json.loads(bytes(z["meta"]).decode())
            if meta.get("key") != key or meta.get("version") != ANALYSIS_VERSION:
                return None
            m, L = ex.size, ex.levels
            levels = []
            for i in range(L + 1):
                lsims = z[f"lattice_simset{i}"] if f"lattice_simset{i}" in z.files else None
                k = search_k(settings, m)
                lv = LevelData(stack=z[f"stack{i}"], feat=z[f"feat{i}"], proj=z[f"proj{i}"],
                               shift=int(z[f"shift{i}"]), nbhd=z[f"nbhd{i}"],
                               simset=z[f"simset{i}"] if k else None, lattice_simset=lsims)
                if (lsims is None) == (settings.lattice != (0, 0) and 0 < i <= lattice_level_limit(m, *settings.lattice)):
                    return None
                if lv.stack.shape != (m, m, ex.channels) or lv.nbhd.shape != (m, m, NDIM) \
                        or (k and lv.simset.shape != (m, m, k, 2)):
                    return None
                levels.append(lv)
    except (OSError, ValueError, KeyError, EOFError, zipfile.BadZipFile, json.JSONDecodeError,
            UnicodeDecodeError, io.UnsupportedOperation):
        return None
    return Analysis(size=ex.size, channels=ex.channels, toroidal=ex.toroidal, settings=settings,
                    levels=levels, key=key)


def _cache_path(key: str, cache_dir: str | None) -> str:
    return os.path.join(cache_dir or default_cache_dir(), f"{key}.npz")


def _cacheable(ex: Exemplar, settings: AnalysisSettings) -> bool:
    """Without similarity sets the analysis takes seconds, less than reading a
    cache entry that large (1.7 GB at 2048 px): only analyses with sets are cached."""
    return search_k(settings, ex.size) > 0


def is_cached(ex: Exemplar, settings: AnalysisSettings, cache_dir: str | None = None) -> bool:
    """Whether ``analyze`` would load this analysis from the disk cache."""
    return _cacheable(ex, settings) and os.path.exists(_cache_path(analysis_key(ex, settings), cache_dir))


def describe_analysis(ex: Exemplar, settings: AnalysisSettings, cache_dir: str | None = None,
                      use_cache: bool = True) -> str:
    """What analyzing this exemplar will do, in a few words (progress lines)."""
    if search_k(settings, ex.size) == 0:
        return "analysis (random-walk search, no similarity sets)"
    if use_cache and is_cached(ex, settings, cache_dir):
        return "analysis (from the cache)"
    return "analysis (first run: similarity sets, cached for next time)" if use_cache else "analysis"


def analyze(ex: Exemplar, settings: AnalysisSettings | None = None, *,
            cache_dir: str | None = None, use_cache: bool = True,
            progress: ProgressFn | None = None, reuse: Analysis | None = None) -> Analysis:
    """Analyze an exemplar, reusing the disk cache when it holds this exemplar
    and these settings. A damaged cache entry is recomputed and replaced.
    ``progress(fraction, message)`` is called as work proceeds; it may raise
    :class:`AnalysisCancelled` to stop. ``reuse``: an analysis of the same
    exemplar with the same settings except the search (the editor's quick
    preview, k = 0): its stack and neighborhoods are taken, only the
    similarity sets are computed."""
    settings = settings or AnalysisSettings()
    settings.validate()
    if reuse is not None and (replace(reuse.settings, k=settings.k) != settings
                              or reuse.key != analysis_key(ex, reuse.settings)):
        raise ValueError("analyze(reuse=...) takes an analysis of the same exemplar and settings but k")
    key = analysis_key(ex, settings)
    path = _cache_path(key, cache_dir)
    use_cache = use_cache and _cacheable(ex, settings)
    if use_cache:
        cached = load_analysis(path, key, settings, ex)
        if cached is not None:
            if progress:
                progress(1.0, "loaded from cache")
            return cached
    t0 = time.perf_counter()
    levels = _compute(ex, settings, progress, None if reuse is None else reuse.levels)
    an = Analysis(size=ex.size, channels=ex.channels, toroidal=ex.toroidal, settings=settings,
                  levels=levels, key=key, seconds=time.perf_counter() - t0)
    if use_cache:
        try:
            save_analysis(path, an)
        except OSError:
            pass  # a read-only or full disk only costs a recomputation next time
    return an
