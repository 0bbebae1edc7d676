"""Exports started from the editor: the window export (one image, or one PNG
a map, rendered here in budgeted slices between frames), the streamed exports
(tile sets, BigTIFF, Zarr, rendered by worker processes while the editor stays
live), each frame's polling of the running job, and stopping them on exit.

A mixin of ``Editor`` (editor.py): it keeps no state of its own; the
attributes it uses (``export_job``, ``estimate``, the export settings) are made
in ``Editor.__init__``.
"""
from __future__ import annotations

import math
import os
import time

from infinitex.engine.material import map_path
from infinitex.engine.pyramid import Rect, SynthesisError
from infinitex.engine.safeio import WriteError, check_output
from infinitex.export import check_zarr_output
from infinitex.export.jobs import StreamedExport
from infinitex.export.window import ExportJob

FRAME_BUDGET_S = 0.030       # synthesis time per frame: keeps the UI above 15 fps on llvmpipe


class ExportsMixin:
    """Starting an export, following it frame by frame, stopping it."""

    # -- export -------------------------------------------------------------

    def view_rect(self) -> Rect:
        w, h = self.canvas_size
        x0, y0 = self.view.top_left(w, h)
        return Rect(math.floor(x0), math.floor(y0), math.ceil(x0 + w / self.view.zoom), math.ceil(y0 + h / self.view.zoom))

    def start_export(self, path: str, rect: Rect, toroidal: int = 0) -> None:
        if not os.path.splitext(path)[1]:
            single = self.session.material is None or self.session.material.single
            path += ".tif" if self.export_depth == 32 and single else ".png"
        coords = os.path.splitext(path)[0] + "_coords.png" if self.write_coords else None
        try:
            check_output(path, (".png", ".tif", ".tiff"), "export")  # before any work
            if coords:
                check_output(coords, (".png",), "coordinate map")
            geometry = "original" if self.geometry() is not None else "rectified"  # what the canvas shows
            job = ExportJob(self.session, rect, path, toroidal=toroidal, coords_path=coords,
                            geometry=geometry, depth=self.export_depth, magnify=1 if coords else self.export_magnify)
            try:
                for _, out, _ in job.outputs:
                    check_output(out, (".png", ".tif"), "export")
            except WriteError:
                job.cancel()
                raise
            self.export_job = job
        except (SynthesisError, ValueError, WriteError) as exc:
            self.dialogs.message("Export", str(exc))

    def start_streamed_export(self, path: str, rect: Rect) -> None:
        """A tile set or BigTIFF of ``rect``, rendered by worker processes while the editor stays live."""
        fmt = self.export_format
        ext = {"tiff": ".tif", "zarr": ".zarr"}.get(fmt, ".png")
        if not os.path.splitext(path)[1]:
            path += ext
        try:
            if fmt == "zarr":
                check_zarr_output(path)
            else:
                check_output(path, (".tif", ".tiff") if ext == ".tif" else (".png",), "export")
            if self.write_coords and fmt != "zarr":
                check_output(os.path.splitext(path)[0] + "_coords" + ext, (ext,), "coordinate map")
            role = "" if self.session.material.single else self.shown_role()
            if role:  # one map per streamed export: the one shown
                path = map_path(path, role)
            self.export_job = StreamedExport(self.doc, self.session.L, rect, path, fmt, self.stream_tile,
                                             self.export_workers, coords=self.write_coords and fmt != "zarr",
                                             role=role)
        except (SynthesisError, ValueError, WriteError) as exc:
            self.dialogs.message("Export", str(exc))

    def _poll_export(self) -> None:
        """A streamed export's progress, or a window export's next slice; a notice once it ends."""
        if isinstance(self.export_job, StreamedExport):
            job = self.export_job
            if job.finished:
                self.export_job = None
                if job.error:
                    self.dialogs.message("Export failed", job.error)
                elif job.cancelled:
                    self.notice = (f"Export stopped: {job.done_tiles} of {job.job.total} tiles are kept; the same "
                                   f"export continues from them", time.monotonic())
                else:
                    r = job.rect
                    where = " and ".join(os.path.abspath(o) for o in job.job.outputs())
                    kept = f" ({job.kept} tiles kept from an earlier run)" if job.kept else ""
                    self.notice = (f"Exported {r.w}x{r.h} to {where}{kept}", time.monotonic())
        elif self.export_job is not None:
            self.export_job.step(FRAME_BUDGET_S)
            self.screen_fbo.use()
            if self.export_job.done or self.export_job.cancelled:
                job, self.export_job = self.export_job, None
                if job.error:
                    self.dialogs.message("Export failed", job.error)
                elif not job.cancelled:
                    r = job.out_rect
                    names = [os.path.abspath(o) for _, o, _ in job.outputs]
                    where = names[0] if len(names) == 1 else f"{len(names)} maps ({', '.join(names)})"
                    extra = f" and {os.path.abspath(job.coords_path)}" if job.coords_path else ""
                    self.notice = (f"Exported {r.w}x{r.h} to {where}{extra}", time.monotonic())

    def _stop_exports(self) -> None:
        """On exit: cancel the running export and close the estimate's workers."""
        if self.export_job is not None:
            self.export_job.cancel()
            if isinstance(self.export_job, StreamedExport):
                self.export_job.wait(120)  # the tiles being rendered finish; every finished one is kept
        if self.estimate is not None:
            self.estimate.close(wait=10.0)
