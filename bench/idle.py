"""CPU used by the editor while it refines and while it idles.

    xvfb-run -a -s "-screen 0 1280x800x24" python -m bench.idle [--seconds 60] [--json OUT.json]

Starts the real editor (``main.py``, default exemplar, a fresh state folder
so no autosave is recovered) as a child process and reads its CPU time
(user + system, all threads) from /proc: over its first ``--refine`` seconds
(start-up, analysis and progressive refinement of the canvas) and then, after
``--settle`` more seconds with no input, over ``--seconds`` of idling.
Reports percent of one core. Target for the idle figure: under 3%.

Then input must wake it at once: the pointer is moved over the window
(XTest, libXtst) 5 times, 2 s apart, and the time until the editor's CPU
time next grows (it draws a frame) is the wake-up latency (10 ms ticks).
"""
from __future__ import annotations

import argparse
import ctypes
import json
import os
import subprocess
import sys
import tempfile
import time

HERE = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
TICKS = os.sysconf("SC_CLK_TCK")


def cpu_seconds(pid: int) -> float:
    """User + system CPU time of a process (all its threads), in seconds."""
    with open(f"/proc/{pid}/stat", encoding="ascii") as f:
        fields = f.read().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / TICKS  # utime, stime (fields 14, 15 of stat)


def wake_latencies(pid: int, moves: int = 5) -> list[float]:
    """Seconds from a pointer motion (XTest) to the editor's next CPU tick."""
    x11 = ctypes.CDLL("libX11.so.6")
    xtst = ctypes.CDLL("libXtst.so.6")
    x11.XOpenDisplay.restype = ctypes.c_void_p
    x11.XOpenDisplay.argtypes = [ctypes.c_char_p]
    x11.XFlush.argtypes = [ctypes.c_void_p]
    x11.XCloseDisplay.argtypes = [ctypes.c_void_p]
    xtst.XTestFakeMotionEvent.argtypes = [ctypes.c_void_p, ctypes.c_int, ctypes.c_int, ctypes.c_int, ctypes.c_ulong]
    dpy = x11.XOpenDisplay(None)
    if not dpy:
        return []
    out = []
    try:
        for i in range(moves):
            time.sleep(2.0)
            c0 = cpu_seconds(pid)
            t0 = time.monotonic()
            xtst.XTestFakeMotionEvent(dpy, -1, 600 + 40 * (i % 2), 400, 0)
            x11.XFlush(dpy)
            while cpu_seconds(pid) == c0 and time.monotonic() - t0 < 10.0:
                time.sleep(0.002)
            out.append(time.monotonic() - t0)
            time.sleep(4.0)  # back to idle (the runner stays active 3 s after an event)
    finally:
        x11.XCloseDisplay(dpy)
    return out


def measure(seconds: float, settle: float, refine: float) -> dict:
    env = dict(os.environ, INFINITEX_STATE=tempfile.mkdtemp(prefix="infinitex-idle-"),
               INFINITEX_CACHE=os.environ.get("INFINITEX_CACHE", tempfile.mkdtemp(prefix="infinitex-idle-cache-")))
    proc = subprocess.Popen([sys.executable, os.path.join(HERE, "main.py")], env=env, cwd=HERE,
                            stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    try:
        t0 = time.monotonic()
        time.sleep(refine)
        busy = cpu_seconds(proc.pid) / (time.monotonic() - t0)
        time.sleep(settle)
        c0, w0 = cpu_seconds(proc.pid), time.monotonic()
        time.sleep(seconds)
        idle = (cpu_seconds(proc.pid) - c0) / (time.monotonic() - w0)
        wake = wake_latencies(proc.pid)
        if proc.poll() is not None:
            raise RuntimeError(f"the editor exited: {proc.stderr.read().decode(errors='replace')[-500:]}")
    finally:
        proc.terminate()
        try:
            proc.wait(10)
        except subprocess.TimeoutExpired:
            proc.kill()
    return {"refining_core_percent": 100.0 * busy, "idle_core_percent": 100.0 * idle, "wake_s": wake,
            "refine_s": refine, "settle_s": settle, "idle_s": seconds}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--seconds", type=float, default=60.0, help="idle measurement (default 60 s)")
    ap.add_argument("--settle", type=float, default=15.0, help="wait after the refining window")
    ap.add_argument("--refine", type=float, default=10.0, help="the first seconds: start-up and refinement")
    ap.add_argument("--json", metavar="OUT.json")
    args = ap.parse_args(argv)
    r = measure(args.seconds, args.settle, args.refine)
    print(f"{'editor (1280x800 window, default exemplar)':44s} {'CPU, % of one core':>20s}")
    print(f"{'first ' + format(args.refine, 'g') + ' s (start-up, analysis, refinement)':44s} "
          f"{r['refining_core_percent']:20.1f}")
    print(f"{'idle, ' + format(args.seconds, 'g') + ' s without input':44s} {r['idle_core_percent']:20.1f}")
    if r["wake_s"]:
        w = sorted(r["wake_s"])
        print(f"wake-up after a pointer motion: median {w[len(w) // 2] * 1000:.0f} ms, max {w[-1] * 1000:.0f} ms "
              f"({len(w)} motions)")
    if args.json:
        sys.path.insert(0, HERE)
        from infinitex.engine.safeio import atomic_write
        atomic_write(args.json, json.dumps(r, indent=1).encode())
    return 0


if __name__ == "__main__":
    sys.exit(main())
