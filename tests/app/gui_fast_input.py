"""Fast input as the window system delivers it: real X events (XTest, through
python-xlib) sent to the real editor (xinput_editor.py, its own runner, idling
and sleeping as it does for a user), each outcome checked exactly.

    xvfb-run -a -s "-screen 0 1280x800x24" python tests/app/gui_fast_input.py OUT_DIR [ROUNDS]

Each round, after the editor has gone idle (more than 3 s without input, so
it sleeps between frames): a 750 px right-button flick released at once must
pan exactly 750 px; a 10 ms Ctrl+O must open the file chooser; a 5 ms Ctrl+Z
must undo one step, and two quick Ctrl+Z while the view refines two; Escape
in an open menu must close it, and the next tool key must choose the tool;
Ctrl+O, Ctrl+S and Ctrl+Z as 1 ms chords (the four events sent at once, Ctrl
released before the letter, as ``xdotool key ctrl+o`` sends them) and as 10 ms
ones must each act once, and a file name typed at once after Ctrl+O ("lt")
must neither choose a tool nor turn tile mode on.
INFINITEX_IDLE_S sets how long each round waits once the editor is idle
(default 3.5 s: the editor then sleeps between frames); INFINITEX_SCENARIOS
(names, e.g. "fast_chords") runs only those.
Writes "ok NAME" / "FAIL NAME: why" lines to OUT_DIR/report.txt.
"""
from __future__ import annotations

import json
import os
import subprocess
import sys
import time

from Xlib import XK, X, display
from Xlib.ext import xtest

HERE = os.path.dirname(os.path.abspath(__file__))
# The editor sleeps between frames (up to 4 s a sleep) 0.5 s after the last input.
IDLE_S = float(os.environ.get("INFINITEX_IDLE_S", "3.5"))


class Driver:
    def __init__(self, out: str):
        self.out = out
        self.state_path = os.path.join(out, "state.json")
        if os.path.exists(self.state_path):
            os.remove(self.state_path)
        self.proc = subprocess.Popen([sys.executable, os.path.join(HERE, "xinput_editor.py"), self.state_path],
                                     stdout=open(os.path.join(out, "editor.log"), "w"), stderr=subprocess.STDOUT)
        self.d = display.Display()
        self.report: list[str] = []

    # -- the editor's state ---------------------------------------------------

    def state(self) -> dict:
        try:
            with open(self.state_path) as fh:
                return json.load(fh)
        except (OSError, ValueError):
            return {}

    def wait(self, cond, timeout: float, what: str) -> dict:
        t = time.monotonic() + timeout
        while time.monotonic() < t:
            if self.proc.poll() is not None:
                raise RuntimeError(f"the editor exited ({self.proc.returncode}) while waiting for {what}")
            s = self.state()
            if s and cond(s):
                return s
            time.sleep(0.01)
        raise RuntimeError(f"timed out waiting for {what}: {self.state()}")

    def check(self, name: str, cond: bool, why: str = "") -> None:
        self.report.append(f"ok {name}" if cond else f"FAIL {name}: {why}")

    # -- X input ----------------------------------------------------------------

    def window_origin(self) -> tuple[int, int]:
        """The editor window's top-left corner on the root window."""
        root = self.d.screen().root
        for w in root.query_tree().children:
            name = w.get_wm_name()
            if name and "Infinitex" in name:
                c = w.translate_coords(root, 0, 0)
                return -c.x, -c.y
        return 0, 0

    def move(self, x: float, y: float) -> None:
        xtest.fake_input(self.d, X.MotionNotify, x=int(round(x)), y=int(round(y)))
        self.d.sync()

    def button(self, b: int, down: bool) -> None:
        xtest.fake_input(self.d, X.ButtonPress if down else X.ButtonRelease, b)
        self.d.sync()

    def key(self, name: str, down: bool) -> None:
        code = self.d.keysym_to_keycode(XK.string_to_keysym(name))
        xtest.fake_input(self.d, X.KeyPress if down else X.KeyRelease, code)
        self.d.sync()

    def burst(self, events: list[tuple[str, bool]]) -> None:
        """Key events sent together, one flush (they reach the editor in one batch)."""
        for name, down in events:
            code = self.d.keysym_to_keycode(XK.string_to_keysym(name))
            xtest.fake_input(self.d, X.KeyPress if down else X.KeyRelease, code)
        self.d.sync()

    def fast_chord(self, key: str, ms: int, then: str = "") -> None:
        """Ctrl+``key`` in about ``ms`` ms. 1 ms: the four events at once, Ctrl up
        before the letter (xdotool's order), then the letters of ``then``."""
        if ms <= 1:
            self.burst([("Control_L", True), (key, True), ("Control_L", False), (key, False)]
                       + [(c, d) for c in then for d in (True, False)])
            return
        step = ms / 4000.0
        for name, down in (("Control_L", True), (key, True), (key, False), ("Control_L", False)):
            self.key(name, down)
            time.sleep(step)
        for c in then:
            self.tap(c)

    def tap(self, name: str) -> None:
        self.key(name, True)
        time.sleep(0.003)
        self.key(name, False)

    def idle(self) -> None:
        """Wait until the editor has nothing to do (the full analysis installed,
        the view exact) and has stopped drawing."""
        self.wait(lambda s: s.get("ready") and s.get("refined") and not s.get("analyzing")
                  and not s.get("path_request") and not s.get("modals"), 600, "a refined, ready editor")
        time.sleep(IDLE_S)

    # -- the scenarios ------------------------------------------------------------

    def flick(self, n: int) -> None:
        s = self.wait(lambda s: s.get("ready") and s.get("canvas"), 600, "the canvas")
        ox, oy = self.window_origin()
        cx0, cy0, cw, ch = s["canvas"]
        x, y = ox + cx0 + 40, oy + cy0 + ch / 2
        self.move(x, y)
        time.sleep(0.2)
        self.idle()
        v0 = self.state()["view"]
        self.button(3, True)  # X button 3: the right button
        for i in range(1, 11):
            time.sleep(0.002)
            self.move(x + 75 * i, y)
        self.button(3, False)
        # The release handled (frames can take a second while the view refines).
        v1 = self.wait(lambda s: s["view"] != v0 and not s.get("dragging"), 30, "the pan")["view"]
        moved = (v0[0] - v1[0]) * v0[2], (v0[1] - v1[1]) * v0[2]
        self.check(f"round {n}: a 750 px flick released at once pans 750 px", moved == (750.0, 0.0),
                   f"panned {moved[0]:.1f}, {moved[1]:.1f} px")

    def ctrl_o(self, n: int) -> None:
        self.idle()
        self.key("Control_L", True)
        time.sleep(0.003)
        self.tap("o")
        time.sleep(0.003)
        self.key("Control_L", False)
        try:
            self.wait(lambda s: s.get("path_request"), 2.0, "the file chooser")
            self.check(f"round {n}: a 10 ms Ctrl+O after idling opens the file chooser", True)
        except RuntimeError as exc:
            self.check(f"round {n}: a 10 ms Ctrl+O after idling opens the file chooser", False, str(exc))
            return
        self.tap("Escape")  # closes the chooser
        try:
            self.wait(lambda s: not s.get("path_request"), 2.0, "the chooser to close")
            self.check(f"round {n}: Escape closes the file chooser", True)
        except RuntimeError as exc:
            self.check(f"round {n}: Escape closes the file chooser", False, str(exc))

    def command(self, text: str) -> None:
        tmp = self.state_path + ".cmd.tmp"
        with open(tmp, "w") as fh:
            fh.write(text)
        os.replace(tmp, self.state_path + ".cmd")

    def chord(self, key: str, times: int = 1) -> None:
        """Ctrl held for ``times`` taps of ``key``, about 5 ms a tap."""
        self.key("Control_L", True)
        time.sleep(0.002)
        for _ in range(times):
            self.tap(key)
            time.sleep(0.002)
        self.key("Control_L", False)

    def undo(self, n: int) -> None:
        """A 5 ms Ctrl+Z from idle undoes one step; two quick Ctrl+Z while the
        view refines undo two (each an undo step of its own, in order)."""
        base = 1000 * (n + 1)
        self.command(" ".join(f"seed {base + k}" for k in range(1, 5)))
        self.wait(lambda s: s.get("seed") == base + 4, 10, "the edits")
        self.idle()
        self.chord("z")
        try:
            self.wait(lambda s: s.get("seed") == base + 3, 2.0, "one undo")
            self.check(f"round {n}: a 5 ms Ctrl+Z after idling undoes one step", True)
        except RuntimeError as exc:
            self.check(f"round {n}: a 5 ms Ctrl+Z after idling undoes one step", False, str(exc))
            return
        refining = not self.state().get("refined")
        self.chord("z", 2)
        try:
            self.wait(lambda s: s.get("seed") == base + 1, 3.0, "two more undos")
            time.sleep(0.5)
            seed = self.state().get("seed")
            self.check(f"round {n}: two quick Ctrl+Z while refining undo two steps", refining and seed == base + 1,
                       f"refining {refining}, seed {seed}")
        except RuntimeError as exc:
            self.check(f"round {n}: two quick Ctrl+Z while refining undo two steps", False, str(exc))
        self.command("saved 1")  # the next Ctrl+O asks nothing about unsaved changes
        self.wait(lambda s: not s.get("modals"), 5, "no question")

    def escape_menu(self, n: int) -> None:
        ox, oy = self.window_origin()
        self.idle()
        start_tool = self.state()["tool"]
        # The File menu: the menu bar's first item.
        self.move(ox + 20, oy + 12)
        time.sleep(0.05)
        self.button(1, True)
        time.sleep(0.01)
        self.button(1, False)
        try:
            self.wait(lambda s: s.get("popup_open"), 2.0, "the File menu")
        except RuntimeError as exc:
            self.check(f"round {n}: the File menu opens", False, str(exc))
            return
        time.sleep(0.3)
        self.tap("Escape")
        try:
            self.wait(lambda s: not s.get("popup_open"), 2.0, "the menu to close")
            self.check(f"round {n}: Escape closes an open menu", True)
        except RuntimeError as exc:
            self.check(f"round {n}: Escape closes an open menu", False, str(exc))
        want, key = ("paint-canvas", "b") if start_tool != "paint-canvas" else ("navigate", "n")
        self.tap(key)
        try:
            s = self.wait(lambda s: s.get("tool") == want, 2.0, f"the {want} tool")
            self.check(f"round {n}: the tool key after Escape chooses the tool", True)
        except RuntimeError as exc:
            self.check(f"round {n}: the tool key after Escape chooses the tool", False, str(exc))

    def fast_chords(self, n: int) -> None:
        """From idle: 1 ms and 10 ms Ctrl+O (a file name typed at once after it),
        Ctrl+S and Ctrl+Z each act exactly once."""
        for ms in (1, 10):
            for key in ("o", "s"):
                self.command("saved 1")
                self.idle()
                before = self.state()
                self.fast_chord(key, ms, then="lt" if key == "o" else "")
                name = f"round {n}: a {ms} ms Ctrl+{key.upper()} after idling opens the file chooser"
                try:
                    s = self.wait(lambda s: s.get("path_request"), 2.0, "the file chooser")
                    time.sleep(0.2)
                    s = self.state()
                    self.check(name, s.get("tool") == before.get("tool") and s.get("tile_mode") == before.get("tile_mode"),
                               f"typing after it changed the tool to {s.get('tool')} / tile mode {s.get('tile_mode')}")
                except RuntimeError as exc:
                    self.check(name, False, str(exc))
                self.tap("Escape")
                self.wait(lambda s: not s.get("path_request"), 3.0, "the chooser to close")
            base = 1000 * (n + 1) + 500 + ms
            self.command(f"seed {base} seed {base + 1} saved 1")
            self.wait(lambda s: s.get("seed") == base + 1, 10, "the edits")
            self.idle()
            self.fast_chord("z", ms)
            name = f"round {n}: a {ms} ms Ctrl+Z after idling undoes one step"
            try:
                self.wait(lambda s: s.get("seed") == base, 2.0, "one undo")
                time.sleep(0.3)
                self.check(name, self.state().get("seed") == base, f"seed {self.state().get('seed')}")
            except RuntimeError as exc:
                self.check(name, False, str(exc))
            self.command("saved 1")

    def close(self) -> None:
        self.proc.terminate()
        try:
            self.proc.wait(20)
        except subprocess.TimeoutExpired:
            self.proc.kill()
        with open(os.path.join(self.out, "report.txt"), "w") as fh:
            fh.write("\n".join(self.report) + "\n")


def main(out: str, rounds: int) -> int:
    drv = Driver(out)
    try:
        for n in range(rounds):
            only = os.environ.get("INFINITEX_SCENARIOS", "").split()  # (by hand: e.g. "fast_chords")
            for scenario in (drv.flick, drv.ctrl_o, drv.undo, drv.escape_menu, drv.fast_chords):
                if only and scenario.__name__ not in only:
                    continue
                try:
                    scenario(n)
                except RuntimeError as exc:  # a wait timed out: that scenario failed, the others still run
                    drv.report.append(f"FAIL round {n}: {scenario.__name__}: {exc}")
                    drv.tap("Escape")
    except Exception as exc:
        drv.report.append(f"FAIL driver: {exc}")
    finally:
        drv.close()
    return 0 if drv.report and all(r.startswith("ok") for r in drv.report) else 1


if __name__ == "__main__":
    sys.exit(main(sys.argv[1], int(sys.argv[2]) if len(sys.argv) > 2 else 1))
