#!/usr/bin/env python3
"""Infinitex: infinite, controllable, example-based textures.

    python main.py [FILE]                              open the editor (on FILE: an image or a .itex project)
    python main.py --screenshot OUT.png [--frames N] [FILE]
                                                       open the editor, refine, save a PNG of the window, exit
    python main.py synth EXEMPLAR -o OUT.png [options] synthesize a window or a toroidal tile, headless
    python main.py export PROJECT -o OUT.png [options] export a project's texture, headless

Run ``python main.py synth --help`` or ``python main.py export --help`` for the options.
"""
from __future__ import annotations

import argparse
import os
import sys

HERE = os.path.dirname(os.path.abspath(__file__))
if HERE not in sys.path:
    sys.path.insert(0, HERE)


def editor_main(argv: list[str]) -> int:
    p = argparse.ArgumentParser(prog="main.py", description="Open the Infinitex editor.",
                                epilog="Headless commands: main.py synth --help, main.py export --help")
    p.add_argument("file", nargs="?", help="an exemplar image or an .itex project (default: a bundled exemplar)")
    p.add_argument("--screenshot", metavar="OUT.png", help="save a PNG of the window once refined, then exit")
    p.add_argument("--frames", type=int, default=10, metavar="N", help="with --screenshot: run at least N frames")
    args = p.parse_args(argv)
    if args.screenshot:
        from engine.safeio import WriteError, check_output
        try:
            check_output(args.screenshot, (".png",), "screenshot")
        except WriteError as exc:
            sys.stderr.write(f"error: {exc}\n")
            return 2
    try:
        from app.ui.editor import run_editor
    except ImportError as exc:
        sys.stderr.write(f"error: the editor cannot start: {exc}. Run scripts/setup.sh first.\n")
        return 4
    return run_editor(args.file, screenshot=args.screenshot, frames=max(1, args.frames))


def main(argv: list[str]) -> int:
    if argv and argv[0] == "synth":
        from engine.cli import main as synth_main
        return synth_main(argv[1:])
    if argv and argv[0] == "export":
        from app.cli import main as export_main
        return export_main(argv[1:])
    return editor_main(argv)


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
