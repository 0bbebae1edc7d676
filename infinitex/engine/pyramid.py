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

from dataclasses import dataclass

import moderngl
import numpy as np

from . import fixed
from .controls import NO_CONTROLS, Controls
from .controls.features import ENTRY_ROW, TABLE_ROW, pack_rows
from .gpu import Gpu, GpuAnalysis, set_uniforms
from .params import SynthParams, correction_margins, subpass_order
from .similarity import border_margin
from .stages import run_fidelity, run_subpasses

COORD_LIMIT = 2 ** 31 - 2 ** 24  # |canvas position| must stay below this


@dataclass(frozen=True)
class Rect:
    """Half-open integer rectangle [x0, x1) x [y0, y1)."""

    x0: int
    y0: int
    x1: int
    y1: int

    @classmethod
    def of(cls, x: int, y: int, w: int, h: int) -> "Rect":
        return cls(int(x), int(y), int(x) + int(w), int(y) + int(h))

    @property
    def w(self) -> int:
        return self.x1 - self.x0

    @property
    def h(self) -> int:
        return self.y1 - self.y0

    @property
    def empty(self) -> bool:
        return self.w <= 0 or self.h <= 0

    def contains(self, o: "Rect") -> bool:
        return self.x0 <= o.x0 and self.y0 <= o.y0 and o.x1 <= self.x1 and o.y1 <= self.y1

    def intersect(self, o: "Rect") -> "Rect":
        return Rect(max(self.x0, o.x0), max(self.y0, o.y0), min(self.x1, o.x1), min(self.y1, o.y1))

    def pad(self, left: int, right: int, top: int, bottom: int) -> "Rect":
        return Rect(self.x0 - left, self.y0 - top, self.x1 + right, self.y1 + bottom)

    def align(self, a: int) -> "Rect":
        """Smallest enclosing rectangle whose edges are multiples of a."""
        return Rect((self.x0 // a) * a, (self.y0 // a) * a, -((-self.x1) // a) * a, -((-self.y1) // a) * a)

    def half(self) -> "Rect":
        """The parent-level pixels whose children cover this rectangle."""
        return Rect(self.x0 // 2, self.y0 // 2, (self.x1 - 1) // 2 + 1, (self.y1 - 1) // 2 + 1)

    def minus(self, o: "Rect") -> list["Rect"]:
        """self \\ o as at most 4 disjoint rectangles."""
        i = self.intersect(o)
        if i.empty:
            return [] if self.empty else [self]
        out = [Rect(self.x0, self.y0, self.x1, i.y0), Rect(self.x0, i.y1, self.x1, self.y1),
               Rect(self.x0, i.y0, i.x0, i.y1), Rect(i.x1, i.y0, self.x1, i.y1)]
        return [r for r in out if not r.empty]


def _merge(rects: list[Rect]) -> list[Rect]:
    """Overlapping rectangles merged into their bounding boxes (until disjoint)."""
    out = list(rects)
    merged = True
    while merged:
        merged = False
        for i in range(len(out)):
            for j in range(i + 1, len(out)):
                if not out[i].intersect(out[j]).empty:
                    a, b = out[i], out[j]
                    out[i] = Rect(min(a.x0, b.x0), min(a.y0, b.y0), max(a.x1, b.x1), max(a.y1, b.y1))
                    del out[j]
                    merged = True
                    break
            if merged:
                break
    return out


class SynthesisError(ValueError):
    """A request the synthesis cannot serve (e.g. coordinates out of range)."""


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
    arrays = [(pack_rows(table, TABLE_ROW).reshape(-1, 2 * TABLE_ROW, 4), 4), (cells, 2),
              (pack_rows(entries, ENTRY_ROW), 1)]
    texs = []
    for unit, (arr, comps) in zip((3, 6, 7), arrays):
        tex = gpu.ctx.texture((arr.shape[1], arr.shape[0]), comps, np.ascontiguousarray(arr).tobytes(), dtype="i4")
        tex.filter = (moderngl.NEAREST, moderngl.NEAREST)
        tex.use(unit)
        texs.append(tex)
    uni.update(nfeat=len(table), fcell_origin=origin, fcell_dims=(cells.shape[1], cells.shape[0]), fcell_shift=shift)
    return texs, uni


class _LevelBuffer:
    def __init__(self, gpu: Gpu, size: tuple[int, int], scrolling: bool, anchor: tuple[int, int]):
        self.size = size
        self.scrolling = scrolling
        self.anchor = (0, 0) if scrolling else anchor
        self.mask = (size[0] - 1, size[1] - 1) if scrolling else (-1, -1)
        self.tex = gpu.int_texture(size, 2)
        self.fbo = gpu.ctx.framebuffer(color_attachments=[self.tex])
        self.valid: Rect | None = None

    def texel(self, gx: int, gy: int) -> tuple[int, int]:
        return (gx - self.anchor[0]) & self.mask[0], (gy - self.anchor[1]) & self.mask[1]

    def fits(self, r: Rect) -> bool:
        if self.scrolling:
            return r.w <= self.size[0] and r.h <= self.size[1]
        return Rect.of(*self.anchor, *self.size).contains(r)

    def release(self) -> None:
        self.fbo.release()
        self.tex.release()


class Pyramid:
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
        self._efield: dict = {}  # textures of the exemplar inputs: level -> R_E,l; "avoid" -> the mask
        self._dummy = gpu.u16_texture(np.full((1, 1), 32768, np.uint16))
        self._dummy_i = gpu.ctx.texture((2, 1), 4, np.zeros(8, np.int32).tobytes(), dtype="i4")
        self.controls = NO_CONTROLS
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
            self.controls = controls
        old = getattr(self, "_signatures", None)
        self.params = params
        self._signatures = self._level_signatures()
        self.corrected = params.correcting_levels()
        radius = fixed.read_radius(self.an.model)
        self.margins = [correction_margins(params.subgrid, params.passes_at(l), radius,
                                           ((params.fidelity_at(l), params.fidelity_radius),))
                        for l in range(self.an.L + 1)]
        if old is None:
            return
        first = next((l for l in range(self.an.L + 1) if old[l] != self._signatures[l]), None)
        if first is not None:
            self.invalidate(first)

    def update_controls(self, controls: Controls, changed: list[Rect] | None = None) -> int:
        """Adopt new controls that differ from the current ones only inside the
        finest-level canvas rectangles ``changed`` (painted randomness, placed
        features; None: computed from the two controls), re-synthesizing in
        place just what that changes in the held buffers.

        Level by level, coarse to fine: the inputs that changed are the pixels
        whose field value changed and the children of the parent pixels whose
        value actually changed; the dirty region is those grown by the reach of
        correction (outside it no result can change), clipped to what the level
        holds, and synthesized again as strips. Comparing each strip with what
        it held before tells which pixels actually changed, and only those
        reach the next level. The result is bit-identical to synthesizing from
        scratch. Areas not held now cost
        nothing and are synthesized with the new controls when shown.
        Returns the number of level pixels synthesized."""
        controls = controls.normalized()
        controls.validate(self.an.size, self.an.settings.lattice)
        self.gpu.activate()
        if changed is None:
            rects = self.controls.changed_rects(controls)
            changed = None if rects is None else [Rect(*r) for r in rects]
        if changed is None or controls.exemplar_inputs() != self.controls.exemplar_inputs():
            self.set_params(self.params, controls)  # the whole canvas changes
            return 0
        self.controls = controls
        self._signatures = self._level_signatures()
        L = self.an.L
        total = 0
        parent_changed: list[Rect] = []
        for l in range(L + 1):
            k = L - l
            buf = self.buffers[l]
            if buf is None or buf.valid is None:
                break  # finer levels hold nothing this could have reached
            # Inputs that changed: where the field changed, and the children of
            # the parent pixels whose values actually changed.
            inputs = [Rect(r.x0 >> k, r.y0 >> k, -((-r.x1) >> k), -((-r.y1) >> k)) for r in changed if not r.empty]
            inputs += [Rect(2 * r.x0, 2 * r.y0, 2 * r.x1, 2 * r.y1) for r in parent_changed]
            reach = max(self.margins[l])
            dirty = [r.pad(reach, reach, reach, reach).intersect(buf.valid) for r in inputs]
            parent_changed = []
            for r in _merge([r for r in dirty if not r.empty]):
                before = self._read_rect(buf, r)
                total += self._synthesize_strip(l, r, buf)
                diff = np.any(self._read_rect(buf, r) != before, axis=-1)
                if diff.any():  # only pixels whose value changed reach the next level
                    ys, xs = np.nonzero(diff)
                    parent_changed.append(Rect(r.x0 + int(xs.min()), r.y0 + int(ys.min()),
                                               r.x0 + int(xs.max()) + 1, r.y0 + int(ys.max()) + 1))
        self.pixels_synthesized = total
        return total

    def _read_rect(self, buf: _LevelBuffer, r: Rect) -> np.ndarray:
        """The held coordinates of ``r`` (H, W, 2) int16, read back piece by piece."""
        out = np.empty((r.h, r.w, 2), dtype=np.int16)
        for (gx, gy), (tx, ty), w, h in self._texel_pieces(buf, r):
            data = buf.fbo.read(viewport=(tx, ty, w, h), components=2, dtype="i2", alignment=1)
            out[gy - r.y0:gy - r.y0 + h, gx - r.x0:gx - r.x0 + w] = np.frombuffer(data, np.int16).reshape(h, w, 2)
        return out

    def _level_signatures(self) -> list[tuple]:
        """What each level depends on: its parameters and the controls."""
        return [(self.params.level_signature(l), self.controls.level_signature(l, self.an.size))
                for l in range(self.an.L + 1)]

    def invalidate(self, first_level: int = 0) -> None:
        """Forget the contents of levels >= first_level."""
        for l in range(first_level, self.an.L + 1):
            if self.buffers[l] is not None:
                self.buffers[l].valid = None

    # -- geometry -----------------------------------------------------------

    def padded(self, level: int, r: Rect) -> Rect:
        """The region a strip is synthesized on: r plus correction margins, s-aligned."""
        return r.pad(*self.margins[level]).align(self.params.subgrid)

    def plan(self, level: int, rect: Rect) -> list[Rect]:
        """The rectangle each level 0..level must hold exactly for ``rect``."""
        need = [Rect(0, 0, 0, 0)] * (level + 1)
        cur = rect
        for l in range(level, -1, -1):
            need[l] = cur
            cur = self.padded(l, cur).half()
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

    def request(self, level: int, rect: Rect) -> int:
        """Make level ``level`` exact over ``rect`` (and its ancestors as needed).

        Returns the number of level pixels synthesized (0 when all was cached).
        """
        if not 0 <= level <= self.an.L:
            raise SynthesisError(f"Level {level} does not exist (0..{self.an.L}).")
        if rect.empty:
            return 0
        self.gpu.activate()
        lim = COORD_LIMIT >> (self.an.L - level)
        if min(rect.x0, rect.y0) < -lim or max(rect.x1, rect.y1) > lim:
            raise SynthesisError(f"Canvas positions must stay within +-{lim} at level {level}.")
        targets = []
        # Decide every level's rectangle first, fine to coarse: a level needs of
        # its parent only what its *new* strips read; then synthesize coarse to fine.
        need: Rect | None = rect
        for l in range(level, -1, -1):
            if need is None:
                break
            t = self._target(l, need)
            targets.append((l, t))
            buf = self.buffers[l]
            valid = buf.valid if buf is not None else None
            strips = [t] if valid is None else t.minus(valid)
            need = None
            for s in strips:
                r = self.padded(l, s).half()
                need = r if need is None else Rect(min(need.x0, r.x0), min(need.y0, r.y0),
                                                   max(need.x1, r.x1), max(need.y1, r.y1))
        total = 0
        for l, target in reversed(targets):
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
        new = _LevelBuffer(self.gpu, size, self.scrolling, (target.x0, target.y0))
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
        for g0, t0, w, hh in self._texel_pieces(dest, r):
            set_uniforms(prog, region_g0=g0, region_t0=t0)
            dest.fbo.viewport = (t0[0], t0[1], w, hh)
            vao.render(moderngl.TRIANGLES)

    def _update_level(self, l: int, target: Rect) -> int:
        buf = self._ensure_buffer(l, target)
        strips = [target] if buf.valid is None else target.minus(buf.valid)
        count = 0
        for strip in strips:
            count += self._synthesize_strip(l, strip, buf)
        buf.valid = target
        return count

    def _scratch_pair(self, w: int, h: int):
        key = (w, h)
        if key not in self._scratch:
            if len(self._scratch) > 24:
                for a, fa, b, fb in self._scratch.values():
                    for o in (fa, fb, a, b):
                        o.release()
                self._scratch.clear()
            a = self.gpu.int_texture((w, h), 2)
            b = self.gpu.int_texture((w, h), 2)
            self._scratch[key] = (a, self.gpu.ctx.framebuffer([a]), b, self.gpu.ctx.framebuffer([b]))
        return self._scratch[key]

    def _synthesize_strip(self, l: int, strip: Rect, buf: _LevelBuffer) -> int:
        p = self.params
        s = p.subgrid
        an = self.an
        region = self.padded(l, strip)
        qdims = (region.w // s, region.h // s)
        a, fa, b, fb = self._scratch_pair(region.w, region.h)
        h = an.h(l)

        # Upsample + jitter into scratch a (modulated by the randomness fields).
        prog, vao = self.gpu.program("upsample.frag", SUB_S=s)
        if l > 0:
            parent = self.buffers[l - 1]
            assert parent is not None and parent.valid is not None and parent.valid.contains(region.half())
            parent.tex.use(0)
            set_uniforms(prog, parent=0, parent_anchor=parent.anchor, parent_mask=parent.mask)
        ftexs, funi = feature_textures(self.gpu, self.controls, an, l, region, p.level_period(l), self._dummy_i)
        efield = self._efield_texture(l)
        (efield or self._dummy).use(1)
        cvals = None
        if self.controls.randomness_canvas is not None:
            cvals = self.controls.randomness_canvas.region(an.L - l, region.x0, region.y0, region.w, region.h,
                                                           p.level_period(l))
        ctex = self.gpu.u16_texture(cvals) if cvals is not None else None
        (ctex or self._dummy).use(2)
        lshift = self.controls.lattice_shift(an.size, l)
        set_uniforms(prog, has_parent=int(l > 0), origin=(region.x0, region.y0), qdims=qdims, h=h,
                     m=an.size, level=l, seed=p.seed, rq=fixed.jitter_q(p.jitter[l]),
                     period=p.level_period(l), efield=1, eshift=an.L - l, has_efield=int(efield is not None),
                     cfield=2, has_cfield=int(ctex is not None), lattice_shift=lshift or (-1, -1), **funi)
        fa.use()
        fa.viewport = (0, 0, region.w, region.h)
        vao.render(moderngl.TRIANGLES)
        if ctex is not None:
            ctex.release()

        # Correction subpasses, then the fidelity stage's, on scratch a.
        if l in self.corrected:
            lt = self.gan.level(l)
            prog, vao = self.gpu.program("correct.frag", SUB_S=s, **self.gan.correction_defines())
            sims = lt.lattice_sim if lshift is not None else (lt.sim or [self._dummy_i] * 2)
            for unit, tex in enumerate([lt.feat, lt.nbhd] + sims, start=1):
                tex.use(unit)
            set_uniforms(prog, src=0, feat=1, nbhd=2, sim01=3, sim23=4,
                         dims=(region.w, region.h), qdims=qdims, k=an.k, h=h, m=an.size,
                         shift=lt.shift, psi=fixed.psi_q(p.kappa))
            prog["P"].write(lt.proj)
            # Lattice levels keep their lattice candidates only.
            walk = p.walk_steps(an.k, self.controls.avoid is not None) if lshift is None else 0
            avoid = self._avoid_texture()
            (avoid or self._dummy).use(5)
            set_uniforms(prog, walk=walk, origin=(region.x0, region.y0), level=l, period=p.level_period(l),
                         border=-1 if an.toroidal else border_margin(an.size, h),
                         avoid=5, has_avoid=int(avoid is not None))
            run_subpasses(self.gpu, prog, vao, s, subpass_order(s, p.passes_at(l)), qdims, (a, fa, b, fb),
                          lambda n: {"walk_seed": fixed.walk_seed(p.seed, n)})
        if p.fidelity_at(l):
            avoid = self._avoid_texture()
            run_fidelity(self.gpu, self.gan, p, l, region, qdims, lshift is not None, (a, fa, b, fb),
                         avoid or self._dummy, avoid is not None)

        # Write the exact strip back, split where the buffer wraps.
        prog, vao = self.gpu.program("writeback.frag", SUB_S=s)
        a.use(0)
        for unit, tex in zip((3, 6, 7), ftexs or [self._dummy_i] * 3):
            tex.use(unit)
        set_uniforms(prog, src=0, qdims=qdims, src_origin=(region.x0, region.y0), dest_mask=buf.mask,
                     h=h, m=an.size, period=p.level_period(l), **funi)
        buf.fbo.use()
        for piece in self._texel_pieces(buf, strip):
            g0, t0, w, hh = piece
            set_uniforms(prog, region_g0=g0, region_t0=t0)
            buf.fbo.viewport = (t0[0], t0[1], w, hh)
            vao.render(moderngl.TRIANGLES)
        for tex in ftexs:
            tex.release()
        return region.w * region.h

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
        for t in self._efield.values():
            t.release()
        self._efield.clear()

    @staticmethod
    def _texel_pieces(buf: _LevelBuffer, r: Rect):
        """Split r into pieces contiguous in the destination texture."""
        xs, ys = [], []
        for lo, hi, axis, out in ((r.x0, r.x1, 0, xs), (r.y0, r.y1, 1, ys)):
            g = lo
            while g < hi:
                t = (g - buf.anchor[axis]) & buf.mask[axis]
                n = min(hi - g, buf.size[axis] - t)
                out.append((g, t, n))
                g += n
        return [((gx, gy), (tx, ty), nx, ny) for gx, tx, nx in xs for gy, ty, ny in ys]

    # -- reading ------------------------------------------------------------

    def read(self, level: int, rect: Rect) -> np.ndarray:
        """Exemplar coordinates (H, W, 2) int32 as (x, y) over ``rect``; must be valid."""
        buf = self.buffers[level]
        if buf is None or buf.valid is None or not buf.valid.contains(rect):
            raise SynthesisError(f"Level {level} does not hold {rect}; request it first.")
        self.gpu.activate()
        data = np.frombuffer(buf.tex.read(alignment=1), dtype=np.int16).reshape(buf.size[1], buf.size[0], 2)
        tx = (np.arange(rect.x0, rect.x1) - buf.anchor[0]) & buf.mask[0]
        ty = (np.arange(rect.y0, rect.y1) - buf.anchor[1]) & buf.mask[1]
        return data[ty[:, None], tx[None, :]].astype(np.int32)

    def release(self) -> None:
        self.gpu.activate()
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
