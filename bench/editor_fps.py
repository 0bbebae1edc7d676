"""Frame rate of the real editor while a randomness slider is dragged.

    xvfb-run -a -s "-screen 0 1280x800x24" python -m bench.editor_fps [--json OUT.json]

The editor runs through imgui-bundle's runner with the imgui test engine,
which drags sliders with the mouse like a user: each frame the slider moves,
the document changes, the affected pyramid levels are dropped and refined
coarse-first within the frame budget. Frame times are taken between
consecutive frames of the editor itself. Prints a table, writes JSON.
"""
from __future__ import annotations

import argparse
import json
import os
import statistics
import sys
import tempfile
import time

HERE = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, HERE)

from imgui_bundle.immapp import testing

from infinitex.app.ui.editor import Editor


def main(argv=None) -> int:
    ap = argparse.ArgumentParser()
    ap.add_argument("--json", metavar="OUT.json")
    ap.add_argument("--seconds", type=float, default=4.0, help="drag duration per slider")
    ap.add_argument("--exemplar", metavar="IMAGE", help="open this image (default: the editor's default)")
    ap.add_argument("--mid-shot", metavar="PNG", help="capture the window in the middle of the first drag "
                                                      "(and beside it, NAME-final.png, once refined after it)")
    args = ap.parse_args(argv)
    os.environ.setdefault("INFINITEX_STATE", tempfile.mkdtemp(prefix="infinitex-bench-"))
    ed = Editor(args.exemplar, recover=False)
    stamps: list[float] = []
    orig_gui = ed.gui

    docs: list = []

    def gui():
        stamps.append(time.perf_counter())
        docs.append(ed.doc)
        orig_gui()

    params = ed.runner_params()
    params.callbacks.show_gui = gui
    results = {}

    def wait_refined(ctx, limit=600):
        for _ in range(limit):
            ctx.yield_()
            if ed.session is not None and ed.session.ready and ed.refined and ed.doc is not None:
                return True
        return False

    def drag(ctx, ref: str, name: str):
        wait_refined(ctx)
        ctx.item_open("//**/Randomness")
        ctx.mouse_move(ref)
        item = ctx.item_info(ref)
        r = item.rect_full
        y = (r.min.y + r.max.y) / 2
        ctx.mouse_down(0)
        n0 = len(stamps)
        t0 = time.perf_counter()
        step = 0
        while time.perf_counter() - t0 < args.seconds:
            frac = 0.15 + 0.7 * (0.5 + 0.5 * ((step % 40) / 20.0 - 1.0 if (step // 40) % 2 == 0 else 1.0 - (step % 40) / 20.0))
            ctx.mouse_move_to_pos((r.min.x + frac * (r.max.x - r.min.x), y))
            ctx.yield_()
            step += 1
            if args.mid_shot and not results and step == 30:
                testing.capture(ctx, args.mid_shot)
        ctx.mouse_up(0)
        frames = [b - a for a, b in zip(stamps[n0:-1], stamps[n0 + 1:])]
        edits = sum(1 for a, b in zip(docs[n0:-1], docs[n0 + 1:]) if a is not b)
        t1 = time.perf_counter()
        wait_refined(ctx, 2000)
        if args.mid_shot and not results:
            testing.capture(ctx, os.path.splitext(args.mid_shot)[0] + "-final.png")
        results[name] = {
            "frames": len(frames),
            "frames_with_an_edit": edits,
            "fps_mean": len(frames) / max(1e-9, sum(frames)),
            "frame_ms_median": 1000 * statistics.median(frames),
            "frame_ms_p90": 1000 * sorted(frames)[int(0.9 * (len(frames) - 1))],
            "frame_ms_max": 1000 * max(frames),
            "refine_after_release_s": time.perf_counter() - t1,
        }

    def test(ctx):
        ctx.yield_()
        drag(ctx, "//**/All levels", "all_levels")
        drag(ctx, "//**/1 px##jit" + str(ed.session.L), "finest_level")
        drag(ctx, "//**/16 px##jit" + str(ed.session.L - 4), "level_L-4")
        results["canvas"] = list(ed.canvas_size)
        results["renderer"] = ed.renderer

    testing.run(test_function=test, runner_params=params, run_speed=testing.TestRunSpeed.fast)
    print(f"Editor frame rate while dragging a randomness slider (canvas {results['canvas'][0]}x{results['canvas'][1]}, "
          f"{results['renderer']})")
    print(f"{'slider':<14}{'frames':>8}{'edits':>7}{'fps':>8}{'median ms':>11}{'p90 ms':>9}{'max ms':>9}{'refine s':>10}")
    for k, v in results.items():
        if isinstance(v, dict):
            print(f"{k:<14}{v['frames']:>8}{v['frames_with_an_edit']:>7}{v['fps_mean']:>8.1f}{v['frame_ms_median']:>11.1f}"
                  f"{v['frame_ms_p90']:>9.1f}{v['frame_ms_max']:>9.1f}{v['refine_after_release_s']:>10.2f}")
    if args.json:
        from infinitex.engine.safeio import atomic_write
        atomic_write(args.json, json.dumps(results, indent=1).encode())
    return 0


if __name__ == "__main__":
    sys.exit(main())
