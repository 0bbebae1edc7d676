"""Autosave: the open project written every few seconds while it has unsaved
edits, and recovered at the next start after a crash.

Every editor process writes its own file, ``autosave-PID-RANDOM.itex`` in the
state folder, and holds an advisory lock (``flock``) on
``autosave-PID-RANDOM.lock`` beside it from its first write until it ends; the
system drops the lock however the process ends. At start-up the autosaves
whose lock is free (their writer is gone) are an earlier session's unsaved
work: :meth:`Autosave.pending_all` lists them, oldest first, and claims each
(takes its lock), so that two editors starting together do not both offer it.
An ``autosave.itex`` left by an older version is offered the same way. A
process removes only its own file (:meth:`Autosave.clear`) and the ones it
recovered or discarded (:meth:`Autosave.discard`); a live editor's file is
never listed, never touched.

An autosave embeds the exemplar and maps while the file stays within the
project limit (format.fitted_project_json); the others are kept beside it, as
``autosave-PID-RANDOM-SHA256.data``, and referenced by that name with their
content hash, so every autosave can be recovered (whatever the exemplar's size,
even if its file changed) and is read from the state folder only, like any
project from its own folder: an autosave cannot make the editor read another
file. They are removed with the autosave.
"""
from __future__ import annotations

import os
import re
import secrets
import stat
import threading
import time
from dataclasses import dataclass

from infinitex.engine.safeio import WriteError, atomic_write

from .document import Document, ExemplarSource, Project, ProjectError
from .format import PROJECT_SUFFIX, load_project, save_project

try:
    import fcntl
except ImportError:  # no advisory locks (Windows): every autosave found is offered
    fcntl = None

LEGACY_NAME = "autosave" + PROJECT_SUFFIX  # the one file of versions before per-process autosaves
NAME_RE = re.compile(r"(autosave-\d+-[0-9a-f]{8})(\.itex|\.lock|-[0-9a-f]{64}\.data)\Z")  # file, lock, stored
MAX_PENDING = 32  # autosaves looked at per start (the oldest); the others wait for a later start


def state_dir() -> str:
    d = os.environ.get("INFINITEX_STATE") or os.path.join(
        os.environ.get("XDG_STATE_HOME") or os.path.join(os.path.expanduser("~"), ".local", "state"), "infinitex")
    return d


def autosave_path() -> str:
    """A new autosave file name for this process, in the state folder."""
    return os.path.join(state_dir(), f"autosave-{os.getpid()}-{secrets.token_hex(4)}{PROJECT_SUFFIX}")


def lock_path(path: str) -> str:
    """The lock file of the autosave ``path``."""
    return os.path.splitext(path)[0] + ".lock"


def stored_files(path: str) -> list[str]:
    """The files stored beside the autosave ``path`` (exemplars too large to embed)."""
    stem = os.path.basename(os.path.splitext(path)[0])
    pattern = re.compile(re.escape(stem) + r"-[0-9a-f]{64}\.data\Z")
    try:
        with os.scandir(os.path.dirname(path)) as entries:
            return [e.path for e in entries if pattern.match(e.name)]
    except OSError:
        return []


def _remove(paths) -> None:
    for p in paths:
        try:
            os.unlink(p)
        except OSError:
            pass


@dataclass(frozen=True)
class Recoverable:
    """An earlier session's unsaved work: its autosave file, its time, and what
    the question about it names (its project's origin and exemplar). The file is
    read whole once at start-up, to set a broken one aside, and not kept: the
    project is loaded again only when it is recovered (``project``), so a dozen
    crashed editors' exemplars are never held at once."""

    path: str
    time: float
    origin: str | None = None
    name: str = ""

    @property
    def project(self) -> Project:
        """The autosaved project, read from its file (ProjectError if it can no longer be)."""
        return load_project(self.path)


def _lock(path: str) -> int | None:
    """A descriptor holding the exclusive lock of the lock file ``path`` (made
    if missing), None when another process holds it; OSError when it cannot
    be locked at all. The file is checked to be still the one at ``path``
    once locked (a lock on a file just removed is no lock)."""
    flags = getattr(os, "O_NOFOLLOW", 0) | getattr(os, "O_CLOEXEC", 0)
    for _ in range(8):
        try:
            fd = os.open(path, os.O_RDWR | os.O_CREAT | flags, 0o600)
        except PermissionError:
            fd = os.open(path, os.O_RDONLY | flags)  # a read-only folder: lock what is there
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            os.close(fd)
            return None
        except OSError:
            os.close(fd)
            raise
        try:
            same = os.path.samestat(os.fstat(fd), os.lstat(path))
        except OSError:
            same = False
        if same:
            return fd
        os.close(fd)
    return None


class Autosave:
    """Writes the open project every ``interval`` seconds while it has unsaved
    edits, to this process's own file (``path``; default: a new name in the
    state folder); the file is removed on a clean exit, so finding one whose
    writer is gone means that session did not end cleanly."""

    def __init__(self, path: str | None = None, interval: float = 10.0, background: bool = False):
        self.path = os.path.abspath(path or autosave_path())
        self.interval = interval
        self.background = background  # write in a thread of its own (the editor)
        self._thread: threading.Thread | None = None
        self._error: ProjectError | None = None
        self._last = time.monotonic()
        self._written: Document | None = None
        self._locks: dict[str, int] = {}  # autosave file -> descriptor holding its lock (ours, and claimed ones)
        self._found: list[Recoverable] | None = None
        self.set_aside_all: list[tuple[str, str]] = []  # (new path, reason) of each broken autosave

    @property
    def set_aside(self) -> tuple[str, str] | None:
        """(new path, reason) of the last broken autosave set aside, if any."""
        return self.set_aside_all[-1] if self.set_aside_all else None

    # -- start-up: what earlier sessions left -------------------------------

    def pending_all(self) -> list[Recoverable]:
        """The autosaves left by sessions that did not end cleanly (their lock
        is free), oldest first, each claimed by this process until it is
        recovered, discarded or the process ends.

        Never raises: a broken autosave file (or anything else at its path) is
        set aside, renamed ``autosave-broken-TIME.itex`` next to it, and
        ``set_aside_all`` says where and why; start-up then goes on as usual."""
        if self._found is not None:
            return list(self._found)
        folder = os.path.dirname(self.path)
        found: list[Recoverable] = []
        candidates: list[tuple[float, str]] = []
        leftovers: set[str] = set()  # autosaves (gone) of which a lock or stored file is left
        try:
            with os.scandir(folder) as entries:
                for e in entries:
                    m = NAME_RE.match(e.name)
                    if m and m.group(2) != PROJECT_SUFFIX:
                        leftovers.add(os.path.join(folder, m.group(1) + PROJECT_SUFFIX))
                    elif (m or e.name == LEGACY_NAME or e.path == self.path) and e.path not in self._locks:
                        try:
                            candidates.append((e.stat(follow_symlinks=False).st_mtime, e.path))
                        except OSError:
                            continue
        except OSError:
            candidates = []
        for path in sorted(leftovers)[:4 * MAX_PENDING]:
            self._remove_leftovers(path)
        for mtime, path in sorted(candidates)[:MAX_PENDING]:
            if not self._claim(path):
                continue  # a live editor's
            try:
                proj = load_project(path)  # never allowed to read outside its folder
            except ProjectError as exc:
                if os.path.lexists(path):
                    self._set_aside(path, str(exc))
                self._release(path)
                continue
            found.append(Recoverable(path, mtime, proj.origin, proj.document.exemplar.name))
            del proj  # (one at a time: see Recoverable)
        self._found = found
        return list(found)

    def pending(self) -> Project | None:
        """The oldest earlier session's unsaved work (see :meth:`pending_all`)."""
        found = self.pending_all()
        return found[0].project if found else None

    def pending_time(self) -> float | None:
        found = self.pending_all()
        return found[0].time if found else None

    def discard(self, rec: Recoverable) -> None:
        """Remove an earlier session's autosave (recovered, or not wanted):
        that one only, and only when this process claimed it."""
        if self._found is not None:
            self._found = [r for r in self._found if r.path != rec.path]
        if rec.path not in self._locks:
            return
        _remove([rec.path, *stored_files(rec.path)])
        if rec.path != self.path:  # (our own file's lock stays ours)
            self._release(rec.path)

    def _claim(self, path: str) -> bool:
        """Take the lock of the autosave ``path``; False when its writer still runs."""
        fd = -1  # no lock to hold: without fcntl, or where none can be taken (offered as before)
        if fcntl is not None:
            try:
                fd = _lock(lock_path(path))
            except OSError:
                pass
            if fd is None:
                return False
        self._locks[path] = fd
        return True

    def _release(self, path: str) -> None:
        """Let go of an autosave's lock; its lock file goes too once the autosave is gone."""
        fd = self._locks.pop(path, None)
        if fd is None:
            return
        if fd < 0:
            return
        if not os.path.lexists(path):
            _remove([lock_path(path)])
        os.close(fd)

    def _remove_leftovers(self, path: str) -> None:
        """The lock and stored files of an autosave that is gone, once their
        writer is gone too (it holds the lock from before its first write)."""
        if fcntl is None or path in self._locks or os.path.lexists(path):
            return
        try:
            fd = _lock(lock_path(path))
        except OSError:
            return
        if fd is not None:
            if not os.path.lexists(path):
                _remove([*stored_files(path), lock_path(path)])
            os.close(fd)

    def _set_aside(self, path: str, reason: str) -> None:
        folder = os.path.dirname(path)
        stamp = time.strftime("%Y%m%d-%H%M%S")
        for i in range(100):
            target = os.path.join(folder, f"autosave-broken-{stamp}{'-' + str(i) if i else ''}{PROJECT_SUFFIX}")
            if not os.path.lexists(target):
                break
        try:
            os.rename(path, target)
            self.set_aside_all.append((target, reason))
        except OSError as exc:
            self.set_aside_all.append((path, f"{reason} (it could not be renamed: {exc.strerror or exc})"))

    # -- this process's own autosave ----------------------------------------

    def tick(self, project: Project, dirty: bool, force: bool = False) -> bool:
        """Write when due; returns True when written (or, ``background``,
        started). With ``background`` the write runs in a thread of its own,
        so a large document (a painted flow, big fields) never holds up the
        editor's frame; ``force`` writes now, after any write under way. An
        error of a write in the background is raised by the next tick."""
        if force:
            self._join()
            self._error = None  # (this write is made now: an earlier one's failure is not its own)
        elif self._thread is not None and self._thread.is_alive():
            return False
        self._raise_error()
        now = time.monotonic()
        if not force and (now - self._last < self.interval):
            return False
        self._last = now
        if not dirty or project.document == self._written:
            return False
        if self.background and not force:
            self._thread = threading.Thread(target=self._write_caught, args=(project,), daemon=True,
                                            name="autosave")
            self._thread.start()
            return True
        self._write(project)
        return True

    def _write(self, project: Project) -> None:
        try:
            os.makedirs(os.path.dirname(self.path), mode=0o700, exist_ok=True)
        except OSError as exc:
            raise ProjectError(f"The autosave folder cannot be made: {exc.strerror or exc}.") from None
        self._hold_lock()
        stored: set[str] = set()
        save_project(self.path, project, store=lambda src: self._store(src, stored))
        _remove(p for p in stored_files(self.path) if os.path.basename(p) not in stored)  # earlier documents'
        self._written = project.document

    def _write_caught(self, project: Project) -> None:
        try:
            self._write(project)
        except ProjectError as exc:
            self._error = exc
        except Exception as exc:  # noqa: BLE001 - one line, raised as the tick's own
            self._error = ProjectError(f"The autosave failed ({exc}).")

    def _join(self) -> None:
        if self._thread is not None:
            self._thread.join()
            self._thread = None

    def _raise_error(self) -> None:
        err, self._error = self._error, None
        if err is not None:
            raise err

    def _store(self, src: ExemplarSource, names: set[str]) -> str:
        """Keep a file too large to embed beside this process's autosave; its name."""
        name = f"{os.path.basename(os.path.splitext(self.path)[0])}-{src.sha256}.data"
        target = os.path.join(os.path.dirname(self.path), name)
        try:
            st = os.lstat(target)
            kept = stat.S_ISREG(st.st_mode) and st.st_size == len(src.data)  # written earlier by this process
        except OSError:
            kept = False
        if not kept:
            try:
                atomic_write(target, src.data)
            except WriteError as exc:
                raise ProjectError(str(exc)) from None
        names.add(name)
        return name

    def _hold_lock(self) -> None:
        """Lock this process's autosave before its first write, for the process's life."""
        if self.path in self._locks:
            return
        fd = -1
        if fcntl is not None:
            try:
                fd = _lock(lock_path(self.path))
            except OSError:
                pass  # no locks here (a file system without them): written all the same
        if fd is None:
            raise ProjectError("Another Infinitex process is using this autosave file.")
        self._locks[self.path] = fd

    def clear(self) -> None:
        """Remove this process's own autosave (saved, or nothing left unsaved);
        never another's. The lock stays for the next write."""
        self._join()  # (a write under way would put it back)
        self._written = self._error = None
        _remove([self.path, *stored_files(self.path)])

    def close(self) -> None:
        """A clean exit without unsaved work: this process's autosave and lock go."""
        self.clear()
        self._release(self.path)

    def release(self) -> None:
        """Let go of every lock without removing any autosave, as the end of the
        process does (what is left is offered at the next start)."""
        self._join()
        for path in list(self._locks):
            self._release(path)

    def __del__(self) -> None:
        try:
            self.release()
        except Exception:
            pass
