"""Streamed exports as jobs the editor runs and polls (the command line runs
:class:`~.streamed.TiledExport` directly): the export's key, the job on a
thread of its own, and the size and time estimate shown before it starts."""
from __future__ import annotations

import hashlib
import json
import multiprocessing
import shutil
import threading
import time
from concurrent.futures import ProcessPoolExecutor

from infinitex.engine.params import SynthParams
from infinitex.engine.priority import lower_priority
from infinitex.engine.pyramid import Rect
from infinitex.project import Document, Project, project_to_json

from .errors import ExportFailed, ExportInterrupted
from .streamed import TiledExport
from .workers import ProjectSynthesizer, calibrate


def export_key(doc: Document, params: SynthParams, role: str = "") -> str:
    """What decides a streamed export's pixels: the whole document (exemplar
    embedded) and the parameters. The editor and the CLI compute the same key,
    so either resumes what the other left."""
    return hashlib.sha256(json.dumps([project_to_json(Project(doc), embed=True), repr(params)]
                                     + ([role] if role else []), sort_keys=True).encode()).hexdigest()


def project_synthesizer(doc: Document, period: int = 0, role: str = "") -> ProjectSynthesizer:
    return ProjectSynthesizer(json.dumps(project_to_json(Project(doc), embed=True)), period, role)


class StreamedExport:
    """A streamed export (:class:`~.streamed.TiledExport`) run from the editor: worker
    processes (their own GL contexts) render the tiles, a thread of this
    process writes them, and the UI polls ``progress``, ``rate`` and
    ``finished``; ``cancel`` stops after the tiles being rendered, keeping
    the finished ones for a later run (the same export resumes)."""

    def __init__(self, doc: Document, L: int, rect: Rect, out_path: str, fmt: str, tile: int,
                 workers: int, coords: bool = False, role: str = ""):
        params = doc.params(L)
        self.job = TiledExport(None, rect, out_path, fmt, tile, key=export_key(doc, params, role), coords=coords, L=L)
        self.init = project_synthesizer(doc, role=role)
        self.out_path, self.rect, self.out_rect, self.fmt, self.workers = out_path, rect, rect, fmt, max(1, workers)
        self.done_tiles = 0
        self.started = time.monotonic()
        self._first: tuple[float, int] | None = None  # (time, tiles) when the first rendered tile came back
        self.finished = False
        self.cancelled = False
        self.cancelling = False
        self.error: str | None = None
        self.thread = threading.Thread(target=self._run, name="streamed-export", daemon=True)
        self.thread.start()

    def _progress(self, done: int, total: int) -> None:
        self.done_tiles = done
        if self._first is None and self.job.rendered:
            self._first = (time.monotonic(), self.job.rendered)

    def _run(self) -> None:
        try:
            self.job.run(self._progress, workers=self.workers, worker_init=self.init)
        except ExportInterrupted:
            self.cancelled = True
        except (OSError, ExportFailed, ValueError) as exc:
            self.error = str(exc)
        except Exception as exc:  # noqa: BLE001 - a worker's failure, reported, never a crash of the editor
            self.error = f"The export failed: {exc}"
        finally:
            self.finished = True

    @property
    def progress(self) -> float:
        return self.done_tiles / max(1, self.job.total)

    @property
    def kept(self) -> int:
        return self.job.kept

    def rate(self) -> float | None:
        """Pixels per second of the tiles rendered by this run (after the first,
        which includes the workers' start-up)."""
        if self._first is None:
            return None
        t0, n0 = self._first
        n = self.job.rendered - n0
        dt = time.monotonic() - t0
        if n <= 0 or dt <= 0:
            return None
        return n * self.job.tile ** 2 / dt

    def seconds_left(self) -> float | None:
        r = self.rate()
        if r is None:
            return None
        return (self.job.total - self.done_tiles) * self.job.tile ** 2 / r

    def cancel(self) -> None:
        self.cancelling = True
        self.job.cancel_event.set()

    def wait(self, timeout: float | None = None) -> bool:
        self.thread.join(timeout)
        return self.finished


def _window_export_worker(project_json: str, rect: tuple, out_path: str, options: dict, progress, cancel,
                          answer) -> None:
    """A window export in a process of its own (BackgroundExport): the
    document loaded on its own GL context (the analysis from the disk
    cache), then ExportJob to the end; ``progress`` a shared fraction,
    ``cancel`` an event, ``answer`` a pipe for (kind, detail)."""
    from infinitex.engine.gpu import Gpu
    from infinitex.project import parse_project_json, project_from_json

    from .loaded import LoadedDocument
    from .window import ExportJob
    gpu = session = None
    lower_priority(19)  # the editor's frames first: the export takes what the cores have left
    try:
        doc = project_from_json(parse_project_json(project_json.encode("utf-8"))).document
        gpu = Gpu()
        session = LoadedDocument(gpu)
        session.load_now(doc)
        job = ExportJob(session, Rect(*rect), out_path, **options)
        while not job.step(0.2):
            progress.value = job.progress
            if cancel.is_set():
                job.cancel()
                answer.send(("cancelled", None))
                return
        answer.send(("error", job.error) if job.error else ("ok", None))
    except Exception as exc:  # noqa: BLE001 - one line for the editor
        answer.send(("error", (str(exc).strip().splitlines() or [type(exc).__name__])[0]))
    finally:
        if session is not None:
            session.release()
        if gpu is not None:
            gpu.release()


class BackgroundExport:
    """A window export (the view, a rectangle, a toroidal tile: one image or
    one file a map) run in a process of its own with its own GL context, so
    the editor stays live (the canvas pans and paints meanwhile). Checked
    first in the editor (``checked``: the ExportJob made there, released at
    once: its outputs and rectangle); the UI polls ``progress``,
    ``finished``, ``error``; ``cancel`` stops it (nothing is written)."""

    def __init__(self, doc: Document, checked, options: dict):
        self.outputs, self.out_rect, self.out_path = checked.outputs, checked.out_rect, checked.out_path
        self.coords_path = checked.coords_path
        ctx = multiprocessing.get_context("spawn")
        self._progress = ctx.Value("d", 0.0, lock=False)
        self._cancel = ctx.Event()
        self._recv, send = ctx.Pipe(duplex=False)
        project = json.dumps(project_to_json(Project(doc), embed=True))
        r = checked.out_rect
        self.proc = ctx.Process(target=_window_export_worker, daemon=True,
                                args=(project, (r.x0, r.y0, r.x1, r.y1), self.out_path, options, self._progress,
                                      self._cancel, send))
        self._send = send
        self.started = time.monotonic()
        self.finished = self.cancelled = self.done = False
        self.error: str | None = None
        self.thread: threading.Thread | None = None

    def start(self) -> None:
        """Start the process (an export waiting in the editor's queue starts later)."""
        self.started = time.monotonic()
        self.proc.start()
        self._send.close()
        self.thread = threading.Thread(target=self._wait, name="background-export", daemon=True)
        self.thread.start()

    def _wait(self) -> None:
        try:
            kind, detail = self._recv.recv()
        except (EOFError, OSError):
            kind, detail = "error", "the export's process ended without finishing"
        self.proc.join()
        if kind == "cancelled":
            self.cancelled = True
        elif kind == "error":
            self.error = detail or "The export failed."
        self.finished = self.done = True

    @property
    def progress(self) -> float:
        return 1.0 if self.finished and not self.error else float(self._progress.value)

    def seconds_left(self) -> float | None:
        p, elapsed = self.progress, time.monotonic() - self.started
        return elapsed * (1.0 - p) / p if 0.02 < p < 1.0 and elapsed > 2.0 else None

    def cancel(self) -> None:
        self._cancel.set()
        if self.thread is None:  # never started
            self.cancelled = self.finished = self.done = True

    def wait(self, timeout: float | None = None) -> bool:
        if self.thread is not None:
            self.thread.join(timeout)
        return self.finished


class ExportEstimate:
    """The size and time of a streamed export, estimated before it starts:
    one worker process (as the export uses) renders and encodes a tile, in
    the background; ``result`` is (seconds per pixel, bytes per pixel) once
    measured. The process is started and awaited by a thread of its own, as
    for StreamedExport: the GUI thread never spawns or joins processes."""

    def __init__(self, doc: Document, fmt: str, tile: int):
        self.key = (doc.analysis_key(), fmt, tile)
        self.init = project_synthesizer(doc)
        self.result: tuple[float, float] | None = None
        self.error: str | None = None
        self.pool = None
        self.closed = False
        self.finished = False
        self.thread = threading.Thread(target=self._run, name="export-estimate", daemon=True)
        self.thread.start()

    def _run(self) -> None:
        try:
            with ProcessPoolExecutor(1, mp_context=multiprocessing.get_context("spawn")) as pool:
                self.pool = pool
                if not self.closed:
                    self.result = pool.submit(calibrate, self.init, self.key[1], self.key[2]).result()
        except Exception as exc:  # noqa: BLE001 - an estimate that failed says so; the export may still work
            if not self.closed:
                self.error = str(exc) or type(exc).__name__
        finally:
            self.finished = True

    def poll(self) -> bool:
        """True once measured (or failed); the worker is then gone."""
        return self.finished

    def close(self, wait: float = 0.0) -> None:
        """Stop the measuring worker now (an estimate nobody waits for)."""
        self.closed = True
        pool = self.pool
        if pool is not None and not self.finished:
            for proc in list((getattr(pool, "_processes", None) or {}).values()):
                proc.terminate()
        if wait:
            self.thread.join(wait)

    def describe(self, w: int, h: int, workers: int, folder: str) -> tuple[str, bool]:
        """One line for the panel ("about 1.2 GB, about 25 min"), and whether the
        disk lacks room for it."""
        if self.error is not None:
            return f"No estimate ({self.error}).", False
        if self.result is None:
            return "Estimating size and time (rendering a sample tile)...", False
        s_px, b_px = self.result
        pixels = w * h
        size = pixels * b_px
        # Measured with one worker. More workers mostly overlap encoding and
        # writing: a software GL (llvmpipe) already spreads one worker over
        # every core, and one GPU is shared (bench/export.py: 2 workers 1.04x).
        seconds = pixels * s_px
        try:
            free = shutil.disk_usage(folder or ".").free
        except OSError:
            free = None
        need = size * (2.1 if self.key[1] == "tiff" else 1.1)  # a TIFF's parts and the file coexist a moment
        low = free is not None and need > free
        text = f"About {_bytes(size)} and {duration_text(seconds)} with {workers} worker{'s' * (workers > 1)}"
        if low:
            text += f"; only {_bytes(free)} free there"
        return text + ".", low


def _bytes(n: float) -> str:
    for unit in ("bytes", "KB", "MB", "GB", "TB"):
        if n < 1000 or unit == "TB":
            return f"{n:.0f} {unit}" if unit == "bytes" else f"{n:.1f} {unit}"
        n /= 1000
    return ""


def duration_text(s: float) -> str:
    """A duration for people: 42 s, 17 min, 3.2 h."""
    if s < 90:
        return f"{max(1, round(s))} s"
    if s < 5400:
        return f"{round(s / 60)} min"
    return f"{s / 3600:.1f} h"
