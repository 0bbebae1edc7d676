"""``python main.py export PROJECT -o OUT.png``: render a project headless.

Shares the editor's export code (``app.session.ExportJob``), so the file is
identical to what File > Export writes. Progress on stderr; Ctrl+C cancels.
"""
from __future__ import annotations

import argparse
import sys
import time

from engine.cli import EXIT_INPUT, CliError, _integer, guarded


def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="main.py export",
                                description="Export a project's texture (a rectangle, its view, or a toroidal tile).")
    p.add_argument("project", help="an .itex project file (or an exemplar image: default settings)")
    p.add_argument("-o", "--output", required=True, help="output PNG")
    g = p.add_mutually_exclusive_group()
    g.add_argument("--rect", nargs=4, type=_integer, metavar=("X", "Y", "W", "H"),
                   help="canvas rectangle in finest-level pixels")
    g.add_argument("--toroidal", type=_integer, metavar="N", help="an N x N tile that wraps seamlessly")
    p.add_argument("--size", nargs=2, type=_integer, default=[1024, 1024], metavar=("W", "H"),
                   help="without --rect/--toroidal: a W x H window centered on the project's view")
    p.add_argument("--coords", action="store_true", help="also write OUT_coords.png (exact exemplar coordinates)")
    p.add_argument("-q", "--quiet", action="store_true")
    return p


def run_export(argv: list[str]) -> int:
    args = build_parser().parse_args(argv)
    import os

    from engine.gpu import Gpu
    from engine.pyramid import Rect

    from .document import Document, ExemplarSource, is_project_file, load_project
    from .session import ExportJob, Session

    if os.path.isfile(args.project) and is_project_file(args.project):
        proj = load_project(args.project)
        doc, view = proj.document, proj.view
    else:
        try:
            doc, view = Document(ExemplarSource.from_file(args.project)), None
        except OSError as exc:
            raise CliError(f"{args.project}: {exc.strerror or exc}.", EXIT_INPUT) from None
    if args.rect:
        x, y, w, h = args.rect
        rect, tor = Rect.of(x, y, w, h), 0
    elif args.toroidal:
        n = args.toroidal
        rect, tor = Rect(0, 0, n, n), n
    else:
        w, h = args.size
        cx, cy = (view.x, view.y) if view else (0.0, 0.0)
        rect, tor = Rect.of(int(cx - w / 2), int(cy - h / 2), w, h), 0
    session = Session(Gpu())
    session.load_now(doc)
    base = os.path.splitext(args.output)[0]
    job = ExportJob(session, rect, args.output, toroidal=tor,
                    coords_path=base + "_coords.png" if args.coords else None, tile=512)
    t0 = time.perf_counter()
    last = [0.0]

    def progress(f: float) -> None:
        now = time.monotonic()
        if not args.quiet and (now - last[0] > 0.25 or f >= 1.0):
            last[0] = now
            sys.stderr.write(f"\rexport {f * 100:5.1f}%")
            if f >= 1.0:
                sys.stderr.write("\n")
            sys.stderr.flush()

    try:
        job.run(progress)
    except KeyboardInterrupt:
        job.cancel()
        raise
    if not args.quiet:
        sys.stderr.write(f"{args.output}: {rect.w}x{rect.h} in {time.perf_counter() - t0:.1f} s "
                         f"({session.gpu.renderer})\n")
    session.release()
    return 0


def main(argv: list[str]) -> int:
    from .document import ProjectError
    return guarded(run_export, argv, (ProjectError, ValueError))
