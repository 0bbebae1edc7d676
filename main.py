#!/usr/bin/env python3
"""Infinitex: infinite, controllable, example-based textures.

    python main.py synth EXEMPLAR -o OUT.png [options]   synthesize a window or a toroidal tile

Run ``python main.py synth --help`` for the options.
"""
from __future__ import annotations

import os
import sys

HERE = os.path.dirname(os.path.abspath(__file__))
if HERE not in sys.path:
    sys.path.insert(0, HERE)

COMMANDS = {
    "synth": "synthesize a window of the infinite texture (or a toroidal tile) to a PNG",
}


def usage() -> str:
    lines = ["usage: python main.py COMMAND [options]", "", "commands:"]
    lines += [f"  {name:<8} {text}" for name, text in COMMANDS.items()]
    return "\n".join(lines) + "\n"


def main(argv: list[str]) -> int:
    if not argv or argv[0] in ("-h", "--help"):
        sys.stdout.write(__doc__.split("\n\n")[0] + "\n\n" + usage())
        return 0 if argv else 2
    cmd, rest = argv[0], argv[1:]
    if cmd == "synth":
        from engine.cli import main as synth_main
        return synth_main(rest)
    sys.stderr.write(f"error: unknown command {cmd!r}\n" + usage())
    return 2


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
