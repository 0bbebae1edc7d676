#!/usr/bin/env bash
# Set up (if needed) and synthesize a 512x512 window and a seamless 256x256
# tile of the default exemplar into out/. (The interactive editor comes next.)
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup.sh
mkdir -p out
.venv/bin/python main.py synth "${1:-assets/gravel.png}" -o out/window.png --size 512 512 --origin 100000 -250000
.venv/bin/python main.py synth "${1:-assets/gravel.png}" -o out/tile.png --size 256 256 --toroidal
echo "wrote out/window.png and out/tile.png"
