"""Time from opening an image to the first texture on the editor's canvas.

    xvfb-run -a -s "-screen 0 1280x800x24" python -m bench.editor_open [--load N] [--only NAME] [--json OUT.json]

Each case runs the real editor (its own runner, no test engine) in a fresh
process with an empty analysis cache, opening the image given on its command
line as a user's double-click would. Measured from the editor's first frame
(the window is up and the image is being read) to: the first frame that draws
synthesized texture ("first texture"; the quick preview where the full
analysis builds similarity sets), the frame the full analysis is installed
("full analysis"), and the frame the view is exact ("exact"). Prints a table,
writes JSON. Images: the shipped gravel (128 px), the bench exemplars at 256 px,
a generated cobblestone photo at 512, 1024 and 2048 px (the default import
fits the last two to 512 px), and generated bricks at 1024 px, whose lattice is
found on opening ("on its lattice": the frame the document is on it). ``--load 2``: two busy processes beside the
editor (a load average of 2, all this machine's cores).
"""
from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time

import numpy as np

HERE = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
if HERE not in sys.path:
    sys.path.insert(0, HERE)


def _child(path: str, out: str) -> int:
    """Run the editor on ``path``; write the timings to ``out`` and exit once exact."""
    from infinitex.app.ui.editor import Editor

    class Timed(Editor):
        marks: dict[str, float] = {}

        def gui(self) -> None:
            now = time.perf_counter()
            self.marks.setdefault("first_frame", now)
            super().gui()
            s = self.session
            if s is not None and s.ready and s.refiner is not None and s.refiner.shows_texture:
                self.marks.setdefault("first_texture", now)
                if self.doc is not None and self.doc.lattice is not None:
                    self.marks.setdefault("on_lattice", now)
                if not getattr(s, "quick_analysis", False) and s.job is None:
                    self.marks.setdefault("full_analysis", now)
                    if self.refined:
                        self.marks.setdefault("exact", now)
                        self.params.app_shall_exit = True
            if now - self.marks["first_frame"] > 300:
                self.params.app_shall_exit = True

    ed = Timed(path, recover=False, window_size=(1280, 800))
    ed.run()
    t0 = Timed.marks.get("first_frame")
    res = {k: (v - t0) for k, v in Timed.marks.items() if k != "first_frame"}
    with open(out, "w") as fh:
        json.dump(res, fh)
    return 0


def cases(folder: str) -> list[tuple[str, str]]:
    from bench.large import exemplar_png
    out = [("gravel 128", os.path.join(HERE, "infinitex", "assets", "gravel.png")),
           ("text 128", os.path.join(HERE, "bench", "exemplars", "text.png")),
           ("reptile skin 256", os.path.join(os.path.dirname(HERE), "shared", "exemplars", "reptile_skin.png"))]
    for m in (512, 1024, 2048):
        out.append((f"cobbles {m}", exemplar_png(m, folder)))
    # A regular texture: its lattice is found on opening (the quick preview shows first, the lattice after).
    sys.path.insert(0, os.path.join(HERE, "tests"))
    from lattice_gen import bricks

    from infinitex.engine.imagefile import to_u8, write_png
    img, _, _ = bricks(np.random.default_rng(1), side=1024, bw=80, bh=36)
    write_png(os.path.join(folder, "bricks1024.png"), to_u8(img))
    out.append(("bricks 1024", os.path.join(folder, "bricks1024.png")))
    return [(n, p) for n, p in out if os.path.exists(p)]


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--json", metavar="OUT.json")
    ap.add_argument("--load", type=int, default=0, metavar="N",
                    help="N busy processes run beside the editor (a load average of N)")
    ap.add_argument("--only", metavar="TEXT", help="only the cases whose name contains TEXT")
    ap.add_argument("--child", nargs=2, help=argparse.SUPPRESS)
    args = ap.parse_args(argv)
    if args.child:
        return _child(*args.child)
    tmp = tempfile.mkdtemp(prefix="infinitex-open-")
    rows = []
    for name, path in cases(tmp):
        if args.only and args.only not in name:
            continue
        out = os.path.join(tmp, "t.json")
        if os.path.exists(out):
            os.remove(out)
        env = dict(os.environ, INFINITEX_CACHE=tempfile.mkdtemp(prefix="cache-", dir=tmp),
                   INFINITEX_STATE=tempfile.mkdtemp(prefix="state-", dir=tmp), INFINITEX_NO_NATIVE_DIALOGS="1")
        from bench.load import busy
        with busy(args.load):
            subprocess.run([sys.executable, "-m", "bench.editor_open", "--child", path, out], cwd=HERE, env=env,
                           timeout=900, capture_output=True)
        t = json.load(open(out)) if os.path.exists(out) else {}
        rows.append({"case": name, **t})
        print(f"{name:<18} first texture {t.get('first_texture', float('nan')):6.2f} s   "
              f"full analysis {t.get('full_analysis', float('nan')):6.2f} s   exact {t.get('exact', float('nan')):6.2f} s"
              + (f"   on its lattice {t['on_lattice']:6.2f} s" if "on_lattice" in t else ""), flush=True)
    if args.json:
        from infinitex.engine.safeio import atomic_write
        atomic_write(args.json, json.dumps({"cases": rows, "load": args.load}, indent=1).encode())
    return 0


if __name__ == "__main__":
    sys.exit(main())
