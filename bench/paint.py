"""Painting randomness in the real editor: latency, pixels per dab, frame rate.

    xvfb-run -a -s "-screen 0 1280x800x24" python -m bench.paint [--json OUT.json]

The imgui test engine selects the Paint canvas tool and draws a scripted
stroke with the mouse like a user: a 48 px brush (radius 24 screen pixels at
100%), one dab per frame, 64 dabs across the canvas, alternating calm and
rough strokes. Each dab edits the document; the session re-synthesizes in
place only what the dab reaches (Pyramid.update_controls) and the canvas is
redrawn in the same frame. Measured per frame with a dab: the frame time
(input to the frame that shows it: the latency), the level pixels
re-synthesized, against the pixels of a full synthesis of the same view; and
the frame rate over the stroke. Prints a table, writes JSON.
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
                    help="Structure preset of the painted document (default: the documents' default; at Balanced "
                         "on llvmpipe the stroke outlasts the test engine's 60 s watchdog)")
    args = ap.parse_args(argv)
    os.environ.setdefault("INFINITEX_STATE", tempfile.mkdtemp(prefix="infinitex-bench-"))
    os.environ["INFINITEX_NO_NATIVE_DIALOGS"] = "1"
    ed = Editor(recover=False)
    stamps: list[float] = []
    dabs_at: list[int] = []
    pixels_at: list[int] = []
    orig_gui = ed.gui
    updates: list[int] = []

    full_view: list[int] = []

    def gui():
        stamps.append(time.perf_counter())
        orig_gui()
        dabs_at.append(ed.tools[1].dabs)
        pixels_at.append(sum(updates))
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
        orig_update = pyr.update_controls

        def counted(controls, changed=None):
            n = orig_update(controls, changed)
            updates.append(n)
            return n
        pyr.update_controls = counted
        ctx.set_ref("//Infinitex")
        ctx.item_click("//**/Paint canvas (B)##tool-paint-canvas")
        tool = ed.tool
        tool.brush.radius, tool.brush.strength, tool.brush.hardness = args.radius, 1.0, 0.5
        r = ctx.item_info("//**/canvas").rect_full
        x0, x1 = r.min.x + 80, r.max.x - 80
        cy = (r.min.y + r.max.y) / 2
        step = 0.25 * args.radius + 0.01  # one dab per frame
        per_row = int((x1 - x0) // step)
        n0 = len(stamps)
        d0 = tool.dabs
        row = 0
        while tool.dabs - d0 < args.dabs:
            tool.brush.value = 0.0 if row % 2 == 0 else 2.0
            y = cy - 120 + 80 * row
            ctx.mouse_move_to_pos((x0, y))
            ctx.mouse_down(0)
            for i in range(1, per_row + 1):
                if tool.dabs - d0 >= args.dabs:
                    break
                ctx.mouse_move_to_pos((x0 + i * step, y))
                ctx.yield_()
            ctx.mouse_up(0)
            row += 1
        ctx.yield_()
        n1 = len(stamps)
        frames = [(b - a, dabs_at[i + 1] - dabs_at[i], pixels_at[i + 1] - pixels_at[i])
                  for i, (a, b) in enumerate(zip(stamps[n0:n1 - 1], stamps[n0 + 1:n1]), start=n0)]
        dab_frames = [f for f in frames if f[1] > 0]
        lat = sorted(f[0] for f in dab_frames)
        px = sorted(f[2] for f in dab_frames)
        # A full synthesis of the same view, counted the same way (padded level pixels).
        full_view.append(-1)
        ctx.yield_(2)
        full = full_view[0]
        results.update({
            "canvas": list(ed.canvas_size), "renderer": ed.renderer, "brush_px": 2 * args.radius,
            "structure": ed.doc.structure,
            "dabs": tool.dabs - d0, "frames_with_a_dab": len(dab_frames),
            "latency_ms_median": 1000 * statistics.median(lat), "latency_ms_p90": 1000 * lat[int(0.9 * (len(lat) - 1))],
            "latency_ms_max": 1000 * lat[-1],
            "pixels_per_dab_median": statistics.median(px), "pixels_per_dab_p90": px[int(0.9 * (len(px) - 1))],
            "full_view_pixels": full, "fewer_pixels_than_full": full / max(1, statistics.median(px)),
            "fps_during_stroke": len(frames) / max(1e-9, sum(f[0] for f in frames)),
        })
        testing.capture(ctx, os.path.join(tempfile.gettempdir(), "infinitex-paint-bench.png"))

    testing.run(test_function=test, runner_params=params, run_speed=testing.TestRunSpeed.fast)
    if not results:
        print("the benchmark did not run (see the test engine log)")
        return 1
    print(f"Painting the canvas randomness (canvas {results['canvas'][0]}x{results['canvas'][1]}, "
          f"{results['brush_px']:.0f} px brush, {results['renderer']})")
    print("| dabs | latency median / p90 ms | pixels per dab (median / p90) | full view pixels | fewer than full | fps |")
    print("|---|---|---|---|---|---|")
    print(f"| {results['dabs']} | {results['latency_ms_median']:.1f} / {results['latency_ms_p90']:.1f} | "
          f"{results['pixels_per_dab_median']:.0f} / {results['pixels_per_dab_p90']:.0f} | {results['full_view_pixels']} | "
          f"{results['fewer_pixels_than_full']:.1f}x | {results['fps_during_stroke']:.1f} |")
    if args.json:
        from infinitex.engine.safeio import atomic_write
        atomic_write(args.json, json.dumps(results, indent=1).encode())
    return 0


if __name__ == "__main__":
    sys.exit(main())
