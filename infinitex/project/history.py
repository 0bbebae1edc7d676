"""Undo/redo over immutable documents, each step with the canvas region it changed."""
from __future__ import annotations

from typing import NamedTuple, Optional

from .document import Document

# Where an edit changed the canvas: finest-level canvas rectangles (x0, y0, x1,
# y1), outside which the new document's controls read as the old one's; None:
# not said (the synthesis compares the two documents' controls to find it).
Region = Optional[tuple]
JOURNAL = 64  # the changes :meth:`History.changes_between` looks back over


def union(a: Region, b: Region) -> Region:
    """Both regions (None, not said, wins)."""
    return None if a is None or b is None else a + b


class Step(NamedTuple):
    doc: Document   # the document before the step (on the undo stack) or after it (redo)
    label: str
    region: Region  # where the step changed the canvas


class History:
    """Undo/redo over immutable documents.

    ``apply(doc, label, group=g)`` with the same non-None ``g`` as the previous
    call replaces the current document without a new undo step: a slider drag
    is one step. ``end_group()`` closes the group (on mouse release).

    Each change says where it reached the canvas (``region``, see
    :data:`Region`); a step keeps the union of its changes', so an undo or a
    redo says it too, and :meth:`changes_between` hands the synthesis where the
    document changed since the one it shows, without comparing the two.
    """

    def __init__(self, doc: Document, limit: int = 500):
        self.current = doc
        self.undo_stack: list[Step] = []
        self.redo_stack: list[Step] = []
        self.limit = limit
        self._group: object = None
        self.saved: Document | None = doc
        self._journal: list[tuple[Document, Region]] = [(doc, ())]  # each document lately current, and its change

    @property
    def dirty(self) -> bool:
        return self.current != self.saved

    def apply(self, doc: Document, label: str, group: object = None, region: Region = None) -> bool:
        """Make ``doc`` current (``region``: where it differs from the current
        one on the canvas; None: not said)."""
        if doc == self.current:
            return False
        doc.validate()
        region = None if region is None else tuple(tuple(int(v) for v in r) for r in region)
        if group is None or group != self._group or not self.undo_stack:
            self.undo_stack.append(Step(self.current, label, region))
            del self.undo_stack[:-self.limit]
        else:
            top = self.undo_stack[-1]
            self.undo_stack[-1] = top._replace(region=union(top.region, region))
        self._group = group
        self.redo_stack.clear()
        self._move(doc, region)
        return True

    def _move(self, doc: Document, region: Region) -> None:
        self.current = doc
        self._journal.append((doc, region))
        del self._journal[:-JOURNAL]

    def changes_between(self, before: Document | None, after: Document) -> Region:
        """Where ``after``, the current document, differs from ``before`` on the
        canvas, when ``before`` was current lately (the last JOURNAL changes);
        else None (not known)."""
        if before is None or after is not self.current:
            return None
        out: Region = ()
        for doc, region in reversed(self._journal):
            if doc is before:
                return out
            out = union(out, region)
        return None

    def end_group(self) -> None:
        self._group = None

    def can_undo(self) -> bool:
        return bool(self.undo_stack)

    def can_redo(self) -> bool:
        return bool(self.redo_stack)

    def undo_label(self) -> str:
        return self.undo_stack[-1].label if self.undo_stack else ""

    def redo_label(self) -> str:
        return self.redo_stack[-1].label if self.redo_stack else ""

    def undo(self) -> bool:
        if not self.undo_stack:
            return False
        step = self.undo_stack.pop()
        self.redo_stack.append(step._replace(doc=self.current))
        self._move(step.doc, step.region)
        self._group = None
        return True

    def redo(self) -> bool:
        if not self.redo_stack:
            return False
        step = self.redo_stack.pop()
        self.undo_stack.append(step._replace(doc=self.current))
        self._move(step.doc, step.region)
        self._group = None
        return True

    def mark_saved(self) -> None:
        self.saved = self.current
