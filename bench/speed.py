"""Speed benchmark of the engine: prints a table and optionally writes JSON.

    python -m bench.speed [--quick] [--json OUT.json] [--exemplar PATH]

Fields (times in seconds or milliseconds as named):
  renderer           GL_RENDERER / GL_VERSION (llvmpipe figures are CPU figures)
  analysis_s[size]   cold-cache analysis of a size x size exemplar, in a fresh process
  analysis_peak_mb   peak resident memory of those processes, per size
  full_ms[size]      full window (warm: shaders compiled, analysis cached), median
  pan_ms             mean per frame, 512^2 viewport panned 8 px/frame over 64 frames
  pan_max_ms         worst frame of that pan
  pan_speedup        full_ms[512] / pan_ms, measured in the same run
  zoom_out_ms        a 512^2 view at 1/4 scale (stops 2 levels early), median
  toroidal_ms        a 512^2 toroidal texture, median
  cli_1024_s         `infinitex synth EXEMPLAR --size 1024 1024` as a user runs it (a new process, the
                     analysis and lattice cached, the PNG written), median of 3 after one untimed run
  cli_over_engine    cli_1024_s over full_ms[1024] of the same run: what the command adds to the work
"""
from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
import time
from dataclasses import replace

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, ROOT)

CHILD = r"""
import json, resource, sys, time
import numpy as np
from PIL import Image
sys.path.insert(0, {root!r})
from infinitex.engine.exemplar import load_exemplar, from_array
from infinitex.engine.analysis import analyze
ex = load_exemplar({path!r})
size = {size}
img = np.stack([np.asarray(Image.fromarray(ex.pixels[:, :, c], mode="F").resize((size, size), Image.LANCZOS))
                for c in range(ex.channels)], axis=2)
ex = from_array(np.clip(img, 0, 1))
t = time.perf_counter()
analyze(ex, use_cache=False)
dt = time.perf_counter() - t
print(json.dumps(dict(seconds=dt, peak_mb=resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024)))
"""


def analysis_cold(path: str, size: int) -> dict:
    code = CHILD.format(root=ROOT, path=path, size=size)
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    return json.loads(out.stdout.strip().splitlines()[-1])


def timed(fn, runs: int) -> float:
    """Median wall time in ms of fn(i) over runs (GL work finished inside)."""
    ts = []
    for i in range(runs):
        t = time.perf_counter()
        fn(i)
        ts.append((time.perf_counter() - t) * 1000.0)
    return statistics.median(ts)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="small analyses and fewer runs (< 1 minute)")
    ap.add_argument("--json", metavar="OUT.json")
    ap.add_argument("--exemplar", default=os.path.join(ROOT, "infinitex", "assets", "gravel.png"),
                    help="exemplar resampled to each analysis size and used for synthesis")
    ap.add_argument("--fidelity", type=int, default=None, metavar="PRESET",
                    help="Structure preset of the measured synthesis (default: the documents' default)")
    args = ap.parse_args(argv)
    from infinitex.engine.params import DEFAULT_STRUCTURE, STRUCTURE_LEVELS, STRUCTURE_NAMES, SynthParams, \
        structure_params
    fidelity = DEFAULT_STRUCTURE if args.fidelity is None else args.fidelity

    from infinitex.engine.analysis import analyze
    from infinitex.engine.exemplar import load_exemplar
    from infinitex.engine.pyramid import Rect
    from infinitex.engine.synth import Synthesizer

    os.environ.setdefault("INFINITEX_CACHE", tempfile.mkdtemp(prefix="infinitex-bench-"))
    sizes = (64, 128) if args.quick else (64, 128, 256, 512)
    runs = 3 if args.quick else 5
    res: dict = {"quick": args.quick, "exemplar": os.path.basename(args.exemplar)}

    res["analysis_s"], res["analysis_peak_mb"] = {}, {}
    for size in sizes:
        r = analysis_cold(args.exemplar, size)
        res["analysis_s"][size] = round(r["seconds"], 3)
        res["analysis_peak_mb"][size] = round(r["peak_mb"], 1)

    ex = load_exemplar(args.exemplar)
    an = analyze(ex)
    synth = Synthesizer(an, structure_params(SynthParams.default(an.L), fidelity))
    ctx = synth.gpu.ctx
    res["renderer"] = synth.gpu.renderer
    res["structure"] = STRUCTURE_NAMES[fidelity]
    res["exemplar_size"] = ex.size
    synth.window(Rect.of(0, 0, 64, 64))  # compile shaders
    synth.toroidal(32)

    def full(n):
        def run(i):
            synth.window(Rect.of(1000 * i, -777 * i, n, n))
            ctx.finish()
        return run

    res["full_ms"] = {n: round(timed(full(n), runs), 1) for n in (256, 512)}
    # The full 512^2 window at every Structure preset (the others as set).
    res["structure_full_512_ms"] = {}
    measured = synth.params
    for s in range(STRUCTURE_LEVELS):
        synth.set_params(structure_params(SynthParams.default(an.L), s))
        synth.window(Rect.of(0, 0, 64, 64))
        res["structure_full_512_ms"][STRUCTURE_NAMES[s]] = round(timed(full(512), max(2, runs - 2)), 1)
    synth.set_params(measured)

    vp = synth.viewport()
    vp.show(Rect.of(0, 0, 512, 512))
    frames = []
    for f in range(1, 65):
        t = time.perf_counter()
        vp.show(Rect.of(8 * f, 3 * f, 512, 512))
        ctx.finish()
        frames.append((time.perf_counter() - t) * 1000.0)
    vp.release()
    res["pan_ms"] = round(statistics.mean(frames), 2)
    res["pan_max_ms"] = round(max(frames), 1)
    res["pan_speedup"] = round(res["full_ms"][512] / res["pan_ms"], 1)

    def zoom(i):
        v = synth.viewport()
        v.show(Rect.of(5000 * i, 0, 512, 512), zoom_out=2)
        ctx.finish()
        v.release()
    res["zoom_out_ms"] = round(timed(zoom, runs), 1)

    def tor(i):
        synth.set_params(replace(synth.params, seed=i))
        synth.toroidal(512)
        ctx.finish()
    res["toroidal_ms"] = round(timed(tor, runs), 1)

    res["full_ms"][1024] = round(timed(full(1024), max(2, runs - 2)), 1)
    with tempfile.TemporaryDirectory() as tmp:
        cmd = [sys.executable, "-m", "infinitex", "synth", args.exemplar, "-o", os.path.join(tmp, "w.png"),
               "--size", "1024", "1024", "--fidelity", str(fidelity), "-q"]
        cli = []
        for i in range(4):  # the first run fills the caches (a user's second run on this exemplar)
            t = time.perf_counter()
            subprocess.run(cmd, cwd=ROOT, check=True)
            cli.append(time.perf_counter() - t)
    res["cli_1024_s"] = round(statistics.median(cli[1:]), 3)
    res["cli_over_engine"] = round(res["cli_1024_s"] * 1000.0 / res["full_ms"][1024], 2)

    rows = [("renderer", res["renderer"])]
    rows += [(f"analysis {s}^2 (cold)", f"{res['analysis_s'][s]:.2f} s, peak {res['analysis_peak_mb'][s]:.0f} MB")
             for s in sizes]
    rows += [(f"full {n}^2 window ({res['structure']})", f"{res['full_ms'][n]:.0f} ms") for n in (256, 512, 1024)]
    rows += [(f"full 512^2, Structure {k}", f"{v:.0f} ms") for k, v in res["structure_full_512_ms"].items()]
    rows += [("pan 512^2, 8 px/frame", f"{res['pan_ms']:.1f} ms/frame (max {res['pan_max_ms']:.0f})"),
             ("pan speedup (full/pan)", f"{res['pan_speedup']:.1f}x"),
             ("zoom out 1/4, 512^2 view", f"{res['zoom_out_ms']:.0f} ms"),
             ("toroidal 512^2", f"{res['toroidal_ms']:.0f} ms"),
             ("command line, 1024^2 window", f"{res['cli_1024_s']:.2f} s ({res['cli_over_engine']:.2f}x the window)")]
    width = max(len(k) for k, _ in rows)
    for k, v in rows:
        print(f"{k:<{width}}  {v}")
    if args.json:
        from infinitex.engine.safeio import atomic_write
        atomic_write(args.json, json.dumps(res, indent=2).encode())
    return 0


if __name__ == "__main__":
    sys.exit(main())
