"""Requests of the synthesis pyramid spread over frames, and what changed for
the view (:class:`SpreadRequests`, a part of
:class:`~infinitex.engine.pyramid.Pyramid`).

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
from .stages import scratch_size


class SpreadRequests:
    """The pyramid's requests spread over frames (uses its buffers, targets and strip synthesis)."""

    def start_request(self, level: int, rect: Rect) -> None:
        """Begin what :meth:`request` does, to be carried out a piece at a time
        by :meth:`advance_request` (the pieces sized by ``self.pacer``): the
        editor's view refines between frames that stay short.

        While it runs no other synthesis may touch the pyramid: :meth:`request`,
        :meth:`settle` and any change of parameters drop it first, and the
        buffers stay consistent (each level claims what it keeps until its new
        strips are written back), so a dropped request loses only its work."""
        self._check(level, rect)
        self.end_request()
        self.gpu.activate()
        targets = self._targets(level, rect)
        self._request_job = (level, rect, self._request_steps(targets), dict(targets))
        self.request_pixels = 0
        # (what request_pixels reaches if no level keeps anything: a measure of progress)
        self.request_total = sum(self.padded(l, t).w * self.padded(l, t).h for l, t in targets)

    def claimed(self, l: int) -> Rect | None:
        """What level l holds or the request in progress is making it hold
        (their bounding box): where its pixels can be, now or once the request ends."""
        buf = self.buffers[l]
        held = buf.valid if buf is not None else None
        target = self._request_job[3].get(l) if self._request_job is not None else None
        if held is None or held.empty:
            return target
        if target is None:
            return held
        return Rect(min(held.x0, target.x0), min(held.y0, target.y0), max(held.x1, target.x1), max(held.y1, target.y1))

    @property
    def requesting(self) -> tuple[int, Rect] | None:
        """The (level, rect) of the request in progress, or None."""
        return None if self._request_job is None else self._request_job[:2]

    def advance_request(self, deadline: float) -> bool:
        """Carry the request in progress on until ``deadline``
        (``time.perf_counter()`` seconds); True when none is left."""
        if self._request_job is None:
            return True
        self.gpu.activate()
        steps = self._request_job[2]
        try:
            while True:
                next(steps)
                if time.perf_counter() >= deadline:
                    return False
        except StopIteration:
            self._request_job = None
            return True

    def end_request(self) -> None:
        """Drop the request in progress, if any (what it finished stays)."""
        if self._request_job is not None:
            steps = self._request_job[2]
            self._request_job = None
            steps.close()

    def _touch(self, l: int, r: Rect | None) -> None:
        """Level l's pixels changed over ``r`` (its valid rectangle grew or
        shrank there, or their values changed)."""
        if r is not None and not r.empty and self.touched is not None:
            self.touched.append((l, r))
            if len(self.touched) > 64:
                self.touched = None

    def take_touched(self) -> list[tuple[int, Rect]] | None:
        """The (level, rect)s whose pixels changed since the last call (None:
        anything may have), for a view that redraws only those."""
        out, self.touched = self.touched, []
        return out

    def _keep(self, l: int, target: Rect) -> tuple[Any, Rect | None, list[Rect]]:
        """Prepare level l for ``target``: its buffer, what it keeps (which
        becomes its valid rectangle until the new strips are written) and the
        new strips."""
        old = self.buffers[l].valid if self.buffers[l] is not None else None
        buf = self._ensure_buffer(l, target)
        keep = buf.valid.intersect(target) if buf.valid is not None else None
        keep = None if keep is None or keep.empty else keep
        buf.valid = keep
        if old is not None and old != keep:
            self._touch(l, old)
        return buf, keep, [target] if keep is None else target.minus(keep)

    def _request_steps(self, targets: list[tuple[int, Rect]]) -> Iterator[None]:
        for l, target in targets:
            buf, keep, strips = self._keep(l, target)
            for strip in strips:
                region = self.padded(l, strip)
                scratch = self._new_scratch(*scratch_size(region, self.params.subgrid))
                try:
                    yield from self._strip_steps(l, strip, scratch, buf, self.pacer)
                finally:
                    for o in (scratch[1], scratch[3], scratch[0], scratch[2]):
                        o.release()
                self.request_pixels += region.w * region.h
            buf.valid = target
            for strip in strips:
                self._touch(l, strip)
