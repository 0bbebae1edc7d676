#!/usr/bin/env python3
"""Run Infinitex from a checkout: the same as the installed ``infinitex`` command
(``python main.py [FILE]``, ``python main.py synth ...``, ``python main.py export ...``)."""
import os
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))

from infinitex.__main__ import console  # noqa: E402

if __name__ == "__main__":
    console()
