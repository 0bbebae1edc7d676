"""Texture in motion in the real editor: how fast a flow plays, and whether
the editor's own frames stay short meanwhile.

    xvfb-run -a -s "-screen 0 1280x800x24" python -m bench.editor_motion [--structure N] [--seconds S] [--json OUT.json]

The real editor (its own runner, 1280 x 800 window, the default gravel) is
settled; a vortex velocity map is placed over the view (as the Flow tool's
placed map does) and Play pressed. For S seconds (default 20): how soon the
first frame shows, the frames the canvas showed (the player process composes
them, app/player.py) per second, then how soon a frame shows the view after a
200 px pan; and the editor's own frame times throughout (start to start:
median, p90, max); then the same with the view zoomed to 200%
(a quarter of the canvas pixels). The issue's targets: a 512 x 512 view at
10 frames a second at Variety and 4 at Balanced on this machine; pans and
strokes never wait for a frame. Prints a table, writes JSON.
"""
from __future__ import annotations

import argparse
import json
import os
import statistics
import sys
import tempfile
import time
from dataclasses import replace

import numpy as np

HERE = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
if HERE not in sys.path:
    sys.path.insert(0, HERE)


def _p(values: list[float], q: float) -> float:
    v = sorted(values)
    return v[min(len(v) - 1, int(round(q * (len(v) - 1))))] if v else float("nan")


def vortex_map(w: int, h: int, x: int, y: int, speed: float = 1.5):
    from infinitex.engine.controls.flow import Q, VelocityMap
    ys, xs = np.mgrid[0:h, 0:w].astype(np.float64)
    dx, dy = xs - w / 2, ys - h / 2
    r = np.hypot(dx, dy) + 1e-9
    s = speed * np.minimum(1.0, r / (0.15 * min(w, h))) * np.clip(1.5 - r / (0.5 * min(w, h)), 0, 1)
    return VelocityMap(np.rint(np.stack([-dy / r * s, dx / r * s], -1) * Q).astype(np.int32), x, y)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--json", metavar="OUT.json")
    ap.add_argument("--structure", type=int, default=None, metavar="N",
                    help="Structure preset of the document (default: the documents' default)")
    ap.add_argument("--seconds", type=float, default=20.0)
    args = ap.parse_args(argv)
    os.environ.setdefault("INFINITEX_STATE", tempfile.mkdtemp(prefix="infinitex-bench-"))
    from infinitex.app.ui.editor import Editor
    from infinitex.engine.controls.flow import Flow
    from infinitex.project.flow_json import Motion

    results: dict = {}
    script = ["settle", "play", "zoom", "play", "done"]

    class Bench(Editor):
        step = 0
        t0 = 0.0
        frames: list[float] = []
        shown: list[float] = []
        quiet_since: float | None = None
        pan_at: float | None = None
        pan_shown: float | None = None
        n_shown = 0

        def gui(self) -> None:
            now = time.perf_counter()
            if script[self.step] == "play" and self.t0 == 0.0 and self.frame is not None:
                self._start_playing(now)  # first in its frame, as Space is
                super().gui()
                return
            super().gui()
            s = self.session
            ready = s is not None and s.ready and self.doc is not None and s.job is None and self.files.pending is None
            what = script[self.step]
            if what == "settle":
                if ready and args.structure is not None and self.doc.structure != args.structure:
                    self.edit(replace(self.doc, structure=args.structure), "bench: structure")
                    return
                if ready and self.refined:
                    self.quiet_since = self.quiet_since or now
                    if now - self.quiet_since > 1.0:
                        self.step += 1
                        self.quiet_since = None
                return
            if what == "done":
                self.playback.stop()
                self.params.app_shall_exit = True
                return
            if what == "zoom":
                self.viewer.zoom_to(2.0)
                self.step += 1
                return
            self.frames.append(now)
            if os.environ.get("MOTION_DEBUG") and now - self.frames[-2] > 0.2:
                print(f"gap {1000 * (now - self.frames[-2]):.0f} ms at {now - self.t0:.2f} s, t {self.playback.t}, "
                      f"shown {self.playback.shown and self.playback.shown.t}", flush=True)
            if self.playback.shown is not None and self.playback.t != self.last_t:
                self.shown.append(now)
                self.last_t = self.playback.t
            self._measure(now)

        def _start_playing(self, now: float) -> None:
            w, h = self.canvas_size
            x0, y0 = self.view.top_left(w, h)
            vm = vortex_map(int(w / self.view.zoom) + 600, int(h / self.view.zoom) + 600,
                            int(x0) - 300, int(y0) - 300)
            flow = Flow(map=vm)
            self.edit(replace(self.doc, motion=Motion(replace(flow, period=flow.suggested_period()), 480, 24.0)),
                      "bench: flow", region=())
            self.playback.play()
            self.t0 = now = time.perf_counter()  # (making the bench's map above is not the editor's time)
            self.frames, self.shown = [now], []
            self.last_t = -1

        def _measure(self, now: float) -> None:
            pb = self.playback
            if self.pan_at is None and now - self.t0 >= args.seconds:
                self.viewer.pan(200, 0)  # a pan while it plays: how soon a frame shows the new view
                self.pan_at, self.pan_shown = now, None
                self.played_s = now - self.t0
                self.n_shown = len(self.shown)
            if self.pan_at is not None and self.pan_shown is None and pb.shown is not None \
                    and pb.shown.rect.contains(self.exports.view_rect()) or self.pan_at is not None and now - self.pan_at > 30:
                self.pan_shown = now - self.pan_at
            if self.pan_at is not None and self.pan_shown is not None:
                ft = [b - a for a, b in zip(self.frames, self.frames[1:])]
                rect = self.exports.view_rect()
                key = f"{self.view.zoom * 100:.0f}%"
                shown = self.shown[:self.n_shown]
                results[key] = {"canvas_px": [rect.w, rect.h], "played_fps": (len(shown) - 1) /
                                (shown[-1] - shown[0]) if len(shown) > 1 else 0.0,
                                "first_frame_s": shown[0] - self.t0 if shown else None,
                                "after_pan_s": self.pan_shown,
                                "frames": len(ft), "frame_median_ms": 1000 * statistics.median(ft),
                                "frame_p90_ms": 1000 * _p(ft, 0.9), "frame_max_ms": 1000 * max(ft),
                                "error": self.playback.player.error}
                self.playback.pause()
                self.step += 1
                self.t0 = 0.0
                self.pan_at = None

    ed = Bench(recover=False, window_size=(1280, 800))
    ed.run()
    for key, r in results.items():
        first = r["first_frame_s"] if r["first_frame_s"] is not None else float("nan")
        print(f"{key:>5} view {r['canvas_px'][0]}x{r['canvas_px'][1]}: first frame {first:5.1f} s, "
              f"played {r['played_fps']:5.1f} fps, after a 200 px pan {r['after_pan_s']:5.1f} s; editor "
              f"frames {r['frames']:4d}: median {r['frame_median_ms']:6.1f} ms, p90 {r['frame_p90_ms']:6.1f} ms, "
              f"max {r['frame_max_ms']:6.1f} ms" + (f"  ({r['error']})" if r["error"] else ""))
    results["renderer"] = ed.renderer
    results["structure"] = ed.doc.structure if ed.doc is not None else None
    if args.json:
        from infinitex.engine.safeio import atomic_write
        atomic_write(args.json, json.dumps(results, indent=1).encode())
    return 0


if __name__ == "__main__":
    sys.exit(main())
