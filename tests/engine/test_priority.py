"""Background processes run below the editor, every thread of them
(engine/priority.py): on Linux a nice value is per thread, and numpy's BLAS
has started its threads before a worker's code runs."""
import os
import subprocess
import sys

import pytest

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))


@pytest.mark.skipif(not os.path.isdir("/proc/self/task"), reason="threads' nice values are read from /proc")
def test_every_thread_of_a_worker_is_lowered():
    code = ("import os, threading, time\n"
            "import numpy as np\n"  # BLAS threads, started at import
            "stop = threading.Event()\n"
            "t = threading.Thread(target=stop.wait); t.start()\n"  # and one of Python's own
            "from infinitex.engine.priority import lower_priority\n"
            "lower_priority(15)\n"
            "nice = [int(open(f'/proc/self/task/{tid}/stat').read().rsplit(')', 1)[1].split()[16])\n"
            "        for tid in os.listdir('/proc/self/task')]\n"
            "stop.set(); t.join()\n"
            "print(len(nice), min(nice))\n")
    env = dict(os.environ, OPENBLAS_NUM_THREADS="2")
    out = subprocess.run([sys.executable, "-c", code], cwd=ROOT, env=env, capture_output=True, text=True, check=True)
    threads, lowest = map(int, out.stdout.split())
    assert threads >= 2 and lowest >= 15  # os.nice(15) would have left the other threads at 0
