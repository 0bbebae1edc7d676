"""The synthesis pyramid: exact windows of the infinite texture, updated incrementally.

Each level ``l`` owns a persistent GPU buffer holding the *exact* coordinates
``S_l`` over a rectangle ``valid[l]`` (global level-l pixels). A texel of
global position ``g`` lives at ``(g - anchor) & mask``: in scrolling mode the
buffer is a power of two and addressing wraps (a toroidal cache, so panning
never copies), in fixed mode the buffer is exactly the rectangle.

To make a view exact, :meth:`Pyramid.request` walks from the view's level to
level 0 computing what each level must hold (``half(pad(K_l))``, LH05 3.4),
then from coarse to fine synthesizes only the strips that are new: each strip
is padded by the correction margins, upsampled from the parent buffer,
jittered, corrected in quadrant-packed scratch buffers and its exact interior
written back. A full window is the special case of one strip per level.
"""
from __future__ import annotations

from collections.abc import Iterator

import moderngl
import numpy as np

from . import fixed
from .controls import NO_CONTROLS, Controls
from .controls.features import ENTRY_ROW, TABLE_ROW, pack_rows
from .gpu import Gpu, GpuAnalysis, set_uniforms
from .local_update import LocalUpdates
from .looks import QuickLooks
from .requests import SpreadRequests
from .state import StateAccess, SynthesisError
from .params import SynthParams, correction_margins, first_rects, subpass_rects
from .rect import Rect
from .stages import (
    Draw,
    Pacer,
    RegionPass,
    correction_draws,
    fidelity_draws,
    label_draws,
    scratch_size,
)

COORD_LIMIT = 2 ** 31 - 2 ** 24  # |canvas position| must stay below this


def _next_pow2(n: int) -> int:
    return 1 << max(0, (int(n) - 1).bit_length())


def feature_textures(gpu: Gpu, controls: Controls, an, l: int, region: Rect, period: int, dummy) -> tuple[list, dict]:
    """The features active over ``region`` (level l) as the shader reads
    them (Controls.feature_lookup), bound to units 3 (table), 6 (cells) and
    7 (their lists; ``dummy`` when there are none); the textures (to release)
    and the uniforms."""
    found = controls.feature_lookup(l, an.L, an.size, an.toroidal, region.x0, region.y0, region.x1, region.y1,
                                    period)
    uni = dict(features=3, fcells=6, fentries=7, nfeat=0, fcell_origin=(0, 0), fcell_dims=(1, 1), fcell_shift=0)
    if found is None:
        for unit in (3, 6, 7):
            dummy.use(unit)
        return [], uni
    table, cells, entries, origin, shift = found
    arrays = [(pack_rows(table, TABLE_ROW).reshape(-1, table.shape[1] * TABLE_ROW, 4), 4), (cells, 2),
              (pack_rows(entries, ENTRY_ROW), 1)]
    texs = []
    for unit, (arr, comps) in zip((3, 6, 7), arrays):
        tex = gpu.texture((arr.shape[1], arr.shape[0]), comps, arr.astype(np.int32, copy=False), "i4")
        tex.use(unit)
        texs.append(tex)
    uni.update(nfeat=len(table), fcell_origin=origin, fcell_dims=(cells.shape[1], cells.shape[0]), fcell_shift=shift)
    return texs, uni


def strip_rects(p: SynthParams, model: str, l: int, npass: int, strip: Rect, region: Rect) -> tuple:
    """For a strip of level l synthesized on its padded ``region`` with ``npass``
    correction passes: what each subpass renders and what the upsampling must
    compute (params.subpass_rects, first_rects), or (None, None)."""
    geometry = (p.subgrid, ((npass, fixed.read_radius(model)), (p.fidelity_passes(l), p.fidelity_radius)),
                (region.w, region.h),
                (strip.x0 - region.x0, strip.y0 - region.y0, strip.x1 - region.x0, strip.y1 - region.y0))
    rects = subpass_rects(*geometry)
    return (None, None) if rects is None else (rects, first_rects(*geometry))


class _LevelBuffer:
    def __init__(self, gpu: Gpu, size: tuple[int, int], scrolling: bool, anchor: tuple[int, int], channels: int = 2):
        self.size = size
        self.scrolling = scrolling
        self.anchor = (0, 0) if scrolling else anchor
        self.mask = (size[0] - 1, size[1] - 1) if scrolling else (-1, -1)
        self.channels = channels  # 4 with a direction field: (nearest texel, remainder in 1/256 px)
        self.tex = gpu.int_texture(size, channels)
        self.fbo = gpu.ctx.framebuffer(color_attachments=[self.tex])
        self.valid: Rect | None = None

    def texel(self, gx: int, gy: int) -> tuple[int, int]:
        return (gx - self.anchor[0]) & self.mask[0], (gy - self.anchor[1]) & self.mask[1]

    def fits(self, r: Rect) -> bool:
        if self.scrolling:
            return r.w <= self.size[0] and r.h <= self.size[1]
        return Rect.of(*self.anchor, *self.size).contains(r)

    def pieces(self, r: Rect) -> list:
        """Split r into pieces contiguous in the texture: ((gx, gy), (tx, ty), w, h)."""
        xs, ys = [], []
        for lo, hi, axis, out in ((r.x0, r.x1, 0, xs), (r.y0, r.y1, 1, ys)):
            g = lo
            while g < hi:
                t = (g - self.anchor[axis]) & self.mask[axis]
                n = min(hi - g, self.size[axis] - t)
                out.append((g, t, n))
                g += n
        return [((gx, gy), (tx, ty), nx, ny) for gx, tx, nx in xs for gy, ty, ny in ys]

    def release(self) -> None:
        self.fbo.release()
        self.tex.release()


class Pyramid(LocalUpdates, SpreadRequests, StateAccess, QuickLooks):
    """Per-level exact coordinate buffers for one analysis and parameter set.

    ``scrolling=True`` keeps power-of-two wrap-around buffers with a prefetch
    border of ``prefetch`` pixels, for views that pan; ``False`` allocates each
    level exactly for a one-off window (export, CLI).
    """

    def __init__(self, gpu: Gpu, gan: GpuAnalysis, params: SynthParams, *,
                 scrolling: bool = True, prefetch: int = 16, chunk: int = 16,
                 controls: Controls = NO_CONTROLS):
        self.gpu = gpu
        self.gan = gan
        self.an = gan.analysis
        self.scrolling = scrolling
        self.prefetch = prefetch if scrolling else 0
        self.chunk = chunk if scrolling else 1
        self.buffers: list[_LevelBuffer | None] = [None] * (self.an.L + 1)
        self._scratch: dict[tuple[int, int], tuple] = {}
        self.pixels_synthesized = 0  # level pixels upsampled by the last request
        gpu.activate()
        self._efield: dict = {}  # textures of the exemplar inputs: level -> R_E,l; "avoid" -> the mask; labels
        self._label_typical: dict = {}  # typical distances per level (texture by numbers' weights)
        self._dummy = gpu.u16_texture(np.full((1, 1), 32768, np.uint16))
        self._dummy_i = gpu.ctx.texture((2, 1), 4, np.zeros(8, np.int32).tobytes(), dtype="i4")
        self.controls = NO_CONTROLS
        # Per level, the regions a local update has still to synthesize again
        # (already grown by the level's reach; clipped to what is held when done).
        self.dirty: list[list[Rect]] = [[] for _ in range(self.an.L + 1)]
        self._job = None  # the dirty region being synthesized: (level, its steps, its scratch)
        self._request_job = None  # a request spread over frames: (level, rect, its steps)
        self.request_pixels = 0  # level pixels the request in progress has synthesized
        self.pacer = Pacer()  # sizes the pieces of work spread over frames
        self.touched: list[tuple[int, Rect]] | None = []  # what changed since take_touched (None: all)
        self._init_quick_looks()
        self.set_params(params, controls)

    # -- parameters ---------------------------------------------------------

    def set_params(self, params: SynthParams, controls: Controls | None = None) -> None:
        """Adopt new parameters (and controls), keeping every level they do not change."""
        params.validate(self.an.L)
        if controls is not None:
            controls = controls.normalized()
            controls.validate(self.an.size, self.an.settings.lattice)
            if controls.exemplar_inputs() != self.controls.exemplar_inputs():
                self._release_efield()
            if controls.directed != self.controls.directed:
                self._release_state()  # the state's format changes (sub-pixel parts)
            self.controls = controls
        old = getattr(self, "_signatures", None)
        self.params = params
        self._signatures = self._level_signatures()
        self.corrected = params.correcting_levels()
        radius = fixed.read_radius(self.an.model)
        self.margins = [correction_margins(params.subgrid, params.passes_at(l), radius,
                                           ((params.fidelity_passes(l), params.fidelity_radius),))
                        for l in range(self.an.L + 1)]
        if old is None:
            return
        first = next((l for l in range(self.an.L + 1) if old[l] != self._signatures[l]), None)
        if first is not None:
            self.invalidate(first)

    def _level_signatures(self) -> list[tuple]:
        """What each level depends on: its parameters and the controls."""
        return [(self.params.level_signature(l), self.controls.level_signature(l, self.an.size))
                for l in range(self.an.L + 1)]

    def invalidate(self, first_level: int = 0) -> None:
        """Forget the contents of levels >= first_level (and any request in progress)."""
        self.end_request()
        if self._job is not None and self._job[0] >= first_level:
            self._end_job()
        self._drop_patches(None)
        self.touched = None
        for l in range(first_level, self.an.L + 1):
            self.dirty[l] = []
            if self.buffers[l] is not None:
                self.buffers[l].valid = None

    # -- geometry -----------------------------------------------------------

    def padded(self, level: int, r: Rect) -> Rect:
        """The region a strip is synthesized on: r plus correction margins, s-aligned."""
        return r.pad(*self.margins[level]).align(self.params.subgrid)

    def plan(self, level: int, rect: Rect, grown: bool = False) -> list[Rect]:
        """The rectangle each level 0..level must hold exactly for ``rect``.
        ``grown``: what to request of each, one level at a time coarse to fine,
        so that no pixel is made twice: grown by what each finer level's target
        (its prefetch, its chunks) will read (asked for the plain plan, each
        finer level sent its parent back for more strips)."""
        need = [Rect(0, 0, 0, 0)] * (level + 1)
        cur = rect
        for l in range(level, -1, -1):
            need[l] = cur
            cur = self.padded(l, self._target(l, cur) if grown else cur).half()
        return need

    def _target(self, l: int, need: Rect) -> Rect:
        """What level l will hold: its current rectangle while that still covers
        ``need`` (hysteresis), else ``need`` plus prefetch, snapped to chunks."""
        buf = self.buffers[l]
        if buf is not None and buf.valid is not None and buf.valid.contains(need):
            return buf.valid
        p = self.prefetch >> (self.an.L - l) if self.scrolling else 0
        p = max(p, 2 if self.scrolling else 0)
        t = need.pad(p, p, p, p).align(self.chunk)
        if buf is not None and buf.valid is not None and self.scrolling:
            v = buf.valid
            union = Rect(min(v.x0, t.x0), min(v.y0, t.y0), max(v.x1, t.x1), max(v.y1, t.y1))
            if buf.fits(union):  # grow what is held rather than drop it
                return union
        return t

    # -- synthesis ----------------------------------------------------------

    def _check(self, level: int, rect: Rect) -> None:
        if not 0 <= level <= self.an.L:
            raise SynthesisError(f"Level {level} does not exist (0..{self.an.L}).")
        lim = COORD_LIMIT >> (self.an.L - level)
        if min(rect.x0, rect.y0) < -lim or max(rect.x1, rect.y1) > lim:
            raise SynthesisError(f"Canvas positions must stay within +-{lim} at level {level}.")

    def _targets(self, level: int, rect: Rect) -> list[tuple[int, Rect]]:
        """What each level must hold for ``rect`` of ``level``, coarse to fine:
        decided fine to coarse; a level whose target holds new strips needs its
        parent to cover what its whole target reads, so that a local update
        anywhere in what it holds finds its parent's pixels (margins differ
        between levels, so a parent covering only the new strips' reads could
        drop what an older part needs); one without new strips needs nothing."""
        targets = []
        need: Rect | None = rect
        for l in range(level, -1, -1):
            if need is None:
                break
            t = self._target(l, need)
            targets.append((l, t))
            buf = self.buffers[l]
            valid = buf.valid if buf is not None else None
            new_strips = valid is None or bool(t.minus(valid))
            need = self.padded(l, t).half() if new_strips else None
        return targets[::-1]

    def request(self, level: int, rect: Rect) -> int:
        """Make level ``level`` exact over ``rect`` (and its ancestors as needed).

        Returns the number of level pixels synthesized (0 when all was cached).
        A request in progress (:meth:`start_request`) is dropped.
        """
        self._check(level, rect)
        self.end_request()
        if rect.empty:
            return 0
        self.gpu.activate()
        total = 0
        for l, target in self._targets(level, rect):
            total += self._update_level(l, target)
        self.pixels_synthesized = total
        return total

    def _ensure_buffer(self, l: int, target: Rect) -> _LevelBuffer:
        buf = self.buffers[l]
        if buf is not None and buf.fits(target):
            return buf
        if self.scrolling:
            slack = 2 * self.chunk + 2 * (self.prefetch >> (self.an.L - l)) + 4
            size = (_next_pow2(target.w + slack), _next_pow2(target.h + slack))
            if buf is not None:  # grow, never shrink: a view that grew once will again
                size = (max(size[0], buf.size[0]), max(size[1], buf.size[1]))
        else:
            size = (target.w, target.h)
        new = _LevelBuffer(self.gpu, size, self.scrolling, (target.x0, target.y0), self.channels)
        if buf is not None:
            keep = buf.valid.intersect(target) if buf.valid is not None else None
            if keep is not None and not keep.empty and new.fits(keep):
                self._copy(buf, new, keep)
                new.valid = keep
            buf.release()
        self.buffers[l] = new
        return new

    def _copy(self, src: _LevelBuffer, dest: _LevelBuffer, r: Rect) -> None:
        """Copy the exact texels of ``r`` from one level buffer to another."""
        prog, vao = self.gpu.program("remap.frag", SUB_S=self.params.subgrid)
        src.tex.use(0)
        set_uniforms(prog, src=0, src_anchor=src.anchor, src_mask=src.mask, dest_mask=dest.mask)
        dest.fbo.use()
        for g0, t0, w, hh in dest.pieces(r):
            set_uniforms(prog, region_g0=g0, region_t0=t0)
            dest.fbo.viewport = (t0[0], t0[1], w, hh)
            vao.render(moderngl.TRIANGLES)

    def _update_level(self, l: int, target: Rect) -> int:
        buf, keep, strips = self._keep(l, target)
        count = 0
        for strip in strips:
            count += self._synthesize_strip(l, strip, buf)
        buf.valid = target
        for strip in strips:
            self._touch(l, strip)
        return count

    def _scratch_pair(self, region: Rect):
        """The pair of scratch textures for a padded region (kept for their size)."""
        w, h = scratch_size(region, self.params.subgrid)
        key = (w, h)
        if key not in self._scratch:
            if len(self._scratch) > 24:
                for a, fa, b, fb in self._scratch.values():
                    for o in (fa, fb, a, b):
                        o.release()
                self._scratch.clear()
            self._scratch[key] = self._new_scratch(w, h)
        return self._scratch[key]

    def _new_buffer(self, r: Rect) -> _LevelBuffer:
        """A level buffer of this pyramid's kind holding exactly ``r`` (not valid yet)."""
        return _LevelBuffer(self.gpu, (r.w, r.h), False, (r.x0, r.y0), self.channels)

    def _new_scratch(self, w: int, h: int):
        """Two w x h state textures and their framebuffers: (a, fa, b, fb) (see _scratch_pair)."""
        a = self.gpu.int_texture((w, h), self.channels)
        b = self.gpu.int_texture((w, h), self.channels)
        return a, self.gpu.ctx.framebuffer([a]), b, self.gpu.ctx.framebuffer([b])

    def _synthesize_strip(self, l: int, strip: Rect, buf: _LevelBuffer) -> int:
        region = self.padded(l, strip)
        steps = self._strip_steps(l, strip, self._scratch_pair(region), buf)
        for _ in steps:
            pass
        return region.w * region.h

    def _strip_steps(self, l: int, strip: Rect, scratch, buf: _LevelBuffer | None,
                     pace: Pacer | None = None, parent: _LevelBuffer | None = None) -> Iterator[None]:
        """Synthesize ``strip`` of level l into ``buf`` (None: the level's buffer at
        the end, over what it then holds), a draw (or a piece of one, sized by
        ``pace``) per step: upsample + jitter, correction, fidelity stage, on ``scratch``;
        the write-back is the last step. Returns (as the generator's value) the
        rectangle of the pixels that changed, when ``buf`` is None. ``parent``:
        read instead of level l - 1's buffer (a quick look, see looks.py)."""
        rp = self._region_pass(l, strip, scratch)
        try:
            yield from self._upsample_steps(rp, parent, pace)
            # Correction subpasses, then the fidelity stage's, on scratch a, each
            # over what the strip needs of it (not in an atlas, whose reads jump).
            draws = []
            if rp.level_corrected:
                # Lattice levels keep their lattice candidates only.
                walk = self.params.walk_steps(self.an.k, self.controls.avoid is not None) \
                    if rp.lattice_shift is None else 0
                draws += correction_draws(rp, walk)
            if self.params.fidelity_at(l):
                draws += fidelity_draws(rp)
            for d in draws:
                yield from d.steps(pace)
            return (yield from self._write_back(rp, strip, buf))
        finally:
            rp.release()

    def _region_pass(self, l: int, strip: Rect, scratch) -> RegionPass:
        """What every pass over ``strip``'s padded region reads (stages.RegionPass)."""
        p, an = self.params, self.an
        region = self.padded(l, strip)
        ftexs, funi = feature_textures(self.gpu, self.controls, an, l, region, p.level_period(l), self._dummy_i)
        cvals = None
        if self.controls.randomness_canvas is not None:
            cvals = self.controls.randomness_canvas.region(an.L - l, region.x0, region.y0, region.w, region.h,
                                                           p.level_period(l))
        dtex, ltex, ptex, ddef = self._geometry_textures(l, region)
        corrected = l in self.corrected
        # Only what the subpasses then read of each phase (not in an atlas, whose reads jump).
        npass = p.passes_at(l) if corrected else 0
        rects, first = (None, None) if ltex is not None else strip_rects(p, an.model, l, npass, strip, region)
        labels = None
        if corrected or p.fidelity_at(l):
            labels = label_draws(self.gpu, self._efield, self._label_typical, self.controls, an, p, l, region)
        return RegionPass(self.gpu, self.gan, p, l, region, scratch, rects, first,
                          self.controls.lattice_shift(an.size, l), ftexs, funi,
                          self.gpu.u16_texture(cvals) if cvals is not None else None, dtex, ltex, ptex, ddef,
                          self._avoid_texture(), labels, self._dummy, self._dummy_i, corrected)

    def _upsample_steps(self, rp: RegionPass, parent: _LevelBuffer | None, pace: Pacer | None) -> Iterator[None]:
        """Upsample + jitter into scratch a (modulated by the randomness fields):
        the whole region, or per phase what the subpasses then read (``rp.first``)."""
        p, an, l, region = self.params, self.an, rp.level, rp.region
        s = p.subgrid
        bstride, boff, tex_size = rp.layout
        prog, vao = self.gpu.program("upsample.frag", SUB_S=s, **rp.defines)
        efield = self._efield_texture(l)
        textures = {1: efield or self._dummy, 2: rp.canvas_field or self._dummy}
        if rp.direction is not None:
            textures[11] = rp.direction
        if rp.links is not None:
            textures[12] = rp.links
            textures[13] = rp.parent_links or rp.links
        uni: dict = {}
        if l > 0:
            parent = parent or self.buffers[l - 1]
            assert parent is not None and parent.valid is not None and parent.valid.contains(region.half())
            textures[0] = parent.tex
            uni = dict(parent=0, parent_anchor=parent.anchor, parent_mask=parent.mask)
        uni.update(has_parent=int(l > 0), origin=(region.x0, region.y0), qdims=rp.qdims, bstride=bstride, boff=boff,
                   h=an.h(l), m=an.size, level=l, seed=p.seed,
                   rq=fixed.jitter_q(self.controls.jitter_at(p, an.size, l)),
                   period=p.level_period(l), efield=1, eshift=an.L - l, has_efield=int(efield is not None),
                   cfield=2, has_cfield=int(rp.canvas_field is not None), lattice_shift=rp.lattice_shift or (-1, -1),
                   **rp.feature_uniforms, **(dict(dfield=11) if rp.direction is not None else {}),
                   **(dict(links=12, plinks=13, plink_origin=(region.half().x0, region.half().y0))
                      if rp.links is not None else {}))
        for unit, tex in zip((3, 6, 7), rp.features or [self._dummy_i] * 3):
            textures[unit] = tex
        fa = rp.scratch[1]
        if rp.first is None:
            yield from Draw(prog, vao, fa, (*boff, tex_size[0] - boff[0], tex_size[1] - boff[1]), textures, uni,
                            l).steps(pace)
            return
        for (i, j), (x0, y0, x1, y1) in sorted(rp.first.items()):
            if x0 < x1 and y0 < y1:
                yield from Draw(prog, vao, fa, (boff[0] + i * bstride[0] + x0, boff[1] + j * bstride[1] + y0,
                                                x1 - x0, y1 - y0), textures, uni, l).steps(pace)

    def _write_back(self, rp: RegionPass, strip: Rect, buf: _LevelBuffer | None) -> Iterator[None]:
        """Write the exact strip back from scratch a, split where the buffer
        wraps; ``buf`` None (a local update): into what the level holds now,
        returning the rectangle of the pixels that changed (or None)."""
        p, an, l, region = self.params, self.an, rp.level, rp.region
        s = p.subgrid
        bstride, boff, _ = rp.layout
        deferred = buf is None
        if deferred:
            buf = self.buffers[l]
            strip = strip.intersect(buf.valid) if buf is not None and buf.valid is not None else Rect(0, 0, 0, 0)
            if strip.empty:
                return None
            before = self._read_rect(buf, strip)
        prog, vao = self.gpu.program("writeback.frag", SUB_S=s, **rp.defines)
        uni = dict(src=0, qdims=rp.qdims, bstride=bstride, boff=boff, src_origin=(region.x0, region.y0),
                   dest_mask=buf.mask, h=an.h(l), m=an.size, period=p.level_period(l), links=12,
                   **rp.feature_uniforms)  # links: charts (on a model)
        textures = {0: rp.scratch[0], 12: self._dummy_i if rp.links is None else rp.links,
                    **dict(zip((3, 6, 7), rp.features or [self._dummy_i] * 3))}
        # At once and without a pause: a level shown between two pieces
        # would hold pixels the view was not told about (Pyramid.touched).
        for g0, t0, w, hh in buf.pieces(strip):
            for _ in Draw(prog, vao, buf.fbo, (t0[0], t0[1], w, hh), textures,
                          dict(uni, region_g0=g0, region_t0=t0), l).steps():
                pass
        if not deferred:
            yield  # (a local update reports what it changed before any frame can draw it: no pause here)
            return None
        diff = np.any(self._read_rect(buf, strip) != before, axis=-1)
        if not diff.any():
            return None
        ys, xs = np.nonzero(diff)
        return Rect(strip.x0 + int(xs.min()), strip.y0 + int(ys.min()),
                    strip.x0 + int(xs.max()) + 1, strip.y0 + int(ys.max()) + 1)

    def _efield_texture(self, l: int):
        e = self.controls.randomness_exemplar
        if e is None:
            return None
        if l not in self._efield:
            self._efield[l] = self.gpu.u16_texture(e.level(self.an.L, l))
        return self._efield[l]

    def _avoid_texture(self):
        a = self.controls.avoid
        if a is None:
            return None
        if "avoid" not in self._efield:
            self._efield["avoid"] = self.gpu.u16_texture(a.values)
        return self._efield["avoid"]

    def _release_efield(self) -> None:
        self._end_job()  # they may read them
        self.end_request()
        for t in self._efield.values():
            t.release()
        self._efield.clear()

    # -- reading ------------------------------------------------------------

    def release(self) -> None:
        self.gpu.activate()
        self._drop_patches(None)
        for buf in self.buffers:
            if buf is not None:
                buf.release()
        self.buffers = [None] * (self.an.L + 1)
        self._release_efield()
        if self._dummy is not None:
            self._dummy.release()
            self._dummy_i.release()
            self._dummy = self._dummy_i = None
        for a, fa, b, fb in self._scratch.values():
            for o in (fa, fb, a, b):
                o.release()
        self._scratch.clear()
