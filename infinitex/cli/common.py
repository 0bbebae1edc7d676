"""What the command line's subcommands share: exit codes, the one-line error
(:class:`CliError`, :func:`guarded`), argument types and checks, the
arguments of painted randomness, features, avoided regions and lattices, and
the progress bar.

Bad input gives a one-line message on stderr and a non-zero exit, never a
traceback: arguments (output names and extensions, sizes, ranges) are all
checked before any work, names are printed escaped on one line, and outputs
are written atomically. Long analyses show progress on stderr; Ctrl+C cancels.
"""
from __future__ import annotations

import argparse
import math
import os
import sys
import warnings
from dataclasses import replace

import numpy as np

from infinitex.engine.pyramid import COORD_LIMIT
from infinitex.engine.safeio import ReadError, WriteError, check_output, printable
from infinitex.engine.synth import MAX_WINDOW_PIXELS, MAX_WINDOW_SIDE

EXIT_USAGE = 2
EXIT_INPUT = 3
EXIT_GL = 4
EXIT_CANCELLED = 130


class CliError(Exception):
    def __init__(self, message: str, code: int = EXIT_INPUT):
        super().__init__(message)
        self.code = code


class Parser(argparse.ArgumentParser):
    """argparse whose errors are a CliError (one line, exit 2), not usage + exit."""

    def error(self, message: str):
        raise CliError(f"{message} (see {self.prog} --help)", EXIT_USAGE)


def jitter_arg(text: str) -> list[float]:
    try:
        vals = [float(v) for v in text.split(",") if v.strip() != ""]
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a number or a comma-separated list of numbers") from None
    if not vals or len(vals) > 16 or any(not 0.0 <= v <= 1.0 for v in vals):
        raise argparse.ArgumentTypeError("randomness values must be in [0, 1]")
    return vals


def structure_arg(text: str) -> int:
    """A Structure preset: its number (0 to 4) or its name (variety, light, balanced, strong, maximum)."""
    from infinitex.engine.params import structure_index
    try:
        return structure_index(text)
    except ValueError as e:
        raise argparse.ArgumentTypeError(str(e).rstrip(".")) from None


def add_make_tileable_arg(p: argparse.ArgumentParser) -> None:
    p.add_argument("--make-tileable", action="store_true",
                   help="a photo that does not wrap: re-synthesize its borders so it tiles (its interior kept; "
                        "shading evened out between opposite borders) instead of repeating its edges")


def add_structure_arg(p: argparse.ArgumentParser, default) -> None:
    from infinitex.engine.params import DEFAULT_STRUCTURE, STRUCTURE_NAMES
    names = ", ".join(f"{i} {n.lower()}" for i, n in enumerate(STRUCTURE_NAMES))
    p.add_argument("--fidelity", type=structure_arg, default=default, metavar="PRESET",
                   help=f"Structure / Variety: how hard the synthesis keeps the exemplar's elements whole ({names}; "
                        + (f"default {DEFAULT_STRUCTURE}, {STRUCTURE_NAMES[DEFAULT_STRUCTURE].lower()})"
                           if default is not None else "default: the project's own)"))


def passes_arg(text: str) -> list[int]:
    try:
        if len(text) > 64:
            raise ValueError
        vals = [int(v) for v in text.split(",") if v.strip() != ""]
    except ValueError:
        raise argparse.ArgumentTypeError(f"{printable(text, 40)!r} is not an integer or a comma-separated list "
                                         "of integers") from None
    if not vals or len(vals) > 16 or any(not 0 <= v <= 8 for v in vals):
        raise argparse.ArgumentTypeError("correction passes must be integers from 0 to 8")
    return vals


def integer(text: str) -> int:
    try:
        if len(text) > 24:
            raise ValueError
        return int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{printable(text, 40)!r} is not an integer") from None


def number(text: str) -> float:
    try:
        v = float(text)
    except ValueError:
        v = math.nan
    if not math.isfinite(v):
        raise argparse.ArgumentTypeError(f"{printable(text, 40)!r} is not a finite number")
    return v


def check_window(x: int, y: int, w: int, h: int, what: str, streamed: bool = False) -> None:
    """A canvas rectangle the engine can make in memory (before any work); a
    streamed (tiled) export may be up to 2^20 px a side."""
    if streamed:
        from infinitex.export import MAX_SIDE
        if not (1 <= w <= MAX_SIDE and 1 <= h <= MAX_SIDE):
            raise CliError(f"{what} must be between 1 and {MAX_SIDE} in each dimension, not {w}x{h}.", EXIT_USAGE)
    elif not (1 <= w <= MAX_WINDOW_SIDE and 1 <= h <= MAX_WINDOW_SIDE) or w * h > MAX_WINDOW_PIXELS:
        raise CliError(f"{what} must be between 1 and {MAX_WINDOW_SIDE} in each dimension and at most "
                       f"{MAX_WINDOW_PIXELS >> 20} Mpixels, not {w}x{h}.", EXIT_USAGE)
    if min(x, y) < -COORD_LIMIT or max(x + w, y + h) > COORD_LIMIT:
        raise CliError(f"Canvas positions must stay within +-{COORD_LIMIT}.", EXIT_USAGE)


def check_out(path: str, extensions: tuple[str, ...], what: str) -> None:
    """An output path the command can write (before any work); usage error if not."""
    try:
        check_output(path, extensions, what)
    except WriteError as exc:
        raise CliError(str(exc), EXIT_USAGE) from None


def check_toroidal(n: int, flag: str = "--toroidal") -> None:
    if n & (n - 1) or not 32 <= n <= 4096:
        raise CliError(f"{flag} needs a power-of-two size from 32 to 4096, not {n}.", EXIT_USAGE)


def add_lattice_args(p: argparse.ArgumentParser) -> None:
    g = p.add_argument_group("near-regular textures (bricks, tiles, weaves: LH05 4.5)")
    g.add_argument("--lattice", metavar="auto|none|OX,OY,T1X,T1Y,T2X,T2Y,NX,NY",
                   help="synthesize on the lattice: 'auto' detects it; or give the origin, the two "
                        "translation vectors (input-image pixels) and the block of NX x NY cells "
                        "(1, 2, 4, 8 or 16); 'none' synthesizes without one (and turns a project's off). "
                        "Without this option an image is searched for a lattice and synthesized on it when "
                        "one is found with confidence. The lattice used is printed on stdout as "
                        "'lattice: ...' (or 'lattice: none')")
    g.add_argument("--lattice-levels", type=integer, default=None, metavar="K",
                   help="number of coarse levels synthesized on the lattice (default: down to a quarter cell)")
    g.add_argument("--geometry", choices=("original", "rectified"), default=None,
                   help="with a lattice: the texture in the input's geometry (a slanted lattice stays "
                        "slanted; the default, or the project's choice) or rectified (cells axis-aligned, "
                        "as synthesized); toroidal tiles are always rectified")


def resolve_lattice(spec: str | None, image: np.ndarray, levels: int | None):
    """The lattice a --lattice argument names for ``image`` (input pixels),
    printed on stdout as one line; None for 'none' or when 'auto' finds none."""
    from infinitex.engine.controls.lattice import Lattice, LatticeError
    from infinitex.engine.controls.lattice_cache import find_lattice
    if spec is None:
        return None
    H, W = image.shape[:2]
    if spec.strip().lower() == "none":
        lat = None
    elif spec.strip().lower() == "auto":
        lat = find_lattice(image).lattice
    else:
        try:
            lat = Lattice.parse(spec)
        except LatticeError as exc:
            raise CliError(f"--lattice: {exc}", EXIT_USAGE) from None
    if lat is not None:
        if levels is not None:
            lat = replace(lat, levels=levels)
        try:
            lat.validate(W, H)
        except LatticeError as exc:
            raise CliError(f"--lattice: {exc}", EXIT_INPUT) from None
    sys.stdout.write(f"lattice: {lat.to_text() if lat else 'none'}\n")
    sys.stdout.flush()
    return lat


def finds_lattice(args) -> bool:
    """Whether synth looks for a lattice without being asked (no --lattice):
    a single image whose other options all go with a lattice (not a palette,
    labels, a direction map, Make tileable, a toroidal setting for the
    exemplar, maps or features placed in the exemplar's pixels, the
    random-walk search, or coordinates in the original geometry)."""
    if getattr(args, "lattice", None) is not None:
        return False
    off = (getattr(args, name, None) for name in (
        "palette", "labels_exemplar", "labels_canvas", "direction_map", "make_tileable",
        "randomness_exemplar", "avoid_exemplar", "features"))
    if any(off) or getattr(args, "exemplar_toroidal", "auto") != "auto" or getattr(args, "k", 2) == 0:
        return False
    return not (getattr(args, "coords", None) and args.geometry != "rectified" and not args.toroidal)


def keep_found_lattice(lattice, found, m: int, whole: int, quiet: bool, verb: str) -> bool:
    """Whether a lattice found without being asked is used for an m x m
    rectified exemplar: not when ``whole`` (a toroidal tile's or a tile set's
    size, 0 for none) is no whole number of its cells. Says which on stdout
    (the ``lattice: ...`` line) and stderr (a note, unless ``quiet``)."""
    cx, cy = lattice.cell(m)
    if whole and (whole % cx or whole % cy):
        if not quiet:
            sys.stderr.write(f"note: the exemplar shows a lattice, but its cells ({cx}x{cy} px rectified) "
                             f"do not divide {whole}: {verb} without it\n")
        return False
    sys.stdout.write(f"lattice: {lattice.to_text()}\n")
    if not quiet:
        sys.stderr.write(f"note: a lattice was found in the exemplar (cells {lattice.describe()}, confidence "
                         f"{found.confidence:.2f}): rows and columns stay straight; --lattice none turns it off\n")
    return True


def check_lattice_args(args) -> None:
    if args.lattice_levels is not None and not 0 <= args.lattice_levels <= 10:
        raise CliError("--lattice-levels must be between 0 and 10.", EXIT_USAGE)
    if args.lattice_levels is not None and not args.lattice:
        raise CliError("--lattice-levels needs --lattice.", EXIT_USAGE)


def add_randomness_args(p: argparse.ArgumentParser) -> None:
    g = p.add_argument_group("painted randomness (grayscale maps: 8-bit M = value/128, 16-bit M = value/32768; "
                             "0 calm, 1 neutral, 2 rough)")
    g.add_argument("--randomness-exemplar", metavar="MAP", help="a map over the exemplar (its size, or brought "
                   "to it by the exemplar's fit rule)")
    g.add_argument("--randomness-canvas", metavar="MAP", help="a map over the canvas (finest-level pixels), "
                   "placed by --randomness-origin; unpainted elsewhere")
    g.add_argument("--randomness-origin", nargs=2, type=integer, default=[0, 0], metavar=("X", "Y"),
                   help="canvas position of the canvas map's top-left pixel (default 0 0)")
    p.add_argument("--avoid-exemplar", metavar="MASK",
                   help="exemplar regions not to copy: a grayscale mask over the exemplar (its size, or brought to "
                        "it by the fit rule), white (at least half intensity) = avoid")
    p.add_argument("--features", metavar="FEATURES.json",
                   help='placed features: a JSON list of {"exemplar": [ux, uy], "canvas": [px, py], '
                        '"radius": [inner, outer], "levels": [first, last] (optional)}')


def add_label_args(p: argparse.ArgumentParser) -> None:
    g = p.add_argument_group("texture by numbers (label maps: each distinct color is a label, pure black too; "
                             "the same color means the same label in both maps)")
    g.add_argument("--labels-exemplar", metavar="MAP", help="the exemplar's label map (its size, brought to the "
                   "exemplar by its fit rule; at most 16 colors; an indexed PNG or flat colors)")
    g.add_argument("--labels-canvas", metavar="MAP", help="where each label goes on the canvas (finest-level "
                   "pixels), placed by --labels-origin; transparent pixels and everything around it are free")
    g.add_argument("--labels-origin", nargs=2, type=integer, default=[0, 0], metavar=("X", "Y"),
                   help="canvas position of the canvas label map's top-left pixel (default 0 0)")
    g.add_argument("--label-strength", type=number, default=None, metavar="S",
                   help="how strongly the synthesis follows the labels (0 to 8; default 1; more at coarse scales)")
    g.add_argument("--palette", type=palette_arg, default=None, metavar="B,C,...",
                   help="more exemplars (or materials, by their first map) after the first, comma-separated: "
                        "each is one label, in order (the first exemplar label 1, colored #e6194b; then #3cb44b, "
                        "#ffe119, #0082c8, ...: docs/controls.md); a --labels-canvas map uses those colors")


def add_direction_args(p: argparse.ArgumentParser) -> None:
    g = p.add_argument_group("direction field (the texture turns, grows and stretches where a map says; "
                             "docs/controls.md#direction-fields)")
    g.add_argument("--direction-map", metavar="MAP", help="a flow map (red, green in [0, 1], mid-gray = leave as "
                   "is) or an angle map (grayscale, 0..1 = 0..360 degrees clockwise from +x) over the canvas "
                   "(finest-level pixels), placed by --direction-origin; the exemplar's +x runs along it")
    g.add_argument("--direction-origin", nargs=2, type=integer, default=[0, 0], metavar=("X", "Y"),
                   help="canvas position of the direction map's top-left pixel (default 0 0)")
    g.add_argument("--direction-kind", choices=("auto", "flow", "angle"), default="auto",
                   help="how the map is read (default auto: grayscale = angle, color = flow)")
    g.add_argument("--flow-y", choices=("up", "down"), default="up",
                   help="where a flow map's green points: up (OpenGL, the default) or down (DirectX)")
    g.add_argument("--direction-scale", type=number, default=1.0, metavar="S",
                   help="how much larger the texture shows where the map gives a direction (0.25 to 4; default 1)")
    g.add_argument("--direction-aspect", type=number, default=1.0, metavar="A",
                   help="stretched A times along the direction and 1/A across (default 1)")


def direction_field(args, base=None):
    """The DirectionField of --direction-map (replacing ``base``), or ``base``."""
    from infinitex.engine.controls.direction import DirectionField, jacobian
    from infinitex.engine.controls.maps import load_direction_map
    if not getattr(args, "direction_map", None):
        return base
    try:
        jacobian(0.0, args.direction_scale, args.direction_aspect)
    except ValueError as exc:
        raise CliError(str(exc), EXIT_USAGE) from None
    values = load_direction_map(args.direction_map, args.direction_kind, args.flow_y == "up",
                                args.direction_scale, args.direction_aspect)
    x, y = args.direction_origin
    if min(x, y) < -COORD_LIMIT or max(x + values.shape[1], y + values.shape[0]) > COORD_LIMIT:
        raise CliError(f"The direction map must lie within +-{COORD_LIMIT}.", EXIT_USAGE)
    return DirectionField.from_jacobians(values, x, y)


def palette_arg(text: str) -> list[str]:
    paths = [p for p in text.split(",") if p.strip()]
    if not 1 <= len(paths) <= 15:
        raise argparse.ArgumentTypeError("a palette adds 1 to 15 exemplars, comma-separated")
    return paths


def palette_document(args, doc, quiet: bool = True):
    """``doc`` (its exemplar or material first) with the --palette files as
    more labels; a file named like a material's map brings its siblings."""
    from infinitex.engine.material import IMAGE, MATERIAL_BUDGET, MaterialError, assign_roles
    from infinitex.engine.palette import check_palette_budget, file_heads
    from infinitex.engine.safeio import ReadError
    from infinitex.project.document import ExemplarSource
    if args.labels_exemplar:
        raise CliError("--palette makes each exemplar a label; it does not go with --labels-exemplar.", EXIT_USAGE)
    entries = [doc.sources()]
    try:
        # The files together within a material's budget, before any is read: their sizes, then their
        # decodes from their first bytes (a palette of huge images is refused having read a few MB).
        total = sum(len(src.data) for _, src in entries[0])
        founds = []
        for path in args.palette:
            found = assign_roles([path])
            total += sum(os.stat(p).st_size for p in found.values() if os.path.isfile(p))
            if total > MATERIAL_BUDGET:
                raise CliError(f"The palette's files come to {total // 2**20} MB, more than the "
                               f"{MATERIAL_BUDGET // 2**20} MB it may import; use fewer or smaller ones.", EXIT_INPUT)
            if (IMAGE in found) != (doc.sources()[0][0] == IMAGE):
                raise CliError(f"{printable(os.path.basename(path))} and the first exemplar are not both single "
                               "images or both materials; a palette's exemplars have the same maps.", EXIT_USAGE)
            founds.append(found)
        heads = [file_heads(list(found.values())) for found in founds]
        sizes = {name: size for _, s in heads for name, size in s.items()}
        check_palette_budget([[(src.name, src.data) for _, src in entries[0]]] + [h for h, _ in heads],
                             doc.fit, sizes)
        for found in founds:
            entries.append(tuple((role, ExemplarSource.from_file(p)) for role, p in found.items()))
    except (ReadError, MaterialError) as exc:
        raise CliError(str(exc), EXIT_INPUT) from None
    if not quiet:
        sys.stderr.write("palette: " + ", ".join(f"label {i + 1} {printable(e[0][1].name)}"
                                                 for i, e in enumerate(entries)) + "\n")
    return doc.with_palette(entries)


def label_maps(args, original: tuple[int, int], fit: str, m: int, base=None):
    """The document's LabelMaps from the label arguments (``base``: the
    project's, whose canvas labels, colors and names a new exemplar map keeps
    when it has the same colors), or ``base``."""
    from infinitex.engine.controls import CanvasLabels, ExemplarLabels
    from infinitex.engine.controls.label_maps import (
        canvas_labels_from_colors,
        exemplar_labels_from_colors,
        fit_label_map,
        load_label_image,
    )
    from infinitex.project.document import LabelMaps
    if args.label_strength is not None and not 0.0 <= args.label_strength <= 8.0:
        raise CliError("--label-strength must be between 0 and 8.", EXIT_USAGE)
    if args.labels_canvas and not (args.labels_exemplar or base is not None):
        raise CliError("--labels-canvas needs --labels-exemplar (which colors are which labels).", EXIT_USAGE)
    lab = base
    if args.labels_exemplar:
        ids, colors = exemplar_labels_from_colors(load_label_image(args.labels_exemplar, "exemplar label map"))
        ids = fit_label_map(ids, fit, m, original, "exemplar label map")
        keep = base is not None and list(base.colors) == colors
        lab = LabelMaps(ExemplarLabels(ids), tuple(colors), base.names if keep else (),
                        base.canvas if keep else CanvasLabels())
    if lab is None:
        return None
    if args.labels_canvas:
        values = canvas_labels_from_colors(load_label_image(args.labels_canvas, "canvas label map"), list(lab.colors))
        x, y = args.labels_origin
        if min(x, y) < -COORD_LIMIT or max(x + values.shape[1], y + values.shape[0]) > COORD_LIMIT:
            raise CliError(f"The canvas label map must lie within +-{COORD_LIMIT}.", EXIT_USAGE)
        lab = replace(lab, canvas=CanvasLabels.from_image(values, x, y))
    if args.label_strength is not None:
        lab = replace(lab, strength=float(args.label_strength))
    return lab


def load_features(path: str):
    """Features from a JSON file (untrusted: size-limited, bounded parse); CliError if bad."""
    from infinitex.engine.controls import features_from_json
    from infinitex.engine.safeio import ReadError, parse_json, read_limited
    try:
        raw = read_limited(path, 16 * 2 ** 20, "features file")
        return features_from_json(parse_json(raw, max_depth=4))
    except ReadError as exc:
        raise CliError(str(exc), EXIT_INPUT) from None
    except ValueError as exc:
        raise CliError(f"The features file {printable(path)} is not usable: {printable(exc, 200)}", EXIT_INPUT) from None


def randomness_controls(args, fit: str, m: int, base=None):
    """Controls from the map arguments (each map replaces the same field of ``base``)."""
    from infinitex.engine.controls import (
        NEUTRAL,
        NO_CONTROLS,
        CanvasField,
        Controls,
        ExemplarField,
        ExemplarMask,
        fit_features,
    )
    from infinitex.engine.controls.maps import fit_field_map, load_field_map
    base = base or NO_CONTROLS
    e, c, feats, avoid = base.randomness_exemplar, base.randomness_canvas, base.features, base.avoid
    if args.randomness_exemplar:
        e = ExemplarField(fit_field_map(load_field_map(args.randomness_exemplar, "exemplar randomness map"), fit, m))
    if args.randomness_canvas:
        values = load_field_map(args.randomness_canvas, "canvas randomness map")
        x, y = args.randomness_origin
        if min(x, y) < -COORD_LIMIT or max(x + values.shape[1], y + values.shape[0]) > COORD_LIMIT:
            raise CliError(f"The canvas randomness map must lie within +-{COORD_LIMIT}.", EXIT_USAGE)
        c = CanvasField.from_image(values, x, y)
    if getattr(args, "features", None):
        feats = fit_features(load_features(args.features), m)
    if getattr(args, "avoid_exemplar", None):
        mask = fit_field_map(load_field_map(args.avoid_exemplar, "avoid mask"), fit, m) >= NEUTRAL
        if mask.all():
            raise CliError("The avoid mask covers the whole exemplar: leave some of it usable (black).", EXIT_USAGE)
        avoid = ExemplarMask(mask.astype(np.uint8))
    return Controls(e, c, feats, base.lattice, avoid).normalized()


def source_document(source: str, allow_outside: bool = False, outside_hint: str = ""):
    """(the Document, the files it reads) of a command's source: an .itex project,
    or an exemplar image or material (one map, its siblings coming along, or its
    folder) with default settings; read errors are a CliError."""
    from infinitex.engine.material import IMAGE, assign_roles
    from infinitex.project import Document, ExemplarOutside, ExemplarSource, is_project_file, load_project
    if is_project_file(source):
        try:
            proj = load_project(source, allow_outside=allow_outside)
        except ExemplarOutside as exc:
            raise CliError(f"{exc}{outside_hint}", EXIT_INPUT) from None
        return proj.document, [source, *proj.document.input_paths()]
    try:
        found = assign_roles([source])
        maps = [(role, ExemplarSource.from_file(p)) for role, p in found.items()]
    except ReadError as exc:
        raise CliError(str(exc), EXIT_INPUT) from None
    doc = Document(maps[0][1])
    return (doc if list(found) == [IMAGE] else doc.with_maps(maps)), list(found.values())


class ProgressBar:
    """A progress bar on stderr (tqdm: percent, elapsed, time left, the current
    step), or nothing when ``quiet``. Call it with a fraction in [0, 1] (and a
    message); it closes itself at 1."""

    def __init__(self, what: str, quiet: bool):
        self.bar = None
        if not quiet:
            from tqdm import tqdm
            self.bar = tqdm(total=1000, desc=what, file=sys.stderr, mininterval=0.25, dynamic_ncols=True,
                            bar_format="{desc} {percentage:3.0f}%|{bar}| {elapsed}<{remaining}{postfix}")

    def __call__(self, fraction: float, message: str = "") -> None:
        bar = self.bar
        if bar is None:
            return
        n = int(round(1000 * min(1.0, max(0.0, fraction))))
        if message:
            bar.set_postfix_str(message[:40], refresh=False)
        bar.update(max(0, n - bar.n))  # (also with no new progress: the elapsed time moves on screen)
        if fraction >= 1.0:
            bar.close()
            self.bar = None


def analysis_progress(quiet: bool, ex, settings, use_cache: bool = True) -> ProgressBar:
    """The analysis's progress bar, its label saying what the analysis does
    (a first run builds similarity sets and caches them)."""
    from infinitex.engine.analysis import describe_analysis
    return ProgressBar(describe_analysis(ex, settings, use_cache=use_cache), quiet)


DECODER_LOGGERS = ("tifffile", "imagecodecs")


def quiet_decoder_logs() -> None:
    """Silence what decoders log about a damaged file (tifffile logs a line
    per bad tag through ``logging``, up to dozens before the error it raises):
    the command's one-line error says what matters, with or without -q."""
    import logging
    for name in DECODER_LOGGERS:
        log = logging.getLogger(name)
        log.handlers[:] = [logging.NullHandler()]
        log.propagate = False
        log.setLevel(logging.CRITICAL + 1)


def guarded(run, argv: list[str], input_errors: tuple = ()) -> int:
    """Run a command, turning every expected failure into one line on stderr
    and an exit code (never a traceback)."""
    from infinitex.engine.analysis import AnalysisCancelled
    from infinitex.engine.controls.lattice import LatticeError
    from infinitex.engine.exemplar import ExemplarError
    from infinitex.engine.gpu import GLUnavailable
    from infinitex.engine.material import MaterialError
    from infinitex.engine.pyramid import SynthesisError
    from infinitex.engine.surface import AtlasError, ModelError
    from infinitex.export import ExportFailed
    from infinitex.project import ProjectError
    # One path for every command: what any of them may refuse (a project, a
    # lattice, a material, a model) is one line whichever command reads it.
    input_errors = (ProjectError, LatticeError, MaterialError, ModelError, AtlasError, ExportFailed, *input_errors)
    # Decoders' warnings about damaged files (Pillow) would add lines of their
    # own; the one-line error says what matters.
    warnings.filterwarnings("ignore", module=r"PIL(\.|$)")
    quiet_decoder_logs()

    def fail(message: object, code: int) -> int:
        sys.stderr.write(f"error: {printable(message, 1000)}\n")
        return code
    try:
        return run(argv)
    except CliError as exc:
        return fail(exc, exc.code)
    except (ExemplarError, SynthesisError, WriteError, *input_errors) as exc:
        return fail(exc, EXIT_INPUT)
    except GLUnavailable as exc:
        return fail(exc, EXIT_GL)
    except (KeyboardInterrupt, AnalysisCancelled):
        sys.stderr.write("\ncancelled\n")
        return EXIT_CANCELLED
    except MemoryError:
        return fail("not enough memory", EXIT_INPUT)
    except OSError as exc:
        return fail(f"{exc.strerror or exc}: {exc.filename or ''}", EXIT_INPUT)


