"""The Zarr output of a streamed export: a multiscale store (OME-NGFF 0.4
metadata, zarr format 2) whose level k is the synthesis's level L - k, built
by the zarr library in the export's parts folder (checked: a real folder of
the user's, see :mod:`.workdir`) and moved to the output when complete.

A store left by an earlier run (``data.zarr``) is reused only if it is a plain
tree of this user's folders and files with the names a store of this export
has (no link, FIFO or device, nothing else) and its arrays have this export's
shapes, chunks and type; a plain tree that does not fit is removed and
started again; anything else is refused (left as it is) before any work. An
earlier output replaced by the new store is moved into the parts folder under
a name of this run's, then removed (a link there: the link, not its target)."""
from __future__ import annotations

import os
import re
import secrets
import stat

import numpy as np

from infinitex.engine.pyramid import Rect
from infinitex.engine.safeio import WriteError

from .workdir import plain_tree

STORE = "data.zarr"         # built here, in the parts folder
_META = {".zgroup", ".zattrs", ".zarray", ".zmetadata"}
_META_MAX = 1 << 20
_CHUNK = re.compile(r"(0|[1-9][0-9]{0,6})(\.(0|[1-9][0-9]{0,6})){1,2}")


class ZarrLevels:
    """The store of one :class:`~.streamed.TiledExport` (its levels, tile size,
    parts folder and output); ``parts`` and ``out_dir`` are the export's open
    parts folder and output folder (:class:`.workdir.Folder`)."""

    def __init__(self, export, parts, out_dir):
        self.export = export
        self.parts = parts
        self.out_dir = out_dir

    def path(self) -> str:
        return os.path.join(self.export.parts, STORE)  # built here, moved to ``out`` when complete

    def _allowed(self, rel: str, st: os.stat_result) -> bool:
        """The entries of a store of this export (see :func:`.workdir.plain_tree`)."""
        parts = rel.split("/")
        folder = stat.S_ISDIR(st.st_mode)
        if len(parts) == 1:
            if folder:
                return parts[0].isdigit() and int(parts[0]) < len(self.export.levels)
            return parts[0] in _META and st.st_size <= _META_MAX
        if folder:
            return False
        if parts[1] in _META:
            return st.st_size <= _META_MAX
        t = self.export.tile
        return bool(_CHUNK.fullmatch(parts[1])) and st.st_size <= t * t * 4 + (1 << 16)

    def _check(self, name: str) -> None:
        """Refuse (before any work) a ``name`` in the parts folder that is not a plain store of this export."""
        limit = 4 * self.export.total + 8 * len(self.export.levels) + 8
        why = plain_tree(self.parts, name, self._allowed, limit)
        if why:
            raise WriteError(f"{self.parts.show(name)} is not a Zarr store this export made ({why}); it is left "
                             f"as it is: remove it (or the whole {self.parts.shown}) and run the export again.")

    def _fits(self, store) -> bool:
        """Whether the arrays of a reused store have this export's levels, shapes, chunks and type."""
        t = self.export.tile
        for name, arr in store.arrays():
            if not (name.isdigit() and int(name) < len(self.export.levels)):
                return False
            r = self.export.levels[int(name)]
            meta = arr.metadata
            c = arr.shape[0] if arr.ndim == 3 else 1
            want = ((r.h, r.w), (t, t)) if arr.ndim == 2 else ((c, r.h, r.w), (c, t, t))
            if (arr.ndim not in (2, 3) or (arr.ndim == 3 and not 2 <= c <= 4) or (arr.shape, arr.chunks) != want
                    or str(arr.dtype) != "uint8" or getattr(meta, "zarr_format", None) != 2
                    or getattr(meta, "filters", None) or getattr(meta, "order", "C") != "C"):
                return False
        return True

    def open(self, fresh: bool):
        """The multiscale store being built (OME-NGFF 0.4 metadata, zarr format
        2, which napari's and most viewers' readers open): arrays "0" (full
        resolution), "1" (half)... of (C, H, W) or (H, W) uint8 chunked by tile."""
        import zarr
        self._check(STORE)
        path = self.path()
        if not fresh and self.parts.lstat(STORE) is not None:
            try:
                store = zarr.open_group(path, mode="r+", zarr_format=2)
                if self._fits(store):
                    return store
            except Exception:  # noqa: BLE001 - no usable store: start it again
                pass
        self.export.guard(lambda: self.parts.remove_tree(STORE))  # a plain store of ours (checked above)
        return self.guard_value(lambda: zarr.open_group(path, mode="w", zarr_format=2))

    def guard_value(self, make):
        out = []
        self.export.guard(lambda: out.append(make()))
        return out[0]

    def array(self, store, level: int, channels: int):
        name = str(level)
        if name in store:
            arr = store[name]
            if (arr.shape[0] if arr.ndim == 3 else 1) != channels:
                raise WriteError(f"{self.parts.show(STORE)} holds the store of another export ({channels} "
                                 f"channels expected); remove {self.parts.shown} and run the export again.")
            return arr
        r = self.export.levels[level]
        t = self.export.tile
        shape, chunks = ((r.h, r.w), (t, t)) if channels == 1 else ((channels, r.h, r.w), (channels, t, t))
        return store.create_array(name, shape=shape, chunks=chunks, dtype="uint8", fill_value=0)

    def level_of(self, name: str) -> int:
        return int(name.split("/", 1)[0])

    def write(self, store, name: str, r: Rect, data: bytes) -> None:
        k = self.level_of(name)
        lr = self.export.levels[k]
        c = len(data) // (r.w * r.h)
        a = np.frombuffer(data, dtype=np.uint8).reshape(r.h, r.w, c)
        arr = self.array(store, k, c)
        ys, xs = slice(r.y0 - lr.y0, r.y1 - lr.y0), slice(r.x0 - lr.x0, r.x1 - lr.x0)
        if c == 1:
            arr[ys, xs] = a[..., 0]
        else:
            arr[:, ys, xs] = np.moveaxis(a, 2, 0)

    def read(self, store, name: str, r: Rect) -> bytes:
        k = self.level_of(name)
        lr = self.export.levels[k]
        arr = store[str(k)]
        ys, xs = slice(r.y0 - lr.y0, r.y1 - lr.y0), slice(r.x0 - lr.x0, r.x1 - lr.x0)
        a = arr[ys, xs][..., None] if arr.ndim == 2 else np.moveaxis(arr[:, ys, xs], 0, 2)
        return np.ascontiguousarray(a).tobytes()

    def finish(self) -> None:
        """Write the multiscale metadata, then move the complete store to ``out``
        (an earlier output of that name is moved into the parts folder first,
        then removed: a link there is removed, not what it points to)."""
        import zarr
        store = zarr.open_group(self.path(), mode="r+", zarr_format=2)
        color = store["0"].ndim == 3
        axes = ([{"name": "c", "type": "channel"}] if color else []) + [
            {"name": "y", "type": "space"}, {"name": "x", "type": "space"}]
        r = self.export.rect
        datasets = []
        for k in range(len(self.export.levels)):
            scale = ([1.0] if color else []) + [float(2 ** k)] * 2
            origin = ([0.0] if color else []) + [float((r.y0 >> k) << k), float((r.x0 >> k) << k)]
            datasets.append({"path": str(k), "coordinateTransformations": [
                {"type": "scale", "scale": scale}, {"type": "translation", "translation": origin}]})
        store.attrs["multiscales"] = [{
            "version": "0.4", "name": os.path.splitext(os.path.basename(self.export.out))[0], "axes": axes,
            "datasets": datasets, "type": "synthesis levels (LH05: the coarser levels are the mipmap)",
            "metadata": {"canvas_rect": [r.x0, r.y0, r.w, r.h], "synthesis_levels": [self.export.L - k for k in
                                                                                    range(len(self.export.levels))]}}]
        out_dir = self.out_dir
        name = os.path.basename(self.export.out)
        old = f"replaced-{secrets.token_hex(4)}.zarr"  # a name of this run's only

        def move():
            if out_dir.lstat(name) is not None:
                os.rename(name, old, src_dir_fd=out_dir.fd, dst_dir_fd=self.parts.fd)
            os.rename(STORE, name, src_dir_fd=self.parts.fd, dst_dir_fd=out_dir.fd)
            out_dir.sync()
            self.parts.remove_tree(old)
        self.export.guard(move)
