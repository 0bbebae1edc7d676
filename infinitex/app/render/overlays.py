"""Overlays drawn over the canvas and the exemplar view: the randomness fields
as translucent heat maps (blue = calm, clear = neutral, red = rough), and the
exemplar's avoided regions hatched in magenta."""
from __future__ import annotations

import math

import moderngl
import numpy as np

from infinitex.engine.controls import NEUTRAL, CanvasField, ExemplarField, ExemplarMask

MAX_OVERLAY = 2048  # texels a side


def heat_rgba(values: np.ndarray) -> np.ndarray:
    """uint16 field values to RGBA8: calm blue, neutral transparent, rough red."""
    d = values.astype(np.float32) / NEUTRAL - 1.0
    out = np.zeros(values.shape + (4,), np.uint8)
    calm, rough = d < 0, d > 0
    out[calm] = (60, 150, 255, 0)
    out[rough] = (255, 80, 40, 0)
    out[..., 3] = np.clip(np.abs(d) * 170.0, 0, 170).astype(np.uint8)
    return out


def direction_rgba(field, n: int, axis: int = 0) -> np.ndarray | None:
    """A direction field over an n x n atlas as RGBA8 short strokes, as the
    plane shows it (draw_field): one stroke per cell of about n / 32 texels
    where the field is painted, along the exemplar's x (``axis`` 1: its y),
    as long as its scale, light on a dark outline; None where nothing is painted."""
    from infinitex.engine.controls.direction import decompose
    if field is None or field.identity or n < 8:
        return None
    step = max(2, int(math.log2(n)) - 5)
    cell = 1 << step
    g = n // cell
    j = field.region(step, 0, 0, g, g)
    if j is None:
        return None
    painted = np.any(j != np.array([4096, 0, 0, 4096], np.int16), axis=-1)
    if not painted.any():
        return None
    th, sc, _ = decompose(j)
    a = np.radians(th + 90.0 * axis)
    half = 0.38 * cell * np.clip(sc, 0.5, 1.25)
    ys, xs = np.mgrid[0:n, 0:n]
    cy, cx = ys // cell, xs // cell
    dy = ys - (cy + 0.5) * cell + 0.5
    dx = xs - (cx + 0.5) * cell + 0.5
    ca, sa = np.cos(a)[cy, cx], np.sin(a)[cy, cx]
    along = dx * ca + dy * sa
    across = np.abs(-dx * sa + dy * ca)
    inside = painted[cy, cx] & (np.abs(along) <= half[cy, cx])
    w = max(1.0, cell / 16)
    out = np.zeros((n, n, 4), np.uint8)
    out[inside & (across <= 2 * w)] = (0, 0, 0, 170)
    out[inside & (across <= w)] = (255, 205, 50, 240)
    return out


def avoid_rgba(values: np.ndarray) -> np.ndarray:
    """An avoid mask to RGBA8: avoided pixels hatched magenta (diagonal stripes,
    so the exemplar stays readable underneath), usable ones transparent."""
    m = values.shape[0]
    ys, xs = np.mgrid[0:m, 0:m]
    stripe = ((xs + ys) // max(1, m // 64)) % 2 == 0
    out = np.zeros(values.shape + (4,), np.uint8)
    on = values != 0
    out[on] = (255, 40, 200, 0)
    out[..., 3] = np.where(on, np.where(stripe, 200, 90), 0).astype(np.uint8)
    return out



def label_rgba(values: np.ndarray, colors, free_value: int | None = 0, alpha: int = 120) -> np.ndarray:
    """Label values to RGBA8 for an overlay: each label in its color, ``free_value`` transparent;
    ``values`` hold label + 1 on the canvas (free_value 0) or the label itself (free_value None)."""
    lut = np.zeros((17, 4), np.uint8)
    offset = 0 if free_value is None else 1
    for i, c in enumerate(colors[:16]):
        lut[i + offset] = (*c, alpha)
    return np.take(lut, np.minimum(values, 16), axis=0)

class FieldOverlay:
    """One texture holding a heat map, re-made only when its inputs change."""

    def __init__(self, ctx: moderngl.Context):
        self.ctx = ctx
        self.tex: moderngl.Texture | None = None
        self._key = None
        self._shown = None  # canvas labels: (what the texture covers, the labels it shows)
        self.placement = None  # canvas: (finest x0, y0, finest width, height) the texture covers

    def _upload(self, rgba: np.ndarray) -> None:
        h, w = rgba.shape[:2]
        if self.tex is None or self.tex.size != (w, h):
            if self.tex is not None:
                self.tex.release()
            self.tex = self.ctx.texture((w, h), 4, dtype="f1")
            self.tex.filter = (moderngl.NEAREST, moderngl.NEAREST)
        self.tex.write(np.ascontiguousarray(rgba).tobytes())

    def _whole(self, key: tuple, rgba) -> moderngl.Texture:
        """The texture of a whole-exemplar overlay, made by ``rgba()`` when ``key`` changes."""
        if key != self._key:
            self._upload(rgba())
            self._key = key
        return self.tex

    def exemplar(self, field: ExemplarField | None, m: int):
        """The texture of an exemplar field (m x m), or None when there is none."""
        if field is None or field.neutral:
            return None
        return self._whole(("e", field.key), lambda: heat_rgba(field.values))

    def mask(self, mask: ExemplarMask | None):
        """The texture of an avoid mask (m x m), or None when nothing is avoided."""
        if mask is None or mask.empty:
            return None
        return self._whole(("a", mask.key), lambda: avoid_rgba(mask.values))

    def canvas(self, field: CanvasField | None, x0: float, y0: float, w_canvas: float, h_canvas: float):
        """The texture of the canvas field over a finest-level rectangle, at a
        resolution near the screen's; ``placement`` says where it lies."""
        if field is None or field.neutral:
            return None
        k = max(0, math.ceil(math.log2(max(w_canvas, h_canvas) / MAX_OVERLAY))) if max(w_canvas, h_canvas) > MAX_OVERLAY else 0
        X0, Y0 = math.floor(x0) >> k, math.floor(y0) >> k
        X1, Y1 = (math.ceil(x0 + w_canvas) >> k) + 1, (math.ceil(y0 + h_canvas) >> k) + 1
        key = ("c", field.key, k, X0, Y0, X1, Y1)
        if key != self._key:
            vals = field.region(k, X0, Y0, X1 - X0, Y1 - Y0)
            if vals is None:
                self._key, self.placement = key, None
                return None
            self._upload(heat_rgba(vals))
            self._key = key
            self.placement = (X0 << k, Y0 << k, (X1 - X0) << k, (Y1 - Y0) << k)
        return self.tex if self.placement is not None else None

    def release(self) -> None:
        self._key = self._shown = None
        if self.tex is not None:
            self.tex.release()
            self.tex = None


class LabelOverlay(FieldOverlay):
    """Texture by numbers' labels in their colors: the exemplar's map (for the
    Labels window) and the canvas labels over the canvas."""

    def exemplar_labels(self, labels, colors) -> moderngl.Texture:
        return self._whole(("l", labels.key, tuple(colors)), lambda: label_rgba(labels.values, colors, None))

    def canvas_labels(self, labels, colors, x0: float, y0: float, w_canvas: float, h_canvas: float):
        """The canvas labels over a finest-level rectangle, sampled near the
        screen's resolution (``placement`` says where), or None where none is painted."""
        if labels is None or labels.empty:
            return None
        big = max(w_canvas, h_canvas)
        k = max(0, math.ceil(math.log2(big / MAX_OVERLAY))) if big > MAX_OVERLAY else 0
        X0, Y0 = math.floor(x0) >> k, math.floor(y0) >> k
        X1, Y1 = (math.ceil(x0 + w_canvas) >> k) + 1, (math.ceil(y0 + h_canvas) >> k) + 1
        geom = (tuple(colors), k, X0, Y0, X1, Y1)
        key = ("cl", labels.key) + geom
        if key == self._key:
            return self.tex if self.placement is not None else None
        f = 1 << k
        shown = self._shown
        if shown is not None and shown[0] == geom and self.placement is not None and self.tex is not None:
            # A stroke on the same view: only the texels whose sample point changed are rewritten.
            for rx0, ry0, rx1, ry1 in labels.changed_rects(shown[1]):
                tx0, ty0 = max(X0, -((f // 2 - rx0) // f)), max(Y0, -((f // 2 - ry0) // f))
                tx1, ty1 = min(X1, (rx1 - 1 - f // 2) // f + 1), min(Y1, (ry1 - 1 - f // 2) // f + 1)
                if tx0 < tx1 and ty0 < ty1:
                    vals = labels.sample(np.arange(tx0, tx1) * f + f // 2, np.arange(ty0, ty1) * f + f // 2)
                    self.tex.write(np.ascontiguousarray(label_rgba(vals, colors)).tobytes(),
                                   viewport=(tx0 - X0, ty0 - Y0, tx1 - tx0, ty1 - ty0))
            self._key, self._shown = key, (geom, labels)
            return self.tex
        vals = labels.sample(np.arange(X0, X1) * f + f // 2, np.arange(Y0, Y1) * f + f // 2)
        self._key, self._shown = key, (geom, labels)
        if not vals.any():
            self.placement = None
            return None
        self._upload(label_rgba(vals, colors))
        self.placement = (X0 << k, Y0 << k, (X1 - X0) << k, (Y1 - Y0) << k)
        return self.tex
