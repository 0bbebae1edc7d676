"""A quick look at a local update before it is exact (:class:`QuickLooks`, a
part of :class:`~infinitex.engine.pyramid.Pyramid`: ``Pyramid.looks``, which
owns the patches).

An exact local update redoes every level a dab reaches, coarse to fine, each
grown by its correction reach: at the Balanced preset on a CPU that is a
tenth of a second and more per dab, and a stroke's dabs come one per frame.
So the editor shows each dab at once as a *patch*: the dab's own rectangle of
the shown level, synthesized with the new controls over the last few levels
only (``PREVIEW_LEVELS``), from the coarser levels as they are held. It shows
the dab's effect at the scales under the brush in the frame it was made, at a
few milliseconds, on its own buffers: the pyramid's levels are never written,
so the exact update (``LocalUpdates.settle``) goes on as before and its result
is unchanged.

A patch is dropped, and the exact texels shown again, as soon as they account
for its dab: the shown level has been synthesized over the patch's rectangle
by a job that started after the patch was made (a job of a level starts only
when every coarser level is clean, so it saw every dab made before it) and
none of its dirty regions still meets the patch. Every patch goes when the
pyramid is settled, invalidated, or shown at another level.
"""
from __future__ import annotations

import time
from dataclasses import dataclass
from typing import Any

from .rect import Rect, merge_rects

PREVIEW_LEVELS = 3  # the finest levels a patch synthesizes again (the coarser ones are taken as held)
LOOK_S = 0.012  # fewer levels where a patch would take longer (its cost per pixel learned as they are made)
MAX_PATCHES = 48    # a stroke's patches beyond these are merged into new ones


@dataclass
class Patch:
    """A quick look at level ``level`` over ``rect``, held in ``buf``."""

    level: int
    rect: Rect
    buf: Any  # a pyramid level buffer (non-scrolling) holding at least ``rect``
    seq: int  # the local-update jobs started before it was made


class QuickLooks:
    """The pyramid's quick looks at local updates (uses its buffers, margins and strip synthesis)."""

    def __init__(self, pyr) -> None:
        self.pyr = pyr
        self.patches: list[Patch] = []
        self._wanted: list[Rect] = []  # finest-level rectangles edited since the last look
        self.made = 0  # patches made so far (benchmarks: when an edit first shows)
        self._cost = 6e-7  # seconds per level pixel of a patch (about 10 ms per 16k px at Balanced on llvmpipe)

    def want(self, changed: list[Rect], pad: int = 1) -> None:
        """Note finest-level rectangles an edit changed, for the next :meth:`look`."""
        self._wanted = merge_rects(self._wanted + [r.pad(pad, pad, pad, pad) for r in changed if not r.empty])

    @property
    def wanted(self) -> bool:
        """Edits were noted since the last :meth:`look`."""
        return bool(self._wanted)

    def look(self, level: int, want: Rect, skip: bool = False) -> int:
        """Make a patch of every edit noted since the last call, at ``level``
        (the shown one) within ``want`` (``skip``: forget them; their exact
        update will show as soon); drop the patches of another level or no
        longer held. Returns the level pixels synthesized."""
        pyr = self.pyr
        L = pyr.an.L
        buf = pyr.buffers[level] if 0 <= level <= L else None
        held = buf.valid if buf is not None and buf.valid is not None else None
        self.drop(lambda p: p.level != level or held is None or not held.contains(p.rect))
        wanted, self._wanted = self._wanted, []
        if skip or held is None or level < 1 or pyr.updates.settled:
            return 0
        k = L - level
        rects = [r.coarser(k).intersect(want).intersect(held) for r in wanted]
        pixels = 0
        for r in merge_rects([r for r in rects if not r.empty]):
            pixels += self.make_patch(level, r)
        if len(self.patches) > MAX_PATCHES:  # a long stroke: the oldest merged into fresh ones
            old = self.patches[:len(self.patches) - MAX_PATCHES // 2]
            self.drop(lambda p: any(p is o for o in old))
            for r in merge_rects([p.rect for p in old]):
                pixels += self.make_patch(level, r)
        return pixels

    def make_patch(self, d: int, rect: Rect) -> int:
        """Synthesize level d over ``rect`` again on its PREVIEW_LEVELS finest
        levels (fewer where that would take over LOOK_S), from the coarser ones
        as held, on buffers of its own. Returns the level pixels synthesized (0:
        the held levels do not cover what it reads; no patch)."""
        pyr = self.pyr
        t0 = time.perf_counter()
        plan = None
        for n in range(min(PREVIEW_LEVELS, d), 0, -1):
            plan = self._plan(d, rect, n)
            if plan is not None and sum(pyr.padded(l, r).area for l, r in plan[0].items()) * self._cost <= LOOK_S:
                break
        if plan is None:
            return 0
        strips, need = plan
        l0 = min(strips)
        made: dict[int, Any] = {}
        pixels = 0
        try:
            for l in range(l0, d + 1):
                n = need[l]
                out = pyr.new_buffer(n)
                made[l] = out
                pyr.copy(pyr.buffers[l], out, n)
                out.valid = n
                region = pyr.padded(l, strips[l])
                # (jobs and requests spread over frames run on scratch of their own)
                for _ in pyr.strips.strip_steps(l, strips[l], pyr.scratch_pair(region), out, parent=made.get(l - 1)):
                    pass
                pixels += region.w * region.h
            self.patches.append(Patch(d, rect, made.pop(d), pyr.updates.jobs_started))
            self.made += 1
            pyr.requests.touch(d, rect)
            pyr.gpu.ctx.finish()  # (shown this frame anyway) timed, to size the next ones
            cost = (time.perf_counter() - t0) / max(1, pixels)
            self._cost = 0.7 * self._cost + 0.3 * cost
        finally:
            for b in made.values():
                b.release()
        return pixels

    def _plan(self, d: int, rect: Rect, n: int) -> tuple[dict, dict] | None:
        """The strips a patch of level d over ``rect`` synthesizes on its n finest
        levels, and what of each level it reads (copied from the held ones); None
        when the held levels do not cover that."""
        l0 = d - n + 1
        strips = {d: rect}
        for l in range(d - 1, l0 - 1, -1):
            strips[l] = strips[l + 1].half().pad(1, 1, 1, 1)
        need = {d: rect}
        for l in range(d - 1, l0 - 2, -1):
            need[l] = self.pyr.padded(l + 1, strips[l + 1]).parents()
        for l, n_l in need.items():
            b = self.pyr.buffers[l]
            if b is None or b.valid is None or not b.valid.contains(n_l):
                return None
        return strips, need

    def drop(self, which) -> None:
        """Drop the patches ``which(patch)`` selects (all: None), showing the level again there."""
        keep = []
        for p in self.patches:
            if which is None or which(p):
                self.pyr.requests.touch(p.level, p.rect)
                p.buf.release()
            else:
                keep.append(p)
        self.patches = keep

    def job_done(self, l: int) -> None:
        """A local-update job of level l ended: drop the patches it accounts for."""
        seq = self.pyr.updates.jobs_started  # the job that just ended (one runs at a time)
        dirty = self.pyr.updates.dirty[l]
        self.drop(lambda p: p.level == l and p.seq < seq
                           and not any(not r.intersect(p.rect).empty for r in dirty))
