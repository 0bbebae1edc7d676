"""The editor's pace: how long a frame's synthesis may take, and when the
editor sleeps between frames and wakes.

``FramePacer`` learns what a busy frame costs besides the synthesis and sets
the refinement's budget from it; ``InputWait`` owns the idle state (set after
each frame from what is running) and the wait before each frame, which ends as
soon as input arrives, so the frame it wakes handles that input.
"""
from __future__ import annotations

import time

from imgui_bundle import imgui

from .keylog import KeyLog

REST_BUDGET_S = 0.020        # synthesis per frame while refining, at most: with drawing, a frame takes about 33 ms
FRAME_S = 0.027              # the frame the refinement's budget aims at (what the rest of a frame leaves)
TYPING_BUDGET_S = 0.004      # the refinement's share of a frame while the user types
IDLE_FPS = 0.25              # frames per second with nothing to do (input wakes the editor at once)
ACTIVE_AFTER_INPUT_S = 0.5   # full frame rate this long after the last input event
BACKGROUND_FPS = 4.0         # while worker processes export: progress, and the cores left to them
TEST_ENGINE_REST_S = 0.05     # under the test engine, the longest rest between frames
ANALYSIS_FPS = 8.0           # while only the analysis thread works (nothing to refine)


class FramePacer:
    """Learns what a busy frame costs besides the synthesis (drawing, the UI,
    an edit), so that the refinement's budget keeps frames near FRAME_S; and
    counts the frame rate the status bar shows."""

    def __init__(self) -> None:
        self._t = 0.0  # when the last frame began (perf_counter)
        self._other_s = 0.010
        self.fps = 0.0
        self._fps_t = time.perf_counter()
        self._fps_n = 0

    def frame_began(self, update_ms: float) -> None:
        """A frame begins; the last one spent ``update_ms`` synthesizing."""
        now = time.perf_counter()
        dt, self._t = now - self._t, now
        if dt < 0.1 and update_ms > 0.0:  # (not after an idle wait)
            self._other_s = 0.8 * self._other_s + 0.2 * max(0.0, dt - update_ms / 1000.0)
        self._fps_n += 1
        if now - self._fps_t >= 0.5:
            self.fps = self._fps_n / (now - self._fps_t)
            self._fps_t, self._fps_n = now, 0

    @property
    def other_s(self) -> float:
        """What a frame costs besides the synthesis, lately."""
        return self._other_s

    @property
    def budget_s(self) -> float:
        """The synthesis budget of this frame; the least while a text field
        takes keys (a file name typed in the chooser: every key shows at once)."""
        if imgui.get_io().want_text_input:
            return TYPING_BUDGET_S
        return min(REST_BUDGET_S, max(0.006, FRAME_S - self._other_s))


class InputWait:
    """Whether the editor may sleep, and its sleep before each frame.

    Idle means idle, and no input is lost: the wait runs before each frame
    (after the runner polled the window system), and the events glfw delivers
    while waiting go to imgui's queue, so the frame they wake handles them.
    While events are queued or came recently (imgui spreads fast input over
    frames: a press and release of one key, a move and a release), the editor
    does not sleep at all."""

    def __init__(self, keys: KeyLog) -> None:
        self.keys = keys
        self.may_idle = False    # nothing to refine, no job (set after each frame)
        self.analyzing = False   # an analysis runs
        self.working = False     # a job runs a slice per frame (an in-process export, a tile set)
        self.fps = IDLE_FPS      # the frame rate while idle
        self.last_input = 0.0    # monotonic time of the last input event seen
        self.last_frame_t = 0.0  # monotonic time the last frame began
        self.never = False       # no sleeping at all (the imgui test engine drives the frames)

    @property
    def idle(self) -> bool:
        """Nothing to do: no refinement, no job, no input for a moment."""
        return (self.may_idle and not self.analyzing
                and time.monotonic() - self.last_input >= ACTIVE_AFTER_INPUT_S)

    def frame_began(self) -> None:
        self.last_frame_t = time.monotonic()

    def frame_ended(self, *, busy: bool, analyzing: bool, working: bool, background: bool,
                    playing: float = 0.0) -> None:
        """What runs now: ``busy`` (something to refine or a job), ``analyzing``
        (the analysis thread), ``working`` (a job sliced into frames: frames stay
        short), ``background`` (worker processes export: a few frames a second),
        ``playing`` (an animation plays at this many frames a second: the editor
        wakes as often, at most 30 times, and sleeps between while its player
        composes)."""
        self.fps = BACKGROUND_FPS if background else IDLE_FPS
        if playing:  # as often as frames are due (input wakes it at once anyway): the player needs the cores
            self.fps = max(self.fps, min(30.0, playing))
        if analyzing and not busy:
            # Only the analysis thread works: a few frames a second show its
            # progress and leave it the cores (full frames would starve it).
            self.fps = ANALYSIS_FPS
        self.may_idle = not busy
        self.analyzing = analyzing
        self.working = working

    def before_frame(self) -> None:
        """The runner's pre-new-frame callback: sleep while there is nothing to do."""
        try:
            self._sleep()
        finally:
            self.keys.new_frame()  # the presses delivered until now are this frame's

    def _sleep(self) -> None:
        now = time.monotonic()
        queue = self.arrived(poll=False)
        if queue:
            self.last_input = now
        if not self.may_idle or queue or now - self.last_input < ACTIVE_AFTER_INPUT_S:
            return
        timeout = 1.0 / self.fps - (now - self.last_frame_t)
        if timeout <= 0:
            return
        if self.never:
            # The test engine's steps need frames, but while only other threads
            # or processes work (an analysis, an export's workers) a frame now
            # and then leaves them the cores, as for a user.
            if self.fps > IDLE_FPS:
                time.sleep(min(timeout, TEST_ENGINE_REST_S))
            return
        try:
            import glfw
            glfw.wait_events_timeout(timeout)  # releases the GIL: the analysis thread runs meanwhile
        except Exception:
            return
        if self.arrived(poll=False):
            self.last_input = time.monotonic()

    def arrived(self, poll: bool = True) -> bool:
        """Input events wait for a frame: imgui's queue or the key log (``poll``:
        asked of the window system first; its callbacks only queue)."""
        if poll:
            try:
                import glfw
                glfw.poll_events()
            except Exception:
                return True
        return bool(len(imgui.get_current_context().input_events_queue) or self.keys.waiting)
