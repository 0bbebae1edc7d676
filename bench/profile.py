"""Where a window's time goes: GL timer queries around every draw of the engine.

    python -m bench.profile [--sizes 512 1024] [--presets Variety Balanced] [--runs 3]
                            [--exemplar PATH] [--json OUT.json]

Per Structure preset and window size (the window at canvas position (10007,
-20011), warm: shaders compiled, analysis cached), it prints and writes:

  wall_ms        the whole window call (synthesis and the readback), median of ``--runs``
  request_ms     the synthesis until the GL work is finished, same runs
  read_ms        the readback and its conversion to (H, W, 2) int32
  draws_ms       the time of every draw (one more run): GL timer queries, or with
                 ``--sync`` (the default on llvmpipe) the CPU's time of each draw with
                 the GL work finished before and after it (llvmpipe renders a draw
                 when its target or inputs change, so a timer query there can hold the
                 work of the draw before it)
  outside_ms     request_ms less draws_ms: CPU work between draws, uploads, waiting
  draws          how many draws; level_pixels: pixels of the padded regions, all levels
  per program    GPU ms, share of the draws, pixels rendered, texel fetches per pixel
                 (for the fidelity stage's search an upper bound: candidates already
                 tried are skipped and patch sums stop once they reach the best)
  per level      its padded region and GPU ms per program

Timer queries exist on llvmpipe (where the draws are the CPU's work) and on any
GPU; the figures of one run are comparable with each other, ratios between runs
less so on a shared machine.
"""
from __future__ import annotations

import argparse
import json
import os
import statistics
import sys
import time
from collections import defaultdict

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, ROOT)

ORIGIN = (10007, -20011)
PROGRAMS = ("upsample", "correct", "fidelity", "fidelity vote", "copy", "writeback")


def fetches_per_pixel(name: str, an, p, level: int, walk: int) -> int | None:
    """Texel fetches per rendered pixel of one program (the default path: no
    labels, direction field or atlas); the search's is an upper bound."""
    from infinitex.engine.params import FIDELITY_SEARCH
    if name == "copy":
        return 1
    if name == "writeback":
        return 1
    if name == "upsample":
        return 1 if level > 0 else 0
    if name == "correct":
        k = an.k
        sims = (9 if k > 0 else 0) + (9 if k > 2 else 0)
        nb = 9 * max(k, 1) + walk
        if an.model == "appearance":
            return 1 + 8 + 12 + sims + nb
        return 1 + 8 + 16 + 25 + sims + nb
    nt = (2 * p.fidelity_radius + 1) ** 2
    if name == "fidelity":
        return 1 + 2 * (nt - 1) + (8 + FIDELITY_SEARCH) * (nt - 1)
    if name == "fidelity vote":
        return 1 + (nt - 1)
    return None


def profile_window(synth, n: int, runs: int, sync: bool = False) -> dict:
    from infinitex.engine.pyramid import Pyramid
    from infinitex.engine.rect import Rect
    from infinitex.engine.stages import timing_draws

    an, gpu = synth.analysis, synth.gpu
    rect = Rect.of(ORIGIN[0], ORIGIN[1], n, n)

    def once(timers=None):
        pyr = Pyramid(gpu, synth.gan, synth.params, scrolling=False, controls=synth.controls)
        try:
            t0 = time.perf_counter()
            pyr.request(an.L, rect)
            gpu.ctx.finish()
            t1 = time.perf_counter()
            pyr.read(an.L, rect)
            t2 = time.perf_counter()
            regions = {l: pyr.padded(l, b.valid) for l, b in enumerate(pyr.buffers) if b is not None}
            return t1 - t0, t2 - t1, regions
        finally:
            pyr.release()

    once()  # compile and upload
    reqs, reads = [], []
    for _ in range(runs):
        rq, rd, regions = once()
        reqs.append(rq)
        reads.append(rd)
    with timing_draws(gpu, sync) as timers:
        once()
        draws = timers.results()
    walk = synth.params.walk_steps(an.k, synth.controls.avoid is not None)
    programs: dict = defaultdict(lambda: dict(ms=0.0, pixels=0, draws=0))
    levels: dict = defaultdict(lambda: defaultdict(float))
    fetch: dict = {}
    for name, level, px, sec in draws:
        programs[name]["ms"] += sec * 1000
        programs[name]["pixels"] += px
        programs[name]["draws"] += 1
        levels[level][name] += sec * 1000
        f = fetches_per_pixel(name, an, synth.params, level, walk)
        if f is not None:
            fetch[name] = max(fetch.get(name, 0), f)
    draws_ms = sum(v["ms"] for v in programs.values())
    request_ms = statistics.median(reqs) * 1000
    read_ms = statistics.median(reads) * 1000
    for name, v in programs.items():
        v["share"] = v["ms"] / draws_ms if draws_ms else 0.0
        v["fetches_per_px"] = fetch.get(name)
        v["ms"] = round(v["ms"], 2)
    return dict(
        wall_ms=round(request_ms + read_ms, 1), request_ms=round(request_ms, 1), read_ms=round(read_ms, 1),
        draws_ms=round(draws_ms, 1), outside_ms=round(request_ms - draws_ms, 1), draws=len(draws),
        level_pixels=sum(r.w * r.h for r in regions.values()),
        programs=dict(programs),
        levels={l: dict(region=f"{regions[l].w}x{regions[l].h}" if l in regions else "-",
                        **{k: round(v, 2) for k, v in levels[l].items()}) for l in sorted(levels) if l >= 0},
    )


def print_case(name: str, n: int, r: dict) -> None:
    print(f"\n{name}, {n}^2: wall {r['wall_ms']:.1f} ms = request {r['request_ms']:.1f} + read {r['read_ms']:.1f}; "
          f"draws {r['draws_ms']:.1f} ms ({r['draws']} draws, {r['level_pixels']:,} level px), "
          f"outside the draws {r['outside_ms']:.1f} ms")
    print(f"  {'program':<14}{'ms':>9}{'share':>7}{'pixels':>12}{'fetch/px':>9}")
    for prog in PROGRAMS:
        v = r["programs"].get(prog)
        if v is None:
            continue
        f = v["fetches_per_px"]
        print(f"  {prog:<14}{v['ms']:>9.1f}{v['share'] * 100:>6.0f}%{v['pixels']:>12,}"
              f"{('<=' if prog == 'fidelity' else '') + str(f) if f is not None else '-':>9}")
    cols = [p for p in PROGRAMS if p in r["programs"]]
    print(f"  {'level':<6}{'region':>11}" + "".join(f"{c[:9]:>10}" for c in cols))
    for l, v in r["levels"].items():
        print(f"  {l:<6}{v['region']:>11}" + "".join(f"{v.get(c, 0.0):>10.1f}" for c in cols))


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sizes", nargs="+", type=int, default=[512, 1024])
    ap.add_argument("--presets", nargs="+", default=["Variety", "Balanced"])
    ap.add_argument("--runs", type=int, default=3)
    ap.add_argument("--exemplar", default=os.path.join(ROOT, "infinitex", "assets", "gravel.png"))
    ap.add_argument("--json", metavar="OUT.json")
    ap.add_argument("--sync", choices=("auto", "on", "off"), default="auto",
                    help="time each draw on the CPU with the GL work finished around it (auto: on llvmpipe)")
    args = ap.parse_args(argv)
    from infinitex.engine.analysis import analyze
    from infinitex.engine.exemplar import load_exemplar
    from infinitex.engine.params import STRUCTURE_NAMES, SynthParams, structure_index, structure_params
    from infinitex.engine.synth import Synthesizer

    an = analyze(load_exemplar(args.exemplar))
    out: dict = dict(exemplar=os.path.basename(args.exemplar), exemplar_size=an.size, origin=list(ORIGIN),
                     runs=args.runs, cases={})
    for preset in args.presets:
        s = structure_index(preset)
        with Synthesizer(an, structure_params(SynthParams.default(an.L), s)) as synth:
            out["renderer"] = synth.gpu.renderer
            sync = args.sync == "on" or (args.sync == "auto" and "llvmpipe" in synth.gpu.renderer)
            out["sync"] = sync
            for n in args.sizes:
                r = profile_window(synth, n, args.runs, sync)
                out["cases"][f"{STRUCTURE_NAMES[s]} {n}"] = r
                print_case(STRUCTURE_NAMES[s], n, r)
    print(f"\n{out['renderer']}; {out['exemplar']} ({an.size} px)")
    if args.json:
        from infinitex.engine.safeio import atomic_write
        atomic_write(args.json, json.dumps(out, indent=1).encode())
    return 0


if __name__ == "__main__":
    sys.exit(main())
