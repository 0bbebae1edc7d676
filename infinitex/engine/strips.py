"""How one strip of a pyramid level is synthesized (:class:`Strips`, a part
of :class:`~infinitex.engine.pyramid.Pyramid`: ``Pyramid.strips``, which owns
the textures of the exemplar-space inputs): the strip's padded region, what
every pass over it reads (stages.RegionPass), upsampling with jitter,
the correction and fidelity stage's draws, and the write-back of its exact
interior into a level buffer (split where the buffer wraps).
"""
from __future__ import annotations

from collections.abc import Iterator
from typing import Any

import numpy as np

from . import fixed
from .controls import Controls
from .controls.features import ENTRY_ROW, TABLE_ROW, pack_rows
from .gpu import Gpu
from .params import SynthParams, first_rects, subpass_rects
from .rect import Rect
from .stages import Draw, Pacer, RegionPass, correction_draws, fidelity_draws, label_draws


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


class Strips:
    """Synthesizes strips of the pyramid's levels (uses its buffers, params, controls and state)."""

    def __init__(self, pyr) -> None:
        self.pyr = pyr
        gpu = pyr.gpu
        self._efield: dict = {}  # textures of the exemplar inputs: level -> R_E,l; "avoid" -> the mask; labels
        self._label_typical: dict = {}  # typical distances per level (texture by numbers' weights)
        self._dummy = gpu.u16_texture(np.full((1, 1), 32768, np.uint16))
        self._dummy_i = gpu.ctx.texture((2, 1), 4, np.zeros(8, np.int32).tobytes(), dtype="i4")

    def strip_steps(self, l: int, strip: Rect, scratch, buf: Any,
                     pace: Pacer | None = None, parent: Any = None) -> Iterator[None]:
        """Synthesize ``strip`` of level l into ``buf`` (None: the level's buffer at
        the end, over what it then holds), a draw (or a piece of one, sized by
        ``pace``) per step: upsample + jitter, correction, fidelity stage, on ``scratch``;
        the write-back is the last step. Returns (as the generator's value) the
        rectangle of the pixels that changed, when ``buf`` is None. ``parent``:
        read instead of level l - 1's buffer (a quick look, see looks.py)."""
        rp = self.region_pass(l, strip, scratch)
        try:
            yield from self._upsample_steps(rp, parent, pace)
            # Correction subpasses, then the fidelity stage's, on scratch a, each
            # over what the strip needs of it (not in an atlas, whose reads jump).
            draws = []
            if rp.level_corrected:
                # Lattice levels keep their lattice candidates only.
                walk = self.pyr.params.walk_steps(self.pyr.an.k, self.pyr.controls.avoid is not None) \
                    if rp.lattice_shift is None else 0
                draws += correction_draws(rp, walk)
            if self.pyr.params.fidelity_at(l):
                draws += fidelity_draws(rp)
            for d in draws:
                yield from d.steps(pace)
            return (yield from self._write_back(rp, strip, buf))
        finally:
            rp.release()

    def region_pass(self, l: int, strip: Rect, scratch) -> RegionPass:
        """What every pass over ``strip``'s padded region reads (stages.RegionPass)."""
        p, an = self.pyr.params, self.pyr.an
        region = self.pyr.padded(l, strip)
        ftexs, funi = feature_textures(self.pyr.gpu, self.pyr.controls, an, l, region, p.level_period(l), self._dummy_i)
        cvals = None
        if self.pyr.controls.randomness_canvas is not None:
            cvals = self.pyr.controls.randomness_canvas.region(an.L - l, region.x0, region.y0, region.w, region.h,
                                                           p.level_period(l))
        dtex, ltex, ptex, ddef = self.pyr.state.geometry_textures(l, region)
        corrected = l in self.pyr.corrected
        # Only what the subpasses then read of each phase (not in an atlas, whose reads jump).
        npass = p.passes_at(l) if corrected else 0
        rects, first = (None, None) if ltex is not None else strip_rects(p, an.model, l, npass, strip, region)
        labels = None
        if corrected or p.fidelity_at(l):
            labels = label_draws(self.pyr.gpu, self._efield, self._label_typical, self.pyr.controls, an, p, l, region)
        return RegionPass(self.pyr.gpu, self.pyr.gan, p, l, region, scratch, rects, first,
                          self.pyr.controls.lattice_shift(an.size, l), ftexs, funi,
                          self.pyr.gpu.u16_texture(cvals) if cvals is not None else None, dtex, ltex, ptex, ddef,
                          self._avoid_texture(), labels, self._dummy, self._dummy_i, corrected)

    def _upsample_steps(self, rp: RegionPass, parent: Any, pace: Pacer | None) -> Iterator[None]:
        """Upsample + jitter into scratch a (modulated by the randomness fields):
        the whole region, or per phase what the subpasses then read (``rp.first``)."""
        p, an, l, region = self.pyr.params, self.pyr.an, rp.level, rp.region
        s = p.subgrid
        bstride, boff, tex_size = rp.layout
        prog, vao = self.pyr.gpu.program("upsample.frag", SUB_S=s, **rp.defines)
        efield = self._efield_texture(l)
        textures = {1: efield or self._dummy, 2: rp.canvas_field or self._dummy}
        if rp.direction is not None:
            textures[11] = rp.direction
        if rp.links is not None:
            textures[12] = rp.links
            textures[13] = rp.parent_links or rp.links
        uni: dict = {}
        if l > 0:
            parent = parent or self.pyr.buffers[l - 1]
            assert parent is not None and parent.valid is not None and parent.valid.contains(region.parents())
            textures[0] = parent.tex
            uni = dict(parent=0, parent_anchor=parent.anchor, parent_mask=parent.mask)
        uni.update(has_parent=int(l > 0), origin=(region.x0, region.y0), qdims=rp.qdims, bstride=bstride, boff=boff,
                   h=an.h(l), m=an.size, level=l, seed=p.seed,
                   rq=fixed.jitter_q(self.pyr.controls.jitter_at(p, an.size, l)),
                   period=p.level_period(l), efield=1, eshift=an.L - l, has_efield=int(efield is not None),
                   cfield=2, has_cfield=int(rp.canvas_field is not None), lattice_shift=rp.lattice_shift or (-1, -1),
                   dithered=int(self.pyr.controls.dithered_upsampling),
                   **rp.feature_uniforms, **(dict(dfield=11) if rp.direction is not None else {}),
                   **(dict(links=12, plinks=13, plink_origin=(region.parents().x0, region.parents().y0))
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

    def _write_back(self, rp: RegionPass, strip: Rect, buf: Any) -> Iterator[None]:
        """Write the exact strip back from scratch a, split where the buffer
        wraps; ``buf`` None (a local update): into what the level holds now,
        returning the rectangle of the pixels that changed (or None)."""
        p, an, l, region = self.pyr.params, self.pyr.an, rp.level, rp.region
        s = p.subgrid
        bstride, boff, _ = rp.layout
        deferred = buf is None
        if deferred:
            buf = self.pyr.buffers[l]
            strip = strip.intersect(buf.valid) if buf is not None and buf.valid is not None else Rect(0, 0, 0, 0)
            if strip.empty:
                return None
            before = self.pyr.state.read_rect(buf, strip)
        prog, vao = self.pyr.gpu.program("writeback.frag", SUB_S=s, **rp.defines)
        uni = dict(src=0, qdims=rp.qdims, bstride=bstride, boff=boff, src_origin=(region.x0, region.y0),
                   dest_mask=buf.mask, h=an.h(l), m=an.size, period=p.level_period(l), links=12,
                   **rp.feature_uniforms)  # links: charts (on a model)
        textures = {0: rp.scratch[0], 12: self._dummy_i if rp.links is None else rp.links,
                    **dict(zip((3, 6, 7), rp.features or [self._dummy_i] * 3))}
        # At once and without a pause: a level shown between two pieces
        # would hold pixels the view was not told about (SpreadRequests.touched).
        for g0, t0, w, hh in buf.pieces(strip):
            for _ in Draw(prog, vao, buf.fbo, (t0[0], t0[1], w, hh), textures,
                          dict(uni, region_g0=g0, region_t0=t0), l).steps():
                pass
        if not deferred:
            yield  # (a local update reports what it changed before any frame can draw it: no pause here)
            return None
        diff = np.any(self.pyr.state.read_rect(buf, strip) != before, axis=-1)
        if not diff.any():
            return None
        ys, xs = np.nonzero(diff)
        return Rect(strip.x0 + int(xs.min()), strip.y0 + int(ys.min()),
                    strip.x0 + int(xs.max()) + 1, strip.y0 + int(ys.max()) + 1)

    def _efield_texture(self, l: int):
        e = self.pyr.controls.randomness_exemplar
        if e is None:
            return None
        if l not in self._efield:
            self._efield[l] = self.pyr.gpu.u16_texture(e.level(self.pyr.an.L, l))
        return self._efield[l]

    def _avoid_texture(self):
        a = self.pyr.controls.avoid
        if a is None:
            return None
        if "avoid" not in self._efield:
            self._efield["avoid"] = self.pyr.gpu.u16_texture(a.values)
        return self._efield["avoid"]

    def release_inputs(self) -> None:
        """Drop the textures of the exemplar inputs (the controls' inputs changed)."""
        self.pyr.updates.end_job()  # they may read them
        self.pyr.requests.end()
        for t in self._efield.values():
            t.release()
        self._efield.clear()

    def release(self) -> None:
        self.release_inputs()
        if self._dummy is not None:
            self._dummy.release()
            self._dummy_i.release()
            self._dummy = self._dummy_i = None
