"""The real editor, run as a user runs it (its own window runner, idling and
sleeping as usual: no test engine), which writes what a driver needs to check
into a small JSON file after every frame (gui_fast_input.py reads it).

    python tests/app/xinput_editor.py STATE.json [IMAGE]
"""
from __future__ import annotations

import json
import os
import sys
import time

HERE = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
if HERE not in sys.path:
    sys.path.insert(0, HERE)

from imgui_bundle import imgui  # noqa: E402

from infinitex.app.ui.editor import Editor  # noqa: E402


# New documents start on the 128 px gravel, as in the imgui drivers (gui_harness.py).
os.environ.setdefault("INFINITEX_DEFAULT_EXEMPLAR", os.path.join(HERE, "infinitex", "assets", "gravel.png"))


class ReportingEditor(Editor):
    def __init__(self, state_path: str, path: str | None):
        super().__init__(path, recover=False, window_size=(1270, 780))
        self.state_path = state_path
        self._last_state = None

    def gui(self) -> None:
        self._commands()
        super().gui()
        r = None
        if getattr(self, "_canvas_rect", None) is not None:
            r = self._canvas_rect
        state = {
            "ready": bool(self.session is not None and self.session.ready and self.doc is not None),
            "refined": bool(self.refined),
            "analyzing": bool(self.files.pending is not None or (self.session is not None and self.session.job is not None)),
            "view": [self.view.x, self.view.y, self.view.zoom],
            "tool": self.tool.name,
            "tile_mode": bool(self.viewer.tile_mode),
            "dragging": self.canvas_state.button >= 0,  # a button went down on the canvas and is not released yet
            "path_request": self.dialogs.path_request is not None,
            "modals": [m.title for m in self.dialogs.modals],
            "popup_open": bool(imgui.is_popup_open("", imgui.PopupFlags_.any_popup_id | imgui.PopupFlags_.any_popup_level)),
            "canvas": r,
            "mouse": [imgui.get_io().mouse_pos.x, imgui.get_io().mouse_pos.y],
            "seed": self.doc.seed if self.doc is not None else None,
        }
        if state != self._last_state:
            self._last_state = state
            state["t"] = time.monotonic()
            state["frame"] = self.frame_count
            tmp = self.state_path + ".tmp"
            with open(tmp, "w") as fh:
                json.dump(state, fh)
            os.replace(tmp, self.state_path)

    def _commands(self) -> None:
        """Edits a driver asks for (STATE.json.cmd: "seed N" pairs, each its own
        undo step, so there is something to undo; "saved 1": mark it saved)."""
        path = self.state_path + ".cmd"
        if self.doc is None or self.history is None or not os.path.exists(path):
            return
        with open(path) as fh:
            lines = fh.read().split()
        os.remove(path)
        from dataclasses import replace
        for i in range(0, len(lines) - 1, 2):
            if lines[i] == "seed":
                self.edit(replace(self.doc, seed=int(lines[i + 1])), f"Seed {lines[i + 1]}")
            elif lines[i] == "saved":  # nothing unsaved: Ctrl+O asks no question
                self.history.mark_saved()

    def _canvas(self) -> None:
        p0 = imgui.get_cursor_screen_pos()
        avail = imgui.get_content_region_avail()
        self._canvas_rect = [p0.x, p0.y, avail.x, avail.y]
        super()._canvas()


if __name__ == "__main__":
    os.environ["INFINITEX_NO_NATIVE_DIALOGS"] = "1"
    sys.exit(ReportingEditor(sys.argv[1], sys.argv[2] if len(sys.argv) > 2 else None).run())
