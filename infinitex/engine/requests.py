"""Requests of the synthesis pyramid spread over frames, and what changed for
the view (:class:`SpreadRequests`, a part of
:class:`~infinitex.engine.pyramid.Pyramid`: ``Pyramid.requests``, which owns the
request in progress and the record of what changed).

The editor's view refines between frames that stay short: a request is planned
at once (what each level must hold) and synthesized a piece of a draw at a time,
each level claiming only what it keeps until its new strips are written back.
The pyramid also records which texels changed (a level's valid rectangle grew or
shrank, a local update rewrote pixels), so the canvas redraws only those.
"""
from __future__ import annotations

import time
from collections.abc import Iterator
from typing import Any

from .rect import Rect
from .stages import release_scratch


class SpreadRequests:
    """The pyramid's requests spread over frames (uses its buffers, targets and strip synthesis)."""

    def __init__(self, pyr) -> None:
        self.pyr = pyr
        self._job = None  # a request spread over frames: (level, rect, its steps, its targets)
        self.pixels = 0  # level pixels the request in progress has synthesized
        self.total = 0  # what ``pixels`` reaches if no level keeps anything: a measure of progress
        self.touched: list[tuple[int, Rect]] | None = []  # what changed since take_touched (None: all)

    def start(self, level: int, rect: Rect) -> None:
        """Begin what :meth:`Pyramid.request` does, to be carried out a piece at
        a time by :meth:`advance` (the pieces sized by ``Pyramid.pacer``): the
        editor's view refines between frames that stay short.

        While it runs no other synthesis may touch the pyramid:
        :meth:`Pyramid.request`, :meth:`LocalUpdates.settle` and any change of
        parameters drop it first, and the buffers stay consistent (each level
        claims what it keeps until its new strips are written back), so a
        dropped request loses only its work."""
        pyr = self.pyr
        pyr.check(level, rect)
        self.end()
        pyr.gpu.activate()
        targets = pyr.targets(level, rect)
        self._job = (level, rect, self._steps(targets), dict(targets))
        self.pixels = 0
        self.total = sum(pyr.padded(l, t).w * pyr.padded(l, t).h for l, t in targets)

    def claimed(self, l: int) -> Rect | None:
        """What level l holds or the request in progress is making it hold
        (their bounding box): where its pixels can be, now or once the request ends."""
        buf = self.pyr.buffers[l]
        held = buf.valid if buf is not None else None
        target = self._job[3].get(l) if self._job is not None else None
        if held is None or held.empty:
            return target
        if target is None:
            return held
        return Rect(min(held.x0, target.x0), min(held.y0, target.y0), max(held.x1, target.x1), max(held.y1, target.y1))

    @property
    def current(self) -> tuple[int, Rect] | None:
        """The (level, rect) of the request in progress, or None."""
        return None if self._job is None else self._job[:2]

    def advance(self, deadline: float) -> bool:
        """Carry the request in progress on until ``deadline``
        (``time.perf_counter()`` seconds); True when none is left."""
        if self._job is None:
            return True
        self.pyr.gpu.activate()
        steps = self._job[2]
        try:
            while True:
                next(steps)
                if time.perf_counter() >= deadline:
                    return False
        except StopIteration:
            self._job = None
            return True

    def end(self) -> None:
        """Drop the request in progress, if any (what it finished stays)."""
        if self._job is not None:
            steps = self._job[2]
            self._job = None
            steps.close()

    def touch(self, l: int, r: Rect | None) -> None:
        """Level l's pixels changed over ``r`` (its valid rectangle grew or
        shrank there, or their values changed)."""
        if r is not None and not r.empty and self.touched is not None:
            self.touched.append((l, r))
            if len(self.touched) > 64:
                self.touched = None

    def touch_all(self) -> None:
        """Any pixel may have changed (levels forgotten)."""
        self.touched = None

    def take_touched(self) -> list[tuple[int, Rect]] | None:
        """The (level, rect)s whose pixels changed since the last call (None:
        anything may have), for a view that redraws only those."""
        out, self.touched = self.touched, []
        return out

    def keep(self, l: int, target: Rect) -> tuple[Any, Rect | None, list[Rect]]:
        """Prepare level l for ``target``: its buffer, what it keeps (which
        becomes its valid rectangle until the new strips are written) and the
        new strips."""
        pyr = self.pyr
        old = pyr.buffers[l].valid if pyr.buffers[l] is not None else None
        buf = pyr.ensure_buffer(l, target)
        keep = buf.valid.intersect(target) if buf.valid is not None else None
        keep = None if keep is None or keep.empty else keep
        buf.valid = keep
        if old is not None and old != keep:
            self.touch(l, old)
        return buf, keep, [target] if keep is None else target.minus(keep)

    def _steps(self, targets: list[tuple[int, Rect]]) -> Iterator[None]:
        pyr = self.pyr
        for l, target in targets:
            buf, keep, strips = self.keep(l, target)
            for strip in strips:
                region = pyr.padded(l, strip)
                scratch = pyr.new_scratch(region)
                try:
                    yield from pyr.strips.strip_steps(l, strip, scratch, buf, pyr.pacer)
                finally:
                    release_scratch(scratch)
                self.pixels += region.w * region.h
            buf.valid = target
            for strip in strips:
                self.touch(l, strip)
