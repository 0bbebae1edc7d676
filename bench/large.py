"""Large exemplars (issue 14): analysis time and peak memory, and synthesis speed.

    python -m bench.large [--sizes 512,1024,2048] [--json OUT.json]

For each exemplar side m, a fresh process (so its peak memory is its own)
imports the engine, reads an m x m PNG (a cobblestone base color made by
``bench/cobbles.py``: the same 100 stones at every side, 3 channels) with the fit rule that
keeps it, and analyzes it without the cache (default settings: similarity
sets up to 512 px, the random-walk search above; at 512 px also k = 0). It
reports the analysis seconds, the process's peak resident memory (VmHWM:
interpreter, libraries, the decoded image and the analysis) and the memory
just after importing, then the time of a warm 512^2 window at the finest
level (GL, llvmpipe here) at (10007, -20011), and the analysis cache file's size.
"""
from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, ROOT)

CHILD = r"""
import json, os, sys, time
ROOT, PATH, TMP, K = sys.argv[1], sys.argv[2], sys.argv[3], int(sys.argv[4])
sys.path.insert(0, ROOT)
def rss():  # VmHWM: this process's peak; ru_maxrss would include the parent's at fork time
    for line in open("/proc/self/status"):
        if line.startswith("VmHWM:"):
            return int(line.split()[1]) / 1024
from infinitex.engine.analysis import AnalysisSettings, analyze
from infinitex.engine.exemplar import load_exemplar
from infinitex.engine.params import SynthParams
from infinitex.engine.pyramid import Rect
from infinitex.engine.synth import Synthesizer
base = rss()
ex = load_exemplar(PATH, fit="resize-2048", toroidal=False)
t0 = time.perf_counter()
an = analyze(ex, AnalysisSettings(k=K), use_cache=False)
seconds = time.perf_counter() - t0
peak = rss()
t0 = time.perf_counter()
from infinitex.engine.analysis import save_analysis
save_analysis(os.path.join(TMP, "a.npz"), an)
save_s = time.perf_counter() - t0
cache_mb = os.path.getsize(os.path.join(TMP, "a.npz")) / 2**20
with Synthesizer(an, SynthParams.default(an.L)) as s:
    s.window(Rect.of(0, 0, 64, 64))
    t0 = time.perf_counter()
    s.window(Rect.of(10007, -20011, 512, 512))
    window = time.perf_counter() - t0
print(json.dumps(dict(size=ex.size, k=an.k, analysis_s=seconds, peak_mb=peak, import_mb=base,
                      cache_mb=cache_mb, cache_write_s=save_s, window_512_s=window, total_peak_mb=rss())))
"""


def exemplar_png(m: int, folder: str) -> str:
    from infinitex.engine.imagefile import write_image
    from bench.cobbles import cobbles
    path = os.path.join(folder, f"cobbles{m}.png")
    write_image(path, cobbles(m, stones=100)["basecolor"], 8)  # the same stones at every side: a finer photo
    return path


def main(argv: list[str]) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sizes", default="512,1024,2048")
    ap.add_argument("--json", default=os.path.join(ROOT, "bench", "results", "large-llvmpipe.json"))
    a = ap.parse_args(argv)
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        runs = []
        for m in (int(v) for v in a.sizes.split(",")):
            runs.append((m, 2))
            if m == 512:
                runs.append((m, 0))
        print(f"{'side':>6}{'k':>3}{'analysis s':>12}{'peak MB':>9}{'import MB':>10}{'cache MB':>9}"
              f"{'512^2 window s':>15}")
        for m, k in runs:
            path = exemplar_png(m, tmp)
            out = subprocess.run([sys.executable, "-c", CHILD, ROOT, path, tmp, str(k)],
                                 capture_output=True, text=True, check=True)
            r = json.loads(out.stdout.strip().splitlines()[-1])
            rows.append(r)
            print(f"{r['size']:>6}{r['k']:>3}{r['analysis_s']:12.1f}{r['peak_mb']:9.0f}{r['import_mb']:10.0f}"
                  f"{r['cache_mb']:9.0f}{r['window_512_s']:15.2f}", flush=True)
    os.makedirs(os.path.dirname(a.json), exist_ok=True)
    with open(a.json, "w") as f:
        json.dump({"rows": rows}, f, indent=1)
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
