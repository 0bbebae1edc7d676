"""Local updates of the synthesis pyramid: what a paint dab or a moved feature
changes, re-synthesized in place, at once or a time budget at a time
(:class:`LocalUpdates`, a part of :class:`~infinitex.engine.pyramid.Pyramid`:
``Pyramid.updates``, which owns the dirty regions and the job in progress).

Each level keeps a dirty region: the pixels within correction reach of an input
that changed (a changed field value, or a child of a parent pixel whose value
changed). :meth:`LocalUpdates.settle` synthesizes them coarse to fine; comparing
each region with what it held before tells which pixels actually changed, and
only those reach the next level, so the result is bit-identical to synthesizing
from scratch. A region is one job whose draws run a piece at a time on its own
scratch buffers, so the editor spreads a large update over frames at no extra
cost while it pans, draws and takes more strokes.
"""
from __future__ import annotations

import time

from .controls import Controls
from .rect import Rect, cover_rects, merge_rects
from .stages import release_scratch

DIRTY_RECTS = 64  # a level's dirty region: at most about this many rectangles


class LocalUpdates:
    """The pyramid's local updates (uses its buffers, margins and strip synthesis)."""

    def __init__(self, pyr) -> None:
        self.pyr = pyr
        # Per level, the regions a local update has still to synthesize again
        # (already grown by the level's reach; clipped to what is held when done).
        self.dirty: list[list[Rect]] = [[] for _ in range(pyr.an.L + 1)]
        self._job = None  # the dirty region being synthesized: (level, its steps, its scratch)
        self.jobs_started = 0  # local-update jobs started so far (a quick look's patch notes it)

    def forget(self, first_level: int = 0) -> None:
        """No level from ``first_level`` on is dirty (their contents are forgotten)."""
        if self._job is not None and self._job[0] >= first_level:
            self.end_job()
        for l in range(first_level, self.pyr.an.L + 1):
            self.dirty[l] = []

    def update_controls(self, controls: Controls, changed: list[Rect] | None = None, *, defer: bool = False) -> int:
        """Adopt new controls that differ from the current ones only inside the
        finest-level canvas rectangles ``changed`` (where an edit reached: a
        dab's box, a feature's old and new circles; None: found by comparing the
        two controls, :meth:`Controls.changed_rects`), re-synthesizing in place
        just what that changes in the held buffers. A change that reaches
        everywhere (:meth:`Controls.reaches_everywhere`) starts again, whatever
        ``changed`` says.

        The pixels whose field value changed, grown by the reach of correction
        (outside it no result can change), become each level's dirty region;
        :meth:`settle` synthesizes them again coarse to fine. Comparing each
        strip with what it held before tells which pixels actually changed, and
        only their children join the next level's dirty region. The result is
        bit-identical to synthesizing from scratch; areas not held cost nothing
        and are synthesized with the new controls when shown.

        ``defer``: only record the work (the editor settles it a little per
        frame); else it is done now. Returns the level pixels synthesized now."""
        pyr = self.pyr
        controls = controls.normalized()
        controls.validate(pyr.an.size, pyr.an.settings.lattice)
        pyr.gpu.activate()
        if pyr.controls.reaches_everywhere(controls):
            changed = None
        elif changed is None:
            changed = [Rect(*r) for r in pyr.controls.changed_rects(controls)]
        else:
            changed = [r if isinstance(r, Rect) else Rect(*r) for r in changed]
        if changed is None:
            pyr.set_params(pyr.params, controls)  # the whole canvas changes
            pyr.pixels_synthesized = 0
            return 0
        # A dab's tiles touch without overlapping: grown by a pixel they merge into
        # its box once here, not once a level (a 512 px dab is 250 tiles).
        changed = merge_rects([r.pad(1, 1, 1, 1) for r in changed if not r.empty])
        # The labels' blur (a level pixel) and their erosion (controls/labels.py: one more).
        b = 2 if controls.labels_active or pyr.controls.labels_active else 0
        if controls.directed and not pyr.controls.directed:
            pyr.state.widen()  # a first direction dab: the same state, with remainders of 0
        pyr.adopt_controls(controls)
        L = pyr.an.L
        pyr.looks.want(changed, b + 1)
        for l in range(L + 1):
            k = L - l
            self.mark(l, [r.coarser(k).pad(b, b, b, b) for r in changed if not r.empty])
        pyr.pixels_synthesized = 0
        if not defer:
            self.settle()
        return pyr.pixels_synthesized

    def mark(self, l: int, inputs: list[Rect]) -> None:
        """Add the pixels within reach of changed inputs to level l's dirty
        region, as far as the level holds pixels or a request in progress is
        making it hold them (:meth:`SpreadRequests.claimed`): what it does not hold is
        synthesized with the current controls, from a parent that is exact or
        itself dirty there, whenever it comes into view (and :meth:`settle`
        skips it anyway). So a dab of any size, at any angle of a model, marks
        at most that window, in a bounded number of rectangles
        (:func:`~infinitex.engine.rect.cover_rects`)."""
        held = self.pyr.requests.claimed(l)
        if held is None or held.empty:
            self.dirty[l] = []
            return
        reach = max(self.pyr.margins[l])
        grown = [r.pad(reach, reach, reach, reach) for r in inputs if not r.empty]
        if grown:
            self.dirty[l] = cover_rects(self.dirty[l] + grown, held, DIRTY_RECTS)

    @property
    def updating(self) -> bool:
        """A dirty region is being synthesized (it must end before a request starts)."""
        return self._job is not None

    @property
    def settled(self) -> bool:
        """No local update is waiting."""
        return self._job is None and not any(self.dirty)

    def settle(self, budget_s: float | None = None, regions: int | None = None) -> bool:
        """Carry out the waiting local updates, coarsest level first, for about
        ``budget_s`` seconds (None: all of them): a dirty region is one job,
        synthesized a draw at a time (a piece of a draw at a time, on its own
        scratch buffers), so it spreads over calls at no extra cost. Adds the
        level pixels synthesized to ``pixels_synthesized``; True when none is left.

        Between calls the buffers stay consistent: a level's pixels are exact
        for its parent's current pixels except within its dirty region, so new
        strips synthesized meanwhile (a pan) are right or marked, and the final
        result is the fresh synthesis. ``regions``: return after finishing
        that many dirty regions (a request may start between two)."""
        pyr = self.pyr
        deadline = None if budget_s is None else time.perf_counter() + budget_s
        pyr.requests.end()  # the two never interleave (see SpreadRequests.start)
        while True:
            if self._job is None:
                nxt = next(((l, r) for l in range(pyr.an.L + 1) for r in self.dirty[l]), None)
                if nxt is None:
                    pyr.looks.drop(None)  # all is exact
                    return True
                l, r = nxt
                self.dirty[l].remove(r)
                buf = pyr.buffers[l]
                r = r.intersect(buf.valid) if buf is not None and buf.valid is not None else Rect(0, 0, 0, 0)
                if r.empty:
                    continue
                region = pyr.padded(l, r)
                scratch = pyr.new_scratch(region)  # its own: other strips may run meanwhile
                pace = None if deadline is None else pyr.pacer
                self._job = (l, pyr.strips.strip_steps(l, r, scratch, None, pace), scratch)
                self.jobs_started += 1
                pyr.pixels_synthesized += region.w * region.h
            l, steps, _ = self._job
            try:
                while True:
                    next(steps)
                    if deadline is not None and time.perf_counter() > deadline:
                        return False
            except StopIteration as stop:
                changed = stop.value
            self.end_job()
            pyr.requests.touch(l, changed)
            pyr.looks.job_done(l)
            if changed is not None and l < pyr.an.L:  # only pixels whose value changed reach the next level
                self.mark(l + 1, [changed.children()])
            if regions is not None:
                regions -= 1
                if regions <= 0:
                    return self.settled

    def end_job(self) -> None:
        """Drop the local update in progress (finished or no longer wanted)."""
        if self._job is not None:
            _, steps, scratch = self._job
            self._job = None
            steps.close()
            release_scratch(scratch)
