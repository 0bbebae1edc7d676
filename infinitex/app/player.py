"""Texture in motion, live: the frames the canvas shows while a flow plays,
rendered in a process of its own (its own headless GL context, the analysis
from the disk cache), so the editor's frames never wait for one: pans, strokes
and menus go on while a frame is composed, and the canvas shows each frame as
it arrives, over the still texture, at its place on the canvas.

The frames are engine/advect.py's ``FlowFrames`` (composed in GL), exactly the
frames an export writes: the same document gives the same frame bit for bit
here, in ``infinitex animate`` and through the API.

:class:`FlowPlayer` talks to the process (a pickled document, then requests of
a frame over a window; each answer is the frame's RGB pixels);
:class:`Playback` is the clock: which frame is due, played in order at the
document's frame rate (or slower, as fast as frames come), paused, stepped or
scrubbed. Neither imports imgui; the Motion panel and the canvas drive them.
"""
from __future__ import annotations

import multiprocessing
import queue
import threading
import time
from dataclasses import dataclass, replace

import numpy as np

from infinitex.engine.priority import lower_priority
from infinitex.engine.rect import Rect
from infinitex.project import Document

MAX_PLAY_PIXELS = 1 << 20  # canvas pixels a played frame covers (the middle of a larger view)
SNAP = 64                  # a played frame's window is on this grid of canvas pixels


@dataclass
class PlayedFrame:
    """A frame as it came back: frame ``t`` of the document sent as ``doc_id`` over ``rect``."""

    t: int
    rect: Rect
    rgb: np.ndarray       # (h, w, 3) uint8
    doc_id: int
    seconds: float        # what composing it took
    exact: bool = True    # its cuts mended (a draft while playing is not)


def play_rect(view_rect: Rect) -> Rect:
    """The canvas rectangle a frame covers for a view: all of it, or its middle
    when it is larger than MAX_PLAY_PIXELS (zoomed out), widened to the SNAP
    grid, so that a small pan keeps the window (its trajectories and static
    texture) and the frame shown simply moves with the canvas."""
    w, h = view_rect.w, view_rect.h
    r = view_rect
    if w * h > MAX_PLAY_PIXELS:
        s = (MAX_PLAY_PIXELS / (w * h)) ** 0.5
        nw, nh = int(w * s) - 2 * SNAP, int(h * s) - 2 * SNAP  # (room for the grid)
        x0, y0 = view_rect.x0 + (w - nw) // 2, view_rect.y0 + (h - nh) // 2
        r = Rect(x0, y0, x0 + max(16, nw), y0 + max(16, nh))
    return Rect(r.x0 // SNAP * SNAP, r.y0 // SNAP * SNAP, -(-r.x1 // SNAP) * SNAP, -(-r.y1 // SNAP) * SNAP)


def _still_part(doc: Document) -> Document:
    return replace(doc, motion=None)


def _player_main(conn) -> None:
    """The player process: documents and requests in, frames out, until told to stop."""
    lower_priority(15)  # the editor's own frames first (and anything else the user runs)
    from infinitex.engine.advect import FlowFrames, SynthSource
    from infinitex.engine.gpu import Gpu
    from infinitex.engine.imagefile import to_u8
    from infinitex.export.loaded import LoadedDocument
    gpu = Gpu()
    loaded = LoadedDocument(gpu)
    doc = doc_id = None
    period = 0
    frames = source = None
    made_for = None  # (doc, period) the frames were made for
    still_for = None  # (the document without its motion, period) the static texture is of
    try:
        while True:
            want = None
            msg = conn.recv()
            while True:
                kind = msg[0]
                if kind == "quit":
                    return
                if kind == "doc":
                    _, doc_id, doc, period = msg
                elif kind == "want":
                    want = msg
                if not conn.poll():
                    break
                msg = conn.recv()  # only the latest request counts
            if want is None or doc is None:
                continue
            _, _, t, rect, role, correct = want
            t0 = time.perf_counter()
            try:
                if made_for is None or made_for[0] is not doc or made_for[1] != period:
                    still = _still_part(doc)
                    if source is None or still_for != (still, period):
                        # Another still texture: install it (the analysis kept when it is the same).
                        if frames is not None:
                            frames.release()
                            frames = None
                        if source is not None:
                            source.release()
                            source = None
                        loaded.period = period
                        if loaded.key != doc.analysis_key():
                            loaded.load_now(still)
                        elif (loaded.synced_doc is None or _still_part(loaded.synced_doc) != still
                              or (loaded.params.period or 0) != period):
                            loaded.install(still, loaded.exemplar, loaded.analysis, loaded.material)
                        source = SynthSource(loaded.synth, period)
                        still_for = (still, period)
                    if frames is not None:  # only the flow changed (a stroke): the static texture is kept
                        frames.release()
                    frames = FlowFrames(source, doc.motion.flow, loaded.params.seed)
                    made_for = (doc, period)
                role = loaded.shown_map(role)
                if correct:  # the exact frame: the export's, bit for bit
                    rgb = to_u8(loaded.material.lookup(role, frames.frame(t, rect)))
                    rgb = np.ascontiguousarray(np.repeat(rgb[..., :1], 3, axis=2) if rgb.shape[2] < 3
                                               else rgb[..., :3])
                else:  # a draft: its cuts not mended, its colors looked up in GL
                    rgb = frames.draft_rgb(t, rect, loaded.display_stack(role)[-1])
                conn.send(("frame", doc_id, t, (rect.x0, rect.y0, rect.x1, rect.y1), rgb,
                           time.perf_counter() - t0, correct))
            except Exception as exc:  # noqa: BLE001 - one line for the editor
                made_for = still_for = None
                conn.send(("error", doc_id, (str(exc).strip().splitlines() or [type(exc).__name__])[0]))
    except (EOFError, OSError, KeyboardInterrupt):
        return
    finally:
        if frames is not None:
            frames.release()
            source.release()
        loaded.release()
        gpu.release()


def _sender(conn, out: queue.Queue) -> None:
    """Sends what the editor queued (a document is megabytes: the pipe takes it while
    the process reads, never while the editor's frame waits)."""
    while True:
        msg = out.get()
        if msg is None:
            return
        try:
            conn.send(msg)
        except Exception:  # noqa: BLE001 - the process or the pipe is gone: the receiver says so
            return


def _receiver(conn, inbox: queue.Queue) -> None:
    """Receives the process' answers whole (a frame is megabytes: never read on the editor's frame)."""
    while True:
        try:
            inbox.put(conn.recv())
        except Exception:  # noqa: BLE001 - EOF: the process ended (or the pipe was closed)
            inbox.put(("died",))
            return


class FlowPlayer:
    """The player process, started on the first request. ``request`` never
    blocks; ``poll`` returns the frames and errors that came back. Each
    document sent has an id, and its still part is kept: a frame fits a
    document with the same still texture (:meth:`fits`; a stroke of the flow
    keeps it, so the frames of the last flow show until the new one's come)."""

    def __init__(self):
        self.proc = None
        self.conn = None
        self._out: queue.Queue | None = None    # messages to the process (a sender thread)
        self._inbox: queue.Queue | None = None  # its answers (a receiver thread)
        self._threads: list[threading.Thread] = []
        self._sent: tuple | None = None   # (doc, period) last sent
        self.doc_id = 0
        self._gens: dict[int, tuple] = {}  # doc id -> (its still part, period)
        self._fit_key: tuple | None = None
        self._fit_still = self._fit_doc = None
        self.asked: tuple | None = None   # (doc_id, t, rect, role) of the request in flight
        self.error: str | None = None

    @property
    def busy(self) -> bool:
        """A request is in flight."""
        return self.asked is not None

    def request(self, doc: Document, period: int, t: int, rect: Rect, role: str, correct: bool = True) -> None:
        """Ask for frame ``t`` over ``rect`` (``correct`` False: a draft, its cuts not mended)."""
        if self.proc is None or not self.proc.is_alive():
            self.close()
            self._start()
        sent = self._sent
        if sent is None or not (sent[0] is doc or sent[0] == doc) or sent[1] != period:
            still = _still_part(doc)
            last = self._gens.get(self.doc_id)
            if last is not None and last[1] == period and last[0] == still:
                still = last[0]  # (the same still texture: the same object, compared at once)
            self.doc_id += 1
            self._gens = {k: v for k, v in self._gens.items() if k > self.doc_id - 64}
            self._gens[self.doc_id] = (still, period)
            self._out.put(("doc", self.doc_id, doc, period))
            self._sent = (doc, period)
        self.asked = (self.doc_id, t, rect, role)
        self.error = None
        self._out.put(("want", self.doc_id, t, rect, role, correct))

    def fits(self, frame: PlayedFrame, doc: Document, period: int) -> bool:
        """The frame shows ``doc``'s still texture (its flow may be an earlier one: a
        stroke while it plays), with ``period``."""
        made = self._gens.get(frame.doc_id)
        if made is None or made[1] != period:
            return False
        key = (id(doc), period)
        if self._fit_key != key:  # (once per document: documents are immutable)
            self._fit_key, self._fit_still = key, _still_part(doc)
            self._fit_doc = doc  # (kept: its id stays its own)
        return made[0] is self._fit_still or made[0] == self._fit_still

    def poll(self) -> PlayedFrame | None:
        """The newest frame that came back since the last poll (errors go to ``error``)."""
        got = None
        if self._inbox is None:
            return None
        while True:
            try:
                msg = self._inbox.get_nowait()
            except queue.Empty:
                break
            if msg[0] == "died":
                self._died()
                return got
            self.asked = None
            if msg[0] == "frame":
                _, doc_id, t, r, rgb, seconds, exact = msg
                got = PlayedFrame(t, Rect(*r), rgb, doc_id, seconds, exact)
                self.error = None
            else:
                self.error = msg[2]
        return got

    def _died(self) -> None:
        self.close()
        self.error = "The motion preview stopped; press Play to start it again."

    def _start(self) -> None:
        ctx = multiprocessing.get_context("spawn")  # a fresh interpreter: no inherited GL state
        self.conn, child = ctx.Pipe()
        self.proc = ctx.Process(target=_player_main, args=(child,), daemon=True, name="infinitex-player")
        self.proc.start()
        child.close()
        self._sent = None
        self.asked = None
        self._out, self._inbox = queue.Queue(), queue.Queue()
        self._threads = [threading.Thread(target=_sender, args=(self.conn, self._out), daemon=True,
                                          name="player-send"),
                         threading.Thread(target=_receiver, args=(self.conn, self._inbox), daemon=True,
                                          name="player-receive")]
        for th in self._threads:
            th.start()

    def close(self) -> None:
        """End the process: asked to quit, then stopped after a moment (it keeps nothing)."""
        if self._out is not None:
            self._out.put(("quit",))
            self._out.put(None)
        if self.proc is not None:
            self.proc.join(0.5)
            if self.proc.is_alive():
                self.proc.terminate()
                self.proc.join(1.0)
        for th in self._threads:
            th.join(0.5)  # (the process is gone: its pipe's reads and writes end)
        if self.conn is not None:
            self.conn.close()
        self.proc = self.conn = self._out = self._inbox = None
        self._threads = []
        self._sent = None
        self.asked = None


class Playback:
    """The playhead: frame ``t`` of the document's animation, shown over the
    canvas while ``active``; playing, it moves on a frame at the document's
    frame rate, or as soon as each frame comes when they come slower (never
    skipping one, so what plays is what an export writes). A loop (or the
    animation's frame count) wraps back to frame 0."""

    def __init__(self, player: FlowPlayer | None = None):
        self.player = player or FlowPlayer()
        self.active = False
        self.playing = False
        self.t = 0
        self.shown: PlayedFrame | None = None   # the frame on the canvas
        self.ready: PlayedFrame | None = None   # the next frame, come early: shown when due
        self._shown_at = 0.0
        self._rates: list[float] = []           # when frames were shown (the rate measured)
        self._asked: tuple | None = None        # the request in flight
        self.drafts = True                      # playing shows drafts (cuts not mended: twice as fast)
        self._failed: tuple | None = None       # the request that failed (not made again as it is)

    # -- controls ---------------------------------------------------------------
    def play(self) -> None:
        self.active = self.playing = True
        self._rates = []

    def pause(self) -> None:
        self.playing = False
        self.ready = None

    def toggle(self) -> None:
        self.pause() if self.playing else self.play()

    def stop(self) -> None:
        """Back to the still texture (frame 0 next time)."""
        self.active = self.playing = False
        self.t = 0
        self.shown = self.ready = None

    def seek(self, t: int, count: int) -> None:
        """Show frame ``t`` (wrapped into the animation's ``count`` frames), paused."""
        self.active = True
        self.playing = False
        self.ready = None
        self.t = int(t) % max(1, count)

    def step(self, d: int, count: int) -> None:
        self.seek(self.t + d, count)

    @property
    def rate(self) -> float | None:
        """Frames per second shown lately while playing."""
        r = self._rates
        return (len(r) - 1) / (r[-1] - r[0]) if len(r) >= 3 and r[-1] > r[0] else None

    # -- each editor frame ---------------------------------------------------------
    def tick(self, doc: Document | None, period: int, rect: Rect, role: str, now: float | None = None) -> bool:
        """Ask for and take frames; True when the canvas has a new frame to show."""
        now = time.monotonic() if now is None else now
        motion = getattr(doc, "motion", None)
        if not self.active or motion is None:
            if self.active and motion is None:
                self.stop()
            return False
        count = motion.frames
        self.t %= count
        player = self.player
        got = player.poll()
        if got is not None and not player.fits(got, doc, period):
            got = None  # another document's still texture (opened or edited since it was asked for)
        if self.ready is not None and not player.fits(self.ready, doc, period):
            self.ready = None
        if self.shown is not None and not player.fits(self.shown, doc, period):
            self.shown = None
        changed = False
        if got is not None:
            if self.playing and self.shown is not None and got.t != self.t:
                self.ready = got   # the next frame: shown when due
            else:
                self.shown, changed = got, True
                self._shown_at = now
        if self.playing and self.ready is not None and now - self._shown_at >= 1.0 / motion.fps:
            self.shown, self.ready, changed = self.ready, None, True
            self.t = self.shown.t
            self._shown_at = now
            self._rates = (self._rates + [now])[-24:]
        if player.error is not None and got is None and self._asked is not None:
            self._failed, self._asked = self._asked, None  # not asked again until something changes
        if player.busy:
            return changed
        # What to ask for next: the frame shown, over this view, of this document; then, playing, the next.
        sent = player._sent
        exact = not (self.playing and self.drafts)
        same = (self.shown is not None and self.shown.rect == rect and self.shown.doc_id == player.doc_id
                and sent is not None and (sent[0] is doc or sent[0] == doc) and sent[1] == period
                and (self.shown.exact or not exact))
        want = None
        if not same or self.shown.t != self.t:
            want = self.t
        elif self.playing and self.ready is None:
            want = (self.t + 1) % count
        if want is not None:
            req = (doc, period, want, rect, role, exact)
            if self._failed is None or not _same_request(self._failed, req):
                self._failed = None
                self._asked = req
                player.request(*req)
        return changed

    def close(self) -> None:
        self.player.close()


def _same_request(a: tuple, b: tuple) -> bool:
    return (a[0] is b[0] or a[0] == b[0]) and a[1:] == b[1:]
