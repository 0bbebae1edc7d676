"""Peak memory of exemplar imports: measured against the budget and the estimate.

    .venv/bin/python -m bench.import_memory [--side 8192] [--json OUT]

For large images of several formats and modes, each import runs in a fresh
process; the peak resident memory it adds (ru_maxrss after minus before) is
compared with ``engine.exemplar.import_cost`` (the bound computed from the
header, which decides refusals) and ``IMPORT_BUDGET``. Prints a table and
writes JSON (default bench/results/import-memory.json).
"""
from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(HERE)

CHILD = """
import json, sys, time
sys.path.insert(0, {root!r})
from infinitex.engine.exemplar import ExemplarError, load_exemplar
def hwm():  # peak RSS of this process image (ru_maxrss would include the parent's peak)
    for line in open("/proc/self/status"):
        if line.startswith("VmHWM:"):
            return int(line.split()[1]) * 1024
base = hwm()
t0 = time.perf_counter()
try:
    ex = load_exemplar(sys.argv[1]); out = "accepted"
except ExemplarError as exc:
    out = "refused: " + str(exc)
dt = time.perf_counter() - t0
peak = hwm()
print(json.dumps(dict(outcome=out, used=peak - base, seconds=dt)))
"""


def measure_import(path: str) -> dict:
    """Import ``path`` in a fresh process: outcome, bytes of peak memory added, seconds."""
    r = subprocess.run([sys.executable, "-c", CHILD.format(root=ROOT), path],
                       capture_output=True, text=True, timeout=600)
    if r.returncode != 0:
        raise RuntimeError(r.stderr[-2000:])
    return json.loads(r.stdout.strip().splitlines()[-1])


def make_cases(side: int, folder: str) -> list[tuple[str, str, str, str]]:
    """(label, path, mode, format) of generated test images (cheap to encode: flat areas and lines)."""
    import numpy as np
    from PIL import Image, ImageDraw

    def drawn(mode, fill, ink):
        img = Image.new(mode, (side, side), fill)
        d = ImageDraw.Draw(img)
        for i in range(0, side, 97):
            d.line((0, i, side, (i * 7) % side), fill=ink, width=3)
        return img
    cases = []
    specs = [("RGBA PNG", "RGBA", "PNG", (10, 20, 30, 255), (200, 100, 50, 255), {"compress_level": 1}),
             ("RGB JPEG", "RGB", "JPEG", (10, 20, 30), (200, 100, 50), {"quality": 90}),
             ("RGB WebP", "RGB", "WEBP", (10, 20, 30), (200, 100, 50), {"lossless": True, "method": 0}),
             ("16-bit PNG", "I;16", "PNG", 1000, 60000, {"compress_level": 1}),
             ("RGB TIFF (deflate)", "RGB", "TIFF", (10, 20, 30), (200, 100, 50), {"compression": "tiff_deflate"})]
    for label, mode, fmt, fill, ink, kw in specs:
        path = os.path.join(folder, label.replace(" ", "_").replace("(", "").replace(")", "") + "." + fmt.lower())
        drawn(mode, fill, ink).save(path, fmt, **kw)
        cases.append((label, path, mode, fmt))
    f = np.zeros((side, side), np.float32)
    f[::5] = 1.5
    f[:, ::7] = -2.0
    path = os.path.join(folder, "float.tif")
    Image.fromarray(f).save(path, compression="tiff_deflate")
    cases.append(("float TIFF (deflate)", path, "F", "TIFF"))
    return cases


def main(argv: list[str]) -> int:
    p = argparse.ArgumentParser(prog="python -m bench.import_memory")
    p.add_argument("--side", type=int, default=8192)
    p.add_argument("--json", default=os.path.join(HERE, "results", "import-memory.json"))
    args = p.parse_args(argv)
    sys.path.insert(0, ROOT)
    from infinitex.engine.exemplar import IMPORT_BUDGET, import_cost
    rows = []
    with tempfile.TemporaryDirectory() as folder:
        for label, path, mode, fmt in make_cases(args.side, folder):
            res = measure_import(path)
            cost = import_cost(args.side, args.side, mode, os.path.getsize(path), "resize", fmt)
            rows.append(dict(image=f"{args.side}^2 {label}", file_mb=round(os.path.getsize(path) / 2 ** 20, 1),
                             estimate_mb=cost >> 20, used_mb=res["used"] >> 20,
                             outcome=res["outcome"][:90], seconds=round(res["seconds"], 2)))
    print(f"budget {IMPORT_BUDGET >> 20} MB")
    print("| image | file MB | estimate MB | peak added MB | outcome | s |")
    print("|---|---|---|---|---|---|")
    for r in rows:
        print(f"| {r['image']} | {r['file_mb']} | {r['estimate_mb']} | {r['used_mb']} | {r['outcome']} | {r['seconds']} |")
    from infinitex.engine.safeio import atomic_write
    atomic_write(args.json, json.dumps(dict(budget_mb=IMPORT_BUDGET >> 20, date=time.strftime("%Y-%m-%d"),
                                            rows=rows), indent=1).encode())
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
