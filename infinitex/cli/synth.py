"""``infinitex synth EXEMPLAR -o OUT.png ...``: a window (or a toroidal tile)
of an exemplar's infinite texture, headless.

Bad input gives a one-line message on stderr and a non-zero exit, never a
traceback: arguments (output names and extensions, sizes, ranges) are all
checked before any work, names are printed escaped on one line, and outputs
are written atomically. Long analyses show progress on stderr; Ctrl+C cancels.
"""
from __future__ import annotations

import argparse
import os
import sys
import time
from dataclasses import replace

import numpy as np

from infinitex.engine.exemplar import FIT_MODES
from infinitex.engine.params import DEFAULT_STRUCTURE, structure_params
from infinitex.engine.safeio import ReadError, atomic_write, printable
from infinitex.engine.synth import MAX_WINDOW_PIXELS, MAX_WINDOW_SIDE

from .common import (
    EXIT_INPUT,
    EXIT_USAGE,
    CliError,
    Parser,
    add_lattice_args,
    add_direction_args,
    add_label_args,
    add_randomness_args,
    add_make_tileable_arg,
    add_structure_arg,
    analysis_progress,
    check_lattice_args,
    check_out,
    check_window,
    direction_field,
    guarded,
    integer,
    label_maps,
    jitter_arg,
    number,
    palette_document,
    passes_arg,
    randomness_controls,
    finds_lattice,
    keep_found_lattice,
    resolve_lattice,
)


def build_parser() -> argparse.ArgumentParser:
    p = Parser(prog="infinitex synth",
                                description="Synthesize a window of the infinite texture of an exemplar.")
    p.add_argument("exemplar", help="exemplar image (PNG, JPEG, BMP, TIFF, WebP...)")
    p.add_argument("-o", "--output", required=True, help="output PNG (.png)")
    p.add_argument("--size", nargs=2, type=integer, default=[256, 256], metavar=("W", "H"),
                   help=f"output size, at most {MAX_WINDOW_SIDE} a side and {MAX_WINDOW_PIXELS >> 20} Mpixels")
    p.add_argument("--origin", nargs=2, type=integer, default=[0, 0], metavar=("X", "Y"),
                   help="canvas position of the top-left pixel (any 32-bit integers)")
    p.add_argument("--seed", type=integer, default=0)
    p.add_argument("--jitter", type=jitter_arg, default=None, metavar="R|r0,r1,...",
                   help="randomness: one value for every level, or one per level (coarse to fine)")
    p.add_argument("--toroidal", action="store_true", help="make a W x W texture that tiles seamlessly")
    p.add_argument("--coords", metavar="OUT.npy", help="save the (H, W, 2) int32 exemplar (x, y) map")
    p.add_argument("--model", choices=("appearance", "color"), default="appearance",
                   help="neighborhood model: appearance space (LH06) or 5x5 colors (LH05)")
    p.add_argument("--k", type=int, default=2, choices=(0, 1, 2, 3, 4),
                   help="similarity-set size; 0: none, TBN10 random-walk search (always so over 512 px)")
    p.add_argument("--feature-weight", type=number, default=0.0, metavar="W",
                   help="LH06 feature-distance channel from the exemplar's own elements (0 to 4; default 0: off)")
    p.add_argument("--passes", type=passes_arg, default=[2], metavar="C|c0,c1,...",
                   help="correction passes (0 to 8): one value for every corrected level (all but the 3 "
                        "coarsest), or one per level, coarse to fine (0: that level is not corrected)")
    p.add_argument("--kappa", type=number, default=0.5, help="coherence penalty (0 to 4)")
    p.add_argument("--walk", type=integer, default=None, metavar="N",
                   help="TBN10 random-walk steps added to each correction (0 to 12; default: 6 when the "
                        "analysis has no similarity sets, --k 0 or an exemplar over 512 px, else 0)")
    add_structure_arg(p, DEFAULT_STRUCTURE)
    p.add_argument("--fit", choices=FIT_MODES, default="resize",
                   help="how a non power-of-two or non-square image becomes the exemplar: resize or crop to at "
                        "most 512 px, or with -2048 to at most 2048 px (large photos)")
    p.add_argument("--exemplar-toroidal", choices=("auto", "yes", "no"), default="auto",
                   help="does the exemplar tile? (auto: guessed from its wrap-around seam)")
    add_make_tileable_arg(p)
    add_randomness_args(p)
    add_label_args(p)
    add_direction_args(p)
    add_lattice_args(p)
    p.add_argument("--no-cache", action="store_true", help="do not read or write the analysis cache")
    p.add_argument("-q", "--quiet", action="store_true")
    return p


def run_synth(argv: list[str]) -> int:
    args = build_parser().parse_args(argv)
    from infinitex.engine.analysis import AnalysisSettings, analyze
    from infinitex.engine.exemplar import load_exemplar
    from infinitex.engine.imagefile import to_u8, write_png
    from infinitex.engine.params import SynthParams
    from infinitex.engine.pyramid import Rect
    from infinitex.engine.synth import Synthesizer

    # Everything the arguments decide is checked before any work.
    w, h = args.size
    check_window(args.origin[0], args.origin[1], w, h, "--size")
    if args.toroidal and (w != h or w & (w - 1) or not 32 <= w <= 4096):
        raise CliError(f"--toroidal needs a square power-of-two --size from 32 to 4096, not {w}x{h}.", EXIT_USAGE)
    try:
        SynthParams(jitter=(0.0,), seed=args.seed, passes=args.passes[0], kappa=args.kappa,
                    walk=args.walk).validate(0)
        AnalysisSettings(model=args.model, k=args.k, feature_weight=args.feature_weight).validate()
    except ValueError as exc:
        raise CliError(str(exc), EXIT_USAGE) from None
    check_out(args.output, (".png",), "output image")
    if args.coords:
        check_out(args.coords, (".npy",), "coordinate map")
        if os.path.realpath(args.coords) == os.path.realpath(args.output):
            raise CliError("--coords and -o name the same file.", EXIT_USAGE)
    from infinitex.export.window import OwnInputError, Writes, check_own_inputs
    try:  # no output may replace a file this run reads
        check_own_inputs(Writes(files=[p for p in (args.output, args.coords) if p]),
                         [args.exemplar, args.randomness_exemplar, args.randomness_canvas, args.avoid_exemplar,
                          args.labels_exemplar, args.labels_canvas,
                          args.features, args.direction_map, *(args.palette or [])])
    except OwnInputError as exc:
        raise CliError(str(exc), EXIT_USAGE) from None
    check_lattice_args(args)
    asked = args.lattice is not None and args.lattice.strip().lower() != "none"
    if args.coords and asked and args.geometry != "rectified" and not args.toroidal:
        raise CliError("--coords needs --geometry rectified: in the original geometry each pixel blends "
                       "four synthesized texels.", EXIT_USAGE)
    if args.make_tileable and (asked or args.exemplar_toroidal != "auto"):
        raise CliError("--make-tileable goes with neither --lattice (a lattice's block already tiles) nor "
                       "--exemplar-toroidal (the result tiles).", EXIT_USAGE)
    tor = {"auto": None, "yes": True, "no": False}[args.exemplar_toroidal]
    lattice = image = None
    found = None  # the lattice found without being asked for (regular textures right by default)
    if asked:
        from infinitex.engine.controls.lattice import rectified_exemplar
        from infinitex.engine.exemplar import load_full
        image = load_full(args.exemplar)
        lattice = resolve_lattice(args.lattice, image, args.lattice_levels)
    elif args.lattice:  # --lattice none: nothing to decode whole
        sys.stdout.write("lattice: none\n")
    elif finds_lattice(args):
        from infinitex.engine.controls.lattice import rectified_exemplar
        from infinitex.engine.controls.lattice_cache import find_lattice
        from infinitex.engine.exemplar import ExemplarError, load_full
        try:  # an image too large to search whole is synthesized without a lattice
            image = load_full(args.exemplar)
        except ExemplarError:
            image = None  # (a file that cannot be read at all says so below)
        if image is not None:
            found = find_lattice(image, use_cache=not args.no_cache)
            lattice = found.lattice
    palette = None
    if args.palette:
        if lattice is not None or args.make_tileable:
            raise CliError("--palette goes with neither --lattice nor --make-tileable.", EXIT_USAGE)
        from infinitex.project.document import Document, ExemplarSource
        from infinitex.project.realize import exemplar_for
        try:
            first = Document(ExemplarSource.from_file(args.exemplar), fit=args.fit, toroidal=tor)
        except ReadError as exc:
            raise CliError(str(exc), EXIT_INPUT) from None
        doc = palette_document(args, first, args.quiet)
        ex = exemplar_for(doc)[0]
        palette = replace(doc.labels, exemplar=doc.labels.exemplar.scaled(ex.size))
    elif lattice is not None:
        ex = rectified_exemplar(image, lattice, source=args.exemplar)
        if found is not None and not keep_found_lattice(lattice, found, ex.size, w if args.toroidal else 0,
                                                        args.quiet, "synthesized"):
            lattice = None
    if lattice is None and palette is None:
        ex = load_exemplar(args.exemplar, fit=args.fit, toroidal=tor)
        from infinitex.engine.tileable import recommended, tileable_exemplar
        if args.make_tileable:
            ex = tileable_exemplar(ex)
        elif tor is None and not args.quiet and recommended(ex):
            sys.stderr.write(f"note: {printable(os.path.basename(args.exemplar))} does not tile and its lighting "
                             "varies; --make-tileable evens out the patches it would repeat\n")
    del image
    jit, L = args.jitter, ex.levels
    if jit is None:
        params = SynthParams.default(L)
    elif len(jit) == 1:
        params = SynthParams(jitter=(jit[0],) * (L + 1))
    elif len(jit) == L + 1:
        params = SynthParams(jitter=tuple(jit))
    else:
        raise CliError(f"--jitter needs 1 value or {L + 1} (one per level of this "
                       f"{ex.size}x{ex.size} exemplar), not {len(jit)}.", EXIT_USAGE)
    if len(args.passes) not in (1, L + 1):
        raise CliError(f"--passes needs 1 value or {L + 1} (one per level of this "
                       f"{ex.size}x{ex.size} exemplar), not {len(args.passes)}.", EXIT_USAGE)
    level_passes = tuple(args.passes) if len(args.passes) > 1 else None
    controls = randomness_controls(args, args.fit, ex.size)  # maps are read before the analysis
    labels = label_maps(args, ex.original_size, args.fit, ex.size, palette)
    if labels is not None:
        if lattice is not None or args.make_tileable:
            raise CliError("Texture by numbers goes with neither --lattice nor --make-tileable.", EXIT_USAGE)
        # With a palette, what is not painted is the first exemplar's (as Document.controls says).
        canvas = replace(labels.canvas, background=1) if palette is not None else labels.canvas
        controls = replace(controls, labels_exemplar=labels.exemplar, labels_canvas=canvas,
                           label_strength=labels.strength)
        try:
            controls.validate(ex.size)
        except ValueError as exc:
            raise CliError(str(exc), EXIT_USAGE) from None
    direction = direction_field(args)
    if direction is not None:
        if lattice is not None:
            raise CliError("--direction-map does not go with --lattice.", EXIT_USAGE)
        controls = replace(controls, direction=direction)
    grid = (0, 0)
    if lattice is not None:
        controls = replace(controls, lattice=lattice)
        grid = (lattice.nx, lattice.ny)
        cx, cy = lattice.cell(ex.size)
        if args.toroidal and (w % cx or w % cy):
            raise CliError(f"A toroidal tile of whole cells needs a size that the cell ({cx}x{cy} exemplar "
                           f"px) divides; use --size {max(cx, cy, 32)} or more.", EXIT_USAGE)
    settings = AnalysisSettings(model=args.model, k=args.k, lattice=grid, feature_weight=args.feature_weight)
    try:
        settings.validate()
    except ValueError as exc:
        raise CliError(str(exc), EXIT_USAGE) from None
    an = analyze(ex, settings, use_cache=not args.no_cache,
                 progress=analysis_progress(args.quiet, ex, settings, use_cache=not args.no_cache))
    try:
        params = structure_params(replace(params, seed=args.seed, passes=args.passes[0], level_passes=level_passes,
                                          kappa=args.kappa, walk=args.walk), args.fidelity)
        params.validate(an.L)
    except ValueError as exc:
        raise CliError(str(exc), EXIT_USAGE) from None
    synth = Synthesizer(an, params, controls=controls)
    original = lattice is not None and args.geometry != "rectified" and not args.toroidal
    try:
        renderer = synth.gpu.renderer
        t0 = time.perf_counter()
        if args.toroidal:
            coords = synth.toroidal(w)
        elif original:
            from infinitex.engine.controls.lattice import original_geometry_box
            box = original_geometry_box(lattice, an.size, args.origin[0], args.origin[1], w, h)
            bw, bh = box[2] - box[0], box[3] - box[1]
            check_window(box[0], box[1], bw, bh, "--size (in the rectified geometry)")
            coords = synth.window(Rect(*box))
        else:
            coords = synth.window(Rect.of(args.origin[0], args.origin[1], w, h))
        dt = time.perf_counter() - t0
    finally:
        synth.release()
    if original:
        from infinitex.engine.controls.lattice import render_original
        source = ex.hires if ex.hires is not None else ex.pixels
        pixels = render_original(coords, box, lattice, an.size, source, args.origin[0], args.origin[1], w, h)
        write_png(args.output, to_u8(pixels))
    else:
        write_png(args.output, to_u8(synth.colors(coords)))
    if args.coords:
        c = coords.astype(np.int32)
        atomic_write(args.coords, writer=lambda f: np.save(f, c))
    if not args.quiet:
        sys.stderr.write(f"{printable(args.output)}: {w}x{h} from a {an.size}x{an.size} exemplar in "
                         f"{dt * 1000:.0f} ms ({renderer})\n")
    return 0


def main(argv: list[str]) -> int:
    from infinitex.engine.controls.lattice import LatticeError
    return guarded(run_synth, argv, (LatticeError,))
