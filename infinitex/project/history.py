"""Undo/redo over immutable documents."""
from __future__ import annotations

from .document import Document


class History:
    """Undo/redo over immutable documents.

    ``apply(doc, label, group=g)`` with the same non-None ``g`` as the previous
    call replaces the current document without a new undo step: a slider drag
    is one step. ``end_group()`` closes the group (on mouse release).
    """

    def __init__(self, doc: Document, limit: int = 500):
        self.current = doc
        self.undo_stack: list[tuple[Document, str]] = []
        self.redo_stack: list[tuple[Document, str]] = []
        self.limit = limit
        self._group: object = None
        self.saved: Document | None = doc

    @property
    def dirty(self) -> bool:
        return self.current != self.saved

    def apply(self, doc: Document, label: str, group: object = None) -> bool:
        if doc == self.current:
            return False
        doc.validate()
        if group is None or group != self._group:
            self.undo_stack.append((self.current, label))
            del self.undo_stack[:-self.limit]
        self._group = group
        self.redo_stack.clear()
        self.current = doc
        return True

    def end_group(self) -> None:
        self._group = None

    def can_undo(self) -> bool:
        return bool(self.undo_stack)

    def can_redo(self) -> bool:
        return bool(self.redo_stack)

    def undo_label(self) -> str:
        return self.undo_stack[-1][1] if self.undo_stack else ""

    def redo_label(self) -> str:
        return self.redo_stack[-1][1] if self.redo_stack else ""

    def undo(self) -> bool:
        if not self.undo_stack:
            return False
        doc, label = self.undo_stack.pop()
        self.redo_stack.append((self.current, label))
        self.current = doc
        self._group = None
        return True

    def redo(self) -> bool:
        if not self.redo_stack:
            return False
        doc, label = self.redo_stack.pop()
        self.undo_stack.append((self.current, label))
        self.current = doc
        self._group = None
        return True

    def mark_saved(self) -> None:
        self.saved = self.current
