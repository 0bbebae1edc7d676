"""How the pyramid's state textures are laid out and read back
(:class:`StateAccess`, a part of :class:`~infinitex.engine.pyramid.Pyramid`:
``Pyramid.state``):
2 components per texel (the exemplar coordinate), or 4 with a direction field
or in a mesh's atlas
(the nearest texel and the sub-pixel remainder in 1/256 px,
engine/controls/direction.py); the J textures of a region; reading coordinates back;
widening it for a first direction field; correcting a given state
(:meth:`StateAccess.correct`).
"""
from __future__ import annotations

import moderngl
import numpy as np

from .controls.direction import IDENTITY
from .gpu import set_uniforms
from .rect import Rect
from .stages import correction_draws, fidelity_draws


class SynthesisError(ValueError):
    """A request the synthesis cannot serve (e.g. coordinates out of range)."""


class StateAccess:
    """The pyramid's state format and read-back (uses its GPU, controls, buffers and params)."""

    def __init__(self, pyr) -> None:
        self.pyr = pyr

    @property
    def channels(self) -> int:
        """Components of a state texel: 4 with a direction field (nearest texel, remainder), else 2."""
        return 4 if self.pyr.controls.directed else 2

    def direction_texture(self, l: int, region: Rect):
        """J_l over a padded region (RGBA16I, row-major local pixels), or None
        without a direction field; its ``extra``: whether the region holds
        pixels where J_l is the identity, and the box (x0, y0, x1, y1) of those
        where it is not (local pixels; None: none)."""
        if not self.pyr.controls.directed:
            return None
        surface = self.pyr.controls.surface
        if surface is not None:
            vals = surface.jacobians(self.pyr.an.L - l, region.x0, region.y0, region.w, region.h)
        else:
            vals = self.pyr.controls.direction.region(self.pyr.an.L - l, region.x0, region.y0, region.w, region.h,
                                                  self.pyr.params.period)
        kinds = (True, None)  # the fidelity stage's draws (stages.fidelity_draws)
        if vals is None:
            vals = np.broadcast_to(IDENTITY, (region.h, region.w, 4))
        else:
            upright = (vals == IDENTITY).all(axis=-1)
            if not upright.all():
                ys, xs = np.nonzero(~upright)
                kinds = (bool(upright.any()), (int(xs.min()), int(ys.min()), int(xs.max()) + 1, int(ys.max()) + 1))
        tex = self.pyr.gpu.int_texture((region.w, region.h), 4, vals)
        tex.extra = kinds
        return tex

    def geometry_textures(self, l: int, region: Rect) -> tuple:
        """What the passes read of the region's geometry: J (or None), the atlas'
        indirection maps of the level and of its parent (or None), and the shader defines."""
        dtex = self.direction_texture(l, region)
        ltex = self.links_texture(l, region)
        ptex = self.links_texture(l - 1, region.parents()) if ltex is not None and l > 0 else None
        return dtex, ltex, ptex, {**(dict(DIRECTION=True) if dtex is not None else {}),
                                  **(dict(ATLAS=True) if ltex is not None else {})}

    def links_texture(self, l: int, region: Rect):
        """The indirection map of a mesh's atlas over a region of level l
        (RGBA16I: own chart, the chart its link serves, the link's target), or
        None when not synthesizing in an atlas (engine/surface/atlas.py)."""
        surface = self.pyr.controls.surface
        if surface is None:
            return None
        return self.pyr.gpu.int_texture((region.w, region.h), 4, surface.links(self.pyr.an.L - l, region.x0, region.y0,
                                                                           region.w, region.h))

    def widen(self) -> None:
        """From 2 to 4 components per texel (a direction field painted for the
        first time): every held texel keeps its coordinate, with a remainder of
        0, which is the same state, so only what the field changes is
        synthesized again. A request in progress is dropped (the next frame asks
        again); a local update in progress is finished first."""
        pyr = self.pyr
        pyr.requests.end()
        if pyr.updates.updating:  # finished first (with what it began with), so what it changed reaches the next level
            pyr.updates.settle(None, regions=1)
        prog, vao = pyr.gpu.program("remap.frag", SUB_S=pyr.params.subgrid, WIDEN=True)
        for buf in pyr.buffers:
            if buf is None or buf.channels == 4:
                continue
            tex = pyr.gpu.int_texture(buf.size, 4)
            fbo = pyr.gpu.ctx.framebuffer(color_attachments=[tex])
            buf.tex.use(0)  # texel for texel, on the GPU
            set_uniforms(prog, src=0, src_anchor=(0, 0), src_mask=(-1, -1), dest_mask=(-1, -1),
                         region_g0=(0, 0), region_t0=(0, 0))
            fbo.use()
            fbo.viewport = (0, 0, *buf.size)
            vao.render(moderngl.TRIANGLES)
            buf.fbo.release()
            buf.tex.release()
            buf.tex, buf.fbo, buf.channels = tex, fbo, 4
        pyr.drop_scratch()

    def read_rect(self, buf, r: Rect) -> np.ndarray:
        """The held state of ``r`` (H, W, channels) int16, read back piece by piece."""
        c = buf.channels
        out = np.empty((r.h, r.w, c), dtype=np.int16)
        for (gx, gy), (tx, ty), w, h in buf.pieces(r):
            data = buf.fbo.read(viewport=(tx, ty, w, h), components=c, dtype="i2", alignment=1)
            out[gy - r.y0:gy - r.y0 + h, gx - r.x0:gx - r.x0 + w] = np.frombuffer(data, np.int16).reshape(h, w, c)
        return out

    def read(self, level: int, rect: Rect, remainder: bool = False) -> np.ndarray:
        """Exemplar coordinates (H, W, 2) int32 as (x, y) over ``rect`` (the nearest
        texels); must be valid. ``remainder``: (H, W, 4), the sub-pixel remainders
        in 1/256 px after them (0 without a direction field)."""
        buf = self.pyr.buffers[level]
        if buf is None or buf.valid is None or not buf.valid.contains(rect):
            raise SynthesisError(f"Level {level} does not hold {rect}; request it first.")
        self.pyr.gpu.activate()
        c = buf.channels
        # Only the rectangle's texels come back (in at most four pieces where the buffer wraps).
        data = self.read_rect(buf, rect)
        if remainder:
            out = np.zeros((rect.h, rect.w, 4), np.int32)
            out[..., :c] = data
            return out
        return data[..., :2].astype(np.int32)

    def correct(self, l: int, strip: Rect, state: np.ndarray) -> np.ndarray:
        """Level l's correction (and fidelity stage) run on a given state instead
        of the upsampled one: ``state`` (H, W, channels) over ``padded(l, strip)``;
        returns the corrected strip, exact (a function of the state within the
        correction's reach; engine/advect.py corrects the frames of a flow so)."""
        region = self.pyr.padded(l, strip)
        if state.shape[:2] != (region.h, region.w):
            raise SynthesisError(f"The state to correct covers {state.shape[1]}x{state.shape[0]}, not the "
                                 f"padded {region.w}x{region.h}.")
        self.pyr.gpu.activate()
        scratch = self.pyr.scratch_pair(region)
        rp = self.pyr.strips.region_pass(l, strip, scratch)
        try:
            s = self.pyr.params.subgrid
            bstride, boff, size = rp.layout
            ys, xs = np.mgrid[0:region.h, 0:region.w]
            ty = boff[1] + (ys % s) * bstride[1] + ys // s
            tx = boff[0] + (xs % s) * bstride[0] + xs // s
            packed = np.zeros((size[1], size[0], self.channels), np.int16)
            packed[ty, tx] = state[..., :self.channels]
            scratch[0].write(packed.tobytes(), viewport=(0, 0, size[0], size[1]), alignment=1)
            draws = []
            if rp.level_corrected:
                draws += correction_draws(rp, self.pyr.params.walk_steps(self.pyr.an.k, self.pyr.controls.avoid is not None))
            if self.pyr.params.fidelity_at(l):
                draws += fidelity_draws(rp)
            for d in draws:
                for _ in d.steps():
                    pass
            data = scratch[1].read(viewport=(0, 0, size[0], size[1]), components=self.channels, dtype="i2",
                                   alignment=1)
            out = np.frombuffer(data, np.int16).reshape(size[1], size[0], self.channels)
            y, x = slice(strip.y0 - region.y0, strip.y1 - region.y0), slice(strip.x0 - region.x0, strip.x1 - region.x0)
            return out[ty[y, x], tx[y, x]].astype(np.int32)
        finally:
            rp.release()
