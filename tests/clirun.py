"""The ``infinitex`` command run in the test process: the same ``main`` as
``python main.py`` / ``infinitex`` (infinitex/__main__.py), its exit status and
what it printed, without starting an interpreter and importing numpy, moderngl
and the engine again (about 0.6 s a call on 2 cores). Tests that need a process
of their own (killed, out of memory, limits, a FIFO that blocks, a real
install) keep running the command as a subprocess."""
from __future__ import annotations

import contextlib
import io
import os
import subprocess
import warnings


def infinitex(*argv, cwd: str | None = None) -> subprocess.CompletedProcess:
    """Run ``infinitex ARGV...``; a CompletedProcess (returncode, stdout, stderr) as subprocess.run gives."""
    from infinitex.__main__ import main
    args = [os.fspath(a) for a in argv]
    out, err = io.StringIO(), io.StringIO()
    with contextlib.ExitStack() as stack:
        if cwd is not None:
            stack.enter_context(contextlib.chdir(cwd))
        stack.enter_context(contextlib.redirect_stdout(out))
        stack.enter_context(contextlib.redirect_stderr(err))
        # Warnings go to stderr as in a fresh interpreter (not to pytest's record),
        # so a test that wants one line of error output sees them.
        stack.enter_context(warnings.catch_warnings())
        warnings.resetwarnings()
        warnings.simplefilter("default")
        for quiet in (DeprecationWarning, PendingDeprecationWarning, ImportWarning, ResourceWarning):
            warnings.simplefilter("ignore", quiet)
        try:
            code = main(args)
        except SystemExit as exc:  # argparse: --help, usage errors
            code = exc.code if isinstance(exc.code, int) else (0 if exc.code is None else 2)
    return subprocess.CompletedProcess(["infinitex", *args], code, out.getvalue(), err.getvalue())
