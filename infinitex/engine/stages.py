"""The renders of one padded region (strips.py ``Strips.strip_steps``): the
correction's and the fidelity stage's subpasses, on quadrant-packed scratch
buffers, as self-contained draws that can run at once or a piece at a time.

Each subpass renders only the block of the phase it rewrites (reading the whole
state), and that block is copied back, so a pass computes each pixel once.
"""
from __future__ import annotations

import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass, field
from typing import Any

import moderngl

from . import fixed
from .gpu import Gpu, GpuAnalysis, set_uniforms
from .params import FIDELITY_SEARCH, SynthParams, subpass_order
from .similarity import border_margin


# llvmpipe renders 64 x 64 tiles, each on one thread: a draw inside one tile
# runs on one core however many there are.
TILE = 64


def block_layout(qdims: tuple[int, int], s: int) -> tuple[tuple[int, int], tuple[int, int], tuple[int, int]]:
    """Where the s x s blocks of a quadrant-packed scratch buffer lie: (bstride,
    boff, texture size), block (i, j) starting at boff + (i, j) bstride. Each
    block's centre sits on a corner of TILE x TILE tiles, so that a subpass's
    rectangle, about centred in its block however small (params.subpass_rects),
    spreads over four tiles, the cores' shares even (a small window's coarse
    scales ran on one core of two)."""
    stride, off, size = [], [], []
    for q in qdims:
        o = -(-(q // 2) // TILE) * TILE - q // 2
        st = -(-q // TILE) * TILE
        stride.append(st)
        off.append(o)
        size.append(o + (s - 1) * st + q)
    return (stride[0], stride[1]), (off[0], off[1]), (size[0], size[1])


def release_scratch(scratch) -> None:
    """Release a pair of scratch textures (a, fa, b, fb): the framebuffers first."""
    a, fa, b, fb = scratch
    for o in (fa, fb, a, b):
        o.release()


def scratch_size(region, s: int) -> tuple[int, int]:
    """The size of a padded region's scratch textures (block_layout)."""
    return block_layout((region.w // s, region.h // s), s)[2]


@dataclass
class Pacer:
    """Sizes the row pieces of draws that run between frames so each takes
    about ``piece_s`` seconds: the cost per pixel of each program is learned
    from the pieces it ran (waiting for the GPU after each). The pieces of a
    draw compute the same pixels however they are cut.

    A piece is a power of two of rows on a multiple of itself: llvmpipe
    renders in 64 x 64 tiles shared among its threads, and pieces that cut
    tiles unevenly cost up to twice as much (8 aligned rows of the fidelity
    stage cost 7% more than the whole draw, 8 unaligned ones 50%)."""

    piece_s: float = 0.006
    first_px: int = 4096  # a program not timed yet
    cost: dict = field(default_factory=dict)  # program -> seconds per pixel

    def rows(self, prog, w: int) -> int:
        c = self.cost.get(prog.glo)
        px = self.first_px if c is None else self.piece_s / c
        n = max(1, int(px) // max(1, w))
        return 1 << (n.bit_length() - 1)

    def record(self, prog, px: int, seconds: float) -> None:
        c = max(seconds, 1e-6) / max(1, px)
        old = self.cost.get(prog.glo)
        self.cost[prog.glo] = c if old is None else 0.6 * old + 0.4 * c


class DrawTimes:
    """The time of every draw of the engine while installed (:func:`timing_draws`;
    bench/profile.py), with its program's name (the shader file, `` vote`` for
    the fidelity stage's vote), level and pixels. Timer queries are read once
    the work is done (:meth:`results`), so timing them adds no wait between draws."""

    def __init__(self, gpu: Gpu, sync: bool = False):
        self.gpu = gpu
        self.sync = sync  # finish the GL work before and after each draw and time it on the CPU
        self._pending: list[tuple[str, int, int, Any]] = []

    def name(self, prog) -> str:
        source = self.gpu.program_source(prog)
        if source is None:
            return "other"
        frag, defines = source
        return frag.rsplit(".", 1)[0] + (" vote" if defines.get("FID_VOTE") else "")

    def query(self, prog, level: int, pixels: int):
        if self.sync:
            return self._synced(self.name(prog), level, pixels)
        q = self.gpu.ctx.query(time=True)
        self._pending.append((self.name(prog), level, pixels, q))
        return q

    @contextmanager
    def _synced(self, name: str, level: int, pixels: int):
        self.gpu.ctx.finish()
        t = time.perf_counter()
        yield
        self.gpu.ctx.finish()
        self._pending.append((name, level, pixels, time.perf_counter() - t))

    def results(self) -> list[tuple[str, int, int, float]]:
        """(program, level, pixels, seconds) per draw since the last call."""
        out = [(name, level, px, q if isinstance(q, float) else q.elapsed * 1e-9)
               for name, level, px, q in self._pending]
        self._pending = []
        return out


_timers: DrawTimes | None = None


@contextmanager
def timing_draws(gpu: Gpu, sync: bool = False) -> Iterator[DrawTimes]:
    """Time every engine draw on ``gpu`` while inside (one profiler at a time):
    with GL timer queries, or with ``sync`` on the CPU, the GL work finished
    before and after each draw. On llvmpipe, which renders a draw when its
    target or inputs change, a timer query can hold the work of the draw
    before it; ``sync`` times each draw alone (what it adds, its waits
    included)."""
    global _timers
    if _timers is not None:
        raise RuntimeError("Draws are already being timed.")
    _timers = DrawTimes(gpu, sync)
    try:
        yield _timers
    finally:
        _timers = None


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
    level: int = -1  # the pyramid level it works on (for DrawTimes)

    def steps(self, pace: Pacer | None = None) -> Iterator[None]:
        """Render at once (``pace`` None) or in row pieces sized by ``pace``
        (waiting for each to finish), yielding after each."""
        x, y, w, h = self.viewport
        y0 = y
        while y0 < y + h:
            if pace is None:
                rows = h
            else:
                n = pace.rows(self.prog, w)
                rows = min(y + h, (y0 // n + 1) * n) - y0
            t = time.perf_counter()
            for unit, tex in self.textures.items():
                tex.use(unit)
            set_uniforms(self.prog, **self.uniforms)
            self.fbo.use()
            self.fbo.viewport = (x, y0, w, rows)
            if _timers is None:
                self.vao.render(moderngl.TRIANGLES)
            else:
                with _timers.query(self.prog, self.level, w * rows):
                    self.vao.render(moderngl.TRIANGLES)
            if pace is not None:
                self.prog.ctx.finish()
                pace.record(self.prog, w * rows, time.perf_counter() - t)
            y0 += rows
            yield


def subpass_draws(gpu: Gpu, programs: list, subgrid: int, orders, qdims: tuple[int, int], scratch,
                  textures: dict, uniforms: dict, per_subpass: Callable[[int], dict],
                  rects: list | None = None) -> list[Draw]:
    """The subpasses of ``orders`` (lists of phases) with ``programs``, (program,
    vao) pairs, over the packed state in scratch ``a`` of ``scratch`` = (a, its
    framebuffer, b, b's): each renders its phase's block into b (each program in
    turn: they write different pixels; a program given as (program, vao, box)
    only over the box (x0, y0, x1, y1) of the region's pixels), which is then
    copied back into a.
    ``textures``/``uniforms``: the program's inputs besides the state (unit 0);
    ``per_subpass(n)``: the uniforms of subpass number n (counted over all passes);
    ``rects``: per subpass, the part of its block to render (params.subpass_rects;
    None: all of it; an empty one renders nothing)."""
    a, fa, b, fb = scratch
    copy, copy_vao = gpu.program("copy.frag", SUB_S=subgrid)
    bstride, boff, _ = block_layout(qdims, subgrid)
    level = uniforms.get("level", -1)
    draws = []
    n = -1
    for order in orders:
        for phase in order:
            n += 1
            x0, y0, x1, y1 = (0, 0, qdims[0], qdims[1]) if rects is None else rects[n]
            if x0 >= x1 or y0 >= y1:
                continue
            block = (boff[0] + phase[0] * bstride[0] + x0, boff[1] + phase[1] * bstride[1] + y0, x1 - x0, y1 - y0)
            uni = {**uniforms, "src": 0, "active_phase": phase, "bstride": bstride, "boff": boff, **per_subpass(n)}
            for prog, vao, *box in programs:
                bx0, by0, bx1, by1 = x0, y0, x1, y1
                if box:  # the block texels whose pixel (t s + phase) lies in the box
                    c0, r0, c1, r1 = box[0]
                    bx0, bx1 = max(x0, -(-(c0 - phase[0]) // subgrid)), min(x1, -(-(c1 - phase[0]) // subgrid))
                    by0, by1 = max(y0, -(-(r0 - phase[1]) // subgrid)), min(y1, -(-(r1 - phase[1]) // subgrid))
                    if bx0 >= bx1 or by0 >= by1:
                        continue
                part = (boff[0] + phase[0] * bstride[0] + bx0, boff[1] + phase[1] * bstride[1] + by0, bx1 - bx0, by1 - by0)
                draws.append(Draw(prog, vao, fb, part, {**textures, 0: a}, uni, level))
            draws.append(Draw(copy, copy_vao, fa, block, {0: b}, {"src": 0}, level))
    return draws


def _region_inputs(textures: dict, uniforms: dict, labels, label_uniforms, direction, links) -> None:
    """Add what both stages read of a region besides the state: texture by
    numbers (``labels`` and the stage's ``label_uniforms``), the J texture of a
    direction field (unit 11) and a mesh atlas' indirection map (unit 12)."""
    if labels is not None:
        textures.update(labels.textures)
        uniforms.update(label_uniforms)
    if direction is not None:
        textures[11] = direction
        uniforms["dfield"] = 11
    if links is not None:
        textures[12] = links
        uniforms["links"] = 12


@dataclass
class RegionPass:
    """One padded region of a level as every pass over it reads it: the level,
    the region, the quadrant-packed state's scratch textures, what each subpass
    renders, and the region's inputs besides the state (the passes' one
    description, made and released by ``Strips.region_pass``)."""

    gpu: Gpu
    gan: GpuAnalysis
    params: SynthParams
    level: int
    region: Any                    # the padded region (Rect, level pixels)
    scratch: tuple                 # (a, its framebuffer, b, b's framebuffer)
    rects: list | None             # per subpass (correction's, then the fidelity stage's) what it renders; None: all
    first: dict | None             # what the upsampling must compute, per phase (None: all)
    lattice_shift: tuple | None    # a lattice level's cell shift (its lattice candidates only), or None
    features: list                 # feature textures (units 3, 6, 7) and their uniforms
    feature_uniforms: dict
    canvas_field: Any = None       # the canvas randomness over the region (u16), or None
    direction: Any = None          # J over the region (anisometric synthesis), or None
    links: Any = None              # a mesh atlas' indirection map over the region, or None
    parent_links: Any = None       # and over the parent's region
    defines: dict = field(default_factory=dict)  # the geometry's (DIRECTION, ATLAS)
    avoid: Any = None              # the avoided exemplar region, or None
    labels: LabelDraws | None = None
    dummy: Any = None              # textures bound where an input is absent (u16, int)
    dummy_i: Any = None
    level_corrected: bool = False  # the level has correction passes

    @property
    def qdims(self) -> tuple[int, int]:
        s = self.params.subgrid
        return (self.region.w // s, self.region.h // s)

    @property
    def layout(self) -> tuple:
        """Where the scratch buffers' blocks lie: (bstride, boff, texture size), block_layout."""
        return block_layout(self.qdims, self.params.subgrid)

    def stage_rects(self, correction: bool) -> list | None:
        """What the correction's (else the fidelity stage's) subpasses render."""
        if self.rects is None:
            return None
        n = self.params.passes_at(self.level) * self.params.subgrid ** 2 if self.level_corrected else 0
        return self.rects[:n] if correction else self.rects[n:]

    def release(self) -> None:
        for tex in self.features:
            tex.release()
        for tex in (self.canvas_field, self.direction, self.links, self.parent_links):
            if tex is not None:
                tex.release()
        if self.labels is not None:
            self.labels.canvas.release()


def correction_draws(rp: RegionPass, walk: int) -> list[Draw]:
    """The correction's subpasses on ``rp``'s region (see shaders/correct.frag);
    a lattice level tries its lattice candidates only; ``walk``: random-walk steps."""
    gpu, gan, p, l, region, qdims = rp.gpu, rp.gan, rp.params, rp.level, rp.region, rp.qdims
    an = gan.analysis
    s = p.subgrid
    lt = gan.level(l)
    rects = rp.stage_rects(True)
    labels, direction = rp.labels, rp.direction
    prog, vao = gpu.program("correct.frag", SUB_S=s, **gan.correction_defines(l, rp.avoid is not None,
                                                                                direction is not None),
                            **(labels.defines if labels else {}), **rp.defines,
                            **(dict(INSIDE=True) if rects is not None else {}))
    sims = lt.lattice_sim if rp.lattice_shift is not None else (lt.sim or [rp.dummy_i] * 2)
    h = an.h(l)
    uni = dict(feat=1, ptable=1, nbhd=2, sim01=3, sim23=4, dims=(region.w, region.h), qdims=qdims, h=h,
               m=an.size, shift=lt.shift, psi=fixed.psi_q(p.kappa), P=lt.proj, walk=walk,
               origin=(region.x0, region.y0), level=l, period=p.level_period(l),
               border=-1 if an.toroidal else border_margin(an.size, h), avoid=5)
    table = gan.projection_tables and direction is None
    textures = dict(enumerate([lt.table if table else lt.feat, lt.nbhd] + sims, start=1))
    textures[5] = rp.avoid or rp.dummy
    _region_inputs(textures, uni, labels, labels and labels.correction, direction, rp.links)
    return subpass_draws(gpu, [(prog, vao)], s, subpass_order(s, p.passes_at(l)), qdims, rp.scratch, textures, uni,
                         lambda n: {"walk_seed": fixed.walk_seed(p.seed, n)}, rects)


def fidelity_draws(rp: RegionPass) -> list[Draw]:
    """The fidelity stage's iterations on ``rp``'s region (see
    shaders/fidelity.frag); a lattice level has no random search."""
    gpu, gan, p, l, region, qdims = rp.gpu, rp.gan, rp.params, rp.level, rp.region, rp.qdims
    an = gan.analysis
    rects = rp.stage_rects(False)
    labels, direction, links, scratch = rp.labels, rp.direction, rp.links, rp.scratch
    defines = dict(SUB_S=p.subgrid, FID_RADIUS=p.fidelity_radius, FID_SEARCH=FIDELITY_SEARCH, FID_NCH=an.channels,
                   **(labels.defines if labels else {}), **(dict(DIRECTION=True) if direction is not None else {}),
                   **(dict(ATLAS=True) if links is not None else {}), **(dict(AVOID=True) if rp.avoid is not None else {}),
                   **(dict(INSIDE=True) if rects is not None else {}))
    if direction is None:
        searches = [gpu.program("fidelity.frag", ROW_TAPS=True, **defines)]
    else:  # the draws each kind of pixel needs (fidelity.frag UPRIGHT, TILTED: two variants whatever the field)
        upright, tilted = direction.extra
        searches = [gpu.program("fidelity.frag", ROW_TAPS=True, UPRIGHT=True, **defines)] if upright else []
        if tilted is not None:  # drawn over their box only
            searches.append((*gpu.program("fidelity.frag", TILTED=True, **defines), tilted))
    uniforms = dict(colors=1, rowtaps=2, avoid=5, dims=(region.w, region.h), qdims=qdims,
                    h=an.h(l), m=an.size, border=-1 if an.toroidal else border_margin(an.size, an.h(l)),
                    origin=(region.x0, region.y0), level=l, period=p.level_period(l),
                    no_search=int(rp.lattice_shift is not None))
    textures = {1: gan.level(l).colors, 5: rp.avoid or rp.dummy}
    textures[2] = gan.level(l).row_taps(an.h(l), p.fidelity_radius, an.toroidal)
    _region_inputs(textures, uniforms, labels, labels and labels.fidelity, direction, links)
    orders = subpass_order(p.subgrid, p.fidelity_passes(l))
    if not p.fidelity_vote:
        return subpass_draws(gpu, searches, p.subgrid, orders, qdims, scratch, textures, uniforms,
                             lambda n: {"search_seed": fixed.fidelity_seed(p.seed, n)}, rects)
    # Search on even passes (subpasses numbered over the searches alone), the vote on odd ones.
    vote, vote_vao = gpu.program("fidelity.frag", FID_VOTE=True, **defines)
    per_pass = p.subgrid * p.subgrid
    draws = []
    for c, order in enumerate(orders):
        part = None if rects is None else rects[c * per_pass:(c + 1) * per_pass]
        if c % 2:
            draws += subpass_draws(gpu, [(vote, vote_vao)], p.subgrid, [order], qdims, scratch, textures, uniforms,
                                   lambda n: {}, part)
        else:
            first = c // 2 * per_pass
            draws += subpass_draws(gpu, searches, p.subgrid, [order], qdims, scratch, textures, uniforms,
                                   lambda n, first=first: {"search_seed": fixed.fidelity_seed(p.seed, first + n)},
                                   part)
    return draws


@dataclass
class LabelDraws:
    """What the correction and the fidelity stage read of texture by numbers
    over one padded region (engine/controls/labels.py): textures by unit, the
    shader defines, each program's uniforms, and the region's own texture
    (``canvas``, released by the caller)."""

    textures: dict
    defines: dict
    correction: dict
    fidelity: dict
    canvas: Any


def label_draws(gpu: Gpu, cache: dict, typical: dict, controls, an, p: SynthParams, l: int, region) -> LabelDraws | None:
    """Level ``l``'s label inputs over ``region``, or None where no painted
    label reaches it (the passes then compute exactly what they would without
    labels). ``cache`` keeps the level's exemplar textures (released with the
    exemplar inputs), ``typical`` the level's typical distances."""
    import numpy as np

    from .controls.labels import (
        LABEL_WALK,
        MAX_LABELS,
        SEED_COUNT,
        SEED_SALT,
        label_weight,
        typical_distance,
        typical_patch_cost,
    )
    if not controls.labels_active:
        return None
    mix = controls.labels_canvas.features(an.L - l, region.x0, region.y0, region.w, region.h, p.period)
    if mix is None:
        return None
    le = controls.labels_exemplar
    if ("labels", l) not in cache:
        cache[("labels", l)] = gpu.u32_texture(le.features(l, an.toroidal))
        seeds = le.seed_table(l, an.toroidal).reshape(MAX_LABELS, SEED_COUNT * 2)
        cache[("seeds", l)] = gpu.int_texture((SEED_COUNT, MAX_LABELS), 2, seeds)
    if ("nbhd", l) not in typical:
        typical[("nbhd", l)] = typical_distance(an.levels[l].nbhd) * fixed.PSI_ONE
    strength = float(controls.label_strength)
    uni = dict(lab_exemplar=8, lab_canvas=9, lab_seeds=10)
    fid = {}
    if p.fidelity_at(l):
        key = ("patch", l, p.fidelity_radius)
        if key not in typical:
            typical[key] = typical_patch_cost(fixed.quantized_colors(an.levels[l].stack), an.h(l),
                                              p.fidelity_radius, an.toroidal)
        fid = dict(uni, lab_weight=label_weight(typical[key], strength, l, an.L))
    canvas = gpu.u32_texture(np.ascontiguousarray(mix))
    return LabelDraws({8: cache[("labels", l)], 9: canvas, 10: cache[("seeds", l)]},
                      dict(LABELS=True, SEED_COUNT=SEED_COUNT, LAB_SEED_SALT=f"{SEED_SALT}u", LAB_WALK=LABEL_WALK),
                      dict(uni, lab_weight=label_weight(typical[("nbhd", l)], strength, l, an.L)), fid, canvas)
