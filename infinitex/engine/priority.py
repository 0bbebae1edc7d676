"""Background processes (exports, the flow player, the shader warm-up) run at
a low priority so the editor's frames come first. On Linux a nice value
belongs to a thread, and numpy's BLAS has started its threads by the time a
worker's code runs: ``os.nice`` would lower the calling thread alone."""
from __future__ import annotations

import os


def lower_priority(level: int) -> None:
    """Run every thread of this process at nice ``level`` or lower priority
    (a thread already nicer is left as it is); quietly nothing where the
    system has no such thing or refuses."""
    if not hasattr(os, "setpriority"):
        return
    try:
        threads = [int(t) for t in os.listdir("/proc/self/task")]
    except (OSError, ValueError):
        threads = [0]  # no /proc: the calling thread (the process where nice is per process)
    for tid in threads:
        try:
            if os.getpriority(os.PRIO_PROCESS, tid) < level:
                os.setpriority(os.PRIO_PROCESS, tid, level)
        except OSError:
            pass  # a thread that ended meanwhile, or a refusal
