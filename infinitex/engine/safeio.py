"""Reading untrusted files and writing files safely: the one place for both.

Every file Infinitex reads on a user's behalf (images, projects, referenced
exemplars) goes through :func:`read_limited`, and every file it writes (PNG,
``.npy``, projects, autosave, the analysis cache) goes through
:func:`atomic_write`:

- **Reads** accept only regular files (not FIFOs, devices or folders; the open
  never blocks on a FIFO) and check the size against a limit *before* reading,
  then read at most that much (files under ``/proc`` claim size 0).
- **Writes** go to a temporary file in the target's folder, are flushed to
  disk, then renamed over the target, so a killed write leaves the old file
  (or none) and never a partial one. A target that exists and is not a regular
  file (a device node, a FIFO, a folder) is refused; a symbolic link is written
  through (the link stays, its file is replaced). The new file gets the
  permissions an ordinary write would give (``0666 & ~umask``, or the old
  file's mode). Temporary files left by killed writes of ours (their process
  is gone, or they are a day old) are removed on the next write to that folder.
- :class:`StagedFiles` writes several files as one unit (a tile set): all
  written beside their names first, renamed only once every one is written;
  their names' links are replaced, never written through.
- :func:`check_output` validates an output path (folder, extension, target
  kind) before any work starts; :func:`printable` makes names safe to print on
  one line.
"""
from __future__ import annotations

import os
import re
import secrets
import stat
import time

TMP_SUFFIX = ".infinitex-tmp"
_TMP_RE = re.compile(r"^\..*\.(\d+)\.[0-9a-f]{12}" + re.escape(TMP_SUFFIX) + r"$")
STALE_AGE_S = 24 * 3600  # a temporary file this old is stale even if its pid was reused


class WriteError(OSError):
    """A file could not be written; the message is a sentence for the user."""

    def __str__(self) -> str:  # OSError would print "[Errno ...]" forms
        return self.args[0] if self.args else "write failed"


class ReadError(OSError):
    """A file could not be read (or is not something we read); a sentence for the user."""

    def __str__(self) -> str:
        return self.args[0] if self.args else "read failed"


def printable(text: object, limit: int = 300) -> str:
    """``text`` on one line: control characters, lone surrogates (undecodable
    file-name bytes) and other unprintables escaped; long texts shortened."""
    s = str(text)
    out = "".join(c if c.isprintable() else c.encode("unicode_escape", "backslashreplace").decode("ascii")
                  for c in s)
    if len(out) > limit:
        out = out[:limit - 3] + "..."
    return out


def name_of(path: str) -> str:
    return printable(os.path.basename(os.fspath(path)) or os.fspath(path))


# -- reading -------------------------------------------------------------------


def _mb(n: int) -> str:
    return f"{n / 2 ** 20:.0f} MB"


def read_limited(path: str, limit: int, what: str = "file") -> bytes:
    """The bytes of a regular file of at most ``limit`` bytes, or :class:`ReadError`."""
    path = os.fspath(path)
    shown = printable(path)
    try:
        fd = os.open(path, os.O_RDONLY | getattr(os, "O_NONBLOCK", 0) | getattr(os, "O_CLOEXEC", 0))
    except FileNotFoundError:
        raise ReadError(f"No such file: {shown}.") from None
    except IsADirectoryError:
        raise ReadError(f"{shown} is a folder, not a {what}.") from None
    except OSError as exc:
        raise ReadError(f"{shown} could not be opened: {exc.strerror or exc}.") from None
    try:
        st = os.fstat(fd)
        if stat.S_ISDIR(st.st_mode):
            raise ReadError(f"{shown} is a folder, not a {what}.")
        if not stat.S_ISREG(st.st_mode):
            raise ReadError(f"{shown} is not a regular file (a device, pipe or socket), so it is not read.")
        if st.st_size > limit:
            raise ReadError(f"{shown} is {_mb(st.st_size)}, larger than the {_mb(limit)} a {what} may be.")
        chunks, total = [], 0
        while True:
            b = os.read(fd, min(1 << 20, limit + 1 - total))  # regular files never block
            if not b:
                break
            chunks.append(b)
            total += len(b)
            if total > limit:
                raise ReadError(f"{shown} is larger than the {_mb(limit)} a {what} may be.")
        return b"".join(chunks)
    except OSError as exc:
        if isinstance(exc, ReadError):
            raise
        raise ReadError(f"{shown} could not be read: {exc.strerror or exc}.") from None
    finally:
        os.close(fd)


def read_head(path: str, n: int) -> bytes:
    """The first ``n`` bytes of a regular file; b"" for anything else (never blocks)."""
    try:
        fd = os.open(os.fspath(path), os.O_RDONLY | getattr(os, "O_NONBLOCK", 0) | getattr(os, "O_CLOEXEC", 0))
    except OSError:
        return b""
    try:
        if not stat.S_ISREG(os.fstat(fd).st_mode):
            return b""
        return os.read(fd, n)
    except OSError:
        return b""
    finally:
        os.close(fd)


class JSONLimitError(ValueError):
    """Untrusted JSON went past a limit (nesting, number size); a phrase for the user."""


_JSON_STRING = re.compile(r'"[^"\\]*(?:\\.[^"\\]*)*"')


def _json_depth(text: str) -> int:
    """How deeply the JSON text nests (strings are skipped), without parsing it."""
    import numpy as np
    b = np.frombuffer(_JSON_STRING.sub('""', text).encode("utf-8", "replace"), dtype=np.uint8)
    if b.size == 0:
        return 0
    delta = ((b == 0x5B) | (b == 0x7B)).astype(np.int32) - ((b == 0x5D) | (b == 0x7D))
    return int(np.cumsum(delta).max())


def parse_json(raw: bytes, max_depth: int, max_digits: int = 18) -> object:
    """Untrusted JSON bytes, parsed with the nesting checked before parsing
    (no RecursionError) and numbers checked while parsing (no huge integers,
    no overflow to infinity, no NaN). JSONLimitError past a limit, ValueError
    (including UnicodeDecodeError and JSONDecodeError) when it is not JSON."""
    import json
    import math
    text = raw.decode("utf-8")
    if _json_depth(text) > max_depth:
        raise JSONLimitError("its JSON nests too deeply")

    def parse_int(t: str) -> int:
        if len(t.lstrip("-")) > max_digits:
            raise JSONLimitError("it holds a number too large for any setting")
        return int(t)

    def parse_float(t: str) -> float:
        v = float(t)
        if not math.isfinite(v) or len(t) > 64:
            raise JSONLimitError("it holds a number too large for any setting")
        return v

    def parse_constant(t: str):
        raise JSONLimitError(f"it holds {t}, which is not a number any setting can take")
    try:
        return json.loads(text, parse_int=parse_int, parse_float=parse_float, parse_constant=parse_constant)
    except RecursionError:
        raise JSONLimitError("its JSON nests too deeply") from None


# -- writing -------------------------------------------------------------------


def read_umask() -> int:
    """The process umask, without changing it where /proc tells it (os.umask()
    is a set-and-restore, racy with other threads creating files)."""
    try:
        with open("/proc/self/status", encoding="ascii", errors="replace") as f:
            for line in f:
                if line.startswith("Umask:"):
                    return int(line.split()[1], 8)
    except (OSError, ValueError, IndexError):
        pass
    m = os.umask(0o022)
    os.umask(m)
    return m


_UMASK = read_umask()


def _existing(real: str, shown: str) -> os.stat_result | None:
    """stat of an output target (symbolic links followed), None if it does not exist."""
    try:
        return os.stat(real)
    except FileNotFoundError:
        return None
    except OSError as exc:
        raise WriteError(f"{shown} cannot be checked: {exc.strerror or exc}.") from None


def check_output(path: str, extensions: tuple[str, ...] = (), what: str = "output") -> str:
    """Validate an output path before any work: its folder exists and is
    writable, its extension is one of ``extensions`` (lowercase, with the dot;
    empty tuple: any), and it is not an existing folder, device or pipe.
    Returns the path; raises :class:`WriteError` with a sentence."""
    path = os.fspath(path)
    shown = printable(path)
    if not path or path.endswith(("/", os.sep)) or os.path.basename(path) in ("", ".", ".."):
        raise WriteError(f"The {what} name {shown!r} is not a file name.")
    real = os.path.realpath(path)
    folder = os.path.dirname(real)
    if not os.path.isdir(folder):
        raise WriteError(f"The folder of {shown} does not exist.")
    st = _existing(real, shown)
    if st is not None:
        if stat.S_ISDIR(st.st_mode):
            ending = f" ending in {' or '.join(extensions)}" if extensions else ""
            raise WriteError(f"The {what} {shown} is a folder; give a file name{ending}.")
        if not stat.S_ISREG(st.st_mode):
            raise WriteError(f"{shown} exists and is not a regular file (a device, pipe or socket); "
                             "it is not overwritten.")
    if extensions:
        ext = os.path.splitext(path)[1].lower()
        if ext not in extensions:
            want = " or ".join(extensions)
            got = f"'{printable(ext)}'" if ext else "no extension"
            raise WriteError(f"The {what} {shown} has {got}; it must end in {want}.")
    if not os.access(folder, os.W_OK | os.X_OK):
        raise WriteError(f"The folder of {shown} is not writable.")
    return path


def _pid_alive(pid: int) -> bool:
    if pid <= 0:
        return False
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except OSError:  # exists, owned by someone else
        return True
    return True


def clean_stale_temporaries(folder: str) -> int:
    """Remove our own temporary files in ``folder`` whose writer is gone (or
    that are older than a day). Returns how many were removed."""
    removed = 0
    now = time.time()
    try:
        entries = list(os.scandir(folder))
    except OSError:
        return 0
    for e in entries:
        m = _TMP_RE.match(e.name)
        if not m:
            continue
        try:
            st = e.stat(follow_symlinks=False)
            if not stat.S_ISREG(st.st_mode):
                continue
            pid = int(m.group(1))
            if (pid != os.getpid() and not _pid_alive(pid)) or now - st.st_mtime > STALE_AGE_S:
                os.unlink(e.path)
                removed += 1
        except (OSError, ValueError):
            continue
    return removed


def _write_temporary(folder: str, name: str, shown: str, mode: int, data: bytes | None, writer) -> str:
    """Write a temporary file of ours in ``folder`` (flushed to disk, with
    ``mode``); its path. On failure it is removed (WriteError with a sentence;
    exceptions of ``writer`` other than OSError propagate)."""
    clean_stale_temporaries(folder)
    tmp = os.path.join(folder, f".{name[:64]}.{os.getpid()}.{secrets.token_hex(6)}{TMP_SUFFIX}")
    try:
        fd = os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_EXCL | getattr(os, "O_CLOEXEC", 0), 0o600)
    except OSError as exc:
        raise WriteError(f"Cannot write in the folder of {shown}: {exc.strerror or exc}.") from None
    try:
        with os.fdopen(fd, "wb") as f:
            if writer is not None:
                writer(f)
            else:
                f.write(data)
            f.flush()
            os.fsync(f.fileno())
            os.fchmod(f.fileno(), mode)
    except BaseException as exc:
        _unlink(tmp)
        if isinstance(exc, OSError) and not isinstance(exc, WriteError):
            raise WriteError(f"Saving {shown} failed: {exc.strerror or exc}.") from None
        raise
    return tmp


def _unlink(path: str) -> None:
    try:
        os.unlink(path)
    except OSError:
        pass


def _sync_folder(folder: str) -> None:
    """Make the renames in ``folder`` durable."""
    try:
        dfd = os.open(folder, os.O_RDONLY | getattr(os, "O_DIRECTORY", 0))
        try:
            os.fsync(dfd)
        finally:
            os.close(dfd)
    except OSError:
        pass


def atomic_write(path: str, data: bytes | None = None, *, writer=None, follow_links: bool = False) -> None:
    """Write ``data`` (or call ``writer(fileobj)``) to ``path`` atomically: in
    full to a new temporary file beside it, then renamed over it.

    A name that is a symbolic link is replaced by the new file (its target
    untouched, a dangling link's target never created): what an export
    writes lands under the name it was given, never somewhere a link points.
    ``follow_links``: write the link's target instead, the link kept (a
    project or settings file the user linked on purpose).

    Raises :class:`WriteError` with a sentence (the old file is then untouched
    and no temporary file is left). Exceptions raised by ``writer`` other than
    OSError (e.g. KeyboardInterrupt, a codec's ValueError) propagate after the
    clean-up."""
    path = os.fspath(path)
    shown = name_of(path)
    if follow_links:
        real = os.path.realpath(path)
    else:  # the name itself, in its folder's real path
        real = os.path.join(os.path.realpath(os.path.dirname(os.path.abspath(path))), os.path.basename(path))
    folder = os.path.dirname(real)
    st = _existing(real, shown) if follow_links or not os.path.islink(real) else None
    if st is not None and not stat.S_ISREG(st.st_mode):
        raise WriteError(f"{printable(path)} exists and is not a regular file; it is not overwritten.")
    mode = stat.S_IMODE(st.st_mode) if st is not None else (0o666 & ~_UMASK)
    tmp = _write_temporary(folder, os.path.basename(real), shown, mode, data, writer)
    try:
        os.replace(tmp, real)
    except OSError as exc:
        _unlink(tmp)
        raise WriteError(f"Saving {shown} failed: {exc.strerror or exc}.") from None
    _sync_folder(folder)


class StagedFiles:
    """Files written as one unit (a tile set: atlases, their side files):
    each is written in full to a temporary file beside its name, and only
    once every one is written are they renamed over their names, one after
    another (microseconds apart), so a kill, a full disk or a name that
    cannot be written while the set is being written leaves the old files
    whole. A name that is a symbolic link is replaced by the new file, never
    written through (nor a dangling link's target created); a name held by a
    folder, pipe or device, or too long for its folder, is refused by
    ``check`` before anything is written. Leaving ``with`` discards what was
    not committed."""

    def __init__(self):
        self._staged: list[tuple[str, str]] = []  # (temporary, final), in order

    @staticmethod
    def check(paths: list[str]) -> None:
        for path in paths:
            path = os.path.abspath(os.fspath(path))
            shown = printable(path)
            folder, name = os.path.split(path)
            try:
                most = os.pathconf(folder, "PC_NAME_MAX")
            except (OSError, ValueError):
                most = 255
            if len(os.fsencode(name)) > most:
                raise WriteError(f"The name {shown} is longer than its folder allows ({most} bytes).")
            try:
                st = os.lstat(path)
            except FileNotFoundError:
                continue
            except OSError as exc:
                raise WriteError(f"{shown} cannot be checked: {exc.strerror or exc}.") from None
            if not (stat.S_ISREG(st.st_mode) or stat.S_ISLNK(st.st_mode)):
                raise WriteError(f"{shown} exists and is not a regular file (a folder, device or pipe); "
                                 "nothing was written.")

    def write(self, path: str, data: bytes | None = None, *, writer=None) -> None:
        path = os.path.abspath(os.fspath(path))
        self.check([path])
        try:
            st = os.lstat(path)
            mode = stat.S_IMODE(st.st_mode) if stat.S_ISREG(st.st_mode) else (0o666 & ~_UMASK)
        except OSError:
            mode = 0o666 & ~_UMASK
        folder, name = os.path.split(path)
        self._staged.append((_write_temporary(folder, name, name_of(path), mode, data, writer), path))

    def commit(self) -> list[str]:
        """Rename every staged file over its name; the names."""
        done = []
        try:
            for tmp, final in self._staged:
                os.replace(tmp, final)
                done.append(final)
        except OSError as exc:
            raise WriteError(f"Saving {name_of(final)} failed: {exc.strerror or exc}.") from None
        finally:
            self.discard()
        for folder in sorted({os.path.dirname(f) for f in done}):
            _sync_folder(folder)
        return done

    def discard(self) -> None:
        for tmp, _ in self._staged:
            if os.path.lexists(tmp):
                _unlink(tmp)
        self._staged = []

    def __enter__(self) -> StagedFiles:
        return self

    def __exit__(self, kind, exc, tb) -> None:
        self.discard()  # whatever was not committed (an exception, or no commit)
