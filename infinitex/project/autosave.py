"""Autosave: the open project written every few seconds while it has unsaved
edits, and recovered at the next start after a crash."""
from __future__ import annotations

import os
import time

from .document import Document, Project, ProjectError
from .format import PROJECT_SUFFIX, load_project, save_project


def state_dir() -> str:
    d = os.environ.get("INFINITEX_STATE") or os.path.join(
        os.environ.get("XDG_STATE_HOME") or os.path.join(os.path.expanduser("~"), ".local", "state"), "infinitex")
    return d


def autosave_path() -> str:
    return os.path.join(state_dir(), "autosave" + PROJECT_SUFFIX)


class Autosave:
    """Writes the open project every ``interval`` seconds while it has unsaved
    edits; the file is removed on a clean exit, so finding one at start-up
    means the last session did not end cleanly."""

    def __init__(self, path: str | None = None, interval: float = 10.0):
        self.path = path or autosave_path()
        self.interval = interval
        self._last = time.monotonic()
        self._written: Document | None = None
        self.set_aside: tuple[str, str] | None = None  # (new path, reason) of a broken autosave

    def pending(self) -> Project | None:
        """The autosaved project left by a session that did not end cleanly.

        Never raises: a broken autosave file (or anything else at its path) is
        set aside, renamed ``autosave-broken-TIME.itex`` next to it, and
        ``set_aside`` says where and why; start-up then goes on as usual."""
        if not os.path.lexists(self.path):
            return None
        try:
            return load_project(self.path)  # never allowed to read outside its folder
        except ProjectError as exc:
            self._set_aside(str(exc))
            return None

    def _set_aside(self, reason: str) -> None:
        folder = os.path.dirname(self.path)
        stamp = time.strftime("%Y%m%d-%H%M%S")
        for i in range(100):
            target = os.path.join(folder, f"autosave-broken-{stamp}{'-' + str(i) if i else ''}{PROJECT_SUFFIX}")
            if not os.path.lexists(target):
                break
        try:
            os.rename(self.path, target)
            self.set_aside = (target, reason)
        except OSError as exc:
            self.set_aside = (self.path, f"{reason} (it could not be renamed: {exc.strerror or exc})")

    def pending_time(self) -> float | None:
        try:
            return os.path.getmtime(self.path)
        except OSError:
            return None

    def tick(self, project: Project, dirty: bool, force: bool = False) -> bool:
        """Write when due; returns True when written."""
        now = time.monotonic()
        if not force and (now - self._last < self.interval):
            return False
        self._last = now
        if not dirty or project.document == self._written:
            return False
        try:
            os.makedirs(os.path.dirname(self.path), exist_ok=True)
        except OSError as exc:
            raise ProjectError(f"The autosave folder cannot be made: {exc.strerror or exc}.") from None
        save_project(self.path, project, embed=True)
        self._written = project.document
        return True

    def clear(self) -> None:
        self._written = None
        try:
            os.unlink(self.path)
        except OSError:
            pass
