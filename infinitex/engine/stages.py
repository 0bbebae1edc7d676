"""The renders of one padded region (pyramid.py ``_strip_steps``): the
correction's and the fidelity stage's subpasses, on quadrant-packed scratch
buffers, as self-contained draws that can run at once or a piece at a time.

Each subpass renders only the block of the phase it rewrites (reading the whole
state), and that block is copied back, so a pass computes each pixel once.
"""
from __future__ import annotations

from collections.abc import Callable, Iterator
from dataclasses import dataclass
from typing import Any

import moderngl

from . import fixed
from .gpu import Gpu, GpuAnalysis, set_uniforms
from .params import FIDELITY_SEARCH, SynthParams, subpass_order
from .similarity import border_margin


@dataclass
class Draw:
    """One render of a program over a viewport, self-contained (its textures by
    unit, its uniforms, its target), so that it can run in row pieces between
    which other work uses the context: every pixel is computed the same way."""

    prog: Any
    vao: Any
    fbo: Any
    viewport: tuple[int, int, int, int]
    textures: dict[int, Any]
    uniforms: dict[str, Any]

    def steps(self, piece_px: int | None = None) -> Iterator[None]:
        """Render, in pieces of about ``piece_px`` pixels (None: at once), yielding after each."""
        x, y, w, h = self.viewport
        rows = h if piece_px is None else max(1, piece_px // max(1, w))
        for y0 in range(y, y + h, rows):
            for unit, tex in self.textures.items():
                tex.use(unit)
            set_uniforms(self.prog, **self.uniforms)
            self.fbo.use()
            self.fbo.viewport = (x, y0, w, min(rows, y + h - y0))
            self.vao.render(moderngl.TRIANGLES)
            yield


def subpass_draws(gpu: Gpu, prog, vao, subgrid: int, orders, qdims: tuple[int, int], scratch,
                  textures: dict, uniforms: dict, per_subpass: Callable[[int], dict]) -> list[Draw]:
    """The subpasses of ``orders`` (lists of phases) with ``prog`` over the
    packed state in scratch ``a`` of ``scratch`` = (a, its framebuffer, b, b's):
    each renders its phase's block into b, which is then copied back into a.
    ``textures``/``uniforms``: the program's inputs besides the state (unit 0);
    ``per_subpass(n)``: the uniforms of subpass number n (counted over all passes)."""
    a, fa, b, fb = scratch
    copy, copy_vao = gpu.program("copy.frag", SUB_S=subgrid)
    draws = []
    for order in orders:
        for phase in order:
            block = (phase[0] * qdims[0], phase[1] * qdims[1], qdims[0], qdims[1])
            n = len(draws) // 2
            draws.append(Draw(prog, vao, fb, block, {**textures, 0: a},
                              {**uniforms, "src": 0, "active_phase": phase, **per_subpass(n)}))
            draws.append(Draw(copy, copy_vao, fa, block, {0: b}, {"src": 0}))
    return draws


def fidelity_draws(gpu: Gpu, gan: GpuAnalysis, p: SynthParams, l: int, region, qdims: tuple[int, int],
                   lattice: bool, scratch, avoid_tex, has_avoid: bool) -> list[Draw]:
    """The fidelity stage's iterations on level ``l``'s padded ``region`` (see
    shaders/fidelity.frag); ``lattice``: a lattice level (no random search)."""
    an = gan.analysis
    prog, vao = gpu.program("fidelity.frag", SUB_S=p.subgrid, FID_RADIUS=p.fidelity_radius,
                            FID_SEARCH=FIDELITY_SEARCH)
    uniforms = dict(colors=1, avoid=5, has_avoid=int(has_avoid), dims=(region.w, region.h), qdims=qdims,
                    h=an.h(l), m=an.size, border=-1 if an.toroidal else border_margin(an.size, an.h(l)),
                    origin=(region.x0, region.y0), level=l, period=p.level_period(l), no_search=int(lattice))
    return subpass_draws(gpu, prog, vao, p.subgrid, subpass_order(p.subgrid, p.fidelity_at(l)), qdims, scratch,
                         {1: gan.level(l).colors, 5: avoid_tex}, uniforms,
                         lambda n: {"search_seed": fixed.fidelity_seed(p.seed, n)})
