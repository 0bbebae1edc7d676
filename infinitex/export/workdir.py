"""The one safe way to work inside an export's folders (the output's folder and
its ``OUT.parts`` working folder), for every streamed format, the editor and
the command line alike.

Each folder is opened once; every file in it is then reached by a plain name
relative to that folder's descriptor, so nothing resolves a path twice and no
symbolic link inside is ever followed:

- **Reads** open with ``O_NOFOLLOW | O_NONBLOCK`` and accept only a regular
  file (``S_ISREG`` after ``fstat``) of at most a given size: a link, a FIFO,
  a device or a folder where a file should be is simply not there (the open
  never blocks on a FIFO).
- **Writes** go to a new temporary file (``O_CREAT | O_EXCL | O_NOFOLLOW``),
  flushed to disk, then renamed onto the name, relative to the folder's
  descriptor: a link at the name is replaced, never written through.
- **The working folder** (:func:`open_parts`) must be a real folder of the user
  running the export (a symbolic link, a file or another user's folder is
  refused before any work, and left as it is); a new one is created ``0700``.
- **Deleting** is by name, of what the export wrote or verified, never a whole
  tree it did not check (:func:`plain_tree`).
"""
from __future__ import annotations

import os
import re
import secrets
import shutil
import stat

from infinitex.engine.safeio import TMP_SUFFIX, WriteError, printable, read_umask

_O_CLOEXEC = getattr(os, "O_CLOEXEC", 0)
_O_NOFOLLOW = getattr(os, "O_NOFOLLOW", 0)
_O_NONBLOCK = getattr(os, "O_NONBLOCK", 0)
_O_DIRECTORY = getattr(os, "O_DIRECTORY", 0)
_TEMP = re.compile(r"^\..*\.(\d+)\.[0-9a-f]{12}" + re.escape(TMP_SUFFIX) + r"$")
_PLAIN_NAME = re.compile(r"^[^/\x00]+$")


FILE_MODE = 0o666 & ~read_umask()  # what an ordinary write gives a new output file


def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except OSError:
        return True
    return True


class Folder:
    """An open folder: files inside are reached by plain name relative to its
    descriptor (see the module's text). ``shown`` is its name for messages."""

    def __init__(self, fd: int, shown: str):
        self.fd = fd
        self.shown = shown

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()

    def close(self) -> None:
        if self.fd >= 0:
            os.close(self.fd)
            self.fd = -1

    @staticmethod
    def _name(name: str) -> str:
        if not _PLAIN_NAME.match(name) or name in (".", ".."):
            raise ValueError(f"not a plain file name: {name!r}")
        return name

    def show(self, name: str) -> str:
        return f"{self.shown}/{printable(name)}"

    # -- looking -----------------------------------------------------------------

    def lstat(self, name: str) -> os.stat_result | None:
        """The entry itself (a link is a link), None if there is none."""
        try:
            return os.stat(self._name(name), dir_fd=self.fd, follow_symlinks=False)
        except FileNotFoundError:
            return None

    def names(self) -> list[str]:
        with os.scandir(self.fd) as it:
            return sorted(e.name for e in it)

    # -- reading -------------------------------------------------------------------

    def open_file(self, name: str, limit: int, size: int | None = None) -> int | None:
        """A descriptor of the regular file ``name`` of at most ``limit`` bytes
        (and exactly ``size`` if given), or None: missing, a link, a FIFO, a
        device, a folder, too large. The caller closes it."""
        try:
            fd = os.open(self._name(name), os.O_RDONLY | _O_NOFOLLOW | _O_NONBLOCK | _O_CLOEXEC, dir_fd=self.fd)
        except OSError:
            return None
        try:
            st = os.fstat(fd)
            if stat.S_ISREG(st.st_mode) and st.st_size <= limit and (size is None or st.st_size == size):
                return fd
        except OSError:
            pass
        os.close(fd)
        return None

    def stream(self, name: str, limit: int, take, size: int | None = None, chunk: int = 1 << 20) -> bool:
        """Give the bytes of a regular file (see :meth:`open_file`) to
        ``take(piece)`` in pieces; False if it is not one or cannot be read."""
        fd = self.open_file(name, limit, size)
        if fd is None:
            return False
        try:
            total = 0
            while True:
                b = os.read(fd, min(chunk, limit + 1 - total))
                if not b:
                    return size is None or total == size
                total += len(b)
                if total > limit:
                    return False
                take(b)
        except OSError:
            return False
        finally:
            os.close(fd)

    def read(self, name: str, limit: int, size: int | None = None) -> bytes | None:
        """The bytes of a regular file of at most ``limit`` bytes, or None (see :meth:`open_file`)."""
        pieces: list[bytes] = []
        return b"".join(pieces) if self.stream(name, limit, pieces.append, size) else None

    # -- writing -------------------------------------------------------------------

    def create_temp(self, name: str, mode: int = 0o600):
        """(temporary name, binary file open for writing and reading) of a new
        file beside ``name``: created here, never through a link."""
        tmp = f".{self._name(name)[:64]}.{os.getpid()}.{secrets.token_hex(6)}{TMP_SUFFIX}"
        fd = os.open(tmp, os.O_RDWR | os.O_CREAT | os.O_EXCL | _O_NOFOLLOW | _O_CLOEXEC, mode, dir_fd=self.fd)
        return tmp, os.fdopen(fd, "w+b")

    def create_new(self, name: str, mode: int = 0o600):
        """(``name``, binary file open for writing and reading) of a file
        created under exactly that name (``O_EXCL | O_NOFOLLOW``): whatever
        was there is removed first (a link itself, never what it points to)."""
        st = self.lstat(name)
        if st is not None and not stat.S_ISDIR(st.st_mode):
            os.unlink(name, dir_fd=self.fd)
        fd = os.open(name, os.O_RDWR | os.O_CREAT | os.O_EXCL | _O_NOFOLLOW | _O_CLOEXEC, mode, dir_fd=self.fd)
        f = os.fdopen(fd, "w+b")
        f.raw.name = self.show(name)  # a path for writers that print (or split) the file's name
        return name, f

    def discard(self, tmp: str, f=None) -> None:
        """Remove a file of :meth:`create_temp` or :meth:`create_new` that is not to be kept (closing ``f``)."""
        if f is not None:
            try:
                f.close()
            except OSError:  # the flush of what is thrown away failed (a full disk): nothing is lost
                pass
        try:
            os.unlink(tmp, dir_fd=self.fd)
        except OSError:
            pass

    def commit(self, tmp: str, f, name: str, into: Folder | None = None, mode: int | None = None) -> None:
        """Flush ``f`` (from :meth:`create_temp`) to disk and rename it onto
        ``name`` in this folder or in ``into``; a link there is replaced."""
        try:
            f.flush()
            os.fsync(f.fileno())
            if mode is not None:
                os.fchmod(f.fileno(), mode)
            f.close()
            dest = into or self
            os.rename(tmp, dest._name(name), src_dir_fd=self.fd, dst_dir_fd=dest.fd)
        except BaseException:
            self.discard(tmp, f)
            raise
        dest.sync()

    def write(self, name: str, data: bytes, mode: int = 0o600) -> None:
        """``data`` to ``name`` atomically (temporary file, then rename)."""
        tmp, f = self.create_temp(name)
        try:
            f.write(data)
        except BaseException:
            self.discard(tmp, f)
            raise
        self.commit(tmp, f, name, mode=mode)

    def output_mode(self, name: str) -> int:
        """The mode a replaced output keeps (an existing regular file's), else an ordinary write's."""
        st = self.lstat(name)
        return stat.S_IMODE(st.st_mode) if st is not None and stat.S_ISREG(st.st_mode) else FILE_MODE

    def append(self, name: str):
        """``name`` opened for appending: only an existing regular file, never through a link."""
        fd = os.open(self._name(name), os.O_WRONLY | os.O_APPEND | _O_NOFOLLOW | _O_NONBLOCK | _O_CLOEXEC,
                     dir_fd=self.fd)
        if not stat.S_ISREG(os.fstat(fd).st_mode):
            os.close(fd)
            raise WriteError(f"{self.show(name)} is not a regular file; it is not written.")
        return os.fdopen(fd, "ab")

    def sync(self) -> None:
        try:
            os.fsync(self.fd)
        except OSError:
            pass

    # -- removing ------------------------------------------------------------------

    def remove_file(self, name: str) -> bool:
        """Remove ``name`` if it is a regular file or a link (the link itself;
        what it points to is untouched). True if removed."""
        st = self.lstat(name)
        if st is None or not (stat.S_ISREG(st.st_mode) or stat.S_ISLNK(st.st_mode)):
            return False
        try:
            os.unlink(name, dir_fd=self.fd)
            return True
        except FileNotFoundError:
            return False

    def remove_tree(self, name: str) -> None:
        """Remove the folder ``name`` with everything in it, following no link
        (a link inside is removed, not what it points to); a link itself is unlinked."""
        st = self.lstat(name)
        if st is None:
            return
        if not stat.S_ISDIR(st.st_mode):
            os.unlink(name, dir_fd=self.fd)
            return
        shutil.rmtree(self._name(name), dir_fd=self.fd)

    def remove_stale_temporaries(self) -> None:
        """Our temporary files whose writer is gone (a killed run), by their names only."""
        try:
            names = self.names()
        except OSError:
            return
        for name in names:
            m = _TEMP.match(name)
            if m and int(m.group(1)) != os.getpid() and not _alive(int(m.group(1))):
                try:
                    st = self.lstat(name)
                    if st is not None and stat.S_ISREG(st.st_mode):  # ours are regular files, nothing else
                        os.unlink(name, dir_fd=self.fd)
                except OSError:
                    pass

    def rmdir(self, name: str) -> bool:
        try:
            os.rmdir(self._name(name), dir_fd=self.fd)
            return True
        except OSError:
            return False


KEY_FILE = "export-manifests.key"
KEY_BYTES = 32


def manifest_key(folder: str | None = None) -> bytes:
    """This user's secret for signing export manifests: 32 random bytes in
    ``KEY_FILE`` of the analysis cache folder (``INFINITEX_CACHE``), made
    ``0600`` on first use. A manifest lying next to a file can then vouch only
    for files this user's exports wrote. Losing the key costs a resumed export
    its kept tiles, nothing else; where it cannot be kept, a key of this
    process's is used (nothing from an earlier run is kept)."""
    if folder is None:
        from infinitex.engine.analysis import default_cache_dir
        folder = default_cache_dir()

    def read() -> bytes | None:
        try:
            fd = os.open(os.path.join(folder, KEY_FILE), os.O_RDONLY | _O_NOFOLLOW | _O_NONBLOCK | _O_CLOEXEC)
        except OSError:
            return None
        try:
            st = os.fstat(fd)
            if not stat.S_ISREG(st.st_mode) or st.st_uid != os.geteuid() or st.st_size != KEY_BYTES:
                return None
            data = os.read(fd, KEY_BYTES + 1)
            return data if len(data) == KEY_BYTES else None
        except OSError:
            return None
        finally:
            os.close(fd)

    key = read()
    if key is not None:
        return key
    new = secrets.token_bytes(KEY_BYTES)
    try:
        os.makedirs(folder, mode=0o700, exist_ok=True)
        with Folder(os.open(folder, os.O_RDONLY | _O_DIRECTORY | _O_CLOEXEC), printable(folder)) as d:
            tmp, f = d.create_temp(KEY_FILE)
            with f:
                f.write(new)
                f.flush()
                os.fsync(f.fileno())
            try:  # the first key made wins (two processes starting at once agree on it)
                os.link(tmp, KEY_FILE, src_dir_fd=d.fd, dst_dir_fd=d.fd, follow_symlinks=False)
            except FileExistsError:  # another's, or a damaged one: replaced when damaged
                if read() is None:
                    os.rename(tmp, KEY_FILE, src_dir_fd=d.fd, dst_dir_fd=d.fd)
            finally:
                d.discard(tmp)
            d.sync()
    except OSError:
        return new
    return read() or new


def open_folder_of(path: str) -> Folder:
    """The folder holding the output ``path`` (a link to it is the user's choice, so followed)."""
    folder = os.path.dirname(os.path.abspath(path))
    try:
        fd = os.open(folder, os.O_RDONLY | _O_DIRECTORY | _O_CLOEXEC)
    except OSError as exc:
        raise WriteError(f"The folder of {printable(path)} cannot be opened: {exc.strerror or exc}.") from None
    return Folder(fd, printable(folder))


def open_parts(parent: Folder, name: str, shown: str) -> tuple[Folder, bool]:
    """(the working folder ``name`` in ``parent``, whether it was created now).
    Refused with a sentence (WriteError) when it is a symbolic link, not a
    folder, or not the user's; a new one is ``0700``."""
    fix = "it is left as it is: remove it or choose another output name"
    created = False
    st = parent.lstat(name)
    if st is None:
        try:
            os.mkdir(name, 0o700, dir_fd=parent.fd)
            created = True
        except FileExistsError:
            pass
        except OSError as exc:
            raise WriteError(f"Cannot create {shown}: {exc.strerror or exc}.") from None
        st = parent.lstat(name)
    if st is None:
        raise WriteError(f"Cannot create {shown}.")
    if stat.S_ISLNK(st.st_mode):
        raise WriteError(f"{shown} is a symbolic link, not the folder an export keeps its finished tiles in; {fix}.")
    if not stat.S_ISDIR(st.st_mode):
        raise WriteError(f"{shown} exists and is not a folder (an export keeps its finished tiles there); {fix}.")
    if st.st_uid != os.geteuid():
        raise WriteError(f"{shown} belongs to another user; {fix}.")
    try:
        fd = os.open(name, os.O_RDONLY | _O_DIRECTORY | _O_NOFOLLOW | _O_CLOEXEC, dir_fd=parent.fd)
    except OSError as exc:
        raise WriteError(f"{shown} cannot be opened: {exc.strerror or exc}.") from None
    now = os.fstat(fd)
    if (now.st_dev, now.st_ino) != (st.st_dev, st.st_ino) or now.st_uid != os.geteuid():
        os.close(fd)
        raise WriteError(f"{shown} changed while it was opened; {fix}.")
    if created:
        os.fchmod(fd, 0o700)  # whatever the umask
    return Folder(fd, shown), created


def plain_tree(parent: Folder, name: str, allowed, max_entries: int, max_depth: int = 2) -> str | None:
    """Why the folder ``name`` is not a plain tree of this user's folders and
    regular files that ``allowed(relative path, lstat)`` accepts
    (no link, FIFO or device anywhere, at most ``max_entries`` entries), or
    None when it is one. Nothing is followed or read."""
    count = [0]

    def walk(dir_fd: int, rel: str, depth: int) -> str | None:
        with os.scandir(dir_fd) as it:
            entries = list(it)
        for e in entries:
            count[0] += 1
            if count[0] > max_entries:
                return "it holds more files than the export writes"
            path = f"{rel}/{e.name}" if rel else e.name
            st = os.stat(e.name, dir_fd=dir_fd, follow_symlinks=False)
            folder = stat.S_ISDIR(st.st_mode)
            if not (folder or stat.S_ISREG(st.st_mode)):
                return f"{printable(path)} is a link or a special file"
            if st.st_uid != os.geteuid():
                return f"{printable(path)} belongs to another user"
            if not allowed(path, st):
                return f"it holds {printable(path)}, which the export does not write"
            if folder:
                if depth >= max_depth:
                    return f"{printable(path)} is nested too deeply"
                fd = os.open(e.name, os.O_RDONLY | _O_DIRECTORY | _O_NOFOLLOW | _O_CLOEXEC, dir_fd=dir_fd)
                try:
                    why = walk(fd, path, depth + 1)
                finally:
                    os.close(fd)
                if why:
                    return why
        return None

    st = parent.lstat(name)
    if st is None:
        return None
    if not stat.S_ISDIR(st.st_mode):
        return "it is a link or a file, not a folder"
    if st.st_uid != os.geteuid():
        return "it belongs to another user"
    try:
        fd = os.open(name, os.O_RDONLY | _O_DIRECTORY | _O_NOFOLLOW | _O_CLOEXEC, dir_fd=parent.fd)
    except OSError as exc:
        return f"it cannot be opened ({exc.strerror or exc})"
    try:
        return walk(fd, "", 0)
    except OSError as exc:
        return f"it cannot be read ({exc.strerror or exc})"
    finally:
        os.close(fd)
