"""A load beside a benchmark: ``busy(n)`` runs n processes that spin (a load
average of about n more; n = 2 takes both cores of this machine), as a busy
machine would (another editor refining, a build, a browser)."""
from __future__ import annotations

import subprocess
import sys
from contextlib import contextmanager
from typing import Iterator


@contextmanager
def busy(n: int) -> Iterator[None]:
    procs = [subprocess.Popen([sys.executable, "-c", "while True: pass"]) for _ in range(max(0, n))]
    try:
        yield
    finally:
        for p in procs:
            p.kill()
            p.wait()
