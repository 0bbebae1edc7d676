#!/usr/bin/env bash
# Set up a fresh Debian/Ubuntu machine (or any machine with Python 3.10+):
# the system GL libraries for headless OpenGL (EGL + Mesa), then .venv with
# the Python dependencies. Safe to run again; it only installs what is missing.
set -euo pipefail
cd "$(dirname "$0")/.."
# --bench: also install the benchmark-only packages (requirements-bench.txt: the G'MIC peer, plenoptic on CPU torch).
# --tests: also the Debian packages only the tests use (tiled: its renderer tmxrasterizer
# checks the Tiled tile sets we write).
BENCH=0
TESTS=0
if [ "${1:-}" = "--bench" ]; then BENCH=1; fi
if [ "${1:-}" = "--tests" ]; then TESTS=1; fi

if command -v dpkg >/dev/null 2>&1 && command -v apt-get >/dev/null 2>&1; then
  missing=()
  # xvfb + xauth: the editor runs (and its tests drive it) on a virtual display.
  pkgs=(libegl1 libgl1 libegl-mesa0 libgl1-mesa-dri xvfb xauth)
  if [ "$TESTS" = 1 ]; then pkgs+=(tiled); fi
  for pkg in "${pkgs[@]}"; do
    dpkg -s "$pkg" >/dev/null 2>&1 || missing+=("$pkg")
  done
  # Debian's python3 ships without venv/ensurepip unless python3-venv is installed.
  if ! command -v "${PYTHON:-python3}" >/dev/null 2>&1; then
    missing+=(python3 python3-venv)
  elif ! "${PYTHON:-python3}" -c "import venv, ensurepip" >/dev/null 2>&1; then
    missing+=(python3-venv)
  fi
  if [ ${#missing[@]} -gt 0 ]; then
    echo "setup: installing Debian packages: ${missing[*]}"
    sudo_cmd=""
    if [ "$(id -u)" != 0 ]; then sudo_cmd="sudo"; fi
    $sudo_cmd apt-get update -qq
    DEBIAN_FRONTEND=noninteractive $sudo_cmd apt-get install -y -qq --no-install-recommends "${missing[@]}"
  fi
fi

PY=${PYTHON:-python3}
if [ ! -x .venv/bin/python ]; then
  echo "setup: creating .venv"
  if ! "$PY" -m venv .venv; then
    echo "setup: python3 -m venv failed; on Debian: apt-get install python3-venv" >&2
    exit 1
  fi
fi
stamp=.venv/.requirements.sha
want=$(cat requirements.txt pyproject.toml | sha256sum | cut -d' ' -f1)
if [ ! -f "$stamp" ] || [ "$(cat "$stamp")" != "$want" ] || [ ! -x .venv/bin/infinitex ]; then
  echo "setup: installing Python packages"
  .venv/bin/python -m pip install -q --upgrade pip
  .venv/bin/python -m pip install -q -r requirements.txt
  # The package itself, editable: the `infinitex` command in .venv/bin runs this checkout.
  .venv/bin/python -m pip install -q --no-deps -e .
  echo "$want" > "$stamp"
fi
if [ "$BENCH" = 1 ]; then
  bstamp=.venv/.requirements-bench.sha
  bwant=$(sha256sum requirements-bench.txt | cut -d' ' -f1)
  if [ ! -f "$bstamp" ] || [ "$(cat "$bstamp")" != "$bwant" ]; then
    echo "setup: installing benchmark packages"
    .venv/bin/python -m pip install -q -r requirements-bench.txt
    echo "$bwant" > "$bstamp"
  fi
fi
