"""Running the subpasses of one padded region (pyramid.py ``_synthesize_strip``):
the correction's and the fidelity stage's, on quadrant-packed scratch buffers.

Each subpass renders only the block of the phase it rewrites (reading the whole
state), and that block is copied back, so a pass computes each pixel once.
"""
from __future__ import annotations

from collections.abc import Callable

import moderngl

from . import fixed
from .gpu import Gpu, GpuAnalysis, set_uniforms
from .params import FIDELITY_SEARCH, SynthParams, subpass_order
from .similarity import border_margin


def run_subpasses(gpu: Gpu, prog, vao, subgrid: int, orders, qdims: tuple[int, int], scratch,
                  per_subpass: Callable[[int], dict]) -> None:
    """Run the subpasses of ``orders`` (lists of phases) with ``prog`` over the
    packed state in scratch ``a`` of ``scratch`` = (a, its framebuffer, b, b's):
    each renders its phase's block into b, which is then copied back into a.
    ``per_subpass(n)``: the uniforms of subpass number n (counted over all passes)."""
    a, fa, b, fb = scratch
    copy, copy_vao = gpu.program("copy.frag", SUB_S=subgrid)
    n_sub = 0
    for order in orders:
        for phase in order:
            block = (phase[0] * qdims[0], phase[1] * qdims[1], qdims[0], qdims[1])
            a.use(0)
            set_uniforms(prog, active_phase=phase, **per_subpass(n_sub))
            n_sub += 1
            fb.use()
            fb.viewport = block
            vao.render(moderngl.TRIANGLES)
            b.use(0)
            set_uniforms(copy, src=0)
            fa.use()
            fa.viewport = block
            copy_vao.render(moderngl.TRIANGLES)


def run_fidelity(gpu: Gpu, gan: GpuAnalysis, p: SynthParams, l: int, region, qdims: tuple[int, int],
                 lattice: bool, scratch, avoid_tex, has_avoid: bool) -> None:
    """The fidelity stage's iterations on level ``l``'s padded ``region`` (see
    shaders/fidelity.frag); ``lattice``: a lattice level (no random search)."""
    an = gan.analysis
    prog, vao = gpu.program("fidelity.frag", SUB_S=p.subgrid, FID_RADIUS=p.fidelity_radius,
                            FID_SEARCH=FIDELITY_SEARCH)
    gan.level(l).colors.use(1)
    avoid_tex.use(5)
    set_uniforms(prog, src=0, colors=1, avoid=5, has_avoid=int(has_avoid),
                 dims=(region.w, region.h), qdims=qdims, h=an.h(l), m=an.size,
                 border=-1 if an.toroidal else border_margin(an.size, an.h(l)),
                 origin=(region.x0, region.y0), level=l, period=p.level_period(l), no_search=int(lattice))
    run_subpasses(gpu, prog, vao, p.subgrid, subpass_order(p.subgrid, p.fidelity_at(l)), qdims, scratch,
                  lambda n: {"search_seed": fixed.fidelity_seed(p.seed, n)})
