"""The Zarr output of a streamed export: a multiscale store (OME-NGFF 0.4
metadata, zarr format 2) whose level k is the synthesis's level L - k, built
in the export's parts folder and moved to the output when complete."""
from __future__ import annotations

import os
import shutil

import numpy as np

from infinitex.engine.pyramid import Rect


class ZarrLevels:
    """The store of one :class:`~.streamed.TiledExport` (its levels, tile size,
    parts folder and output)."""

    def __init__(self, export):
        self.export = export

    def path(self) -> str:
        return os.path.join(self.export.parts, "data.zarr")  # built here, moved to ``out`` when complete

    def open(self, fresh: bool):
        """The multiscale store being built (OME-NGFF 0.4 metadata, zarr format
        2, which napari's and most viewers' readers open): arrays "0" (full
        resolution), "1" (half)... of (C, H, W) or (H, W) uint8 chunked by tile."""
        import zarr
        path = self.path()
        if not fresh:
            try:
                return zarr.open_group(path, mode="r+", zarr_format=2)
            except Exception:  # noqa: BLE001 - no usable store: start it again
                pass
        shutil.rmtree(path, ignore_errors=True)
        return self.guard_value(lambda: zarr.open_group(path, mode="w", zarr_format=2))

    def guard_value(self, make):
        out = []
        self.export.guard(lambda: out.append(make()))
        return out[0]

    def array(self, store, level: int, channels: int):
        name = str(level)
        if name in store:
            return store[name]
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
        """Write the multiscale metadata, then move the complete store to ``out``."""
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

        def move():
            old = os.path.join(self.export.parts, "replaced.zarr")
            if os.path.lexists(self.export.out):
                os.rename(self.export.out, old)  # an earlier export of the same name, removed below
            os.rename(self.path(), self.export.out)
        self.export.guard(move)
