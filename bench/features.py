"""Features: dragging one in the real editor, and the cost of many when panning.

    xvfb-run -a -s "-screen 0 1280x800x24" python -m bench.features [--json OUT.json]

1. Drag: the imgui test engine places a feature of outer radius 64 px in the
   real editor and drags it 60 steps across the canvas with the Features tool
   (one step per frame). Per step: the frame time (the step is applied and
   shown in that frame), the level pixels re-synthesized, the editor's fps;
   after release, the time until the canvas is exact again.
2. Pan: a 512 x 512 viewport panned 8 px per frame for 64 frames, headless,
   with no features and with 1,000 features scattered around it; the ratio of
   the mean frame times (target: at most 1.2).
Prints a table, writes JSON.
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


def pan_cost(features: int, frames: int = 64) -> float:
    """Mean ms per frame panning a 512^2 viewport 8 px per frame (headless)."""
    import numpy as np

    from infinitex.engine.analysis import analyze
    from infinitex.engine.controls import Controls, Feature
    from infinitex.engine.exemplar import load_exemplar
    from infinitex.engine.params import SynthParams
    from infinitex.engine.pyramid import Rect
    from infinitex.engine.synth import Synthesizer
    an = analyze(load_exemplar(os.path.join(HERE, "infinitex", "assets", "gravel.png")))
    rng = np.random.default_rng(1)
    feats = tuple(Feature((int(rng.integers(0, an.size)), int(rng.integers(0, an.size))),
                          (int(rng.integers(-4000, 4000)), int(rng.integers(-4000, 4000))), 16, 48)
                  for _ in range(features))
    synth = Synthesizer(an, SynthParams.default(an.L), controls=Controls(features=feats))
    vp = synth.viewport()
    vp.show(Rect.of(0, 0, 512, 512))
    synth.gpu.ctx.finish()
    times = []
    for i in range(1, frames + 1):
        t = time.perf_counter()
        vp.show(Rect.of(8 * i, 5 * i, 512, 512))
        synth.gpu.ctx.finish()
        times.append(time.perf_counter() - t)
    vp.release()
    synth.release()
    return 1000 * statistics.mean(times)


def drag_in_editor(steps: int) -> dict:
    from imgui_bundle.immapp import testing

    from infinitex.app.ui.editor import Editor
    os.environ.setdefault("INFINITEX_STATE", tempfile.mkdtemp(prefix="infinitex-bench-"))
    os.environ["INFINITEX_NO_NATIVE_DIALOGS"] = "1"
    ed = Editor(recover=False)
    stamps: list[float] = []
    pixels_at: list[int] = []
    updates: list[int] = []
    orig_gui = ed.gui
    results: dict = {}

    moved_at: list = []

    def gui():
        stamps.append(time.perf_counter())
        orig_gui()
        pixels_at.append(sum(updates))
        tool = ed.tool
        moved_at.append(getattr(tool, "preview", None) or (ed.doc.features if ed.doc is not None else None))

    params = ed.runner_params()
    params.callbacks.show_gui = gui

    def settle(ctx, limit=3000):
        for _ in range(limit):
            ctx.yield_()
            if ed.session is not None and ed.session.ready and ed.refined and ed.doc is not None:
                return True
        return False

    def test(ctx):
        settle(ctx)
        pyr = ed.session.pyramid
        orig_settle = pyr.updates.settle

        def counted(*a, **k):  # the local updates are done by settle(), a frame's budget at a time
            n0 = pyr.pixels_synthesized
            done = orig_settle(*a, **k)
            updates.append(pyr.pixels_synthesized - n0)
            return done
        pyr.updates.settle = counted
        ctx.set_ref("//Infinitex")
        ctx.item_click("//**/Features (F)##tool-feature")
        tool = ed.tool
        tool.inner, tool.outer = 32, 64
        r = ctx.item_info("//**/canvas").rect_full
        x0, cy = r.min.x + 150, (r.min.y + r.max.y) / 2
        ctx.mouse_move_to_pos((x0, cy))
        ctx.mouse_down(0)  # grab what is under the cursor: a new feature
        ctx.yield_()
        n0 = len(stamps)
        span = (r.max.x - 150) - x0
        for i in range(1, steps + 1):
            ctx.mouse_move_to_pos((x0 + span * i / steps, cy + 40 * ((i // 10) % 2)))
            ctx.yield_()
        n1 = len(stamps)
        t_release = time.perf_counter()
        n_release = len(updates)
        ctx.mouse_up(0)  # the release frame commits the move
        exact = settle(ctx)
        exact_s = time.perf_counter() - t_release
        results["pixels_on_release"] = sum(updates[n_release:])
        frames = [b - a for a, b in zip(stamps[n0:n1 - 1], stamps[n0 + 1:n1])]
        # Steps: the frames in which the (previewed) feature moved; the test engine
        # moves the mouse over several frames.
        step_idx = [i for i in range(n0, n1 - 1) if moved_at[i] != moved_at[i - 1]]
        px = [pixels_at[i] - pixels_at[i - 1] for i in step_idx]
        lat = sorted(stamps[i + 1] - stamps[i] for i in step_idx)
        results.update({
            "canvas": list(ed.canvas_size), "renderer": ed.renderer, "steps": steps, "outer_radius": 64,
            "frames_with_a_move": len(step_idx),
            "step_ms_median": 1000 * statistics.median(lat), "step_ms_p90": 1000 * lat[int(0.9 * (len(lat) - 1))],
            "pixels_per_step_median": statistics.median(px), "pixels_per_step_p90": sorted(px)[int(0.9 * (len(px) - 1))],
            "fps_while_dragging": len(frames) / max(1e-9, sum(frames)),
            "exact_after_release_s": exact_s if exact else None,
        })
        testing.capture(ctx, os.path.join(tempfile.gettempdir(), "infinitex-features-bench.png"))

    testing.run(test_function=test, runner_params=params, run_speed=testing.TestRunSpeed.fast)
    return results


def main(argv=None) -> int:
    ap = argparse.ArgumentParser()
    ap.add_argument("--json", metavar="OUT.json")
    ap.add_argument("--steps", type=int, default=60)
    args = ap.parse_args(argv)
    res = drag_in_editor(args.steps)
    res["pan_ms_no_features"] = pan_cost(0)
    res["pan_ms_1000_features"] = pan_cost(1000)
    res["pan_ratio"] = res["pan_ms_1000_features"] / res["pan_ms_no_features"]
    print(f"Dragging a feature (outer radius 64 px, {res['steps']} steps, canvas {res['canvas'][0]}x{res['canvas'][1]}, "
          f"{res['renderer']})")
    print("| step median / p90 ms | pixels per step (median / p90) | fps while dragging | exact after release |")
    print("|---|---|---|---|")
    print(f"| {res['step_ms_median']:.1f} / {res['step_ms_p90']:.1f} | {res['pixels_per_step_median']:.0f} / "
          f"{res['pixels_per_step_p90']:.0f} | {res['fps_while_dragging']:.1f} | {res['exact_after_release_s']:.2f} s |")
    print(f"Panning 512^2 at 8 px/frame: {res['pan_ms_no_features']:.1f} ms/frame without features, "
          f"{res['pan_ms_1000_features']:.1f} ms/frame with 1,000 ({res['pan_ratio']:.2f}x)")
    if args.json:
        from infinitex.engine.safeio import atomic_write
        atomic_write(args.json, json.dumps(res, indent=1).encode())
    return 0


if __name__ == "__main__":
    sys.exit(main())
