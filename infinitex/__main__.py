#!/usr/bin/env python3
"""The ``infinitex`` command (also ``python -m infinitex`` and ``python main.py``).

    infinitex [FILE]                              open the editor (on FILE: an image or a .itex project)
    infinitex --screenshot OUT.png [--frames N] [FILE]
                                                  open the editor, refine, save a PNG of the window, exit
    infinitex synth EXEMPLAR -o OUT.png [options]  synthesize a window or a toroidal tile, headless
    infinitex export PROJECT -o OUT.png [options]  export a project's texture, headless
    infinitex surface MODEL SOURCE -o OUT.glb      texture a model (synthesis in its atlas), headless
    infinitex animate SOURCE -o OUT --frames N     the texture flowing along a velocity field, headless
    infinitex --version

Run ``infinitex synth --help``, ``infinitex export --help``, ``infinitex surface --help`` or ``infinitex animate --help`` for the options.
"""
from __future__ import annotations

import argparse
import sys

from . import __version__

PROG = "infinitex"


def editor_main(argv: list[str]) -> int:
    p = argparse.ArgumentParser(prog=PROG, description="Open the Infinitex editor.",
                                epilog=f"Headless commands: {PROG} synth --help, {PROG} export --help, {PROG} surface --help, "
                                       f"{PROG} animate --help")
    p.add_argument("--version", action="version", version=f"{PROG} {__version__}")
    p.add_argument("file", nargs="?", help="an exemplar image or an .itex project (default: a bundled exemplar)")
    p.add_argument("--screenshot", metavar="OUT.png", help="save a PNG of the window once refined, then exit")
    p.add_argument("--frames", type=int, default=10, metavar="N", help="with --screenshot: run at least N frames")
    args = p.parse_args(argv)
    if args.screenshot:
        from infinitex.engine.safeio import WriteError, check_output
        try:
            check_output(args.screenshot, (".png",), "screenshot")
        except WriteError as exc:
            sys.stderr.write(f"error: {exc}\n")
            return 2
    try:
        from infinitex.app.ui.editor import run_editor
    except ImportError as exc:
        sys.stderr.write(f"error: the editor cannot start: {exc}. Run scripts/setup.sh first.\n")
        return 4
    return run_editor(args.file, screenshot=args.screenshot, frames=max(1, args.frames))


def main(argv: list[str] | None = None) -> int:
    """Dispatch: the editor, or the headless ``synth`` / ``export`` commands."""
    if argv is None:
        argv = sys.argv[1:]
    if argv and argv[0] == "synth":
        from infinitex.cli.synth import main as synth_main
        return synth_main(argv[1:])
    if argv and argv[0] == "export":
        from infinitex.cli.export import main as export_main
        return export_main(argv[1:])
    if argv and argv[0] == "animate":
        from infinitex.cli.animate import main as animate_main
        return animate_main(argv[1:])
    if argv and argv[0] == "surface":
        from infinitex.cli.surface import main as surface_main
        return surface_main(argv[1:])
    return editor_main(argv)


def console() -> None:
    """Entry point of the ``infinitex`` console script."""
    sys.exit(main(sys.argv[1:]))


if __name__ == "__main__":
    console()
