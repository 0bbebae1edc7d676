"""What the canvas shows while a control is dragged or just changed
(:class:`CanvasRefine`, a part of the editor: ``Editor.refinement``).

A change of a randomness slider, the Structure preset or the seed redoes the
pyramid from the levels it changes. On a CPU one level of a large view can cost
more than a frame (the fidelity stage's levels: a few hundred milliseconds at
Balanced on llvmpipe), so a preview that starts again at every frame of a drag
never got past the coarsest levels, and those magnified 32 times showed melted
elements and smears. Now a change is shown only once its texture looks like the
result:

- the canvas keeps what it showed until the view's level less
  ``PREVIEW_MAX_K`` is complete for the change (texels at most 8 screen pixels,
  drawn by the synthesis magnification: the exact texture at a lower
  resolution; measured against the exemplar, the neighbourhood energy of that
  preview is 1.3-1.7x the settled result's, of the coarsest levels 2-3x);
- meanwhile further changes wait (:class:`EditHold`): the session keeps the
  document of the change in progress, so whole levels are made a piece at a
  time over frames (``Refiner.coarse``) and never started again half done;
  then the newest document is taken. On a GPU that is every frame; on llvmpipe,
  a few times a second.

The same holds when the full analysis replaces the quick analysis shown while
an image opens: its texture stays until the final one is presentable.
Local edits (paint, labels, features, direction) never wait: they have their
own exact local updates and quick looks.
"""
from __future__ import annotations

import math
import time
from dataclasses import replace

from imgui_bundle import imgui

from infinitex.engine.pyramid import SynthesisError
from infinitex.project import Document, View

from ..render.canvas import PREVIEW_MAX_K  # a change shows once the view's level less this many is complete

INTERACTIVE_S = 0.25  # seconds after the last edit that still count as dragging
SETTLE_FRAME_S = 0.080  # a frame while nothing is touched, at most (see CanvasRefine._work)


def local_edit(prev: Document | None, doc: Document) -> bool:
    """Whether ``doc`` differs from ``prev`` only in what is re-synthesized
    locally and exactly (canvas paint, canvas labels, features, the direction
    field): no coarse preview for those."""
    if prev is None:
        return False
    labels = prev.labels if None in (prev.labels, doc.labels) else replace(prev.labels, canvas=doc.labels.canvas)
    return replace(prev, randomness_canvas=doc.randomness_canvas, features=doc.features, labels=labels,
                   direction=doc.direction) == doc


class EditHold:
    """The document the session synthesizes while changes come faster than
    their previews: one change at a time, each until it is presentable."""

    def __init__(self) -> None:
        self.synced: Document | None = None  # what the session was last given
        self.waiting = False                 # its change is not presentable yet

    def doc(self, doc: Document, holding: bool = True, dragging: bool = True) -> Document:
        """The document to give the session this frame, for the editor's ``doc``.
        ``holding`` False (a model is shown: no preview of the flat canvas) passes
        it on; ``dragging`` False (no control held: a click, the release) takes
        it at once, the picture kept until it is presentable."""
        held = self.synced
        if doc is held:
            return doc
        if held is None or not holding or local_edit(held, doc) \
                or held.analysis_key() != doc.analysis_key():
            self.synced, self.waiting = doc, False
            return doc
        if self.waiting and dragging:  # (its progress is never thrown away for a newer change)
            return held
        self.synced, self.waiting = doc, True
        return doc

    def hold_picture(self) -> None:
        """Keep the picture shown until the texture is presentable (the full
        analysis replacing the quick preview: the same view, a new texture)."""
        self.waiting = True

    def reached(self, level: int, target: int) -> None:
        """The preview is complete to ``level`` (-1: no level yet); presentable
        from ``target``, and only then shown: the canvas draws no level coarser
        than that, so giving way earlier shows it empty (there was a safety
        net, 10 s, which on a loaded machine replaced a slider drag's picture
        with the flat grey of an empty canvas)."""
        if level >= target:
            self.waiting = False


class CanvasRefine:
    """The editor's refinement and redraw of the flat canvas each frame."""

    def __init__(self, ed) -> None:
        self.ed = ed
        self.hold = EditHold()
        self.peek_asked = False  # a test asks for what this frame shows (no refinement forced)
        self._was_quick = False
        self._last_doc = None
        self._last_edit = 0.0

    def session_doc(self) -> Document:
        """The document the session shows this frame (see :class:`EditHold`)."""
        return self.hold.doc(self.ed.doc, holding=not self.ed.model_mode, dragging=imgui.is_any_item_active())

    def _work(self, step, done, settle: bool):
        """Run ``step(budget)`` for this frame's synthesis budget; while nothing
        is touched (no button held, no control active, no input queued) and no
        other job takes a slice of each frame (an export, a tile set), again
        and again until ``done(result)``, a frame of about SETTLE_FRAME_S, or an
        input event arrives (glfw is polled between steps, so a key or a move
        ends the frame within one step, and the next frame is short again).
        A frame's drawing and UI cost about the same whatever its synthesis: on
        a slow or busy machine, where they take most of a 27 ms frame, a view
        that no one touches settles about twice as fast this way."""
        budget = self.ed.frame_pacer.budget_s
        t0 = time.perf_counter()
        result = step(budget)
        if not settle or self.ed.canvas_state.read_asked or not self._untouched():
            return result
        settle_s = SETTLE_FRAME_S - self.ed.frame_pacer.other_s
        while not done(result) and time.perf_counter() - t0 + budget <= settle_s and not self.ed.waits.arrived():
            result = step(budget)
        return result

    def _untouched(self) -> bool:
        io = imgui.get_io()
        return not (imgui.is_any_item_active() or imgui.is_any_mouse_down() or io.want_text_input
                    or self.ed.canvas_state.button >= 0 or self.ed.waits.working or self.ed.waits.arrived(poll=False))

    def draw(self, s, geom) -> None:
        """Synthesize for this frame and bring the canvas texture up to date."""
        ed = self.ed
        if ed.doc is not self._last_doc:
            prev, self._last_doc = self._last_doc, ed.doc
            if not local_edit(prev, ed.doc):
                self._last_edit = time.monotonic()
        interactive = (time.monotonic() - self._last_edit < INTERACTIVE_S) and not ed.canvas_state.read_asked
        hold = self.hold
        was, self._was_quick = self._was_quick, s.quick_analysis
        if was and not s.quick_analysis and s.key == ed.doc.analysis_key():
            hold.hold_picture()  # the full analysis replaces the quick one: no coarse levels meanwhile
        frame = ed.frame
        t0 = time.perf_counter()
        scale = 1
        try:
            if (interactive or hold.waiting) and not ed.canvas_state.read_asked:
                # A control is being dragged, or a change is not presentable
                # yet: whole levels, coarse to fine, a piece at a time.
                target = frame.level - PREVIEW_MAX_K
                c = self._work(lambda b: s.refiner.coarse(frame, b, max_level=target),
                               lambda c: c >= target, settle=not interactive)
                hold.reached(c, target)
                ed.canvas_state.set_refined(False)
                texel_px = ed.view.zoom * (1 << (s.L - c)) if c >= 0 else 1
                if ed.display.magnify == "nearest":  # plain texel blocks: draw them at their own size
                    scale = 1 << max(0, min(3, int(math.floor(math.log2(max(1.0, texel_px))))))
            else:
                ed.canvas_state.set_refined(self._work(lambda b: s.refine(frame, b), bool, settle=True))
        except SynthesisError as exc:
            ed.viewer.center(0, 0)
            hold.waiting = False
            ed.dialogs.message("Synthesis", str(exc))
        ed.canvas_state.synthesized((time.perf_counter() - t0) * 1000.0, s.refiner.last_pixels if s.refiner else 0)
        w, h = ed.canvas_size
        view = ed.view if scale == 1 else View(ed.view.x, ed.view.y, ed.view.zoom / scale)
        reading = ed.canvas_state.read_asked
        if hold.waiting and not reading and ed.canvas.shows(frame, view, ed.display, geom, (w // scale, h // scale)):
            self._peek()
            return  # the last presentable texture stays until this change's is
        ed.canvas.ensure_size(w // scale, h // scale)
        ed.canvas.redraw(s.pyramid, frame, view, ed.display, geom, (s.generation, s.params), force=reading)
        if ed.canvas.pending is not None:  # a large redraw spreads over frames
            ed.canvas_state.set_refined(False)
        if reading:
            ed.canvas_state.give_read_back(ed.canvas.read())
        self._peek()

    def _peek(self) -> None:
        """Read back what the canvas shows this frame, changing nothing (tests: ``peek_asked``)."""
        if self.peek_asked:
            self.ed.canvas_state.give_read_back(self.ed.canvas.read())
            self.peek_asked = False
