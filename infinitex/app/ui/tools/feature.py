"""Features (LH05 4.4): place chosen exemplar features anywhere on the canvas.

- Press on empty canvas and drag: "grab what I see": the feature's exemplar
  point is the synthesized coordinate under the cursor, and it follows the
  mouse to where it is released.
- Drag the exemplar thumbnail (Exemplar panel) onto the canvas: the point
  under the mouse on the thumbnail becomes a feature at the drop point.
- Press on a feature's center (or inside its inner circle) and drag: move it;
  drag its inner or outer circle: resize that radius; the wheel over a
  feature resizes both radii (Shift: the outer one only); Del deletes the
  selected feature. One gesture is one undo step.
While dragging, the feature is previewed (its circles and the exemplar it
copies follow the mouse, no synthesis); on release the canvas re-synthesizes
the old and the new area once, locally and exactly. The Features panel lists
every feature (radii, levels, jump to, delete).
"""
from __future__ import annotations

import math
from dataclasses import replace

from imgui_bundle import imgui

from infinitex.engine.controls import MAX_FEATURE_RADIUS, Feature
from infinitex.engine.pyramid import Rect, SynthesisError


from . import Tool
from ..tips import tip

PAYLOAD = "INFINITEX_FEATURE"   # drag-and-drop payload: exemplar point as uy * 4096 + ux


class FeatureTool(Tool):
    name = "feature"
    label = "Features"
    key = "F"
    tooltip = ("Place exemplar features: drag on the canvas to move what you see, or drag the exemplar "
               "thumbnail onto the canvas; drag a feature's center to move it, its circles to resize (F)")
    space = "canvas"
    panel = "Features"

    def __init__(self, ed):
        super().__init__(ed)
        self._model = None
        self.inner = 24
        self.outer = 48
        self.exact = False        # False: every level but the finest two (fresh detail); True: all levels
        self.show = True          # draw circles and handles
        self.selected: int | None = None
        self._mode: str | None = None
        self._group: object = None
        self._press: tuple[float, float] = (0.0, 0.0)
        self._start: Feature | None = None
        self.preview: Feature | None = None   # the selected feature as dragged, committed on release

    def new_document(self) -> None:
        self.selected, self.preview = None, None

    # -- document helpers -------------------------------------------------

    @property
    def features(self) -> tuple[Feature, ...]:
        return self.ed.doc.features if self.ed.doc is not None else ()

    def _set(self, features, label: str, group=None, changed=None) -> None:
        """The features become ``features``; ``changed``: the features added,
        removed or replaced (old and new), whose circles the edit reaches."""
        ed = self.ed
        ed.edit(replace(ed.doc, features=tuple(features)), label, group=group,
                region=None if changed is None else [f.bbox() for f in changed])

    def levels(self):
        return (0, self.ed.session.L) if self.exact else None

    def sample(self, pos) -> tuple[int, int]:
        """The synthesized exemplar coordinate shown at canvas point ``pos``."""
        ed = self.ed
        s = ed.session
        m = s.analysis.size
        level = ed.frame.level if ed.frame is not None else s.L
        k = s.L - level
        x, y = math.floor(pos[0]) >> k, math.floor(pos[1]) >> k
        try:
            c = s.pyramid.read(level, Rect.of(x, y, 1, 1))
            ed.screen_fbo.use()
            return int(c[0, 0, 0]) % m, int(c[0, 0, 1]) % m
        except SynthesisError:
            return m // 2, m // 2

    def place(self, u: tuple[int, int], pos, label: str = "Place feature", group=None) -> None:
        f = Feature(u, (round(pos[0]), round(pos[1])), self.inner, max(self.inner, self.outer), self.levels())
        self._set(self.features + (f,), label, group, (f,))
        self.selected = len(self.features) - 1

    # -- hit testing --------------------------------------------------------

    def _hit(self, pos) -> tuple[int, str] | None:
        z = self.ed.view.zoom
        for i in range(len(self.features) - 1, -1, -1):  # the topmost (last) first
            f = self.features[i]
            d = math.hypot(pos[0] - f.canvas[0], pos[1] - f.canvas[1]) * z
            if abs(d - f.outer * z) <= 5:
                return i, "outer"
            if abs(d - f.inner * z) <= 5 and f.inner * z > 10:
                return i, "inner"
            if d <= max(7.0, f.inner * z):
                return i, "move"
        return None

    # -- gestures -----------------------------------------------------------

    def press(self, pos, screen) -> None:
        self._group = object()
        self._press = pos
        hit = self._hit(pos)
        if hit is None:
            self.place(self.sample(pos), pos, "Place feature", self._group)
            self._mode = "move"
        else:
            self.selected, self._mode = hit
        self._start = self.features[self.selected]

    def drag(self, pos, screen) -> None:
        """While the button is held the feature is previewed (its circles and the
        exemplar it copies follow the mouse, no synthesis); release commits it,
        and the canvas re-synthesizes the old and new area once, exactly."""
        if self._mode is None or self.selected is None or self.selected >= len(self.features):
            return
        f0 = self._start
        if self._mode == "move":
            c = (f0.canvas[0] + round(pos[0] - self._press[0]), f0.canvas[1] + round(pos[1] - self._press[1]))
            self.preview = replace(f0, canvas=c)
        else:
            r = min(MAX_FEATURE_RADIUS, round(math.hypot(pos[0] - f0.canvas[0], pos[1] - f0.canvas[1])))
            self.preview = (replace(f0, outer=max(r, f0.inner)) if self._mode == "outer"
                            else replace(f0, inner=min(r, f0.outer)))

    def release(self) -> None:
        f = self.preview
        if f is not None and self.selected is not None and self.selected < len(self.features) \
                and self.features[self.selected] != f:
            feats = list(self.features)
            old, feats[self.selected] = feats[self.selected], f
            self._set(feats, "Move feature" if self._mode == "move" else "Resize feature", self._group, (old, f))
        if self._group is not None and self.ed.history is not None:
            self.ed.history.end_group()
        self._group, self._mode, self.preview = None, None, None

    def wheel(self, pos, amount: float) -> bool:
        """Resize the feature under the cursor; True when the wheel was used."""
        hit = self._hit(pos)
        if hit is None:
            return False
        self.resize(hit[0], amount)
        return True

    def resize(self, i: int, amount: float) -> None:
        """Feature i's radii scaled by the wheel's ``amount`` (Shift: the outer one only); one undo step per feature."""
        f = self.features[i]
        s = 2.0 ** (0.125 * amount)
        outer = min(MAX_FEATURE_RADIUS, max(1, round(f.outer * s)))
        inner = f.inner if imgui.get_io().key_shift else min(outer, max(0, round(f.inner * s)))
        feats = list(self.features)
        feats[i] = replace(f, inner=min(inner, outer), outer=outer)
        self._set(feats, "Resize feature", ("feature-wheel", i), (f, feats[i]))
        self.selected = i

    def keys(self) -> None:
        if imgui.get_io().want_text_input:
            return
        if self.selected is not None and (imgui.is_key_pressed(imgui.Key.delete) or imgui.is_key_pressed(imgui.Key.backspace)):
            self.delete(self.selected)

    def delete(self, i: int) -> None:
        feats = list(self.features)
        if 0 <= i < len(feats):
            gone = feats.pop(i)
            self._set(feats, "Delete feature", changed=(gone,))
        self.selected = None

    def model_gesture(self):
        if self._model is None:
            from .feature_model import ModelFeatures
            self._model = ModelFeatures(self.ed)
        return self._model

    # -- drawing ------------------------------------------------------------

    def overlay(self, draw_list, p0, w, h) -> None:
        pass  # handles are drawn for every visible feature by handles()

    def handles(self, draw_list, p0, w: int, h: int) -> None:
        ed = self.ed
        if not self.show or not self.features:
            return
        z = ed.view.zoom
        x0, y0 = ed.view.top_left(w, h)
        white, black = imgui.get_color_u32((1, 1, 1, 0.9)), imgui.get_color_u32((0, 0, 0, 0.75))
        sel = imgui.get_color_u32((1.0, 0.8, 0.2, 1.0))
        draw_list.push_clip_rect(p0, (p0.x + w, p0.y + h), True)
        shown = list(self.features)
        if self.preview is not None and self.selected is not None and self.selected < len(shown):
            f = shown[self.selected] = self.preview
            tex = ed.canvas.exemplar_tex
            if tex is not None and f.inner > 0:  # the exemplar the feature copies, under the mouse
                m = ed.session.analysis.size
                c = (p0.x + (f.canvas[0] - x0) * z, p0.y + (f.canvas[1] - y0) * z)
                r = f.inner * z
                ux, uy, ri = f.exemplar[0], f.exemplar[1], f.inner
                draw_list.add_image_rounded(imgui.ImTextureRef(tex.glo), (c[0] - r, c[1] - r), (c[0] + r, c[1] + r),
                                            ((ux - ri) / m, (uy - ri) / m), ((ux + ri) / m, (uy + ri) / m),
                                            imgui.get_color_u32((1, 1, 1, 0.85)), r)
        for i, f in enumerate(shown):
            c = (p0.x + (f.canvas[0] - x0) * z, p0.y + (f.canvas[1] - y0) * z)
            ro = f.outer * z
            if c[0] + ro < p0.x or c[0] - ro > p0.x + w or c[1] + ro < p0.y or c[1] - ro > p0.y + h:
                continue
            col = sel if i == self.selected else white
            for r in (f.outer * z, f.inner * z):
                if r >= 2:
                    draw_list.add_circle(c, r, black, 0, 3.0)
                    draw_list.add_circle(c, r, col, 0, 1.5)
            draw_list.add_circle_filled(c, 4.0, black)
            draw_list.add_circle_filled(c, 3.0, col)
        draw_list.pop_clip_rect()

    def options(self) -> None:
        ed = self.ed
        imgui.push_item_width(-110)
        _, self.inner = imgui.slider_int("Inner radius", self.inner, 0, 512)
        tip("New features: inside this radius the exemplar is copied at the finest level used")
        _, self.outer = imgui.slider_int("Outer radius", max(self.outer, self.inner), self.inner, 1024)
        tip("New features: the radius at the coarsest level; the texture around blends in")
        imgui.pop_item_width()
        _, self.exact = imgui.checkbox("Exact copy (all levels)", self.exact)
        tip("Off: the finest two levels stay free, so the feature gets fresh detail (LH05)")
        _, self.show = imgui.checkbox("Show feature handles", self.show)
        feats = self.features
        imgui.text(f"{len(feats)} feature{'s' if len(feats) != 1 else ''}")
        if feats and imgui.begin_list_box("##features", (-1, min(160, 22 * len(feats) + 6))):
            for i, f in enumerate(feats):
                if imgui.selectable(f"#{i + 1}  at ({f.canvas[0]}, {f.canvas[1]})  r {f.inner}/{f.outer}##feat{i}",
                                    i == self.selected)[0]:
                    self.selected = i
            imgui.end_list_box()
        i = self.selected
        if i is not None and i < len(feats):
            f = feats[i]
            L = ed.session.L
            imgui.push_item_width(-110)
            ch1, inner = imgui.slider_int("Inner##sel", f.inner, 0, f.outer)
            ch2, outer = imgui.slider_int("Outer##sel", f.outer, max(1, f.inner), MAX_FEATURE_RADIUS)
            a, b = f.level_range(L)
            ch3, lv = imgui.slider_int2("Levels##sel", [a, b], 0, L)
            imgui.pop_item_width()
            if ch1 or ch2 or ch3:
                levels = (min(lv[0], lv[1]), max(lv[0], lv[1]))
                g = replace(f, inner=min(inner, outer), outer=outer,
                            levels=None if levels == (0, max(0, L - 2)) and f.levels is None else levels)
                new = list(feats)
                new[i] = g
                self._set(new, "Edit feature", ("feature-edit", i), (f, g))
            if imgui.is_item_deactivated():
                ed.history.end_group()
            if imgui.button("Jump to"):
                if ed.model_mode:
                    self.model_gesture().jump_to(f)
                else:
                    ed.viewer.center(f.canvas[0], f.canvas[1])
            imgui.same_line()
            if imgui.button("Delete (Del)"):
                self.delete(i)
