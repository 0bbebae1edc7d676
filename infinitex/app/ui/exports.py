"""Exports started from the editor: the window export (one image, or one PNG
a map, rendered here in budgeted slices between frames), the streamed exports
(tile sets, BigTIFF, Zarr, rendered by worker processes while the editor stays
live), each frame's polling of the running job, and stopping them on exit.

``Exports`` is a part of the editor (``Editor.exports``): it owns the running
export (``job``), the ones waiting (``queue``) and the Export panel's settings
(``settings``, written by that panel alone).
"""
from __future__ import annotations

import math
import os
from dataclasses import dataclass, field

from infinitex.engine.material import export_depths, map_path, output_paths
from infinitex.engine.pyramid import Rect, SynthesisError
from infinitex.engine.safeio import WriteError, check_output, printable
from infinitex.export import check_zarr_output, udim_name
from infinitex.export.engines import ENGINES
from infinitex.export.jobs import BackgroundExport, ExportEstimate, StreamedExport
from infinitex.export.window import (
    ExportJob,
    Writes,
    check_own_inputs,
    same_file,
    streamed_writes,
)

FRAME_BUDGET_S = 0.030       # synthesis time per frame: keeps the UI above 15 fps on llvmpipe


@dataclass
class ExportSettings:
    """The Export panel's settings (panels/export.py writes them, alone; the
    exports read them)."""

    rect: list = field(default_factory=lambda: [0, 0, 2048, 2048])  # x, y, w, h (canvas pixels)
    format: str = "png"     # png (one image, in memory) | tiles (UDIM PNG set) | tiff (BigTIFF) | zarr
    stream_tile: int = 1024  # tile size of the streamed formats
    workers: int = field(default_factory=lambda: max(1, (os.cpu_count() or 2) - 1))  # leave a core to the editor
    tile_size: int = 1024    # the seamless tile's size (tile mode shows it)
    write_coords: bool = False
    depth: int | None = None  # bit depth of exported maps; None: each map's own
    magnify: int = 1          # exported pixels per texel (synthesis magnification)
    estimate: ExportEstimate | None = None  # the streamed export's estimate running for these settings


class Exports:
    """Starting an export, following it frame by frame, stopping it."""

    def __init__(self, ed) -> None:
        self.ed = ed
        self.job: ExportJob | StreamedExport | BackgroundExport | None = None  # the running export
        self.queue: list = []  # exports waiting for the running one
        self.settings = ExportSettings()  # what the Export panel sets (it alone), the exports read

    # -- export -------------------------------------------------------------

    def view_rect(self) -> Rect:
        w, h = self.ed.canvas_size
        x0, y0 = self.ed.view.top_left(w, h)
        return Rect(math.floor(x0), math.floor(y0), math.ceil(x0 + w / self.ed.view.zoom), math.ceil(y0 + h / self.ed.view.zoom))

    def inputs(self) -> list[str]:
        """The files the document was read from (exemplar, every map) and its
        project file: no export may replace them."""
        return [*self.ed.doc.input_paths(), *([self.ed.files.project_path] if self.ed.files.project_path else [])]

    def confirm_replace(self, writes: Writes, asked: str | None, again) -> bool:
        """True to go on; else ask first (Replace calls ``again()``) about the
        existing files among ``writes`` the file dialog did not ask about
        (the system's dialogs ask about the file chosen; the in-window
        browser and the path box ask nothing; nor does any dialog ask about
        a material's other maps or the coordinate map). A streamed export's
        tile set is asked about only when it is not being continued."""
        existing = [f for f in writes.files if os.path.lexists(f) and not (asked and same_file(f, asked))]
        existing += [f for f in writes.folders if not f.endswith(".parts") and os.path.lexists(f)
                     and not (asked and same_file(f, asked))]
        for base, cols, rows in writes.tile_sets:
            first = udim_name(base, 0, 0, cols)
            if os.path.lexists(first) and not any(os.path.lexists(f) for f in writes.folders):
                existing.append(f"{base}.<UDIM>.png" if cols <= 10 else f"{base}_u<U>_v<V>.png")
        if not existing:
            return True
        names = [printable(os.path.basename(f)) for f in existing]
        what = names[0] if len(names) == 1 else f"{', '.join(names[:-1])} and {names[-1]}"
        self.ed.dialogs.ask("Replace?", f"{what} already exist{'s' if len(names) == 1 else ''} in "
                         f"{printable(os.path.dirname(existing[0]))}. Replace {'it' if len(names) == 1 else 'them'}?",
                         [("Replace", again), ("Cancel", None)])
        return False

    def asked(self, chosen: str, path: str) -> str | None:
        """The file a system dialog asked about replacing (the name chosen, unchanged), if any."""
        return path if self.ed.dialogs.native and os.path.abspath(chosen) == os.path.abspath(path) else None

    def start(self, path: str, rect: Rect, toroidal: int = 0, confirmed: bool = False) -> None:
        if self.ed.session.quick_analysis:
            job = self.ed.session.job
            done = f" ({job.progress * 100:.0f}% done)" if job is not None else ""
            self.ed.dialogs.message("Export", "The canvas still shows the quick preview while the full analysis "
                                 f"runs{done}; export once it is finished, so the file holds the final texture.")
            return
        chosen = path
        if not os.path.splitext(path)[1]:
            single = self.ed.session.material is None or self.ed.session.material.single
            path += ".tif" if self.settings.depth == 32 and single else ".png"
        coords = os.path.splitext(path)[0] + "_coords.png" if self.settings.write_coords else None
        try:
            check_output(path, (".png", ".tif", ".tiff"), "export")  # before any work
            if coords:
                check_output(coords, (".png",), "coordinate map")
            mat = self.ed.session.material
            if mat is not None:  # every file the export writes: none may be one of its inputs
                outs = [p for _, p, _ in output_paths(path, mat.roles,
                                                      export_depths(mat, mat.roles, self.settings.depth, path))]
                writes = Writes(files=outs + ([coords] if coords else []))
                check_own_inputs(writes, self.inputs())
                if not confirmed and not self.confirm_replace(
                        writes, self.asked(chosen, path), lambda: self.start(path, rect, toroidal, True)):
                    return
            geometry = "original" if self.ed.geometry() is not None else "rectified"  # what the canvas shows
            options = dict(toroidal=toroidal, coords_path=coords, geometry=geometry, depth=self.settings.depth,
                           magnify=1 if coords else self.settings.magnify)
            job = ExportJob(self.ed.session, rect, path, **options)
            job.cancel()  # it checked the export; the export itself runs in a process of its own
            for _, out, _ in job.outputs:
                check_output(out, (".png", ".tif"), "export")
            self.enqueue(BackgroundExport(self.ed.doc, job, options))
        except (SynthesisError, ValueError, WriteError) as exc:  # OwnInputError, MaterialError are ValueErrors
            self.ed.dialogs.message("Export", str(exc))

    def start_streamed(self, path: str, rect: Rect, confirmed: bool = False) -> None:
        """A tile set or BigTIFF of ``rect``, rendered by worker processes while the editor stays live."""
        fmt = self.settings.format
        ext = {"tiff": ".tif", "zarr": ".zarr"}.get(fmt, ".png")
        chosen = path
        if not os.path.splitext(path)[1]:
            path += ext
        try:
            if fmt == "zarr":
                check_zarr_output(path)
            else:
                check_output(path, (".tif", ".tiff") if ext == ".tif" else (".png",), "export")
            if self.settings.write_coords and fmt != "zarr":
                check_output(os.path.splitext(path)[0] + "_coords" + ext, (ext,), "coordinate map")
            asked = self.asked(chosen, path)
            role = "" if self.ed.session.material.single else self.ed.shown_role()
            if role:  # one map per streamed export: the one shown
                path = map_path(path, role)
                asked = None
            writes = streamed_writes(path, fmt, rect.w, rect.h, self.settings.stream_tile, self.settings.write_coords)
            check_own_inputs(writes, self.inputs())
            if not confirmed and not self.confirm_replace(
                    writes, asked, lambda: self.start_streamed(path, rect, True)):
                return
            self.job = StreamedExport(self.ed.doc, self.ed.session.L, rect, path, fmt, self.settings.stream_tile,
                                             self.settings.workers, coords=self.settings.write_coords and fmt != "zarr",
                                             role=role)
        except (SynthesisError, ValueError, WriteError) as exc:
            self.ed.dialogs.message("Export", str(exc))

    def start_tileset(self, path: str, job, per_tile: bool = False, seed: int = 0,
                             confirmed: bool = False, engines: tuple[str, ...] = ENGINES) -> None:
        """Write a tile set (made, or being made, by ``job``: the tile-set
        dialog's) to ``path``; it is finished and written while the editor stays live."""
        chosen = path
        if not os.path.splitext(path)[1]:
            single = self.ed.session.material is None or self.ed.session.material.single
            path += ".tif" if self.settings.depth == 32 and single else ".png"
        try:
            check_output(path, (".png", ".tif", ".tiff"), "export")
            job.set_output(path, depth=self.settings.depth, per_tile=per_tile, preview_seed=seed,
                           engines=engines)
            writes = Writes(files=job.writes)
            check_own_inputs(writes, self.inputs())
            if not confirmed and not self.confirm_replace(
                    writes, self.asked(chosen, path),
                    lambda: self.start_tileset(path, job, per_tile, seed, True, engines)):
                return
            self.enqueue(job)
        except (SynthesisError, ValueError, WriteError) as exc:
            job.cancel()
            self.ed.dialogs.message("Export", str(exc))

    def apart(self) -> bool:
        """The running export works in other processes (the editor stays live)."""
        return isinstance(self.job, (StreamedExport, BackgroundExport))

    def enqueue(self, job) -> None:
        """Start an export now, or after the ones before it (a window export's
        process starts then; a tile set or a model export is stepped then)."""
        if self.job is None:
            getattr(job, "start", lambda: None)()
            self.job = job
        else:
            self.queue.append(job)
            self.ed.tell(f"Export queued ({len(self.queue)} waiting): {os.path.basename(job.out_path)}")

    def _next(self) -> None:
        if self.job is None and self.queue:
            job = self.queue.pop(0)
            getattr(job, "start", lambda: None)()
            self.job = job

    def poll(self) -> None:
        """A streamed export's progress, or a window export's next slice; a notice once it ends."""
        self._next()
        job = self.job
        if isinstance(job, (BackgroundExport, StreamedExport)):  # in processes of their own
            if not job.finished:
                return
            self.job = None
            if job.error:
                self.ed.dialogs.message("Export failed", job.error)
            elif isinstance(job, BackgroundExport):
                self.ed.tell(f"Export of {os.path.basename(job.out_path)} cancelled" if job.cancelled
                          else _written(job))
            elif job.cancelled:
                self.ed.tell(f"Export stopped: {job.done_tiles} of {job.job.total} tiles are kept; the same "
                          f"export continues from them")
            else:
                r = job.rect
                where = " and ".join(os.path.abspath(o) for o in job.job.outputs())
                kept = f" ({job.kept} tiles kept from an earlier run)" if job.kept else ""
                self.ed.tell(f"Exported {r.w}x{r.h} to {where}{kept}")
                if job.job.notes:  # e.g. a parts folder left in place because it held foreign files
                    self.ed.dialogs.message("Export finished", "\n".join(job.job.notes))
            if isinstance(job, BackgroundExport):
                self._next()
        elif self.job is not None:
            self.job.step(FRAME_BUDGET_S)
            self.ed.screen_fbo.use()
            if self.job.done or self.job.cancelled:
                job, self.job = self.job, None
                if job.error:
                    self.ed.dialogs.message("Export failed", job.error)
                elif not job.cancelled and hasattr(job, "summary"):  # a tile set
                    self.ed.tell(job.summary())
                elif not job.cancelled:
                    self.ed.tell(_written(job))

    def closed(self) -> None:
        """The progress window of an export done in the editor was closed."""
        self.job = None

    def stop(self) -> None:
        """On exit: cancel the running export and close the estimate's workers."""
        for job in self.queue:
            job.cancel()
        if self.job is not None:
            self.job.cancel()
            if isinstance(self.job, StreamedExport):
                self.job.wait(120)  # the tiles being rendered finish; every finished one is kept
            elif isinstance(self.job, BackgroundExport):
                self.job.wait(30)
        if self.settings.estimate is not None:
            self.settings.estimate.close(wait=10.0)


def _written(job) -> str:
    """Where a finished window (or model) export went, for the status bar."""
    r = job.out_rect
    names = [os.path.abspath(o) for _, o, _ in job.outputs]
    where = names[0] if len(names) == 1 else f"{len(names)} maps ({', '.join(names)})"
    extra = f" and {os.path.abspath(job.coords_path)}" if job.coords_path else ""
    return f"Exported {r.w}x{r.h} to {where}{extra}"
