"""The frames of a flowing texture composed in GL (engine/advect.py says what
they are; its numpy ``FlowFrames._frame`` is the oracle these passes equal bit
for bit): ``shaders/flow_step.frag`` extends the trajectories a frame,
``flow_chain.frag`` looks each chain up in the static texture and gives its
blobs' turns, ``flow_pick.frag`` votes, chooses and finds the seams. The
static windows are synthesized once a chain (SynthSource) and uploaded once;
a frame played in order steps the last frame's trajectories.

Without a direction field only (a field's J turns the sub-pixel rest: the
numpy composition does it).
"""
from __future__ import annotations

import moderngl
import numpy as np

from .controls.flow import Q
from .gpu import set_uniforms
from .rect import Rect


class GpuComposer:
    """Composes FlowFrames' windows on ``source``'s GL context."""

    def __init__(self, frames, source, vote: int, seam: int, blob: int, nudge: int, key_radius: int):
        self.frames = frames  # (FlowFrames: the flow, its chains and their key offsets and seeds)
        self.source = source
        self.gpu = source.synth.gpu
        self.vote, self.seam, self.blob, self.nudge = vote, seam, blob, nudge
        self.key_radius = key_radius  # px: every R_j is within it (engine/advect.py)
        self._rect: Rect | None = None
        self._paths: dict[int, object] = {}  # age -> RG32I texture of the trajectories
        self._chains: dict[tuple, tuple] = {}  # (key, born) -> (still, still units, origin, moved, ..., origin)
        flow = frames.flow
        vm = flow.map
        if vm is None:
            vals = np.zeros((1, 1, 2), np.int32)
            self._map_xy, self._map_wh = (0, 0), (0, 0)
        else:
            vals = vm.values
            self._map_xy, self._map_wh = (vm.x, vm.y), (vals.shape[1], vals.shape[0])
        bordered = np.zeros((vals.shape[0] + 4, vals.shape[1] + 4, 2), np.int32)
        bordered[2:-2, 2:-2] = vals
        self._vmap = self.gpu.texture((bordered.shape[1], bordered.shape[0]), 2, bordered, "i4")
        self._has_map = int(not flow.uniform)
        self._palette = None  # (key, texture, array) of draft_colors' map

    # -- textures ---------------------------------------------------------------
    def _tex(self, w: int, h: int, comps: int, dtype: str, data=None):
        return self.gpu.texture((w, h), comps, data, dtype)

    def _draw(self, prog, vao, targets: list, w: int, h: int, textures: dict, **uniforms) -> None:
        fbo = self.gpu.ctx.framebuffer(color_attachments=targets)
        try:
            fbo.use()
            fbo.viewport = (0, 0, w, h)
            for unit, tex in textures.items():
                tex.use(unit)
            set_uniforms(prog, **uniforms)
            vao.render(moderngl.TRIANGLES)
        finally:
            fbo.release()

    def _read(self, tex, w: int, h: int, comps: int, dtype: str, np_dtype) -> np.ndarray:
        fbo = self.gpu.ctx.framebuffer(color_attachments=[tex])
        try:
            data = fbo.read(viewport=(0, 0, w, h), components=comps, dtype=dtype, alignment=1)
        finally:
            fbo.release()
        return np.frombuffer(data, np_dtype).reshape(h, w, comps)

    # -- trajectories -------------------------------------------------------------
    def _window(self, win: Rect) -> None:
        if win != self._rect:
            self._drop_paths()
            self._rect = win

    def _drop_paths(self, keep=()) -> None:
        for age in [a for a in self._paths if a not in keep]:
            self._paths.pop(age).release()

    def trajectory(self, age: int):
        """The trajectories of age ``age`` over the window plus one column and row (RG32I)."""
        if age in self._paths:
            return self._paths[age]
        win = self._rect
        w, h = win.w + 1, win.h + 1
        start = age - 1 if age - 1 in self._paths else 0
        cur = self._paths[start] if start else self._tex(w, h, 2, "i4", np.zeros((h, w, 2), np.int32))
        prog, vao = self.gpu.program("flow_step.frag", SUB_S=2)
        flow = self.frames.flow
        for _ in range(start, age):
            nxt = self._tex(w, h, 2, "i4")
            self._draw(prog, vao, [nxt], w, h, {0: cur, 1: self._vmap}, path=0, vmap=1, origin=(win.x0, win.y0),
                       map_xy=self._map_xy, map_wh=self._map_wh, velocity=tuple(flow.velocity),
                       period=self.source.period, has_map=self._has_map)
            if cur is not self._paths.get(start):
                cur.release()
            cur = nxt
        self._paths[age] = cur
        return cur

    # -- chains -------------------------------------------------------------------
    def _static(self, key: int, born: int, win: Rect):
        """The static windows a chain reads (uploaded once for its life)."""
        ck = (key, born, win)
        if ck not in self._chains:
            while len(self._chains) > 3:  # two chains are alive at a time
                _release(self._chains.pop(next(iter(self._chains))))
            flow, src = self.frames.flow, self.source
            n = src.period
            bx, by = _split(flow.velocity[0] * born)[0], _split(flow.velocity[1] * born)[0]
            reach = flow.reach(2 * flow.period) + 2
            parts = []
            rx, ry = self.frames.key_offset(key)
            if not n:  # one synthesis for this chain and the next few: every R_j, four periods of travel
                src.window(self._union(win, born, reach), 0)
            for ox, oy in ((0, 0), (rx, ry)):
                if n:
                    box = Rect(0, 0, n, n)
                else:
                    box = Rect(win.x0 - bx + ox - reach, win.y0 - by + oy - reach,
                               win.x1 - bx + ox + reach, win.y1 - by + oy + reach)
                coords, units = src.window(box, 0)  # (the box covers the chain's life)
                u32 = (np.asarray(units, np.int64) & 0xFFFFFFFF).astype(np.uint32).view(np.int32)
                parts += [self._tex(box.w, box.h, 4, "i2", coords.astype(np.int16)),
                          self._tex(box.w, box.h, 2, "i4", np.ascontiguousarray(u32)), (box.x0, box.y0)]
                if not (rx or ry):
                    parts += parts[:]
                    break
            self._chains[ck] = tuple(parts)
        return self._chains[ck]

    def _union(self, win: Rect, born: int, reach: int) -> Rect:
        """What the static windows of the chains born at ``born`` and in the next
        four periods read over ``win``: one synthesis (SynthSource keeps it)."""
        flow = self.frames.flow
        pad = reach + (self.key_radius if not flow.uniform else 0)
        x0 = win.x0 - _split(flow.velocity[0] * born)[0] - pad
        y0 = win.y0 - _split(flow.velocity[1] * born)[0] - pad
        ahead = [-(-abs(v) * 4 * flow.period // Q) for v in flow.velocity]  # px, up
        ex = (ahead[0] if flow.velocity[0] < 0 else 0, ahead[0] if flow.velocity[0] > 0 else 0)
        ey = (ahead[1] if flow.velocity[1] < 0 else 0, ahead[1] if flow.velocity[1] > 0 else 0)
        # (later chains read farther against the velocity: T at p - V0 t_j)
        return Rect(x0 - ex[1], y0 - ey[1], x0 + win.w + 2 * pad + ex[0], y0 + win.h + 2 * pad + ey[0])

    def _chain(self, key: int, born: int, age: int, win: Rect, turns_wanted: bool = True):
        """(coordinates RGBA16I, turns R32I: 0 without ``turns_wanted``) of one chain over the window."""
        flow, src = self.frames.flow, self.source
        still, still_u, still_o, moved, moved_u, moved_o = self._static(key, born, win)
        bpx, bfx = _split(flow.velocity[0] * born)
        bpy, bfy = _split(flow.velocity[1] * born)
        rx, ry = self.frames.key_offset(key)
        coords = self._tex(win.w, win.h, 4, "i2")
        turns = self._tex(win.w, win.h, 1, "i4")
        prog, vao = self.gpu.program("flow_chain.frag", SUB_S=2)
        seed = self.frames.turn_seed(key)
        self._draw(prog, vao, [coords, turns], win.w, win.h,
                   {0: self.trajectory(age), 1: still, 2: still_u, 3: moved, 4: moved_u, 5: self._vmap},
                   path=0, still=1, still_units=2, moved=3, moved_units=4, vmap=5,
                   still_origin=still_o, moved_origin=moved_o, map_xy=self._map_xy, map_wh=self._map_wh,
                   has_offset=int(bool(rx or ry)), offset=(rx, ry), origin=(win.x0, win.y0),
                   born_px=(bpx, bpy), born_frac=(bfx, bfy), period=src.period, m=src.m, wrap=int(src.wrap),
                   seed=seed, blob=self.blob, nudge=self.nudge, want_turns=int(turns_wanted))
        return coords, turns

    # -- a frame ------------------------------------------------------------------
    def frame(self, t: int, rect: Rect) -> tuple[np.ndarray, np.ndarray]:
        """(coordinates (H, W, 4) int32, seams (H, W) bool) of frame t over rect, as FlowFrames._frame."""
        e = self.seam
        made = []
        try:
            chosen, seams = self._compose(t, rect, made, seams_wanted=True)
            H, W = rect.h + 2 * e, rect.w + 2 * e
            coords = self._read(chosen, W, H, 4, "i2", np.int16)[e:-e or None, e:-e or None].astype(np.int32)
            seam = self._read(seams, rect.w, rect.h, 1, "i4", np.int32)[..., 0] != 0
            return coords, seam
        finally:
            for tex in made:
                tex.release()

    def draft_colors(self, t: int, rect: Rect, palette: np.ndarray) -> np.ndarray:
        """Frame t over rect as RGB8 without the correction of its cuts, its colors
        sampled here (``palette``: the map, uint8 (m, m, C)): what the editor plays.
        The same coordinates as :meth:`frame`; the colors within a level of
        8 bits of engine/subpixel.py's (bilinear in the map's 8 bits, not in floats)."""
        e = self.seam
        made = []
        try:
            chosen, _ = self._compose(t, rect, made, seams_wanted=False)
            key = (palette.__array_interface__["data"][0], palette.shape)
            if self._palette is None or self._palette[0] != key:
                if self._palette is not None:
                    self._palette[1].release()
                m = palette.shape[0]
                tex = self.gpu.ctx.texture((m, m), palette.shape[2], np.ascontiguousarray(palette).tobytes(),
                                           dtype="f1", alignment=1)
                self._palette = (key, tex, palette)  # (the array kept: its address stays its own)
            rgba = self._tex(rect.w, rect.h, 4, "f1")
            made.append(rgba)
            prog, vao = self.gpu.program("flow_color.frag", SUB_S=2)  # (common.glsl wants it)
            self._draw(prog, vao, [rgba], rect.w, rect.h, {0: chosen, 1: self._palette[1]}, coords=0, palette=1,
                       m=self.source.m, wrap=int(self.source.wrap), channels=int(palette.shape[2]), margin=e)
            return self._read(rgba, rect.w, rect.h, 4, "f1", np.uint8)[..., :3].copy()
        finally:
            for tex in made:
                tex.release()

    def _compose(self, t: int, rect: Rect, made: list, seams_wanted: bool):
        """The chosen coordinates over rect plus SEAM a side (RGBA16I) and the
        seams over rect (R32I; None without ``seams_wanted``); every texture
        made goes to ``made``."""
        old, new = self.frames.chains(t)
        v, e = self.vote, self.seam
        win = Rect(rect.x0 - v - e, rect.y0 - v - e, rect.x1 + v + e, rect.y1 + v + e)
        self.gpu.activate()
        self._window(win)
        made += self._chain(*old, win, turns_wanted=False)  # (the old chain's turns have passed)
        c0 = made[-2]
        made += self._chain(*new, win)
        c1, turns = made[-2], made[-1]
        self._drop_paths(keep={old[2], new[2]})
        H, W = rect.h + 2 * e, rect.w + 2 * e
        due = ((new[2] + 1) << 16) // self.frames.flow.period
        take = self._tex(W, H, 1, "i4")
        junk = self._tex(W, H, 4, "i2")
        chosen = self._tex(W, H, 4, "i2")
        cuts = self._tex(W, H, 1, "i4")
        made += [take, junk, chosen, cuts]
        defines = dict(SUB_S=2, VOTE=v, SEAM=e)
        prog, vao = self.gpu.program("flow_pick.frag", STAGE=0, **defines)
        self._draw(prog, vao, [junk, take], W, H, {0: turns}, a=0, due=due, margin=v)
        prog, vao = self.gpu.program("flow_pick.frag", STAGE=1, **defines)
        self._draw(prog, vao, [chosen, cuts], W, H, {0: take, 1: c0, 2: c1}, a=0, c0=1, c1=2, margin=v)
        if not seams_wanted:
            return chosen, None
        seams = self._tex(rect.w, rect.h, 1, "i4")
        junk2 = self._tex(rect.w, rect.h, 4, "i2")
        made += [seams, junk2]
        prog, vao = self.gpu.program("flow_pick.frag", STAGE=2, **defines)
        self._draw(prog, vao, [junk2, seams], rect.w, rect.h, {0: cuts}, a=0, margin=e)
        return chosen, seams

    def release(self) -> None:
        if self._palette is not None:
            self._palette[1].release()
            self._palette = None
        self._drop_paths()
        for parts in self._chains.values():
            _release(parts)
        self._chains.clear()
        self._vmap.release()


def _release(parts: tuple) -> None:
    """Release a chain's textures (the same ones twice over when it has no key offset)."""
    seen = set()
    for t in parts:
        if hasattr(t, "release") and id(t) not in seen:
            seen.add(id(t))
            t.release()


def _split(q8: int) -> tuple[int, int]:
    """(floor(q8 / 256), q8 mod 256): a position in 1/256 px as whole and fractional pixels."""
    return q8 >> 8, q8 & (Q - 1)
