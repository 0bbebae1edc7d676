"""Integer rectangles of level pixels: what the pyramid holds, requests and updates."""
from __future__ import annotations

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

    def minus(self, o: "Rect") -> list["Rect"]:
        """self \\ o as at most 4 disjoint rectangles."""
        i = self.intersect(o)
        if i.empty:
            return [] if self.empty else [self]
        out = [Rect(self.x0, self.y0, self.x1, i.y0), Rect(self.x0, i.y1, self.x1, self.y1),
               Rect(self.x0, i.y0, i.x0, i.y1), Rect(i.x1, i.y0, self.x1, i.y1)]
        return [r for r in out if not r.empty]


def merge_rects(rects: list[Rect]) -> list[Rect]:
    """Overlapping rectangles merged into their bounding boxes (until disjoint)."""
    out = list(rects)
    merged = True
    while merged:
        merged = False
        for i in range(len(out)):
            for j in range(i + 1, len(out)):
                if not out[i].intersect(out[j]).empty:
                    a, b = out[i], out[j]
                    out[i] = Rect(min(a.x0, b.x0), min(a.y0, b.y0), max(a.x1, b.x1), max(a.y1, b.y1))
                    del out[j]
                    merged = True
                    break
            if merged:
                break
    return out
