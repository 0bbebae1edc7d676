"""The one gate for every file a model names: what is checked is what is read.

trimesh reads a model's other files (an OBJ's material library and textures,
a glTF's buffers and images) by asking a *resolver* for a name. It is given
:class:`ModelFiles`, so the only bytes it ever gets are the ones handed out
here, after the file they come from was opened without blocking (a FIFO, a
device or a folder is refused, never read), seen to be a regular file inside
the model's folder (the path of the open file, links resolved), and counted
against the model's size budget. A name is resolved exactly as trimesh's own
resolver would (the name, the name without a leading ``/``, its base name), so
no fallback reaches a file the gate did not see.

What was read, and every file a name could mean (read or not: an option
before a texture name, a map trimesh skips), are the model's inputs, which no
export may replace (``Model.meta["files"]``).

A refusal raised inside trimesh may be swallowed by it (it goes on without a
texture it cannot read): the gate keeps the first one, and the loader raises
it once trimesh returns (:meth:`ModelFiles.check`).
"""
from __future__ import annotations

import io
import os
import re
import stat

import numpy as np

from ..safeio import printable

MAX_TEXTURE_PIXELS = 64 << 20  # a texture trimesh would decode (the exemplar's limit)
_IMAGE_MAGIC = (b"\x89PNG", b"\xff\xd8\xff", b"GIF8", b"BM", b"RIFF", b"II*\0", b"MM\0*")
_MAP_LINE = re.compile(rb"(?im)^[ \t]*(?:map_\w+|bump|disp|decal|refl|norm)[ \t]+([^\r\n]+)")


class ModelFiles:
    """The files of one model: the model itself (named by the user, so in any
    folder) and every file it names (inside the model's folder), read here
    and nowhere else, within ``budget`` bytes together."""

    def __init__(self, path: str, budget: int, error: type[Exception]):
        self.path = os.path.abspath(path)
        self.name = os.path.basename(self.path)
        self.folder = os.path.dirname(self.path)
        self.budget = budget
        self.error = error
        self.used = 0
        self.read: list[str] = []   # the files handed out, as named
        self.named: list[str] = []  # every path a name could mean (inputs, read or not)
        self.texts: dict[str, bytes] = {}
        self.missing: list[str] = []  # names asked for that no file answers
        self.refusal: str | None = None

    # -- reading -------------------------------------------------------------
    def main(self) -> bytes:
        """The model's own file."""
        return self._read(self.path, self.name, inside=False)

    def get(self, name) -> bytes:
        """What trimesh asked for by ``name``: the first of its candidates that
        exists (trimesh's order), checked; FileNotFoundError when none does."""
        if not isinstance(name, str) or "\0" in name:  # no file has such a name: missing
            self.missing.append(printable(str(name).strip()[:80]))
            raise FileNotFoundError(repr(name))
        shown = printable(name.strip()[:80])
        if name.strip().lower().startswith("data:"):  # base64 ones are decoded by trimesh and never reach here
            self.refuse(f"{self.name} holds a data: URI that is not base64 ({shown}); glTF's data URIs are "
                        "base64.")
        top = os.path.realpath(self.folder)
        for candidate in self.candidates(name):
            try:
                real = os.path.realpath(candidate)
                if not os.path.exists(candidate) or os.path.isdir(candidate):
                    continue
            except (OSError, ValueError):
                continue
            if not _inside(real, top):  # trimesh's own rule too: a name that leaves the folder is not looked up
                continue
            found = os.path.relpath(candidate, self.folder)
            data = self._read(candidate, shown if found == name.strip() else f"{shown} (found as "
                              f"{printable(found[:80])})", inside=True)
            self.texts[name] = data
            return data
        self.missing.append(shown)
        raise FileNotFoundError(name)

    def candidates(self, name: str) -> list[str]:
        """The paths trimesh's FilePathResolver tries for ``name``, in order
        (each also recorded as an input: a file it could mean)."""
        out = []
        for c in (name.strip(), name.strip().lstrip("/"), os.path.split(name)[-1]):
            if c and "\0" not in c:
                p = os.path.join(self.folder, c)
                if p not in out:
                    out.append(p)
        for p in out:
            if p not in self.named:
                self.named.append(p)
        return out

    def _read(self, path: str, shown: str, inside: bool) -> bytes:
        flags = os.O_RDONLY | os.O_NONBLOCK | getattr(os, "O_NOCTTY", 0) | getattr(os, "O_CLOEXEC", 0)
        try:
            fd = os.open(path, flags)
        except OSError as exc:
            self.refuse(f"Cannot read {shown}: {exc.strerror or exc}.")
        try:
            st = os.fstat(fd)
            if not stat.S_ISREG(st.st_mode):
                self.refuse(f"{shown} is not a regular file." if not inside else
                            f"{self.name} refers to {shown}, which is not a regular file.")
            if inside and not _inside(_opened_path(fd, path), os.path.realpath(self.folder)):
                self.refuse(f"{self.name} refers to {shown}, which is outside the model's folder; copy it beside "
                            "the model.")
            left = self.budget - self.used
            if st.st_size > left:
                self._over(st.st_size)
            with os.fdopen(os.dup(fd), "rb") as f:
                data = f.read(left + 1)  # (a file that grew since fstat is held to the budget too)
            if len(data) > left:
                self._over(len(data))
        finally:
            os.close(fd)
        self.used += len(data)
        if inside:
            self.read.append(path)
            self._check_image(data, shown)
        return data

    def _over(self, size: int) -> None:
        if not self.read and self.used == 0:
            self.refuse(f"{self.name} is {size / 2 ** 20:.0f} MB; models of up to {self.budget >> 20} MB are read.")
        self.refuse(f"The files {self.name} refers to are {(self.used + size) / 2 ** 20:.0f} MB together; models "
                    f"of up to {self.budget >> 20} MB are read.")

    def _check_image(self, data: bytes, shown: str) -> None:
        """A texture trimesh may decode: its size from its header first."""
        if not data.startswith(_IMAGE_MAGIC):
            return
        from PIL import Image
        try:
            with Image.open(io.BytesIO(data)) as im:
                w, h = im.size
        except Exception:  # not an image after all (a buffer's first bytes), or damaged: trimesh skips it
            return
        if w * h > MAX_TEXTURE_PIXELS:
            self.refuse(f"{self.name} refers to {shown}, an image of {w} x {h} pixels; textures of up to "
                        f"{MAX_TEXTURE_PIXELS >> 20} Mpixels are read.")

    # -- refusals and inputs --------------------------------------------------
    def refuse(self, message: str):
        if self.refusal is None:
            self.refusal = message
        raise self.error(message)

    def check(self) -> None:
        """Raise the first refusal, if trimesh swallowed it."""
        if self.refusal is not None:
            raise self.error(self.refusal)

    def name_maps(self, mtllib: str | None) -> None:
        """Record the maps a material library names (read or not: trimesh
        reads only map_Kd, and takes options before a name as part of it):
        the rest of each line and its last word, as inputs."""
        text = self.texts.get(mtllib) if mtllib is not None else None
        for ref in _MAP_LINE.findall(text or b"")[:1024]:
            ref = ref.decode("utf-8", "replace").strip()
            for name in {ref, ref.split()[-1] if ref.split() else ref}:
                self.candidates(name)

    def inputs(self) -> list[str]:
        """The model, every file read and every file a name could mean."""
        out = [self.path]
        for p in self.read + self.named:
            if p not in out:
                out.append(p)
        return out

    def resolver(self):
        """A trimesh resolver that asks this gate for everything."""
        from trimesh.resolvers import Resolver

        gate = self

        class _Gate(Resolver):
            def __init__(self):
                self.file_name = gate.name  # (trimesh names an unnamed OBJ object after it)

            def get(self, name):
                return gate.get(name)

            def write(self, name, data):
                raise PermissionError("models are read, not written, here")

            def namespaced(self, namespace):
                return self

            def keys(self):
                return iter(())

        return _Gate()


def _inside(real: str, top: str) -> bool:
    return real == top or real.startswith(top.rstrip(os.sep) + os.sep)


def _opened_path(fd: int, path: str) -> str:
    """The real path of an open file (what was opened, not what a name meant
    a moment before)."""
    try:
        return os.readlink(f"/proc/self/fd/{fd}")
    except OSError:
        return os.path.realpath(path)


def trimesh_mtllib(text: str) -> str | None:
    """The material library name trimesh takes from an OBJ's text: the rest of
    the line after the first ``mtllib`` anywhere (a comment's included)."""
    at = text.find("mtllib")
    if at < 0:
        return None
    end = text.find("\n", at)
    return text[at + 6:end if end >= 0 else len(text)].strip()


_SPACE = np.zeros(256, bool)
_SPACE[[9, 10, 11, 12, 13, 28, 29, 30, 31, 32]] = True  # str.split()'s ASCII whitespace


def obj_counts(text: bytes, chunk: int = 8 << 20, limit: int | None = None) -> tuple[int, int, int]:
    """(triangles, positions, the larger of texture coordinates and normals)
    an OBJ's text can give trimesh, counted the way trimesh finds them: every
    line that starts with ``f`` (``f1/1 2/2 3/3`` included) is a polygon of
    as many triangles as it has references less two (at least one); ``v``,
    ``vt`` and ``vn`` lines. ``text``: as trimesh sees it (lines joined at a
    backslash, CR LF as LF). ``limit``: where the text cannot hold more
    triangles than that (a polygon's corners are words, and every word
    follows a whitespace byte), that bound is given without counting them one
    by one (the exact count: about 0.3 s per 10 MB here)."""
    t = b"\n" + text.replace(b"\r\n", b"\n").replace(b"\\\n", b"")
    verts = t.count(b"\nv") - t.count(b"\nvt") - t.count(b"\nvn") - t.count(b"\nvp")
    others = max(t.count(b"\nvt"), t.count(b"\nvn"))
    lines = t.count(b"\nf")
    if len(t) < 2 * lines + 4 * 1024:  # (no room for polygons beyond one triangle a line)
        return lines, verts, others
    if limit is not None:
        words = 1 + sum(t.count(bytes([c])) for c in np.flatnonzero(_SPACE))
        if words <= limit:
            return words, verts, others
    tri = 0
    start = 0
    while start < len(t):  # in pieces that end at a line's end (memory: a few times the piece)
        end = t.find(b"\n", min(start + chunk, len(t)))
        end = len(t) if end < 0 else end
        a = np.frombuffer(t, np.uint8, end - start, start)
        nl = np.flatnonzero(a == 10)
        face = nl[(nl + 1 < len(a))]
        face = face[a[face + 1] == ord("f")]
        if len(face):
            space = _SPACE[a]
            starts = np.empty(len(a), bool)
            starts[0] = not space[0]
            np.greater(~space[1:], ~space[:-1], out=starts[1:])  # a word begins
            words = np.cumsum(starts, dtype=np.int64)
            line_end = np.append(nl, len(a))[np.searchsorted(nl, face, side="right")]
            n = words[line_end - 1] - words[face]  # words on the line, "f" or "f1/1" the first
            bare = space[np.minimum(face + 2, len(a) - 1)] | (face + 2 >= line_end)
            refs = n - bare
            tri += int(np.maximum(refs - 2, 1).sum())
        start = end
    return tri, verts, others
