"""Painting randomness in the real editor: latency, pixels per dab, frame rate.

    xvfb-run -a -s "-screen 0 1280x800x24" python -m bench.paint [--json OUT.json]

The imgui test engine selects the Paint canvas tool and draws a scripted
stroke with the mouse like a user: a 48 px brush (radius 24 screen pixels at
100%), one dab per frame, 64 dabs across the canvas, alternating calm and
rough strokes. Each dab edits the document; the session re-synthesizes in
place only what the dab reaches (Pyramid.update_controls), a time budget per
frame at a time (Pyramid.settle), and the canvas is redrawn as it changes.
Measured: the frame time during the stroke (the editor's responsiveness), the
time from a dab to the first frame whose texture is settled (everything painted
so far shown exactly: the latency an artist sees), the level pixels
re-synthesized per dab against those of a full synthesis of the same view, the
frame rate over the stroke and the time the view takes to settle after the
last dab. Prints a table, writes JSON.
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

from imgui_bundle.immapp import testing  # noqa: E402

from infinitex.app.ui.editor import Editor  # noqa: E402


def main(argv=None) -> int:
    ap = argparse.ArgumentParser()
    ap.add_argument("--json", metavar="OUT.json")
    ap.add_argument("--dabs", type=int, default=64)
    ap.add_argument("--radius", type=float, default=24.0, help="brush radius in screen pixels (48 px brush)")
    ap.add_argument("--fidelity", type=int, default=None, metavar="PRESET",
                    help="Structure preset of the painted document (default: the documents' default)")
    ap.add_argument("--labels", action="store_true",
                    help="paint labels (texture by numbers: two labels proposed on the exemplar, strokes "
                         "alternating between them) instead of randomness")
    ap.add_argument("--comb", action="store_true", help="comb a direction field (the Direction tool) instead")
    ap.add_argument("--no-looks", action="store_true", help="without quick looks (QuickLooks.look): for an A/B")
    ap.add_argument("--mid-shot", metavar="PNG", help="also capture the window in the middle of the stroke")
    ap.add_argument("--files", action="store_true",
                    help="list the package's files whose code runs in a dab's frame (a profiler on the frame; "
                         "the timings are then not the editor's)")
    ap.add_argument("--load", type=int, default=0, metavar="N",
                    help="N busy processes run beside the editor (a load average of N more)")
    args = ap.parse_args(argv)
    os.environ.setdefault("INFINITEX_STATE", tempfile.mkdtemp(prefix="infinitex-bench-"))
    os.environ["INFINITEX_NO_NATIVE_DIALOGS"] = "1"
    ed = Editor(recover=False)
    stamps: list[float] = []
    dabs_at: list[int] = []
    pixels_at: list[int] = []
    settled_at: list[bool] = []
    looks_at: list[int] = []
    upd_at: list[float] = []
    ends: list[float] = []
    orig_gui = ed.gui
    updates: list[int] = []

    full_view: list[int] = []

    package = os.path.join(HERE, "infinitex") + os.sep
    frame_files: list[set] = []  # --files: the package files whose code ran in each frame
    path_files: list[set] = []   # those of them that ran under the dab's own entry points (DAB_PATH)
    profiling = [False]
    from infinitex.app.session import Session
    from infinitex.app.ui.tools.paint import PaintCanvasTool
    from infinitex.engine.local_update import LocalUpdates
    from infinitex.engine.looks import QuickLooks
    # A dab's way through a frame: the tool's stroke (and the edit it makes), the
    # session's sync (the local update recorded), the settling and the quick look.
    entries = {f.__code__ for f in (PaintCanvasTool.drag, Session.sync, LocalUpdates.settle, QuickLooks.look)}

    def gui():
        stamps.append(time.perf_counter())
        if profiling[0]:
            seen: set = set()
            path: set = set()
            depth = [0]

            def prof(frame, event, arg):
                code = frame.f_code
                if code in entries:
                    depth[0] += 1 if event == "call" else -1 if event == "return" else 0
                if event == "call" and code.co_filename.startswith(package):
                    seen.add(os.path.relpath(code.co_filename, HERE))
                    if depth[0] > 0:
                        path.add(os.path.relpath(code.co_filename, HERE))
            sys.setprofile(prof)
            try:
                orig_gui()
            finally:
                sys.setprofile(None)
            frame_files.append(seen)
            path_files.append(path)
        else:
            orig_gui()
            frame_files.append(set())
            path_files.append(set())
        ends.append(time.perf_counter())
        dabs_at.append(ed.tools[4 if args.labels else 5 if args.comb else 1].dabs)
        pixels_at.append(sum(updates))
        s = ed.session
        settled_at.append(bool(s is not None and s.pyramid is not None and s.pyramid.settled and ed.refined))
        upd_at.append((ed.canvas_state.update_ms, 1000 * ed.frame_pacer.budget_s))
        looks_at.append(s.pyramid.looks.made if s is not None and s.pyramid is not None else 0)
        if full_view == [-1]:  # asked by the test (GL calls belong in the frame, on the GL thread)
            from infinitex.engine.pyramid import Pyramid
            s = ed.session
            fresh = Pyramid(s.gpu, s.synth.gan, s.params, scrolling=False, controls=s.controls)
            fresh.request(ed.frame.level, ed.frame.want)
            full_view[0] = fresh.pixels_synthesized
            fresh.release()
            ed.screen_fbo.use()

    params = ed.runner_params()
    params.callbacks.show_gui = gui
    results: dict = {}

    def settle(ctx, limit=3000):
        for _ in range(limit):
            ctx.yield_()
            if ed.session is not None and ed.session.ready and ed.refined and ed.doc is not None:
                return

    def test(ctx):
        settle(ctx)
        if args.fidelity is not None and ed.doc.structure != args.fidelity:
            from dataclasses import replace
            ed.edit(replace(ed.doc, structure=args.fidelity), "Structure")
            for _ in range(3):
                ctx.yield_()
            settle(ctx)
        pyr = ed.session.pyramid
        orig_settle = pyr.updates.settle

        def counted(*a, **k):
            n0 = pyr.pixels_synthesized
            done = orig_settle(*a, **k)
            updates.append(pyr.pixels_synthesized - n0)
            return done
        pyr.updates.settle = counted
        if args.no_looks:
            pyr.looks.look = lambda *a: 0
        ctx.set_ref("//Infinitex")
        if args.labels:
            ctx.item_click("//**/Labels (G)##tool-labels")
            tool = ed.tool
            tool.propose_n = 2
            tool.propose()
            settle(ctx)
        elif args.comb:
            ctx.item_click("//**/Direction (D)##tool-direction")
            tool = ed.tool
            tool.mode, tool.axis = "comb", 1  # the exemplar's y along the strokes: a quarter turn
        else:
            ctx.item_click("//**/Paint canvas (B)##tool-paint-canvas")
            tool = ed.tool
        tool.brush.radius, tool.brush.strength, tool.brush.hardness = args.radius, 1.0, 0.5
        r = ctx.item_info("//**/canvas").rect_full
        x0, x1 = r.min.x + 80, r.max.x - 80
        cy = (r.min.y + r.max.y) / 2
        step = 0.25 * args.radius + 0.01  # one dab per frame
        per_row = int((x1 - x0) // step)
        if args.files:
            profiling[0] = True
            ctx.mouse_move_to_pos((x0, cy - 120))
            ctx.yield_(3)  # frames without a dab, the same view: what every frame runs
        n0 = len(stamps)
        d0 = tool.dabs
        row = 0
        while tool.dabs - d0 < args.dabs:
            if args.labels:
                tool.active = row % 2
            elif not args.comb:
                tool.brush.value = 0.0 if row % 2 == 0 else 2.0
            y = cy - 120 + 80 * row
            ctx.mouse_move_to_pos((x0, y))
            ctx.mouse_down(0)
            for i in range(1, per_row + 1):
                if tool.dabs - d0 >= args.dabs:
                    break
                ctx.mouse_move_to_pos((x0 + i * step, y))
                ctx.yield_()
                if args.mid_shot and tool.dabs - d0 == args.dabs // 2:
                    shown = ed.viewer.show_fields
                    ed.viewer.show_painted(False)  # the texture itself
                    testing.capture(ctx, args.mid_shot)
                    ed.viewer.show_painted(shown)
            ctx.mouse_up(0)
            row += 1
        ctx.yield_()
        n1 = len(stamps)
        profiling[0] = False
        if args.files:
            base = frame_files[n0 - 1]
            dab_frames = [frame_files[k] for k in range(n0 + 1, n1) if dabs_at[k] > dabs_at[k - 1]]
            counts = sorted(len(f) for f in dab_frames)
            own = sorted(len(f - base) for f in dab_frames)
            typical = min(dab_frames, key=lambda f: abs(len(f) - counts[len(counts) // 2]))
            paths = [path_files[k] for k in range(n0 + 1, n1) if dabs_at[k] > dabs_at[k - 1]]
            plen = sorted(len(f) for f in paths)
            results["files_on_the_dab_path"] = {"median": plen[len(plen) // 2], "max": plen[-1],
                                                "union": sorted(set().union(*paths))}
            results["files"] = {"frame_without_a_dab": sorted(base), "dab_frame_median": counts[len(counts) // 2],
                                "dab_frame_max": counts[-1], "added_by_the_dab_median": own[len(own) // 2],
                                "added_by_the_dab_max": own[-1], "typical_dab_frame": sorted(typical),
                                "added_by_a_typical_dab": sorted(typical - base)}
        t_end = time.perf_counter()
        for _ in range(100000):  # until the view shows every dab exactly
            ctx.yield_()
            if settled_at[-1]:
                break
        settle_s = time.perf_counter() - t_end
        n2 = len(stamps)
        frames = [(b - a, dabs_at[i + 1] - dabs_at[i])
                  for i, (a, b) in enumerate(zip(stamps[n0:n1 - 1], stamps[n0 + 1:n1]), start=n0)]
        # A dab made in frame k (dabs_at[k] > dabs_at[k - 1]) shows exactly at the end of
        # the first frame j >= k that ends settled (about stamps[j + 1]).
        # It first shows at the end of the first frame that ends settled or with a
        # quick look made since the frame before it (QuickLooks.look).
        shown, seen = [], []
        for k in range(n0 + 1, n2 - 1):
            if dabs_at[k] > dabs_at[k - 1]:
                j = next((j for j in range(k, n2 - 1) if settled_at[j]), n2 - 2)
                shown.append(stamps[j + 1] - stamps[k])
                j = next((j for j in range(k, n2 - 1) if settled_at[j] or looks_at[j] > looks_at[k - 1]), n2 - 2)
                seen.append(stamps[j + 1] - stamps[k])
        if os.environ.get("PAINT_DEBUG"):
            for k in range(n0, n1 - 1):
                print(f"frame {1000 * (stamps[k + 1] - stamps[k]):.1f} gui {1000 * (ends[k] - stamps[k]):.1f} "
                      f"update {upd_at[k][0]:.1f} budget {upd_at[k][1]:.1f} look {looks_at[k] - looks_at[k - 1]}")
        lat = sorted(shown)
        vis = sorted(seen)
        frame_s = sorted(f[0] for f in frames)
        dabs = tool.dabs - d0
        px = pixels_at[n2 - 1] - pixels_at[n0]
        # A full synthesis of the same view, counted the same way (padded level pixels).
        full_view.append(-1)
        ctx.yield_(2)
        full = full_view[0]
        results.update({
            "canvas": list(ed.canvas_size), "renderer": ed.renderer, "brush_px": 2 * args.radius,
            "structure": ed.doc.structure,
            "dabs": dabs, "frames_with_a_dab": sum(1 for f in frames if f[1] > 0),
            "latency_ms_median": 1000 * statistics.median(lat), "latency_ms_p90": 1000 * lat[int(0.9 * (len(lat) - 1))],
            "latency_ms_max": 1000 * lat[-1],
            "visible_ms_median": 1000 * statistics.median(vis), "visible_ms_p90": 1000 * vis[int(0.9 * (len(vis) - 1))],
            "visible_ms_max": 1000 * vis[-1],
            "frame_ms_median": 1000 * statistics.median(frame_s),
            "frame_ms_p90": 1000 * frame_s[int(0.9 * (len(frame_s) - 1))], "frame_ms_max": 1000 * frame_s[-1],
            "pixels_per_dab": px / max(1, dabs),
            "full_view_pixels": full, "fewer_pixels_than_full": full * dabs / max(1, px),
            "fps_during_stroke": len(frames) / max(1e-9, sum(f[0] for f in frames)),
            "settle_after_stroke_s": settle_s, "load": args.load,
        })
        testing.capture(ctx, os.path.join(tempfile.gettempdir(), "infinitex-paint-bench.png"))

    from bench.load import busy
    with busy(args.load):
        testing.run(test_function=test, runner_params=params, run_speed=testing.TestRunSpeed.fast)
    if not results:
        print("the benchmark did not run (see the test engine log)")
        return 1
    print(f"Painting the canvas {'labels' if args.labels else 'a direction field' if args.comb else 'randomness'} (canvas {results['canvas'][0]}x{results['canvas'][1]}, "
          f"{results['brush_px']:.0f} px brush, {results['renderer']})")
    print("| structure | dabs | dab visible median / p90 / max ms | dab exact median / p90 ms | frame median / p90 / max ms | fps | settles after "
          "the stroke s | pixels per dab | full view pixels | fewer than full |")
    print("|---|---|---|---|---|---|---|---|---|---|")
    print(f"| {results['structure']} | {results['dabs']} | {results['visible_ms_median']:.1f} / "
          f"{results['visible_ms_p90']:.1f} / {results['visible_ms_max']:.1f} | {results['latency_ms_median']:.1f} / "
          f"{results['latency_ms_p90']:.1f} | {results['frame_ms_median']:.1f} / {results['frame_ms_p90']:.1f} / "
          f"{results['frame_ms_max']:.1f} | {results['fps_during_stroke']:.1f} | {results['settle_after_stroke_s']:.2f} | "
          f"{results['pixels_per_dab']:.0f} | {results['full_view_pixels']} | {results['fewer_pixels_than_full']:.1f}x |")
    if "files" in results:
        f = results["files"]
        print(f"package files run in a frame: {len(f['frame_without_a_dab'])} without a dab; with one "
              f"{f['dab_frame_median']} (median, max {f['dab_frame_max']}); the dab's own: "
              f"{f['added_by_the_dab_median']} (median, max {f['added_by_the_dab_max']})")
        print("  a typical dab's own files: " + ", ".join(f["added_by_a_typical_dab"]))
        print("  every frame's: " + ", ".join(f["frame_without_a_dab"]))
        p = results["files_on_the_dab_path"]
        print(f"files on a dab's path (under PaintCanvasTool.drag, Session.sync, LocalUpdates.settle, "
              f"QuickLooks.look): {p['median']} (median, max {p['max']}); all dabs: {len(p['union'])}: "
              + ", ".join(p["union"]))
    if args.json:
        from infinitex.engine.safeio import atomic_write
        atomic_write(args.json, json.dumps(results, indent=1).encode())
    return 0


if __name__ == "__main__":
    sys.exit(main())
