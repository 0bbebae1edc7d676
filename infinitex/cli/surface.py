"""``infinitex surface MODEL SOURCE -o OUT.glb --size 4096``: texture a model.

Synthesis runs directly in the model's texture atlas, continuous across its UV
seams (LH06 section 6; engine/surface). SOURCE is an exemplar image, one map
of a material (its siblings come with it), or an .itex project (its exemplar,
material and settings). Writes every map beside OUT (OUT_basecolor.png...) and,
for a .glb OUT, the model with them attached. Every argument is checked before
any work; progress on stderr; Ctrl+C cancels.
"""
from __future__ import annotations

import os
import sys
import time
from dataclasses import replace

from infinitex.engine.safeio import printable

from .common import (
    EXIT_INPUT,
    EXIT_USAGE,
    CliError,
    Parser,
    ProgressBar,
    add_structure_arg,
    analysis_progress,
    check_out,
    guarded,
    integer,
    number,
    source_document,
)


def build_parser() -> Parser:
    p = Parser(prog="infinitex surface",
               description="Texture a model: synthesize in its texture atlas, seamless across UV seams.")
    p.add_argument("model", help="the model: OBJ, glTF or GLB with texture coordinates (UVs)")
    p.add_argument("source", help="an exemplar image, one map of a material (wood_basecolor.png brings "
                   "wood_normal.png...), a material's folder, or an .itex project")
    p.add_argument("-o", "--output", required=True,
                   help="OUT.glb: the model with its new textures plus every map beside it (OUT_basecolor.png...); "
                        "OUT.png: the maps only")
    p.add_argument("--size", type=integer, default=2048, metavar="N",
                   help="texture size (a power of two, 64 to 8192; over 4096 synthesis is magnified; default 2048)")
    scale = p.add_mutually_exclusive_group()
    scale.add_argument("--repeats", type=number, default=None, metavar="R",
                       help="the exemplar's width fits R times across the model's largest side")
    scale.add_argument("--texel-ratio", type=number, default=None, metavar="T",
                       help="exemplar pixels per texture texel, typically (0.25 to 4; default 1: as much of the "
                            "exemplar as the texture size shows)")
    p.add_argument("--frame", choices=("up", "uv"), default=None,
                   help="which way the texture runs: up (its top towards the model's up, bricks stay level; "
                        "default, or a project's own) or uv (its x along the model's u direction)")
    p.add_argument("--up", nargs=3, type=number, default=None, metavar=("X", "Y", "Z"),
                   help="the model's up direction (default 0 1 0, glTF's, or a project's own)")
    p.add_argument("--seed", type=integer, default=None, help="random seed (default: the project's, else 0)")
    add_structure_arg(p, None)
    p.add_argument("--maps", default=None, metavar="ROLES",
                   help="the maps of a material to write, comma-separated (default all)")
    p.add_argument("--depth", type=int, choices=(8, 16, 32), default=None,
                   help="bits per channel of the maps written (default: each map's own; 32 is float TIFF); "
                        "the GLB's textures are 8-bit PNG")
    p.add_argument("--unwrap", action="store_true",
                   help="a model without texture coordinates gets new ones (xatlas)")
    p.add_argument("--no-seams", action="store_true",
                   help="synthesize each chart on its own (no reads across seams): for comparison")
    p.add_argument("--coords", metavar="OUT.npy", help="save the (N, N, 4) int32 exemplar coordinates "
                   "(x, y, remainder x, remainder y in 1/256 px) of the synthesized atlas")
    p.add_argument("-q", "--quiet", action="store_true")
    return p


def run_surface(argv: list[str]) -> int:
    args = build_parser().parse_args(argv)
    from infinitex.engine.surface.mesh import MODEL_SUFFIXES
    from infinitex.export.surface import MAX_OUTPUT
    out = args.output
    ext = os.path.splitext(out)[1].lower()
    if ext not in (".glb", ".png", ".tif", ".tiff"):
        raise CliError("-o names a .glb (the model with its textures) or a .png (the maps only).", EXIT_USAGE)
    check_out(out, (".glb", ".png", ".tif", ".tiff"), "output")
    n = args.size
    if n & (n - 1) or not 64 <= n <= MAX_OUTPUT:
        raise CliError(f"--size must be a power of two from 64 to {MAX_OUTPUT}, not {n}.", EXIT_USAGE)
    if not str(args.model).lower().endswith(MODEL_SUFFIXES):
        raise CliError("The model must be an OBJ, glTF or GLB file.", EXIT_USAGE)
    if args.coords:
        check_out(args.coords, (".npy",), "coordinate map")
    import numpy as np

    from infinitex.engine.analysis import analyze
    from infinitex.engine.controls import rescaled_features
    from infinitex.engine.material import MaterialError, export_depths, parse_maps, single
    from infinitex.engine.surface import AtlasDomain, AtlasError, load_model
    from infinitex.export.surface import bake_maps, map_files, plan, surface_controls, write_outputs
    from infinitex.export.window import OwnInputError, Writes, check_own_inputs
    from infinitex.project.realize import exemplar_for, material_or_none

    doc = source_document(args.source)[0]
    if args.fidelity is not None:
        doc = replace(doc, structure=args.fidelity)
    if args.seed is not None:
        doc = replace(doc, seed=args.seed)
    model = load_model(args.model, unwrap_missing=args.unwrap)
    # The model's file and those it names (its .mtl and textures, a glTF's buffers and images) are inputs too.
    inputs = [args.source, *doc.input_paths(), *model.meta["files"]]
    material = material_or_none(doc)
    ex, settings = exemplar_for(doc, None, material)
    if material is None:
        material = single(ex)
    try:
        roles = parse_maps(args.maps, material)
        depths = export_depths(material, roles, args.depth, out if ext != ".glb" else os.path.splitext(out)[0] + ".png")
    except MaterialError as exc:
        raise CliError(str(exc), EXIT_USAGE) from None
    files = map_files(out, roles, depths, material.single and ext != ".glb")
    try:  # no output may replace a file this run reads
        check_own_inputs(Writes(files=[p for _, p, _ in files] + [out] + ([args.coords] if args.coords else [])),
                         [p for p in inputs if p])
    except OwnInputError as exc:
        raise CliError(str(exc), EXIT_USAGE) from None
    own = doc.surface  # a project with a model: its texture size, scale and direction unless given here
    frame = args.frame or (own.frame if own is not None else "up")
    up = tuple(args.up) if args.up is not None else (tuple(own.up) if own is not None else (0.0, 1.0, 0.0))
    painted = own is not None and own.model.key == model.key
    try:
        if own is not None and args.repeats is None and args.texel_ratio is None:
            pl = plan(model, n, ex.size, repeats=float(own.repeats),
                      synth_size=own.size if painted and own.size <= n else None)
        else:
            pl = plan(model, n, ex.size, args.repeats, args.texel_ratio)
        atlas = AtlasDomain(model, pl.synth_size, pl.sigma, frame=frame, up=up, seams=not args.no_seams)
    except ValueError as exc:
        raise CliError(str(exc), EXIT_USAGE if not isinstance(exc, AtlasError) else EXIT_INPUT) from None
    if not args.quiet:
        sys.stderr.write(f"{printable(model.name)}: {len(model.faces):,} triangles, {atlas.charts} charts"
                         f"{' (UVs generated by xatlas)' if model.meta.get('unwrapped') else ''}\n")
        if atlas.stretch_clamped > 0.01:
            sys.stderr.write(f"note: {atlas.stretch_clamped:.0%} of the triangles stretch the texture more than 4x; "
                             "it is held at 4x there (check the model's UVs, or --size)\n")
    # The randomness painted on a project's model is in its texels: it goes with the same model at its
    # size. Its features and combed directions go with the same model at any size (scaled).
    placed = painted
    painted = painted and pl.synth_size == own.size
    controls, dropped = surface_controls(doc.controls(ex.size), painted_on_model=placed)
    if placed:
        factor = pl.synth_size / own.size
        controls = replace(controls, features=rescaled_features(controls.features, factor),
                           randomness_canvas=controls.randomness_canvas if painted else None,
                           direction=None if controls.direction is None
                           else controls.direction.rescaled(factor, own.size))
    if own is not None:
        dropped = [d for d in dropped if d not in ("canvas randomness", "features", "direction field")]
        if not placed and (doc.features or doc.direction is not None) and not args.quiet:
            sys.stderr.write("note: the features and directions placed on the project's model are left out "
                             "(another model)\n")
        if not painted and doc.randomness_canvas is not None and not args.quiet:
            sys.stderr.write("note: the randomness painted on the project's model is left out (another model, "
                             "or a smaller texture size than the project's)\n")
    if dropped and not args.quiet:
        sys.stderr.write(f"note: the project's {', '.join(dropped)} belong to the plane; the model leaves them out\n")
    an = analyze(ex, settings, progress=analysis_progress(args.quiet, ex, settings))
    from infinitex.engine.gpu import Gpu
    from infinitex.engine.synth import Synthesizer
    gpu = Gpu()
    renderer = gpu.renderer
    bar = ProgressBar(f"{printable(model.name)} {n}x{n}", args.quiet)
    steps = 1 + len(roles)
    done = [0]

    def progress(what: str) -> None:
        done[0] += 1
        bar(done[0] / (steps + 1), what)
    try:
        t0 = time.perf_counter()
        synth = Synthesizer(an, doc.params(an.L), gpu, controls=controls)
        try:
            maps, coords = bake_maps(synth, atlas, material, roles, pl, controls, progress)
        finally:
            synth.release()
        dt = time.perf_counter() - t0
        written = write_outputs(out, model, maps, files, material)
        if args.coords:
            from infinitex.engine.safeio import atomic_write
            c = coords.astype(np.int32)
            atomic_write(args.coords, writer=lambda f: np.save(f, c))
            written.append(args.coords)
        bar(1.0, "written")
    finally:
        gpu.release()
    if not args.quiet:
        sys.stderr.write(f"{', '.join(printable(os.path.basename(w)) for w in written)}: {n}x{n}"
                         f"{f' (synthesized at {pl.synth_size}, magnified)' if pl.magnify > 1 else ''} in "
                         f"{dt:.1f} s ({renderer})\n")
    return 0


def main(argv: list[str]) -> int:
    from infinitex.engine.surface import AtlasError, ModelError
    return guarded(run_surface, argv, (ModelError, AtlasError))
