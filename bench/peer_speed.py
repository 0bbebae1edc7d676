"""Warm speed side by side with the patch-based peer (G'MIC's syntexturize_matchpatch), on the same CPU.

    python -m bench.peer_speed [--sizes 256 768] [--presets Balanced] [--runs 3]
                               [--exemplars DIR ...] [--json OUT.json]

For every exemplar (default ``../shared/exemplars`` and ``bench/exemplars``)
and output size: ``ours_ms``, a window and its colors (Synthesizer.window +
colors; the analysis cached, shaders compiled), median of ``--runs`` windows
at different canvas positions; ``peer_ms``, G'MIC synthesizing the same size
from the same exemplar in this process, median of as many runs after one
to warm up; ``peer_over_ours`` (above 1: ours is faster). Prints a table and
the median and lowest ratio per size and preset. ``pip install gmic`` (the
benchmark-only requirements, requirements-bench.txt) provides the peer;
bench.quality compares the textures themselves.
"""
from __future__ import annotations

import argparse
import glob
import json
import os
import statistics
import sys
import tempfile
import time

import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, ROOT)

ORIGIN = (10007, -20011)
IMAGE_TYPES = (".png", ".jpg", ".jpeg", ".bmp", ".tif", ".tiff", ".webp")


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sizes", nargs="+", type=int, default=[256, 768])
    ap.add_argument("--presets", nargs="+", default=["Balanced"])
    ap.add_argument("--runs", type=int, default=3)
    ap.add_argument("--exemplars", nargs="+", default=[os.path.join(os.path.dirname(ROOT), "shared", "exemplars"),
                                                       os.path.join(ROOT, "bench", "exemplars")])
    ap.add_argument("--json", metavar="OUT.json")
    args = ap.parse_args(argv)
    try:
        import gmic
    except ImportError:
        sys.stderr.write("bench.peer_speed needs the peer: .venv/bin/pip install gmic\n")
        return 2
    from bench.quality import _save
    from infinitex.engine.analysis import analyze
    from infinitex.engine.exemplar import load_exemplar
    from infinitex.engine.params import STRUCTURE_NAMES, SynthParams, structure_index, structure_params
    from infinitex.engine.rect import Rect
    from infinitex.engine.synth import Synthesizer

    paths = [p for folder in args.exemplars for p in sorted(glob.glob(os.path.join(folder, "*")))
             if p.lower().endswith(IMAGE_TYPES)]
    if not paths:
        sys.stderr.write(f"no exemplars in {args.exemplars}\n")
        return 2
    presets = [structure_index(p) for p in args.presets]
    tmp = tempfile.mkdtemp(prefix="infinitex-peer-speed-")
    res: dict = {"sizes": args.sizes, "runs": args.runs, "exemplars": {}}
    print(f"{'exemplar':<14}{'m':>5}{'size':>6}{'peer ms':>9}" + "".join(f"{STRUCTURE_NAMES[s]:>12} ms  peer/ours"
                                                                        for s in presets))
    for path in paths:
        name = os.path.splitext(os.path.basename(path))[0]
        ex = load_exemplar(path)
        an = analyze(ex)
        png = os.path.join(tmp, f"{name}.png")
        _save(png, ex.pixels)
        entry = res["exemplars"][name] = {"size": ex.size}
        synths = {s: Synthesizer(an, structure_params(SynthParams.default(an.L), s)) for s in presets}
        try:
            for syn in synths.values():
                syn.window(Rect.of(0, 0, 32, 32))  # shaders compiled, textures uploaded
            res["renderer"] = next(iter(synths.values())).gpu.renderer
            for n in args.sizes:
                cmd = f"{png} syntexturize_matchpatch {n},{n} cut 0,255 output {os.path.join(tmp, 'peer.png')}"
                gmic.run(cmd)
                peer = []
                for _ in range(args.runs):
                    t = time.perf_counter()
                    gmic.run(cmd)
                    peer.append(time.perf_counter() - t)
                row = {"peer_ms": statistics.median(peer) * 1000}
                line = f"{name:<14}{ex.size:>5}{n:>6}{row['peer_ms']:>9.0f}"
                for s, syn in synths.items():
                    ours = []
                    for i in range(args.runs):
                        t = time.perf_counter()
                        syn.colors(syn.window(Rect.of(ORIGIN[0] + 3001 * i, ORIGIN[1], n, n)))
                        ours.append(time.perf_counter() - t)
                    ms = statistics.median(ours) * 1000
                    row[STRUCTURE_NAMES[s]] = {"ours_ms": round(ms, 1), "peer_over_ours": round(row["peer_ms"] / ms, 2)}
                    line += f"{ms:>15.0f}{row['peer_ms'] / ms:>11.2f}"
                row["peer_ms"] = round(row["peer_ms"], 1)
                entry[str(n)] = row
                print(line, flush=True)
        finally:
            for syn in synths.values():
                syn.release()
    summary = {}
    for s in presets:
        key = STRUCTURE_NAMES[s]
        for n in args.sizes:
            ratios = [e[str(n)][key]["peer_over_ours"] for e in res["exemplars"].values()]
            summary[f"{key} {n}"] = {"median": float(np.median(ratios)), "lowest": min(ratios),
                                     "ours_faster": sum(r > 1 for r in ratios), "exemplars": len(ratios)}
    res["summary"] = summary
    print(f"\n{res.get('renderer', '')}")
    for k, v in summary.items():
        print(f"{k}: peer/ours median {v['median']:.2f}, lowest {v['lowest']:.2f}; "
              f"ours faster on {v['ours_faster']} of {v['exemplars']}")
    if args.json:
        from infinitex.engine.safeio import atomic_write
        atomic_write(args.json, json.dumps(res, indent=1).encode())
    return 0


if __name__ == "__main__":
    sys.exit(main())
