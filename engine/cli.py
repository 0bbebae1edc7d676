"""Headless command line: ``python main.py synth EXEMPLAR -o OUT.png ...``.

Bad input gives a one-line message on stderr and a non-zero exit, never a
traceback. Long analyses show progress on stderr; Ctrl+C cancels cleanly.
"""
from __future__ import annotations

import argparse
import os
import sys
import time
from dataclasses import replace

import numpy as np

EXIT_USAGE = 2
EXIT_INPUT = 3
EXIT_GL = 4
EXIT_CANCELLED = 130


class CliError(Exception):
    def __init__(self, message: str, code: int = EXIT_INPUT):
        super().__init__(message)
        self.code = code


def _jitter_arg(text: str) -> list[float]:
    try:
        vals = [float(v) for v in text.split(",") if v.strip() != ""]
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a number or a comma-separated list of numbers") from None
    if not vals or any(not 0.0 <= v <= 1.0 for v in vals):
        raise argparse.ArgumentTypeError("randomness values must be in [0, 1]")
    return vals


def _integer(text: str) -> int:
    try:
        return int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not an integer") from None


def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="main.py synth",
                                description="Synthesize a window of the infinite texture of an exemplar.")
    p.add_argument("exemplar", help="exemplar image (PNG, JPEG, BMP, TIFF, WebP...)")
    p.add_argument("-o", "--output", required=True, help="output PNG")
    p.add_argument("--size", nargs=2, type=_integer, default=[256, 256], metavar=("W", "H"))
    p.add_argument("--origin", nargs=2, type=_integer, default=[0, 0], metavar=("X", "Y"),
                   help="canvas position of the top-left pixel (any 32-bit integers)")
    p.add_argument("--seed", type=_integer, default=0)
    p.add_argument("--jitter", type=_jitter_arg, default=None, metavar="R|r0,r1,...",
                   help="randomness: one value for every level, or one per level (coarse to fine)")
    p.add_argument("--toroidal", action="store_true", help="make a W x W texture that tiles seamlessly")
    p.add_argument("--coords", metavar="OUT.npy", help="save the (H, W, 2) int32 exemplar (x, y) map")
    p.add_argument("--model", choices=("appearance", "color"), default="appearance",
                   help="neighborhood model: appearance space (LH06) or 5x5 colors (LH05)")
    p.add_argument("--k", type=int, default=2, choices=(1, 2, 3, 4), help="similarity-set size")
    p.add_argument("--passes", type=int, default=2, help="correction passes c")
    p.add_argument("--kappa", type=float, default=0.5, help="coherence penalty")
    p.add_argument("--fit", choices=("resize", "crop"), default="resize",
                   help="how a non power-of-two or non-square image becomes the exemplar")
    p.add_argument("--exemplar-toroidal", choices=("auto", "yes", "no"), default="auto",
                   help="does the exemplar tile? (auto: guessed from its wrap-around seam)")
    p.add_argument("--no-cache", action="store_true", help="do not read or write the analysis cache")
    p.add_argument("-q", "--quiet", action="store_true")
    return p


def _progress(quiet: bool):
    last = [0.0]

    def report(fraction: float, message: str) -> None:
        now = time.monotonic()
        if quiet or (now - last[0] < 0.25 and fraction < 1.0):
            return
        last[0] = now
        sys.stderr.write(f"\ranalysis {fraction * 100:5.1f}%  {message:<40}")
        if fraction >= 1.0:
            sys.stderr.write("\n")
        sys.stderr.flush()
    return report


def run_synth(argv: list[str]) -> int:
    args = build_parser().parse_args(argv)
    from PIL import Image

    from engine.analysis import AnalysisSettings, analyze
    from engine.exemplar import PIL_MODES, load_exemplar, to_u8
    from engine.params import SynthParams
    from engine.pyramid import Rect
    from engine.synth import Synthesizer

    w, h = args.size
    if not (1 <= w <= 16384 and 1 <= h <= 16384):
        raise CliError("--size must be between 1 and 16384 in each dimension.", EXIT_USAGE)
    if args.toroidal and (w != h or w & (w - 1) or not 32 <= w <= 4096):
        raise CliError("--toroidal needs a square power-of-two --size from 32 to 4096.", EXIT_USAGE)
    out_dir = os.path.dirname(os.path.abspath(args.output))
    if not os.path.isdir(out_dir):
        raise CliError(f"The output folder {out_dir} does not exist.", EXIT_USAGE)
    tor = {"auto": None, "yes": True, "no": False}[args.exemplar_toroidal]
    ex = load_exemplar(args.exemplar, fit=args.fit, toroidal=tor)
    an = analyze(ex, AnalysisSettings(model=args.model, k=args.k), use_cache=not args.no_cache,
                 progress=_progress(args.quiet))
    jit = args.jitter
    if jit is None:
        params = SynthParams.default(an.L)
    elif len(jit) == 1:
        params = SynthParams(jitter=(jit[0],) * (an.L + 1))
    elif len(jit) == an.L + 1:
        params = SynthParams(jitter=tuple(jit))
    else:
        raise CliError(f"--jitter needs 1 value or {an.L + 1} (one per level of this "
                       f"{an.size}x{an.size} exemplar), not {len(jit)}.", EXIT_USAGE)
    try:
        params = replace(params, seed=args.seed, passes=args.passes, kappa=args.kappa)
        params.validate(an.L)
    except ValueError as exc:
        raise CliError(str(exc), EXIT_USAGE) from None
    synth = Synthesizer(an, params)
    t0 = time.perf_counter()
    coords = synth.toroidal(w) if args.toroidal else synth.window(Rect.of(args.origin[0], args.origin[1], w, h))
    dt = time.perf_counter() - t0
    colors = synth.colors(coords)
    img = to_u8(colors)
    mode = PIL_MODES[img.shape[2]]
    Image.fromarray(img[:, :, 0] if mode == "L" else img, mode=mode).save(args.output)
    if args.coords:
        np.save(args.coords, coords.astype(np.int32))
    if not args.quiet:
        sys.stderr.write(f"{args.output}: {w}x{h} from a {an.size}x{an.size} exemplar in {dt * 1000:.0f} ms"
                         f" ({synth.gpu.renderer})\n")
    return 0


def guarded(run, argv: list[str], input_errors: tuple = ()) -> int:
    """Run a command, turning every expected failure into one line on stderr
    and an exit code (never a traceback)."""
    from engine.analysis import AnalysisCancelled
    from engine.exemplar import ExemplarError
    from engine.gpu import GLUnavailable
    from engine.pyramid import SynthesisError
    try:
        return run(argv)
    except CliError as exc:
        sys.stderr.write(f"error: {exc}\n")
        return exc.code
    except (ExemplarError, SynthesisError, *input_errors) as exc:
        sys.stderr.write(f"error: {exc}\n")
        return EXIT_INPUT
    except GLUnavailable as exc:
        sys.stderr.write(f"error: {exc}\n")
        return EXIT_GL
    except (KeyboardInterrupt, AnalysisCancelled):
        sys.stderr.write("\ncancelled\n")
        return EXIT_CANCELLED
    except OSError as exc:
        sys.stderr.write(f"error: {exc.strerror or exc}: {exc.filename or ''}\n")
        return EXIT_INPUT


def main(argv: list[str]) -> int:
    return guarded(run_synth, argv)
