#!/usr/bin/env bash
# Set up (if needed), then open the editor on the default exemplar (or on "$1":
# an image or an .itex project). Without a display (no $DISPLAY / $WAYLAND_DISPLAY)
# the editor runs on a virtual X display and saves a screenshot to out/editor.png.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup.sh
if [ -n "${DISPLAY:-}" ] || [ -n "${WAYLAND_DISPLAY:-}" ] || [ "$(uname)" != Linux ]; then
  exec .venv/bin/python main.py "$@"
fi
mkdir -p out
echo "editor: no display here; running it on a virtual display and saving out/editor.png"
xvfb-run -a -s "-screen 0 1280x800x24" .venv/bin/python main.py --screenshot out/editor.png "$@"
echo "wrote out/editor.png"
