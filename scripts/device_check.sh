#!/usr/bin/env bash
# The prepared check for a lent GPU machine (the device tool; never in CI).
# Run there from the repository root with `.whl` (the engine's wheels for
# Python 3.12: moderngl, glcontext, numpy, scipy, Pillow, tqdm) and `.gl` (the
# GL loader packages) carried, as docs/benchmarks.md "On a GPU" describes:
#
#   bash scripts/device_check.sh          # results under $OUT (or out/device)
#
# It measures the presets (bench.device run: windows, pans, 1920x1080 and
# 3840x2160 views, dabs), profiles Variety and Balanced up to 4096^2
# (bench.profile with GL timer queries) and times flowing frames of 1920x1080 (bench.flow). Back here, `python -m bench.device
# compare $OUT/coords.npz` checks that its windows are bit-identical to llvmpipe's.
set -euo pipefail
OUT=${OUT:-out/device}
mkdir -p "$OUT"
if [ -d .gl ]; then for f in .gl/*.deb; do dpkg -x "$f" /; done; ldconfig; fi
if [ -d .whl ]; then
    python3 -m pip install -q --no-index --no-deps --no-compile --no-cache-dir --upgrade --target /tmp/site .whl/*.whl
    export PYTHONPATH=/tmp/site
fi
export PYTHONUNBUFFERED=1
nvidia-smi --query-gpu=name,driver_version --format=csv,noheader || true
python3 -m bench.profile --sizes 512 1024 4096 --presets Variety Balanced --runs 3 --json "$OUT/profile.json" \
    2>&1 | tee "$OUT/profile.log"
python3 -m bench.device run "$OUT" 2>&1 | tee "$OUT/device.log"
# Texture in motion: frames of 1920 x 1080 played in order (target: 60 per second at Balanced).
python3 -m bench.flow --speed-only --speed-size 1920 1080 --json "$OUT/flow.json" 2>&1 | tee "$OUT/flow.log"
