"""Canvas drawing: synthesized coordinates to screen pixels, on the GPU.

The canvas is rendered into its own RGBA8 texture (shown by the UI with
``imgui.image``). Each frame draws the finest pyramid level that covers the
view, then any finer level that is only partly refined on top of it, so the
texture appears coarse first and sharpens band by band.
"""
from __future__ import annotations

import math
import os

import moderngl
import numpy as np
from PIL import Image

from infinitex.engine.gpu import Gpu, build_program, set_uniforms
from infinitex.engine.imagefile import to_u8
from infinitex.engine.pyramid import Pyramid
from infinitex.engine.rect import Rect
from infinitex.project import Display, View

from ..session import Frame, level_rect

SHADER_DIR = os.path.join(os.path.dirname(__file__), "shaders")
MODES = {"color": 0, "coords": 1, "patches": 2, "level": 3, "relief": 4, "lit": 5}
SHAPE_KINDS = {"normal": 0, "height": 1}
MAX_HIRES = 4096
REDRAW_PX = 160_000  # canvas pixels redrawn a frame where the synthesis changed texels (redraw)
PREVIEW_MAX_K = 3  # the coarsest level drawn: the view's less this many (texels at most 8 screen px)
FEATHER_TEXELS = 6.0  # a quick look's patch blends in over this many texels from its edges


class Canvas:
    def __init__(self, gpu: Gpu):
        self.gpu = gpu
        self._programs: dict[tuple, tuple] = {}  # (mode, mag, alpha, shape kind) -> (program, vao)
        self.size = (0, 0)
        self.tex: moderngl.Texture | None = None
        self.fbo: moderngl.Framebuffer | None = None
        self.stack_tex: moderngl.TextureArray | None = None
        self.hires_tex: moderngl.Texture | None = None
        self.exemplar_tex: moderngl.Texture | None = None
        self.shape_tex: moderngl.TextureArray | None = None  # "lit": the normal or height map's stack (half floats)
        self.shape_kind = 1
        self.shape_key: tuple | None = None
        self.shown: tuple | None = None  # (generation, map) of the stack uploaded
        self.generation = -1
        self.m = 0
        self.channels = 3
        self.toroidal = False
        self.shown_key: tuple | None = None  # what the texture shows (redraw)
        self.pending: tuple[int, int, int, int] | None = None  # a box still to redraw (redraw)

    # -- exemplar textures ----------------------------------------------------

    def set_exemplar(self, stack_u8: np.ndarray, toroidal: bool, hires: np.ndarray | None, generation: int) -> None:
        """Upload the uint8 stack (L+1, m, m, C) and, if given, the float hires exemplar."""
        self.gpu.activate()
        self._release_exemplar()
        n, m = stack_u8.shape[0], stack_u8.shape[1]
        rgba = to_rgba(stack_u8)
        ctx = self.gpu.ctx
        self.stack_tex = ctx.texture_array((m, m, n), 4, np.ascontiguousarray(rgba).tobytes())
        self.stack_tex.filter = (moderngl.LINEAR, moderngl.LINEAR)
        self.stack_tex.repeat_x = self.stack_tex.repeat_y = bool(toroidal)
        self.exemplar_tex = ctx.texture((m, m), 4, np.ascontiguousarray(rgba[-1]).tobytes())  # panel thumbnail
        if hires is not None:
            hi = to_u8(hires)
            if hi.shape[0] > MAX_HIRES:
                img = Image.fromarray(hi[..., 0] if hi.shape[2] == 1 else hi)
                hi = np.asarray(img.resize((MAX_HIRES, MAX_HIRES), Image.LANCZOS)).reshape(MAX_HIRES, MAX_HIRES, -1)
            hi = to_rgba(hi[None])[0]
            self.hires_tex = ctx.texture((hi.shape[1], hi.shape[0]), 4, np.ascontiguousarray(hi).tobytes())
            self.hires_tex.build_mipmaps()
            self.hires_tex.filter = (moderngl.LINEAR_MIPMAP_LINEAR, moderngl.LINEAR)
            self.hires_tex.repeat_x = self.hires_tex.repeat_y = bool(toroidal)
        self.generation = generation
        self.m = m
        self.channels = stack_u8.shape[3]
        self.toroidal = bool(toroidal)

    def set_shape(self, stack: list[np.ndarray], kind: str, toroidal: bool, key: tuple) -> None:
        """Upload the map that shapes the lit preview: a normal map's stack
        (encoded normals, RGB) or a height stack (1 channel), float32 levels
        (L+1) of (m, m, C), kept as half floats (11 bits: no stair steps)."""
        self.gpu.activate()
        if self.shape_tex is not None:
            self.shape_tex.release()
            self.shape_tex = None
        n, m = len(stack), stack[0].shape[0]
        a = np.zeros((n, m, m, 4), dtype=np.float16)
        for i, lv in enumerate(stack):
            a[i, :, :, :lv.shape[2]] = lv[..., :4]
        self.shape_tex = self.gpu.ctx.texture_array((m, m, n), 4, np.ascontiguousarray(a).tobytes(), dtype="f2")
        self.shape_tex.filter = (moderngl.LINEAR, moderngl.LINEAR)
        self.shape_tex.repeat_x = self.shape_tex.repeat_y = bool(toroidal)
        self.shape_kind = SHAPE_KINDS[kind]
        self.shape_key = key

    def _program(self, mode: int, mag: int, alpha: int, shape_kind: int, direction: bool = False,
                 feather: bool = False):
        """The canvas program compiled for one kind of draw (see canvas.frag)."""
        key = (mode, mag, alpha, shape_kind, direction, feather)
        if key not in self._programs:
            ctx = self.gpu.ctx
            prog = build_program(ctx, ["fullscreen.vert"], [os.path.join(SHADER_DIR, "canvas.frag")],
                                 dict(MODE=mode, MAG=mag, ALPHA=alpha, SHAPE_KIND=shape_kind,
                                      DIRECTION=direction, FEATHER=feather))
            self._programs[key] = (prog, ctx.vertex_array(prog, [(self.gpu.quad, "2f", "in_pos")]))
        return self._programs[key]

    @property
    def has_hires(self) -> bool:
        return self.hires_tex is not None

    # -- drawing --------------------------------------------------------------

    def ensure_size(self, w: int, h: int) -> None:
        self.gpu.activate()
        w, h = max(1, int(w)), max(1, int(h))
        if (w, h) == self.size and self.tex is not None:
            return
        if self.tex is not None:
            self.fbo.release()
            self.tex.release()
        self.tex = self.gpu.ctx.texture((w, h), 4)
        self.tex.filter = (moderngl.NEAREST, moderngl.NEAREST)
        self.fbo = self.gpu.ctx.framebuffer([self.tex])
        self.size = (w, h)

    def shows(self, frame: Frame, view: View, display: Display, geom: np.ndarray | None,
              size: tuple[int, int]) -> bool:
        """Whether the texture holds a full drawing of this view (of whatever
        source): what is kept while a change's preview is not presentable."""
        key = self.shown_key
        return (key is not None and self.pending is None and tuple(size) == tuple(self.size)
                and key[1:] == self._view_key(frame, view, display, geom))

    def _view_key(self, frame: Frame, view: View, display: Display, geom: np.ndarray | None) -> tuple:
        """What a drawing depends on besides its source."""
        return (frame, view, display, self.size, None if geom is None else tuple(np.ravel(geom)))

    def redraw(self, pyramid: Pyramid, frame: Frame, view: View, display: Display, geom: np.ndarray | None,
               source: tuple, force: bool = False) -> None:
        """Bring the texture up to date for this frame: drawn whole when the view,
        the display or ``source`` (what the pyramid is synthesized from) changed,
        else only where the synthesis changed texels since the last call (a band
        of the view's level is cheap; the whole canvas magnified is not: about
        25 ms on llvmpipe, so a redraw of more than REDRAW_PX canvas pixels is
        spread over frames, that many a frame, the rest kept in ``pending``)."""
        key = (source, *self._view_key(frame, view, display, geom))
        touched = pyramid.requests.take_touched()
        if key != self.shown_key or force or touched is None:
            self.render(pyramid, frame, view, display, geom)
            self.shown_key = key
            self.pending = None
            return
        if touched:
            L = len(pyramid.buffers) - 1
            box = union_box(self.screen_box(l, r, L, view, geom) for l, r in touched)
            if box is not None and box[2] * box[3] <= REDRAW_PX:
                self.render(pyramid, frame, view, display, geom, box=box)  # (a dab's quick look: at once)
            elif box is not None:
                self.pending = box if self.pending is None else union_box([self.pending, box])
        if self.pending is not None:
            x, y, w, h = self.pending
            rows = max(1, min(h, REDRAW_PX // max(1, w)))
            self.render(pyramid, frame, view, display, geom, box=(x, y, w, rows))
            self.pending = (x, y + rows, w, h - rows) if rows < h else None

    def render(self, pyramid: Pyramid | None, frame: Frame | None, view: View, display: Display,
               geom: np.ndarray | None = None, box: tuple[int, int, int, int] | None = None) -> int:
        """Draw into the canvas texture; returns the coarsest level drawn (-1: none).

        ``geom`` (2x2): the view is in a lattice's input geometry and this maps
        its positions to the synthesized (rectified) canvas. ``box`` (x, y, w,
        h in canvas pixels, as :meth:`screen_box` gives them): redraw only there
        (what the pyramid changed since a full render of the same view), each
        pixel exactly as a full render draws it."""
        self.gpu.activate()
        self.fbo.use()
        self.fbo.viewport = (0, 0, *self.size)
        self.gpu.ctx.scissor = box
        self.gpu.ctx.clear(0.16, 0.16, 0.17, 1.0)
        try:
            if pyramid is None or frame is None or self.stack_tex is None:
                return -1
            return self._draw_levels(pyramid, frame, view, display, geom, box)
        finally:
            self.gpu.ctx.scissor = None

    def _draw_levels(self, pyramid: Pyramid, frame: Frame, view: View, display: Display,
                     geom: np.ndarray | None, box: tuple[int, int, int, int] | None) -> int:
        L = len(pyramid.buffers) - 1
        tlx, tly, G = self._origin(view, geom)
        ix, iy = math.floor(tlx), math.floor(tly)
        M = G / view.zoom  # screen pixel -> finest-level canvas pixel
        want_box = frame.want if box is None else self._level_box(box, frame.level, L, tlx, tly, M)
        levels = []
        # Levels coarser than the view's less PREVIEW_MAX_K are never drawn: magnified
        # 16x and more they show melted elements and smears, not the texture. Where
        # none finer is held yet (a strip a fast pan uncovers, a view just opened),
        # the canvas stays empty for the few frames until one is.
        for l in range(frame.level, max(-1, frame.level - PREVIEW_MAX_K - 1), -1):
            buf = pyramid.buffers[l]
            if buf is None or buf.valid is None:
                continue
            want = level_rect(want_box, frame.level, l)
            inter = want.intersect(buf.valid)
            if inter.empty:
                continue
            levels.append(l)
            if buf.valid.contains(want):  # it covers what is drawn: coarser levels would be hidden
                break
        if not levels:
            return -1
        mode = MODES.get(display.mode, 0)
        if mode == MODES["lit"] and self.shape_tex is None:
            mode = MODES["relief"]
        self.stack_tex.use(1)
        if self.hires_tex is not None:
            self.hires_tex.use(2)
        if self.shape_tex is not None:
            self.shape_tex.use(3)
        az, el = math.radians(display.light_azimuth), math.radians(display.light_elevation)
        light = (math.cos(el) * math.cos(az), math.cos(el) * math.sin(az), math.sin(el))
        alpha = int(self.channels in (2, 4))
        # Coarse first, finer partial levels on top; then the quick looks at the
        # edits (QuickLooks.look) over the shown level until it is exact
        # there, blended in at their edges.
        draws = [(l, pyramid.buffers[l], i > 0, None) for i, l in enumerate(reversed(levels))]
        draws += [(p.level, p.buf, True, p.rect) for p in pyramid.looks.patches if p.level == frame.level]
        ctx = self.gpu.ctx
        for l, buf, clip, patch in draws:
            k = L - l
            buf.tex.use(0)
            texel_px = view.zoom * (1 << k) / float(np.linalg.norm(G, 2))
            exact = geom is None and texel_px == 1.0 and tlx == ix and tly == iy and (ix % (1 << k)) == 0 and (iy % (1 << k)) == 0
            # Synthesis magnification wherever texels are enlarged, the coarse levels
            # standing in while the view refines included (a dragged slider shows
            # real texture, patchy but sharp, LH05 5): each texel's coordinate is
            # extrapolated across the pixels it covers and the view's own level
            # (or the hi-res exemplar) is sampled there.
            magnify = display.magnify != "nearest" and texel_px > 1.0 and not exact
            use_hires = (self.hires_tex is not None and display.magnify == "hires" and frame.level == L and magnify)
            mag = 0 if not magnify or mode in (1, 2, 3, 4) else (2 if use_hires else 1)
            directed = buf.channels == 4
            prog, vao = self._program(mode, mag, alpha if mode in (0, 3, 5) else 0,
                                      self.shape_kind if mode == 5 else 0, directed, patch is not None)
            if patch is not None:
                set_uniforms(prog, feather=(patch.x0, patch.y0, patch.x1, patch.y1), feather_w=FEATHER_TEXELS)
                ctx.enable(moderngl.BLEND)
                ctx.blend_func = (moderngl.SRC_ALPHA, moderngl.ONE_MINUS_SRC_ALPHA, moderngl.ZERO, moderngl.ONE)
            if directed:
                self._jacobians(pyramid, (l, buf is not pyramid.buffers[l]), k, buf.valid).use(4)
                set_uniforms(prog, jfield=4, jorigin=(buf.valid.x0, buf.valid.y0), jdims=(buf.valid.w, buf.valid.h))
            scissor = self._screen_box(buf.valid, k, tlx, tly, M) if clip else None
            if box is not None:
                scissor = box if scissor is None else _intersect(scissor, box)
            self.gpu.ctx.scissor = scissor
            set_uniforms(prog, coords=0, stack=1, hires=2, anchor=buf.anchor, cmask=buf.mask,
                         vlo=(buf.valid.x0, buf.valid.y0), vhi=(buf.valid.x1, buf.valid.y1),
                         tl_i=(ix, iy), tl_f=(tlx - ix, tly - iy), zoom=float(view.zoom), k=k, m=self.m,
                         geom=(float(M[0, 0]), float(M[0, 1]), float(M[1, 0]), float(M[1, 1])),
                         layer=l, mag_layer=frame.level if l < frame.level else l,
                         toroidal=int(self.toroidal), relief_strength=float(self.m) / 24.0, shape=3,
                         light=light, relief=float(display.relief) * self.m / 8.0)
            vao.render(moderngl.TRIANGLES)
            if patch is not None:
                ctx.disable(moderngl.BLEND)
                ctx.blend_func = moderngl.DEFAULT_BLENDING
        return levels[-1]

    def _jacobians(self, pyramid: Pyramid, slot: tuple[int, bool], k: int, r: Rect):
        """Level L - k's J over ``r`` as an RGBA16I texture (kept in ``slot``, the
        level and whether for a quick look, while the field and ``r`` stay; after
        a dab only the tiles it changed are computed and written again)."""
        from infinitex.engine.controls.direction import IDENTITY
        field = pyramid.controls.direction
        period = pyramid.params.period
        key = (field.key, r, period)
        cache = self.__dict__.setdefault("_jtex", {})  # slot -> (key, texture, field)
        held = cache.get(slot)
        if held is not None and held[0] != key and held[0][1:] == key[1:] and not period:
            for box in field.changed_rects(held[2]):
                c = Rect(*box).coarser(k).intersect(r)
                if not c.empty:
                    vals = field.region(k, c.x0, c.y0, c.w, c.h, period)
                    vals = np.broadcast_to(IDENTITY, (c.h, c.w, 4)) if vals is None else vals
                    held[1].write(np.ascontiguousarray(vals, dtype=np.int16).tobytes(),
                                  viewport=(c.x0 - r.x0, c.y0 - r.y0, c.w, c.h), alignment=1)
            cache[slot] = held = (key, held[1], field)
        if held is None or held[0] != key:
            if held is not None:
                held[1].release()
            vals = field.region(k, r.x0, r.y0, r.w, r.h, period)
            if vals is None:
                vals = np.broadcast_to(IDENTITY, (r.h, r.w, 4))
            cache[slot] = held = (key, self.gpu.int_texture((r.w, r.h), 4, vals), field)
        return held[1]

    def _origin(self, view: View, geom: np.ndarray | None) -> tuple[float, float, np.ndarray]:
        """The canvas's top-left corner in finest-level pixels (through the
        lattice's geometry ``geom``, if any) and that geometry (identity: none)."""
        tlx, tly = view.top_left(*self.size)
        if geom is None:
            return tlx, tly, np.eye(2)
        G = np.asarray(geom, dtype=np.float64)
        x, y = G @ np.array([tlx, tly])
        return float(x), float(y), G

    def _level_box(self, box: tuple[int, int, int, int], level: int, L: int, tlx: float, tly: float,
                   M: np.ndarray) -> Rect:
        """The level texels that the canvas pixels of ``box`` show (one texel more around)."""
        x, y, w, h = box
        corners = np.array([[x, y], [x + w, y], [x, y + h], [x + w, y + h]], dtype=np.float64)
        pos = corners @ M.T + np.array([tlx, tly])
        s = 1 << (L - level)
        return Rect(math.floor(pos[:, 0].min() / s) - 1, math.floor(pos[:, 1].min() / s) - 1,
                    math.floor(pos[:, 0].max() / s) + 2, math.floor(pos[:, 1].max() / s) + 2)

    def screen_box(self, level: int, r: Rect, L: int, view: View, geom: np.ndarray | None = None):
        """The canvas pixels (x, y, w, h) that show level texels ``r``, clipped (w or h 0: none)."""
        tlx, tly, G = self._origin(view, geom)
        x, y, w, h = self._screen_box(r.pad(1, 1, 1, 1), L - level, tlx, tly, G / view.zoom)
        return (x, y, w, h)

    def _screen_box(self, r, k: int, tlx: float, tly: float, M: np.ndarray):
        """Canvas pixels covered by level-(L-k) rectangle r: (x, y, w, h), clipped.
        M maps screen pixels to finest-level canvas pixels (relative to tlx, tly)."""
        s = 1 << k
        corners = np.array([[r.x0 * s - tlx, r.y0 * s - tly], [r.x1 * s - tlx, r.y0 * s - tly],
                            [r.x0 * s - tlx, r.y1 * s - tly], [r.x1 * s - tlx, r.y1 * s - tly]])
        scr = corners @ np.linalg.inv(M).T
        x0 = max(0, math.floor(scr[:, 0].min()))
        y0 = max(0, math.floor(scr[:, 1].min()))
        x1 = min(self.size[0], math.ceil(scr[:, 0].max()))
        y1 = min(self.size[1], math.ceil(scr[:, 1].max()))
        return (x0, y0, max(0, x1 - x0), max(0, y1 - y0))

    def read(self) -> np.ndarray:
        """The canvas as uint8 (H, W, 3), row 0 at the top."""
        self.gpu.activate()
        data = self.fbo.read(components=3, alignment=1)
        return np.frombuffer(data, dtype=np.uint8).reshape(self.size[1], self.size[0], 3).copy()

    def _release_exemplar(self) -> None:
        for t in (self.stack_tex, self.hires_tex, self.exemplar_tex):
            if t is not None:
                t.release()
        self.stack_tex = self.hires_tex = self.exemplar_tex = None

    def release(self) -> None:
        self.gpu.activate()
        self._release_exemplar()
        if self.shape_tex is not None:
            self.shape_tex.release()
            self.shape_tex, self.shape_key = None, None
        if self.tex is not None:
            self.fbo.release()
            self.tex.release()
            self.tex = self.fbo = None
        for _, tex, _ in self.__dict__.pop("_jtex", {}).values():
            tex.release()


def to_rgba(a: np.ndarray) -> np.ndarray:
    """uint8 (..., C) with C in 1..4 to (..., 4): gray to RGB, alpha 255 if none."""
    c = a.shape[-1]
    if c == 4:
        return a
    out = np.full(a.shape[:-1] + (4,), 255, dtype=np.uint8)
    if c in (1, 2):
        out[..., :3] = a[..., :1]
        if c == 2:
            out[..., 3] = a[..., 1]
    else:
        out[..., :3] = a
    return out


def _intersect(a: tuple[int, int, int, int], b: tuple[int, int, int, int]) -> tuple[int, int, int, int]:
    x0, y0 = max(a[0], b[0]), max(a[1], b[1])
    x1, y1 = min(a[0] + a[2], b[0] + b[2]), min(a[1] + a[3], b[1] + b[3])
    return (x0, y0, max(0, x1 - x0), max(0, y1 - y0))


def union_box(boxes) -> tuple[int, int, int, int] | None:
    """The smallest box (x, y, w, h) holding the non-empty ones; None if none is."""
    x0 = y0 = x1 = y1 = None
    for x, y, w, h in boxes:
        if w <= 0 or h <= 0:
            continue
        x0 = x if x0 is None else min(x0, x)
        y0 = y if y0 is None else min(y0, y)
        x1 = x + w if x1 is None else max(x1, x + w)
        y1 = y + h if y1 is None else max(y1, y + h)
    return None if x0 is None else (x0, y0, x1 - x0, y1 - y0)
