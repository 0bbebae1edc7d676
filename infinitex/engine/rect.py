"""Integer rectangles of level pixels: what the pyramid holds, requests and updates."""
from __future__ import annotations

import heapq
from dataclasses import dataclass


@dataclass(frozen=True)
class Rect:
    """Half-open integer rectangle [x0, x1) x [y0, y1)."""

    x0: int
    y0: int
    x1: int
    y1: int

    @classmethod
    def of(cls, x: int, y: int, w: int, h: int) -> "Rect":
        return cls(int(x), int(y), int(x) + int(w), int(y) + int(h))

    @property
    def w(self) -> int:
        return self.x1 - self.x0

    @property
    def h(self) -> int:
        return self.y1 - self.y0

    @property
    def area(self) -> int:
        return max(0, self.w) * max(0, self.h)

    @property
    def empty(self) -> bool:
        return self.w <= 0 or self.h <= 0

    def contains(self, o: "Rect") -> bool:
        return self.x0 <= o.x0 and self.y0 <= o.y0 and o.x1 <= self.x1 and o.y1 <= self.y1

    def intersect(self, o: "Rect") -> "Rect":
        return Rect(max(self.x0, o.x0), max(self.y0, o.y0), min(self.x1, o.x1), min(self.y1, o.y1))

    def pad(self, left: int, right: int, top: int, bottom: int) -> "Rect":
        return Rect(self.x0 - left, self.y0 - top, self.x1 + right, self.y1 + bottom)

    def align(self, a: int) -> "Rect":
        """Smallest enclosing rectangle whose edges are multiples of a."""
        return Rect((self.x0 // a) * a, (self.y0 // a) * a, -((-self.x1) // a) * a, -((-self.y1) // a) * a)

    def coarser(self, k: int) -> "Rect":
        """The pixels k levels coarser that cover this rectangle (k = 1: :meth:`half`)."""
        return Rect(self.x0 >> k, self.y0 >> k, -((-self.x1) >> k), -((-self.y1) >> k))

    def half(self) -> "Rect":
        """The parent-level pixels whose children cover this rectangle."""
        return Rect(self.x0 // 2, self.y0 // 2, (self.x1 - 1) // 2 + 1, (self.y1 - 1) // 2 + 1)

    def parents(self) -> "Rect":
        """The parent-level pixels this rectangle is upsampled from: each pixel
        reads its own parent or, per axis, the nearest other one (common.glsl
        parent_step), so :meth:`half` grown by a child pixel on each side."""
        return self.pad(1, 1, 1, 1).half()

    def children(self) -> "Rect":
        """The pixels of the next finer level that read these parent pixels
        (the inverse of :meth:`parents`)."""
        return Rect(2 * self.x0 - 1, 2 * self.y0 - 1, 2 * self.x1 + 1, 2 * self.y1 + 1)

    def minus(self, o: "Rect") -> list["Rect"]:
        """self \\ o as at most 4 disjoint rectangles."""
        i = self.intersect(o)
        if i.empty:
            return [] if self.empty else [self]
        out = [Rect(self.x0, self.y0, self.x1, i.y0), Rect(self.x0, i.y1, self.x1, self.y1),
               Rect(self.x0, i.y0, i.x0, i.y1), Rect(i.x1, i.y0, self.x1, i.y1)]
        return [r for r in out if not r.empty]


def uncovered(rects: list[Rect], by: list[Rect]) -> list[Rect]:
    """The parts of ``rects`` outside every rectangle of ``by``."""
    parts = [r for r in rects if not r.empty]
    for b in by:
        parts = [q for p in parts for q in p.minus(b) if not q.empty]
    return parts


def merge_rects(rects: list[Rect]) -> list[Rect]:
    """Overlapping rectangles merged into their bounding boxes, until no two
    overlap (empty ones dropped).

    Each pass finds every overlapping pair with a sweep along x (rectangles
    sorted by x0; those still open at a rectangle's x0 are the only
    candidates) and joins the connected groups at once, so n rectangles cost
    about n log n plus the pairs that really meet, per pass, and a pass
    happens only when the previous one merged something. (Merging one pair
    and starting over, as before, took minutes for the 14,000 tiles a huge
    dab touched.)"""
    out = list(dict.fromkeys(r for r in rects if not r.empty))
    while len(out) > 1:
        n = len(out)
        parent = list(range(n))

        def root(i: int) -> int:
            while parent[i] != i:
                parent[i] = parent[parent[i]]
                i = parent[i]
            return i

        order = sorted(range(n), key=lambda i: out[i].x0)
        heap: list[tuple[int, int]] = []  # (x1, index) of the rectangles open at the sweep's x
        open_: dict[int, Rect] = {}
        merged = False
        for i in order:
            r = out[i]
            while heap and heap[0][0] <= r.x0:
                open_.pop(heapq.heappop(heap)[1], None)
            for j, o in open_.items():
                if o.y0 < r.y1 and r.y0 < o.y1:  # x ranges overlap: both are open here
                    a, b = root(i), root(j)
                    if a != b:
                        parent[b] = a
                        merged = True
            heapq.heappush(heap, (r.x1, i))
            open_[i] = r
        if not merged:
            break
        boxes: dict[int, list[int]] = {}
        for i, r in enumerate(out):
            b = boxes.setdefault(root(i), [r.x0, r.y0, r.x1, r.y1])
            b[0], b[1], b[2], b[3] = min(b[0], r.x0), min(b[1], r.y0), max(b[2], r.x1), max(b[3], r.y1)
        out = [Rect(*b) for b in boxes.values()]
    return out


def cover_rects(rects: list[Rect], within: Rect, most: int = 64) -> list[Rect]:
    """At most about ``most`` disjoint rectangles covering ``rects`` clipped to
    ``within``: merged (:func:`merge_rects`), and when more remain, snapped
    outward to a grid of ``within`` cut about sqrt(most) ways a side first (a
    cover: a few pixels more, never fewer). What a region's bookkeeping costs
    is then bounded whatever an edit sends (a dirty region's pixels are
    redone exactly, so a larger cover changes only the work)."""
    clipped = [r.intersect(within) for r in rects]
    out = merge_rects([r for r in clipped if not r.empty])
    if len(out) <= most:
        return out
    k = max(1, int(most ** 0.5))
    g = max(1, -(-max(within.w, within.h) // k))
    return merge_rects([r.align(g).intersect(within) for r in out])
