"""Throughput and peak memory of huge streamed exports (issue 12).

    python -m bench.export [--size 16384] [--workers 0,1,2] [--format tiff] [--tile 1024]
                           [--exemplar PATH] [--scheduler] [--keep] [--json OUT.json]

Runs the real command (``infinitex export EXEMPLAR --format tiff --rect 0 0 N N``)
once per worker count, as a child process, and samples every 0.2 s the
resident memory of the whole process tree (the command and its workers,
psutil: installed with dask.distributed); reports wall time, Mpixel/s, peak
RSS of all processes together and of the largest one, and the output's size.
The analysis is cached (warmed by a small export first), so the figures are
the export's own. ``--workers 0`` renders in the command's process.

Target (issue 12): a 32768^2 export under 1.5 GB of peak RSS, all processes.
"""
from __future__ import annotations

import argparse
import json
import os
import shutil
import subprocess
import sys
import tempfile
import time

import psutil

HERE = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
GRAVEL = os.path.join(HERE, "infinitex", "assets", "gravel.png")


def tree_rss(proc: psutil.Process) -> tuple[int, int]:
    """(sum, max) resident bytes of a process and its descendants."""
    total, largest = 0, 0
    try:
        procs = [proc, *proc.children(recursive=True)]
    except psutil.Error:
        return 0, 0
    for p in procs:
        try:
            rss = p.memory_info().rss
        except psutil.Error:
            continue
        total += rss
        largest = max(largest, rss)
    return total, largest


def run_export(exemplar: str, n: int, out: str, fmt: str, tile: int, workers: int, scheduler: bool,
               env: dict) -> dict:
    args = [sys.executable, os.path.join(HERE, "main.py"), "export", exemplar, "-o", out, "--format", fmt,
            "--rect", "0", "0", str(n), str(n), "--tile", str(tile), "-q"]
    if workers:
        args += ["--workers", str(workers)]
    if scheduler:
        args += ["--scheduler"]
    t0 = time.perf_counter()
    child = subprocess.Popen(args, env=env, stderr=subprocess.PIPE)
    proc = psutil.Process(child.pid)
    peak_sum = peak_one = 0
    while child.poll() is None:
        s, m = tree_rss(proc)
        peak_sum, peak_one = max(peak_sum, s), max(peak_one, m)
        time.sleep(0.2)
    wall = time.perf_counter() - t0
    err = child.stderr.read().decode("utf-8", "replace")
    if child.returncode != 0:
        raise SystemExit(f"export failed ({child.returncode}): {err[-2000:]}")
    if fmt == "tiff":
        size = os.path.getsize(out)
    else:
        base = os.path.splitext(out)[0]
        folder = os.path.dirname(out)
        size = sum(os.path.getsize(os.path.join(folder, f)) for f in os.listdir(folder)
                   if f.startswith(os.path.basename(base) + ".") or f.startswith(os.path.basename(base) + "_u"))
    return {"size": n, "workers": workers, "scheduler": "LocalCluster" if scheduler else None, "format": fmt,
            "tile": tile, "seconds": round(wall, 1), "mpix_per_s": round(n * n / wall / 1e6, 3),
            "peak_rss_all_mb": round(peak_sum / 2**20), "peak_rss_largest_mb": round(peak_one / 2**20),
            "output_mb": round(size / 2**20, 1)}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--size", type=int, default=16384)
    ap.add_argument("--workers", default="0,1,2", help="comma-separated worker counts (0: in the command's process)")
    ap.add_argument("--format", choices=("tiff", "tiles"), default="tiff")
    ap.add_argument("--tile", type=int, default=1024)
    ap.add_argument("--exemplar", default=GRAVEL)
    ap.add_argument("--scheduler", action="store_true", help="also run on a Dask LocalCluster of each worker count")
    ap.add_argument("--dir", default=None, help="where the outputs go (default: a temporary folder, removed)")
    ap.add_argument("--keep", action="store_true", help="keep the outputs")
    ap.add_argument("--json", default=None)
    args = ap.parse_args(argv)
    folder = args.dir or tempfile.mkdtemp(prefix="infinitex-bench-export-")
    os.makedirs(folder, exist_ok=True)
    env = dict(os.environ)
    env.setdefault("INFINITEX_CACHE", os.path.join(folder, "cache"))
    ext = ".tif" if args.format == "tiff" else ".png"
    run_export(args.exemplar, 256, os.path.join(folder, "warm" + ext), args.format, 256, 0, False, env)
    rows = []
    plans = [(int(w), False) for w in args.workers.split(",")]
    if args.scheduler:
        plans += [(int(w), True) for w in args.workers.split(",") if int(w) > 0]
    try:
        for workers, scheduler in plans:
            out = os.path.join(folder, f"x{args.size}_{workers}{'d' if scheduler else ''}{ext}")
            r = run_export(args.exemplar, args.size, out, args.format, args.tile, workers, scheduler, env)
            rows.append(r)
            print(f"{r['size']}^2 {r['format']} tile {r['tile']}, workers {workers}"
                  f"{' (Dask LocalCluster)' if scheduler else ''}: {r['seconds']} s, {r['mpix_per_s']} Mpx/s, "
                  f"peak RSS {r['peak_rss_all_mb']} MB all / {r['peak_rss_largest_mb']} MB largest, "
                  f"output {r['output_mb']} MB", flush=True)
            if not args.keep:
                if os.path.isfile(out):
                    os.remove(out)
                else:
                    for f in os.listdir(folder):
                        if f.startswith(os.path.basename(os.path.splitext(out)[0])):
                            os.remove(os.path.join(folder, f))
    finally:
        if args.dir is None and not args.keep:
            shutil.rmtree(folder, ignore_errors=True)
    print()
    print("| size | workers | s | Mpx/s | peak RSS, all (MB) | largest process (MB) | output (MB) |")
    print("|---|---|---|---|---|---|---|")
    for r in rows:
        w = f"{r['workers']}{' Dask' if r['scheduler'] else ''}"
        print(f"| {r['size']}^2 | {w} | {r['seconds']} | {r['mpix_per_s']} | {r['peak_rss_all_mb']} | "
              f"{r['peak_rss_largest_mb']} | {r['output_mb']} |")
    if args.json:
        from infinitex.engine.gpu import Gpu
        try:
            renderer = Gpu().renderer
        except Exception as exc:  # noqa: BLE001 - report, do not fail the benchmark
            renderer = f"unknown ({exc})"
        with open(args.json, "w") as f:
            json.dump({"renderer": renderer, "exemplar": os.path.basename(args.exemplar), "runs": rows}, f, indent=1)
    return 0


if __name__ == "__main__":
    sys.exit(main())
