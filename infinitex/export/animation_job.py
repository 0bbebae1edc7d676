"""An animation exported from the editor (its Motion panel): the frames of a
flowing texture (engine/advect.py) rendered in a process of its own with its
own GL context, like a window export (:class:`~.jobs.BackgroundExport`: the
editor polls its progress, can cancel it, and stays live meanwhile), and
written at the end by export/animation.py's writers: nothing partial is left
behind by a cancel or a failure."""
from __future__ import annotations

import multiprocessing
import pickle
import threading
import time
from dataclasses import replace

from infinitex.engine.priority import lower_priority
from infinitex.engine.rect import Rect
from infinitex.project import Document

from .jobs import BackgroundExport


def _animation_worker(doc_bytes: bytes, spec: dict, progress, cancel, answer) -> None:
    """The export's process: the document (pickled by the editor, our own
    data) loaded on a headless GL context, its frames rendered and written."""
    from infinitex.engine.advect import FlowFrames, SynthSource
    from infinitex.engine.gpu import Gpu
    from infinitex.engine.material import IMAGE

    from .animation import AnimationWriter, render_animation
    from .loaded import LoadedDocument
    gpu = loaded = frames = source = None
    lower_priority(19)  # the editor's frames first
    try:
        doc = pickle.loads(doc_bytes)
        gpu = Gpu()
        loaded = LoadedDocument(gpu)
        loaded.period = spec["period"]
        loaded.load_now(replace(doc, motion=None))
        source = SynthSource(loaded.synth, spec["period"])
        flow = doc.motion.flow
        frames = FlowFrames(source, flow, loaded.params.seed)
        writers = {role: AnimationWriter(path, spec["fmt"], doc.motion.fps, bool(flow.loop),
                                         make_parent=role != IMAGE)
                   for role, path in spec["outputs"]}

        def step(fraction: float, _t: int) -> None:
            progress.value = fraction

        written = render_animation(frames, loaded.material, Rect(*spec["rect"]), 0, doc.motion.frames, writers,
                                   step, cancel.is_set)
        answer.send(("cancelled", None) if written is None else ("ok", None))
    except Exception as exc:  # noqa: BLE001 - one line for the editor
        answer.send(("error", (str(exc).strip().splitlines() or [type(exc).__name__])[0]))
    finally:
        for obj in (frames, source, loaded, gpu):
            if obj is not None:
                obj.release()


class AnimationExport(BackgroundExport):
    """The document's animation (``doc.motion``: its frames, rate and loop)
    over ``rect`` (a toroidal tile when ``period``), one output per map:
    ``outputs`` [(role, path)] in format ``fmt`` (export/animation.py)."""

    def __init__(self, doc: Document, rect: Rect, period: int, fmt: str, outputs: list[tuple[str, str]]):
        self.outputs = [(role, path, None) for role, path in outputs]
        self.out_rect, self.out_path, self.coords_path = rect, outputs[0][1], None
        ctx = multiprocessing.get_context("spawn")
        self._progress = ctx.Value("d", 0.0, lock=False)
        self._cancel = ctx.Event()
        self._recv, send = ctx.Pipe(duplex=False)
        spec = {"rect": (rect.x0, rect.y0, rect.x1, rect.y1), "period": period, "fmt": fmt,
                "outputs": list(outputs)}
        self.proc = ctx.Process(target=_animation_worker, daemon=True,
                                args=(pickle.dumps(doc), spec, self._progress, self._cancel, send))
        self._send = send
        self.started = time.monotonic()
        self.finished = self.cancelled = self.done = False
        self.error: str | None = None
        self.thread: threading.Thread | None = None
        self.frames = doc.motion.frames

    def start(self) -> None:
        """Start the process from a thread: spawning it writes the document into its
        pipe and waits for a new interpreter, never on the editor's frame."""
        self.started = time.monotonic()
        self.thread = threading.Thread(target=self._start_and_wait, name="animation-export", daemon=True)
        self.thread.start()

    def _start_and_wait(self) -> None:
        try:
            self.proc.start()
        except Exception as exc:  # noqa: BLE001 - one line for the editor
            self.error = f"The export could not start ({exc})."
            self.finished = self.done = True
            return
        self._send.close()
        self._wait()
