"""The Features tool on a model (engine/surface/features.py): the same
gestures as on the plane (tools/feature.py), ray-picked into the atlas.

- Press on the model away from any feature: a feature of what is shown
  there (the synthesized exemplar point) is placed, and follows the mouse
  until release.
- Drag the exemplar thumbnail onto the model: the point under the mouse on
  the thumbnail becomes a feature where it is dropped.
- Press on a feature's centre and drag: move it over the surface; drag its
  outer circle: resize it; the wheel over a feature resizes it (Shift: the
  outer radius only); Del deletes the selected one. One gesture is one undo step.

A feature's centre is an atlas texel of the model's texture (Feature.canvas)
and its radii are exemplar pixels: the circles drawn are its disc on the
surface seen from the camera (at its centre's depth). While dragging, only
the handles move; on release the texture is synthesized again.
"""
from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
from imgui_bundle import imgui

from infinitex.engine.controls import MAX_FEATURE_RADIUS, Feature
from infinitex.engine.pyramid import Rect, SynthesisError

from . import ModelGesture


class ModelFeatures(ModelGesture):
    """Press / drag / release / wheel / drop / handles of the Features tool on the model view."""

    def __init__(self, ed):
        super().__init__(ed)
        self._mode: str | None = None
        self._group: object = None
        self._start: Feature | None = None
        self._press = (0.0, 0.0)

    @property
    def tool(self):
        return self.ed.tool

    @property
    def features(self) -> tuple[Feature, ...]:
        return self.ed.doc.features

    def _atlas(self):
        return self.ed.session.model.atlas

    # -- geometry --------------------------------------------------------------

    def surface_point(self, texel: tuple[int, int]) -> np.ndarray | None:
        """The 3D point of an atlas texel's centre (its triangle's, barycentric), or None off the model."""
        atlas = self._atlas()
        if atlas is None:
            return None
        n = atlas.size
        x, y = texel
        if not (0 <= x < n and 0 <= y < n):
            return None
        t = int(atlas.nearest_triangle(0)[y, x])
        if t < 0:
            return None
        f = atlas.model.faces[t]
        A, B, C = atlas.uvpx[f]
        p = np.array([x + 0.5, y + 0.5])
        den = (B[0] - A[0]) * (C[1] - A[1]) - (C[0] - A[0]) * (B[1] - A[1])
        if den == 0:
            return atlas.model.positions[f[0]].astype(np.float64)
        b1 = ((p[0] - A[0]) * (C[1] - A[1]) - (C[0] - A[0]) * (p[1] - A[1])) / den
        b2 = ((B[0] - A[0]) * (p[1] - A[1]) - (p[0] - A[0]) * (B[1] - A[1])) / den
        P = atlas.model.positions[f]
        return P[0] + b1 * (P[1] - P[0]) + b2 * (P[2] - P[0])

    def screen(self, point: np.ndarray, w: int, h: int) -> tuple[float, float, float] | None:
        """(x, y) in view pixels and the screen pixels per world unit there, or None behind the camera."""
        cam = self.ed.model.camera
        view, proj = cam.matrices(w / max(1, h))
        v = view @ np.r_[point, 1.0]
        if v[2] >= -1e-9:
            return None
        c = proj @ v
        x = (c[0] / c[3] * 0.5 + 0.5) * w
        y = (0.5 - c[1] / c[3] * 0.5) * h
        per_unit = h / (2.0 * math.tan(math.radians(cam.fovy) / 2) * -v[2])
        return x, y, per_unit

    def pick(self, mx: float, my: float, w: int, h: int) -> tuple[int, int] | None:
        """The atlas texel under view pixel (mx, my), or None off the model."""
        uvh = self.ed.model.uv_image(w, h)
        xi, yi = int(mx), int(my)
        if not (0 <= xi < w and 0 <= yi < h) or uvh[yi, xi, 2] < 0.5:
            return None
        n = self.ed.doc.surface.size
        return (min(n - 1, max(0, int(uvh[yi, xi, 0] * n))), min(n - 1, max(0, int((1 - uvh[yi, xi, 1]) * n))))

    def world_per_exemplar_px(self, texel: tuple[int, int]) -> float:
        """How long an exemplar pixel is on the surface at an atlas texel (the
        texture's own scale there: the frame's, a combed field's, the held stretch)."""
        atlas = self._atlas()
        x, y = texel
        t = int(atlas.nearest_triangle(0)[y, x])
        f = atlas.model.faces[t]
        P, X = atlas.model.positions[f], atlas.uvpx[f]
        area3 = 0.5 * np.linalg.norm(np.cross(P[1] - P[0], P[2] - P[0]))
        e1, e2 = X[1] - X[0], X[2] - X[0]
        area2 = 0.5 * abs(e1[0] * e2[1] - e1[1] * e2[0])
        J = atlas.texel_jacobians(np.array([x]), np.array([y]))[0].astype(np.float64) / 4096
        det = abs(J[0] * J[3] - J[1] * J[2])
        if area2 <= 0 or det <= 0:
            return 1.0 / atlas.sigma
        return math.sqrt(area3 / area2) / math.sqrt(det)  # (world per texel) / (exemplar px per texel)

    def visible(self, point: np.ndarray, x: float, y: float, w: int, h: int) -> bool:
        """Whether the model's front surface at view pixel (x, y) is ``point`` (not hidden behind it)."""
        uvh = self.ed.model.uv_image(w, h)
        xi, yi = int(x), int(y)
        if not (0 <= xi < w and 0 <= yi < h) or uvh[yi, xi, 2] < 0.5:
            return False
        n = self.ed.doc.surface.size
        front = self.surface_point((min(n - 1, max(0, int(uvh[yi, xi, 0] * n))),
                                    min(n - 1, max(0, int((1 - uvh[yi, xi, 1]) * n)))))
        return front is not None and np.linalg.norm(front - point) <= 0.02 * self._atlas().model.extent

    def _handles(self, w: int, h: int, shown=None):
        """Per feature seen from the camera (index, screen x, y, inner and outer
        radius in screen px), topmost last; those the model hides are left out."""
        atlas = self._atlas()
        if atlas is None:
            return []
        out = []
        for i, f in enumerate(shown if shown is not None else self.features):
            p = self.surface_point(f.canvas)
            s = self.screen(p, w, h) if p is not None else None
            if s is not None and self.visible(p, s[0], s[1], w, h):
                k = s[2] * self.world_per_exemplar_px(f.canvas)  # screen px per exemplar px
                out.append((i, s[0], s[1], f.inner * k, f.outer * k))
        return out

    def _hit(self, mx: float, my: float, w: int, h: int) -> tuple[int, str] | None:
        for i, x, y, ri, ro in reversed(self._handles(w, h)):
            d = math.hypot(mx - x, my - y)
            if abs(d - ro) <= 5 and ro > 10:
                return i, "outer"
            if d <= max(7.0, ri):
                return i, "move"
        return None

    def sample(self, texel: tuple[int, int]) -> tuple[int, int]:
        """The exemplar point synthesized at an atlas texel (the finest level shown), else the exemplar's centre."""
        pv = self.ed.session.model
        m = self.ed.session.analysis.size
        if pv.run is None or pv.image_level < 0:
            return m // 2, m // 2
        k = pv.run.L - pv.image_level
        try:
            c = pv.run.pyramid.read(pv.image_level, Rect.of(texel[0] >> k, texel[1] >> k, 1, 1))
        except SynthesisError:
            return m // 2, m // 2
        finally:
            self.ed.screen_fbo.use()
        return int(c[0, 0, 0]) % m, int(c[0, 0, 1]) % m

    # -- gestures --------------------------------------------------------------

    def _set(self, features, label: str, group=None) -> None:
        self.ed.edit(replace(self.ed.doc, features=tuple(features)), label, group=group)

    def place(self, u: tuple[int, int], texel: tuple[int, int], label: str = "Place feature", group=None) -> None:
        t = self.tool
        f = Feature(u, texel, t.inner, max(t.inner, t.outer), t.levels())
        self._set(self.features + (f,), label, group)
        t.selected = len(self.features) - 1

    def press(self, mx: float, my: float, w: int, h: int) -> None:
        self._group = object()
        self._press = (mx, my)
        hit = self._hit(mx, my, w, h)
        if hit is None:
            texel = self.pick(mx, my, w, h)
            if texel is None:
                self._mode = None
                return
            self.place(self.sample(texel), texel, "Place feature", self._group)
            self._mode = "move"
        else:
            self.tool.selected, self._mode = hit
        self._start = self.features[self.tool.selected]

    def drag(self, mx: float, my: float, w: int, h: int) -> None:
        t = self.tool
        if self._mode is None or t.selected is None or t.selected >= len(self.features):
            return
        f0 = self._start
        if self._mode == "move":
            texel = self.pick(mx, my, w, h)
            if texel is not None:
                t.preview = replace(f0, canvas=texel)
            return
        p = self.surface_point(f0.canvas)
        s = self.screen(p, w, h) if p is not None else None
        if s is not None:  # the outer circle follows the mouse: screen px to exemplar px at the centre's depth
            per = s[2] * self.world_per_exemplar_px(f0.canvas)
            r = min(MAX_FEATURE_RADIUS, max(1, round(math.hypot(mx - s[0], my - s[1]) / max(per, 1e-9))))
            t.preview = replace(f0, outer=max(r, f0.inner))

    def release(self) -> None:
        t = self.tool
        f = t.preview
        if f is not None and t.selected is not None and t.selected < len(self.features) \
                and self.features[t.selected] != f:
            feats = list(self.features)
            feats[t.selected] = f
            self._set(feats, "Move feature" if self._mode == "move" else "Resize feature", self._group)
        if self._group is not None and self.ed.history is not None:
            self.ed.history.end_group()
        self._group, self._mode, t.preview = None, None, None

    def wheel(self, mx: float, my: float, w: int, h: int, amount: float) -> bool:
        hit = self._hit(mx, my, w, h)
        if hit is None:
            return False
        self.tool.resize(hit[0], amount)
        return True

    def drop(self, u: tuple[int, int], mx: float, my: float, w: int, h: int) -> None:
        texel = self.pick(mx, my, w, h)
        if texel is not None:
            self.place(u, texel)

    def jump_to(self, f: Feature) -> None:
        """Turn the camera to look at the feature, straight down its surface's normal."""
        p = self.surface_point(f.canvas)
        if p is None:
            return
        atlas = self._atlas()
        t = int(atlas.nearest_triangle(0)[f.canvas[1], f.canvas[0]])
        P = atlas.model.positions[atlas.model.faces[t]]
        nrm = np.cross(P[1] - P[0], P[2] - P[0])
        length = float(np.linalg.norm(nrm))
        cam = replace(self.ed.model.camera, target=tuple(float(v) for v in p))
        if length > 0:
            nx, ny, nz = nrm / length  # the eye goes where the normal points (OrbitCamera.eye)
            cam = replace(cam, yaw=math.degrees(math.atan2(nx, nz)) % 360.0,
                          pitch=max(-89.0, min(89.0, math.degrees(math.asin(max(-1.0, min(1.0, ny)))))))
        self.ed.model.look_with(cam)

    def draw(self, dl, p0, w: int, h: int) -> None:
        t = self.tool
        if not t.show or not self.features:
            return
        shown = list(self.features)
        if t.preview is not None and t.selected is not None and t.selected < len(shown):
            shown[t.selected] = t.preview
        white, black = imgui.get_color_u32((1, 1, 1, 0.9)), imgui.get_color_u32((0, 0, 0, 0.75))
        sel = imgui.get_color_u32((1.0, 0.8, 0.2, 1.0))
        dl.push_clip_rect(p0, (p0.x + w, p0.y + h), True)
        for i, x, y, ri, ro in self._handles(w, h, shown):
            c = (p0.x + x, p0.y + y)
            col = sel if i == t.selected else white
            for r in (ro, ri):
                if r >= 2:
                    dl.add_circle(c, r, black, 0, 3.0)
                    dl.add_circle(c, r, col, 0, 1.5)
            dl.add_circle_filled(c, 4.0, black)
            dl.add_circle_filled(c, 3.0, col)
        dl.pop_clip_rect()
