#!/usr/bin/env bash
# Set up (if needed) and run the whole test suite.
#   bash scripts/test.sh          everything (about 11 minutes on 2 cores with llvmpipe)
#   bash scripts/test.sh --fast   the edit-test loop: all but the GUI drivers (-m gui) and the
#                                 long tests (-m slow), about 3 minutes
# Other arguments go to pytest (e.g. tests/engine, -k lattice, -x).
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup.sh
args=()
if [ "${1:-}" = "--fast" ]; then
  shift
  args=(-m "not gui and not slow")
fi
# In parallel processes, one per core (pytest-xdist; the long tests are handed out first,
# tests/conftest.py, then the rest to whichever is free). `-n 0` runs in one process.
exec .venv/bin/python -m pytest -q -n auto --dist load ${args[@]+"${args[@]}"} "$@"
