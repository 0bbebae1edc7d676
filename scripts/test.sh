#!/usr/bin/env bash
# Set up (if needed) and run the whole test suite.
#   bash scripts/test.sh          everything (15 minutes on 2 cores with llvmpipe, 2026-12-07; budget 12)
#   bash scripts/test.sh --fast   the edit-test loop: all but the GUI drivers (-m gui) and the
#                                 long tests (-m slow, tests/fast_set.py), under 3 minutes
# Other arguments go to pytest (e.g. tests/engine, -k lattice, -x).
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup.sh --tests
args=()
if [ "${1:-}" = "--fast" ]; then
  shift
  args=(-m "not gui and not slow")
fi
# In parallel processes (pytest-xdist), one more than the cores: the GUI drivers and the
# exports wait on other processes (an editor going idle, workers starting) while a third
# test uses the core. Work goes out in units (tests/conftest.py): the GUI drivers in two
# chains first, then each test module whole, to whichever process is free, in the suite's
# order. INFINITEX_TEST_WORKERS=N sets the count; `-n 0` runs in one.
workers=${INFINITEX_TEST_WORKERS:-$(( $(nproc) + 1 ))}
exec .venv/bin/python -m pytest -q -n "$workers" --dist load ${args[@]+"${args[@]}"} "$@"
