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

import moderngl
import numpy as np

from . import fixed
from .controls import NO_CONTROLS, Controls
from .gpu import Gpu, GpuAnalysis, set_uniforms
from .local_update import LocalUpdates
from .looks import QuickLooks
from .requests import SpreadRequests
from .state import StateAccess, SynthesisError
from .strips import Strips
from .params import SynthParams, correction_margins
from .rect import Rect
from .stages import Pacer, release_scratch, scratch_size

COORD_LIMIT = 2 ** 31 - 2 ** 24  # |canvas position| must stay below this


def _next_pow2(n: int) -> int:
    return 1 << max(0, (int(n) - 1).bit_length())


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


class Pyramid:
    """Per-level exact coordinate buffers for one analysis and parameter set.

    ``scrolling=True`` keeps power-of-two wrap-around buffers with a prefetch
    border of ``prefetch`` pixels, for views that pan; ``False`` allocates each
    level exactly for a one-off window (export, CLI).

    Its parts, each with its own state: ``updates`` (local updates,
    local_update.py), ``requests`` (requests spread over frames and what
    changed, requests.py), ``looks`` (quick looks, looks.py) and ``state``
    (the state's layout and read-back, state.py); ``strips`` (strips.py)
    synthesizes a level's strips. The pyramid itself holds the levels'
    buffers and decides what each must hold.
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
        self.controls = NO_CONTROLS
        self.pacer = Pacer()  # sizes the pieces of work spread over frames
        self.strips = Strips(self)
        self.updates = LocalUpdates(self)
        self.requests = SpreadRequests(self)
        self.looks = QuickLooks(self)
        self.state = StateAccess(self)
        self.set_params(params, controls)

    # -- parameters ---------------------------------------------------------

    def set_params(self, params: SynthParams, controls: Controls | None = None) -> None:
        """Adopt new parameters (and controls), keeping every level they do not change."""
        params.validate(self.an.L)
        if controls is not None:
            controls = controls.normalized()
            controls.validate(self.an.size, self.an.settings.lattice)
            if controls.exemplar_inputs() != self.controls.exemplar_inputs():
                self.strips.release_inputs()
            if controls.directed != self.controls.directed:
                self.drop_buffers()  # the state's format changes (sub-pixel parts)
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

    def adopt_controls(self, controls: Controls) -> None:
        """Take ``controls`` without invalidating any level (a local update marks what they change)."""
        self.controls = controls
        self._signatures = self._level_signatures()

    def invalidate(self, first_level: int = 0) -> None:
        """Forget the contents of levels >= first_level (and any request in progress)."""
        self.requests.end()
        self.updates.forget(first_level)
        self.looks.drop(None)
        self.requests.touch_all()
        for l in range(first_level, self.an.L + 1):
            if self.buffers[l] is not None:
                self.buffers[l].valid = None

    def drop_buffers(self) -> None:
        """Drop every level buffer and scratch texture (their format changes)."""
        self.invalidate(0)  # (the local update in progress ends with it)
        for i, buf in enumerate(self.buffers):
            if buf is not None:
                buf.release()
            self.buffers[i] = None
        self.drop_scratch()

    def drop_scratch(self) -> None:
        """Release the scratch textures kept for their size."""
        for scratch in self._scratch.values():
            release_scratch(scratch)
        self._scratch.clear()

    # -- what its users ask of it (done by its parts) -------------------------

    def update_controls(self, controls: Controls, changed: list[Rect] | None = None, *, defer: bool = False) -> int:
        """Adopt controls that differ only inside ``changed`` (:meth:`LocalUpdates.update_controls`)."""
        return self.updates.update_controls(controls, changed, defer=defer)

    def settle(self, budget_s: float | None = None, regions: int | None = None) -> bool:
        """Carry out the waiting local updates (:meth:`LocalUpdates.settle`); True when none is left."""
        return self.updates.settle(budget_s, regions)

    @property
    def settled(self) -> bool:
        """No local update is waiting."""
        return self.updates.settled

    def read(self, level: int, rect: Rect, remainder: bool = False) -> np.ndarray:
        """The exemplar coordinates held over ``rect`` (:meth:`StateAccess.read`)."""
        return self.state.read(level, rect, remainder)

    def correct(self, l: int, strip: Rect, state: np.ndarray) -> np.ndarray:
        """Level l's correction run on a given state (:meth:`StateAccess.correct`)."""
        return self.state.correct(l, strip, state)

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
            cur = self.padded(l, self._target(l, cur) if grown else cur).parents()
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

    def check(self, level: int, rect: Rect) -> None:
        if not 0 <= level <= self.an.L:
            raise SynthesisError(f"Level {level} does not exist (0..{self.an.L}).")
        lim = COORD_LIMIT >> (self.an.L - level)
        if min(rect.x0, rect.y0) < -lim or max(rect.x1, rect.y1) > lim:
            raise SynthesisError(f"Canvas positions must stay within +-{lim} at level {level}.")

    def targets(self, level: int, rect: Rect) -> list[tuple[int, Rect]]:
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
            need = self.padded(l, t).parents() if new_strips else None
        return targets[::-1]

    def request(self, level: int, rect: Rect) -> int:
        """Make level ``level`` exact over ``rect`` (and its ancestors as needed).

        Returns the number of level pixels synthesized (0 when all was cached).
        A request in progress (:meth:`SpreadRequests.start`) is dropped.
        """
        self.check(level, rect)
        self.requests.end()
        if rect.empty:
            return 0
        self.gpu.activate()
        total = 0
        for l, target in self.targets(level, rect):
            total += self._update_level(l, target)
        self.pixels_synthesized = total
        return total

    def ensure_buffer(self, l: int, target: Rect) -> _LevelBuffer:
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
        new = _LevelBuffer(self.gpu, size, self.scrolling, (target.x0, target.y0), self.state.channels)
        if buf is not None:
            keep = buf.valid.intersect(target) if buf.valid is not None else None
            if keep is not None and not keep.empty and new.fits(keep):
                self.copy(buf, new, keep)
                new.valid = keep
            buf.release()
        self.buffers[l] = new
        return new

    def copy(self, src: _LevelBuffer, dest: _LevelBuffer, r: Rect) -> None:
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
        buf, keep, strips = self.requests.keep(l, target)
        count = 0
        for strip in strips:
            count += self._synthesize_strip(l, strip, buf)
        buf.valid = target
        for strip in strips:
            self.requests.touch(l, strip)
        return count

    def scratch_pair(self, region: Rect):
        """The pair of scratch textures for a padded region (kept for their size)."""
        key = scratch_size(region, self.params.subgrid)
        if key not in self._scratch:
            if len(self._scratch) > 24:
                self.drop_scratch()
            self._scratch[key] = self.new_scratch(region)
        return self._scratch[key]

    def new_buffer(self, r: Rect) -> _LevelBuffer:
        """A level buffer of this pyramid's kind holding exactly ``r`` (not valid yet)."""
        return _LevelBuffer(self.gpu, (r.w, r.h), False, (r.x0, r.y0), self.state.channels)

    def new_scratch(self, region: Rect):
        """Two state textures for a padded region and their framebuffers:
        (a, fa, b, fb), released by ``stages.release_scratch`` (see scratch_pair)."""
        w, h = scratch_size(region, self.params.subgrid)
        a = self.gpu.int_texture((w, h), self.state.channels)
        b = self.gpu.int_texture((w, h), self.state.channels)
        return a, self.gpu.ctx.framebuffer([a]), b, self.gpu.ctx.framebuffer([b])

    def _synthesize_strip(self, l: int, strip: Rect, buf: _LevelBuffer) -> int:
        region = self.padded(l, strip)
        steps = self.strips.strip_steps(l, strip, self.scratch_pair(region), buf)
        for _ in steps:
            pass
        return region.w * region.h

    # -- reading ------------------------------------------------------------

    def release(self) -> None:
        self.gpu.activate()
        self.looks.drop(None)
        for buf in self.buffers:
            if buf is not None:
                buf.release()
        self.buffers = [None] * (self.an.L + 1)
        self.strips.release()
        self.drop_scratch()
