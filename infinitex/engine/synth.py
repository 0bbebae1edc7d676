"""The engine's front door: windows, viewports and toroidal tiles.

    ex = load_exemplar("gravel.png")
    an = analyze(ex)
    synth = Synthesizer(an)                      # SynthParams.default(...)
    coords = synth.window(Rect.of(x, y, 256, 256))  # (256, 256, 2) exemplar (x, y)
    image = synth.colors(coords)                 # E_L[S]

Everything returned is a deterministic function of (analysis, params, rect):
any two windows agree where they overlap.
"""
from __future__ import annotations

from dataclasses import replace

import numpy as np

from .analysis import Analysis
from .controls import NO_CONTROLS, Controls
from .gpu import Gpu, GpuAnalysis
from .params import SynthParams
from .pyramid import Pyramid, Rect, SynthesisError
from .subpixel import sample

# Largest image assembled in memory (synth command, exports): 64 Mpixels of
# int32 coordinates is 512 MB. Streamed exports will lift this.
MAX_WINDOW_SIDE = 16384
MAX_WINDOW_PIXELS = 64 * 1024 * 1024


class Synthesizer:
    """Synthesizes windows of one analyzed exemplar on one GL context."""

    def __init__(self, analysis: Analysis, params: SynthParams | None = None, gpu: Gpu | None = None,
                 controls: Controls = NO_CONTROLS):
        controls.validate(analysis.size, analysis.settings.lattice)
        self.controls = controls
        self.analysis = analysis
        self.owns_gpu = gpu is None
        self.gpu = gpu or Gpu()
        self.gpu.activate()
        self.gan = GpuAnalysis(self.gpu, analysis)
        self.params = params or SynthParams.default(analysis.L)
        self.params.validate(analysis.L)
        # What ``colors`` looks up: the analyzed exemplar's Gaussian stack, or
        # another map aligned with it (a material's, ``engine.material``).
        self.palette: list[np.ndarray] | None = None
        self.normals = False  # the palette is a normal map: exports turn it with a direction field

    @property
    def L(self) -> int:
        return self.analysis.L

    def __enter__(self) -> "Synthesizer":
        return self

    def __exit__(self, *exc) -> None:
        self.release()

    def set_params(self, params: SynthParams, controls: Controls | None = None) -> None:
        params.validate(self.L)
        if controls is not None:
            controls.validate(self.analysis.size, self.analysis.settings.lattice)
            self.controls = controls
        self.params = params

    def window(self, rect: Rect, level: int | None = None, remainder: bool | None = None) -> np.ndarray:
        """Exact coordinates of ``rect`` at ``level`` (default: finest), (H, W, 2) int32;
        with ``remainder`` (by default: when a direction field is painted) (H, W, 4),
        the sub-pixel remainders (1/256 px) after them (engine/subpixel.py)."""
        level = self.L if level is None else level
        remainder = self.controls.directed if remainder is None else remainder
        pyr = Pyramid(self.gpu, self.gan, self.params, scrolling=False, controls=self.controls)
        try:
            pyr.request(level, rect)
            return pyr.read(level, rect, remainder)
        finally:
            pyr.release()

    def toroidal(self, n: int) -> np.ndarray:
        """Coordinates of an n x n texture that tiles seamlessly (LH05 section 6)."""
        if n & (n - 1) or not 32 <= n <= 4096:
            raise SynthesisError("A toroidal texture size must be a power of two from 32 to 4096.")
        saved = self.params
        self.params = replace(saved, period=n)
        try:
            return self.window(Rect(0, 0, n, n))
        finally:
            self.params = saved

    def viewport(self, prefetch: int = 16) -> "Viewport":
        return Viewport(self, prefetch=prefetch)

    def colors(self, coords: np.ndarray, level: int | None = None) -> np.ndarray:
        """E_l[S]: float32 (H, W, C) colors of coordinates at ``level`` (bilinear
        between texels where they carry sub-pixel remainders)."""
        level = self.L if level is None else level
        stack = self.palette[level] if self.palette is not None else self.analysis.levels[level].stack
        return sample(stack, coords, self.analysis.toroidal)

    def release(self) -> None:
        self.gpu.activate()
        self.gan.release()
        if self.owns_gpu:
            self.gpu.release()


class Viewport:
    """A view that pans and zooms over the infinite canvas, updated incrementally.

    ``show(rect, zoom_out=k)`` makes the view exact; ``rect`` is in the level
    ``L - k`` pixels (a view zoomed out by 2^k stops k levels early: the
    intermediate levels are the mipmap, LH05 section 6). Only strips that were
    not held before are synthesized.
    """

    def __init__(self, synth: Synthesizer, prefetch: int = 16):
        self.synth = synth
        self.pyramid = Pyramid(synth.gpu, synth.gan, synth.params, scrolling=True, prefetch=prefetch,
                               controls=synth.controls)

    def set_params(self, params: SynthParams, controls: Controls | None = None) -> None:
        self.synth.set_params(params, controls)
        self.pyramid.set_params(params, controls)

    def show(self, rect: Rect, zoom_out: int = 0) -> int:
        """Make ``rect`` exact at level L - zoom_out; returns pixels synthesized."""
        level = max(0, self.synth.L - zoom_out)
        return self.pyramid.request(level, rect)

    def read(self, rect: Rect, zoom_out: int = 0) -> np.ndarray:
        return self.pyramid.read(max(0, self.synth.L - zoom_out), rect)

    def release(self) -> None:
        self.pyramid.release()
