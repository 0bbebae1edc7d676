"""What the GUI drivers (gui_driver.py, gui_lattice.py, gui_everyday.py) share:
the real editor run by the imgui test engine, exact canvas read-backs, and a
report of "ok NAME" / "FAIL NAME: why" lines in OUT_DIR/report.txt that
test_editor.py reads."""
from __future__ import annotations

import faulthandler
import os
import sys
import time

HERE = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
if HERE not in sys.path:
    sys.path.insert(0, HERE)

from imgui_bundle.immapp import testing  # noqa: E402

from infinitex.app.session import Session  # noqa: E402
from infinitex.app.ui.editor import Editor  # noqa: E402


class Harness:
    def __init__(self, out: str, path: str | None = None, window_size=(1280, 800)):
        os.environ["INFINITEX_NO_NATIVE_DIALOGS"] = "1"
        os.environ["INFINITEX_PATH_PROMPT"] = "1"  # the drivers type paths (gui_everyday also opens the browser)
        # New documents start on the 128 px gravel (a quarter of the shipped
        # default's analysis and levels; test_editor's screenshot test opens that).
        os.environ.setdefault("INFINITEX_DEFAULT_EXEMPLAR", os.path.join(HERE, "infinitex", "assets", "gravel.png"))
        self.out = out
        Session.verify_regions = True  # every edit's region is checked against what changed
        self.ed = Editor(path, recover=False, window_size=window_size)
        self.report: list[str] = []

    def check(self, name: str, cond: bool, why: str = "") -> None:
        self.report.append(f"ok {name}" if cond else f"FAIL {name}: {why}")

    def settle(self, ctx, limit_s: float = 300.0) -> None:
        """Frames until the document is loaded, analyzed and the view refined
        (a time limit: frames are short, about 30 ms, while the view refines)."""
        ed = self.ed
        t0 = time.monotonic()
        while time.monotonic() - t0 < limit_s:
            ctx.yield_()
            if (ed.session is not None and ed.session.ready and ed.doc is not None and ed.refined
                    and ed.files.pending is None and ed.session.job is None):
                return
        raise RuntimeError("the editor did not settle")

    @staticmethod
    def wait(ctx, cond, seconds: float) -> bool:
        """Frames until ``cond()`` holds or ``seconds`` pass (an export in a
        process of its own takes seconds to start on a busy machine); whether it held."""
        t0 = time.monotonic()
        while time.monotonic() - t0 < seconds:
            if cond():
                return True
            ctx.yield_()
            time.sleep(0.01)
        return cond()

    def canvas(self, ctx):
        """The canvas read back exactly (RGB), by the editor itself during a frame."""
        self.settle(ctx)
        self.ed.canvas_state.ask_read_back()
        while self.ed.canvas_state.read_asked:
            ctx.yield_()
        return self.ed.canvas_state.read_back

    def peek(self, ctx):
        """What the canvas shows now (RGB), read back in a frame without
        waiting for the refinement or forcing a redraw."""
        self.ed.refinement.peek_asked = True
        while self.ed.refinement.peek_asked:
            ctx.yield_()
        return self.ed.canvas_state.read_back

    def run(self, test, watchdog_s: float = 600.0) -> int:
        """Run ``test(ctx)`` in the editor; write the report; 0 when every check passed.
        The test engine stops a test running longer than ``watchdog_s`` (its own
        default, 60 s, is too short for a driver on a loaded 2-core machine)."""
        params = self.ed.runner_params()

        def register_tests() -> None:
            from imgui_bundle import hello_imgui, imgui
            io = imgui.test_engine.get_io(hello_imgui.get_imgui_test_engine())
            io.config_watchdog_warning = watchdog_s
            io.config_watchdog_kill_test = watchdog_s
        params.callbacks.register_tests = register_tests

        def traced(ctx) -> None:
            # The test engine's crash handler (installed after start-up) only says
            # "Crashed while running"; Python's own handler, installed again over it,
            # prints every thread's stack first, then the crash goes on as before.
            faulthandler.enable(all_threads=True)
            test(ctx)
        try:
            testing.run(test_function=traced, runner_params=params, run_speed=testing.TestRunSpeed.fast)
        except Exception as exc:
            self.report.append(f"FAIL driver: {exc}")
        missed = Session.missed_regions
        self.check("every edit's region holds what it changed", not missed,
                   f"{len(missed)} edits missed {missed[:3]}")
        with open(os.path.join(self.out, "report.txt"), "w") as fh:
            fh.write("\n".join(self.report) + "\n")
        return 0 if self.report and all(r.startswith("ok") for r in self.report) else 1
