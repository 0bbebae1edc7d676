"""``infinitex export PROJECT -o OUT.png``: render a project headless.

Shares the editor's export code (:class:`infinitex.export.window.ExportJob`), so the file is
identical to what File > Export writes. Every argument is checked before any
work; progress on stderr; Ctrl+C cancels.
"""
from __future__ import annotations

import os
import sys
import time
from dataclasses import replace

from infinitex.engine.safeio import ReadError, printable

from .common import (
    EXIT_INPUT,
    EXIT_USAGE,
    CliError,
    Parser,
    ProgressBar,
    add_lattice_args,
    add_direction_args,
    add_label_args,
    add_randomness_args,
    add_make_tileable_arg,
    add_structure_arg,
    analysis_progress,
    check_lattice_args,
    check_out,
    check_toroidal,
    check_window,
    direction_field,
    guarded,
    integer,
    label_maps,
    palette_document,
    randomness_controls,
    finds_lattice,
    keep_found_lattice,
    resolve_lattice,
)


def build_parser() -> Parser:
    p = Parser(prog="infinitex export",
               description="Export a project's texture (a rectangle, its view, a toroidal tile, or a tile set "
                           "for game engines).")
    p.add_argument("project", help="an .itex project file, or an exemplar image or material (default settings): "
                   "one map of a material (wood_basecolor.png) brings its siblings named by the rule "
                   "(wood_normal.png, wood_height.tif...), a folder holds one material's maps")
    p.add_argument("-o", "--output", required=True,
                   help="output PNG (.png; .tif for a 32-bit float single image); a material writes one file "
                        "per map: OUT_basecolor.png, OUT_height.png... (32-bit maps as .tif)")
    p.add_argument("--maps", default=None, metavar="all|basecolor,height,...",
                   help="the maps of a material to write (default all)")
    p.add_argument("--depth", type=integer, default=None, choices=(8, 16, 32),
                   help="bit depth of every map written: 8 or 16 (PNG) or 32 (float TIFF); default: each map's "
                        "own (8-bit sources 8, 16-bit 16, float 32)")
    p.add_argument("--magnify", type=integer, default=1, choices=(1, 2, 4, 8),
                   help="--format png: N x N output pixels per texel, by synthesis magnification (LH05 5) from "
                        "the full-resolution maps when the import kept them; normals are renormalized")
    g = p.add_mutually_exclusive_group()
    g.add_argument("--rect", nargs=4, type=integer, metavar=("X", "Y", "W", "H"),
                   help="canvas rectangle in finest-level pixels")
    g.add_argument("--toroidal", type=integer, metavar="N",
                   help="an N x N tile that wraps seamlessly (N a power of two, 32 to 4096)")
    g.add_argument("--wang", type=integer, metavar="C",
                   help="a corner Wang tile set: C corner colours (2: 16 tiles, 3: 81) of --tile px that meet "
                        "without a seam wherever their corner colours agree, each inside different. Writes the "
                        "atlas OUT.png (itself a valid arrangement: it tiles), OUT.json (each tile's corner "
                        "colours nw ne sw se and atlas x y) and OUT_preview.png (8 x 8 tiles at random)")
    g.add_argument("--variants", type=integer, metavar="K",
                   help="K tiles (2 to 64) with the borders of one toroidal tile and different insides: any "
                        "of them fits next to any other. Files as with --wang")
    p.add_argument("--for", dest="engines", default=None, metavar="tiled|godot|all|none",
                   help="--wang/--variants: the game engines' own terrain resources beside the atlas (default all): "
                        "tiled: OUT.tsx (a tileset with a corner Wang set; per map for a material) and OUT.tmx (an "
                        "example map of the preview's arrangement); godot: OUT.tres (a Godot 4 TileSet with a "
                        "Match Corners terrain set); none: the atlas and JSON only")
    p.add_argument("--per-tile", action="store_true",
                   help="--wang/--variants: also one file per tile, OUT_0110.png (corner colours nw ne sw se) "
                        "or OUT_v3.png")
    p.add_argument("--size", nargs=2, type=integer, default=None, metavar=("W", "H"),
                   help="without --rect/--toroidal: a W x H window centered on the project's view (default 1024 1024)")
    p.add_argument("--coords", action="store_true",
                   help="also write the exact exemplar-coordinate map: OUT_coords.png (or, streamed, "
                        "OUT_coords.<UDIM>.png or OUT_coords.tif)")
    p.add_argument("--format", choices=("png", "tiles", "tiff", "zarr"), default="png",
                   help="png: one image, made in memory (at most 16384 px a side); tiles: a set of PNG tiles "
                        "with UDIM numbers (-o NAME.png writes NAME.1001.png ...); tiff: one tiled BigTIFF "
                        "(-o NAME.tif); zarr: a multiscale Zarr pyramid (-o NAME.zarr, OME-NGFF 0.4) whose "
                        "coarser levels are the synthesis's own. tiles, tiff and zarr are streamed in bounded "
                        "memory, up to 2^20 px a side, and resume where an interrupted run stopped")
    p.add_argument("--tile", type=integer, default=None, metavar="N",
                   help="tile size of --format tiles|tiff|zarr: 256, 512, 1024 (default), 2048, 4096 or 8192; "
                        "of --wang/--variants: 64 to 2048, a power of two (default 256)")
    p.add_argument("--workers", type=integer, default=0, metavar="N",
                   help="--format tiles|tiff|zarr: render with N worker processes, each with its own GL context "
                        "(0: in this process); with --scheduler, the LocalCluster's size (default: one per "
                        "core); the files are the same bytes")
    p.add_argument("--scheduler", nargs="?", const="local", default=None, metavar="ADDRESS",
                   help="--format tiles|tiff|zarr: render the tiles on a Dask cluster (dask.distributed) whose "
                        "scheduler is at ADDRESS (e.g. tcp://10.0.0.5:8786; its workers need infinitex "
                        "installed), or, without ADDRESS, on a LocalCluster of --workers processes. Tiles of a "
                        "worker that dies are rendered again elsewhere")
    add_randomness_args(p)
    add_label_args(p)
    add_direction_args(p)
    add_lattice_args(p)
    add_structure_arg(p, None)
    add_make_tileable_arg(p)
    p.add_argument("--allow-outside-exemplar", action="store_true",
                   help="read an exemplar the project refers to outside the project's folder")
    p.add_argument("-q", "--quiet", action="store_true")
    return p


def run_export(argv: list[str]) -> int:
    args = build_parser().parse_args(argv)
    from infinitex.engine.pyramid import Rect

    # Arguments first: nothing is read or computed before they are all good.
    from infinitex.export import TILE_SIZES
    from infinitex.project import (
        Document,
        ExemplarOutside,
        ExemplarSource,
        is_project_file,
        load_project,
    )
    streamed = args.format != "png"
    tileset = _tileset_plan(args)
    if args.size is not None and (args.rect or args.toroidal is not None or tileset):
        raise CliError("--size goes with none of --rect, --toroidal, --wang and --variants.", EXIT_USAGE)
    if streamed and args.tile is None:
        args.tile = 1024
    if tileset:
        cols, rows = tileset.grid
        w, h = cols * tileset.tile, rows * tileset.tile
    elif args.rect:
        x, y, w, h = args.rect
        check_window(x, y, w, h, "--rect", streamed)
    elif args.toroidal is not None:
        check_toroidal(args.toroidal)
    else:
        w, h = args.size or (1024, 1024)
        check_window(0, 0, w, h, "--size", streamed)
    if args.format == "zarr":
        from infinitex.engine.safeio import WriteError
        from infinitex.export import check_zarr_output
        try:
            check_zarr_output(args.output)
        except WriteError as exc:
            raise CliError(str(exc), EXIT_USAGE) from None
        if args.coords:
            raise CliError("--coords goes with --format png, tiles or tiff.", EXIT_USAGE)
    else:
        check_out(args.output, (".tif", ".tiff") if args.format == "tiff" else (".png", ".tif", ".tiff"),
                  "output image")
    if streamed and (args.depth not in (None, 8) or args.magnify != 1):
        raise CliError("--format tiles, tiff and zarr write 8-bit maps at 1:1; --depth 16/32 and --magnify go "
                       "with --format png.", EXIT_USAGE)
    from infinitex.engine.material import MaterialError, check_maps_spec
    try:
        check_maps_spec(args.maps)
    except MaterialError as exc:
        raise CliError(str(exc), EXIT_USAGE) from None
    if args.magnify != 1 and args.coords:
        raise CliError("The coordinate map is written at 1:1: --coords does not go with --magnify.", EXIT_USAGE)
    if streamed and args.tile not in TILE_SIZES:
        raise CliError(f"--tile must be one of {', '.join(map(str, TILE_SIZES))}, not {args.tile}.", EXIT_USAGE)
    if not 0 <= args.workers <= 64 or (args.workers and not streamed):
        raise CliError("--workers is 0 to 64, with --format tiles, tiff or zarr.", EXIT_USAGE)
    if args.scheduler is not None and not streamed:
        raise CliError("--scheduler goes with --format tiles, tiff or zarr.", EXIT_USAGE)
    if args.scheduler is not None:
        from infinitex.export.workers import check_scheduler_address
        try:
            args.scheduler = check_scheduler_address(args.scheduler)
        except ValueError as exc:
            raise CliError(str(exc), EXIT_USAGE) from None
    coords_path = None
    if args.coords and streamed:
        base = os.path.splitext(args.output)[0] + "_coords"
        check_out(base + (".tif" if args.format == "tiff" else ".png"), (".tif", ".png"), "coordinate map")
    elif args.coords:
        coords_path = os.path.splitext(args.output)[0] + "_coords.png"
        check_out(coords_path, (".png",), "coordinate map")

    # No output may replace a file this export reads (checked again once the maps' depths are known).
    inputs = [args.randomness_exemplar, args.randomness_canvas, args.avoid_exemplar, args.features,
              args.labels_exemplar, args.labels_canvas, args.direction_map]
    size = (args.toroidal, args.toroidal) if args.toroidal is not None else (w, h)  # (a tile set: its atlas)
    project = is_project_file(args.project)
    if project:
        try:
            proj = load_project(args.project, allow_outside=args.allow_outside_exemplar)
        except ExemplarOutside as exc:
            raise CliError(f"{exc} Pass --allow-outside-exemplar to read it.", EXIT_INPUT) from None
        doc, view = proj.document, proj.view
        geometry = proj.display.geometry
        inputs += [args.project, *doc.input_paths()]
        check_own_inputs(args, size, {role: src.name for role, src in doc.sources()}, inputs)
    else:
        from infinitex.engine.material import IMAGE, assign_roles
        try:
            found = assign_roles([args.project])
            inputs += list(found.values())
            check_own_inputs(args, size, {role: os.path.basename(p) for role, p in found.items()}, inputs)
            maps = [(role, ExemplarSource.from_file(p)) for role, p in found.items()]
            doc, view = Document(maps[0][1]), None
            if list(found) != [IMAGE]:
                doc = doc.with_maps(maps)
                if not args.quiet:
                    sys.stderr.write(f"material: {', '.join(f'{r} {printable(os.path.basename(p))}' for r, p in found.items())}\n")
            geometry = "original"
        except ReadError as exc:
            raise CliError(str(exc), EXIT_INPUT) from None
    if args.palette:
        doc = palette_document(args, doc, args.quiet)
        inputs += doc.input_paths()
        check_own_inputs(args, size, {role: src.name for role, src in doc.sources()}, inputs)
    if args.fidelity is not None:
        doc = replace(doc, structure=args.fidelity)
    if args.make_tileable:
        if args.lattice not in (None, "none") or (doc.lattice is not None and args.lattice is None):
            raise CliError("--make-tileable goes with no lattice (a lattice's block already tiles).", EXIT_USAGE)
        doc = replace(doc, make_tileable=True)
    if tileset:
        rect, tor = Rect.of(0, 0, w, h), 0
    elif args.rect:
        rect, tor = Rect.of(x, y, w, h), 0
    elif args.toroidal is not None:
        n = args.toroidal
        rect, tor = Rect(0, 0, n, n), n
    else:
        cx, cy = (view.x, view.y) if view else (0.0, 0.0)
        rect, tor = Rect.of(int(cx - w / 2), int(cy - h / 2), w, h), 0
        check_window(rect.x0, rect.y0, w, h, "--size", streamed)

    # Decode and analyze before any GL: a bad exemplar fails fast.
    from infinitex.engine.analysis import analyze
    from infinitex.engine.gpu import Gpu
    from infinitex.engine.material import IMAGE, parse_maps
    from infinitex.export.loaded import LoadedDocument
    from infinitex.export.window import ExportJob
    from infinitex.project.realize import exemplar_for, material_or_none
    check_lattice_args(args)
    image = found = None
    if args.lattice and doc.maps:
        raise CliError("A lattice works on a single image, not on a material.", EXIT_USAGE)
    if args.lattice and args.lattice.strip().lower() == "none":  # removes the project's (nothing to decode)
        doc = replace(doc, lattice=None)
        sys.stdout.write("lattice: none\n")
    elif args.lattice:  # replaces the project's lattice
        from infinitex.engine.exemplar import decode_full
        image = decode_full(doc.exemplar.data, doc.exemplar.name)
        doc = replace(doc, lattice=resolve_lattice(args.lattice, image, args.lattice_levels))
    elif doc.lattice is not None:
        sys.stdout.write(f"lattice: {doc.lattice.to_text()}\n")
    elif not project and not doc.maps and finds_lattice(args) \
            and not (streamed and not tor and (args.geometry or geometry) != "rectified"):
        # An image is searched for a lattice (regular textures right by default),
        # unless it is too large to search whole: then it is synthesized without one.
        from infinitex.engine.exemplar import ExemplarError, decode_full
        from infinitex.project.realize import with_found_lattice
        try:
            image = decode_full(doc.exemplar.data, doc.exemplar.name)
        except ExemplarError:
            image = None  # (a file that cannot be read at all says so below)
        if image is not None:
            doc, found = with_found_lattice(doc, image)
    material = material_or_none(doc)
    ex, settings = exemplar_for(doc, image, material)
    whole = tor or (tileset.tile if tileset else 0)  # a tile of whole cells
    if found is not None and doc.lattice is not None \
            and not keep_found_lattice(doc.lattice, found, ex.size, whole, args.quiet, "exported"):
        doc = replace(doc, lattice=None)
        ex, settings = exemplar_for(doc, None, material)
    del image
    if material is not None:
        roles = parse_maps(args.maps, material)
        if not streamed:  # now exactly: each map's file is .png or .tif by its depth
            check_own_inputs(args, size, {role: src.name for role, src in doc.sources()}, inputs, material)
        if streamed and len(roles) > 1:
            raise CliError("--format tiles, tiff and zarr write one map per run: add --maps ROLE "
                           f"(this material has {', '.join(material.roles)}), or use --format png.", EXIT_USAGE)
    else:
        roles = None
        if args.maps is not None and args.maps.strip().lower() not in ("all", IMAGE):
            raise CliError("--maps chooses among a material's maps; this exemplar is a single image.", EXIT_USAGE)
    if doc.lattice is not None and tor:
        cx, cy = doc.lattice.cell(ex.size)
        if tor % cx or tor % cy:
            raise CliError(f"A toroidal tile of whole cells needs a size that the cell ({cx}x{cy} exemplar px) "
                           f"divides; use --toroidal {max(cx, cy, 32)} or more.", EXIT_USAGE)
    if args.randomness_exemplar or args.randomness_canvas or args.features or args.avoid_exemplar:
        # these replace the project's
        c = randomness_controls(args, doc.fit, ex.size, doc.controls(ex.size))
        doc = replace(doc, randomness_exemplar=c.randomness_exemplar, randomness_canvas=c.randomness_canvas,
                      features=c.features, avoid_exemplar=c.avoid)
    if args.labels_exemplar or args.labels_canvas or args.label_strength is not None:
        doc = replace(doc, labels=label_maps(args, ex.original_size, doc.fit, ex.size, doc.labels))
    if args.direction_map:  # replaces the project's
        if tileset:
            raise CliError("A tile set follows no direction field (its tiles meet in any order): --direction-map "
                           "goes with none of --wang and --variants.", EXIT_USAGE)
        doc = replace(doc, direction=direction_field(args, doc.direction))
    try:  # the project with every argument applied (--make-tileable, --lattice, labels...)
        doc.validate()
        doc.controls(ex.size).validate(ex.size)
    except ValueError as exc:
        raise CliError(str(exc), EXIT_USAGE) from None
    if args.scheduler not in (None, "local"):
        from infinitex.export.workers import probe_scheduler
        probe_scheduler(args.scheduler)  # a cluster out of reach fails now, not after the analysis
    an = analyze(ex, settings, progress=analysis_progress(args.quiet, ex, settings))
    gpu = Gpu()
    session = LoadedDocument(gpu)
    try:
        session.install(doc, ex, an, material)
        if tileset:
            return _run_tileset(session, tileset, view, roles, args, gpu.renderer)
        if streamed:
            role = roles[0] if roles else ""
            return _run_streamed(session, doc, rect, tor, args, gpu.renderer, args.geometry or geometry, role)
        job = ExportJob(session, rect, args.output, toroidal=tor, coords_path=coords_path, tile=512,
                        geometry=args.geometry or geometry, maps=roles, depth=args.depth, magnify=args.magnify)
        return _run(job, args, rect, gpu.renderer)
    finally:
        session.release()
        gpu.release()


def check_own_inputs(args, size: tuple[int, int], sources: dict[str, str], inputs: list, material=None) -> None:
    """Refuse, as a usage error naming the file, an export whose outputs
    (every map's file, the coordinate map, tile sets, the Zarr store, the
    parts folder) would replace or remove one of its ``inputs``. ``sources``:
    {role: file name} of the maps ({"image": name} for a single image).
    Before the maps are decoded, a map whose depth (so its file's extension)
    is not yet known is left to the call with its ``material``."""
    from infinitex.engine.imagefile import depth_extension
    from infinitex.engine.material import (
        IMAGE,
        MaterialError,
        export_depths,
        map_path,
        output_paths,
        parse_maps,
    )
    from infinitex.export.window import OwnInputError, Writes, streamed_writes
    from infinitex.export.window import check_own_inputs as check
    single = list(sources) == [IMAGE]
    if single:
        roles = [IMAGE]
    else:
        try:
            roles = parse_maps(args.maps, material or _Roles(sources))
        except MaterialError:
            return  # said where the maps are chosen
    writes = Writes()
    if args.format != "png":
        for role in roles:
            out = args.output if single else map_path(args.output, role)
            writes.add(streamed_writes(out, args.format, size[0], size[1], args.tile, args.coords))
    else:
        if single:
            writes.files.append(args.output)
        elif material is not None:
            try:
                depths = export_depths(material, roles, args.depth, args.output)
            except MaterialError:
                return  # said by the export itself
            writes.files += [p for _, p, _ in output_paths(args.output, roles, depths)]
        else:  # a map from a TIFF may be 32-bit (written .tif): known once decoded
            writes.files += [map_path(args.output, r, depth_extension(args.depth or 8)) for r in roles
                             if args.depth or not sources[r].lower().endswith((".tif", ".tiff"))]
        if args.coords:
            writes.files.append(os.path.splitext(args.output)[0] + "_coords.png")
    plan = _tileset_plan(args)
    if plan is not None:
        from infinitex.export.tileset import set_paths, tile_file
        paths = set_paths(args.output)
        tiles = plan.tiles() if args.per_tile else []
        atlases = list(writes.files)
        writes.files += [paths["json"], paths["preview"]] + [tile_file(f, t) for f in atlases for t in tiles]
        if atlases:  # the engines' files of the PNG atlases (the first: the primary map)
            from infinitex.export.engines import engine_files
            writes.files += engine_files(args.output, [(f, f, 0) for f in atlases], atlases[0], args.engines).files
    try:
        check(writes, inputs)
    except OwnInputError as exc:
        raise CliError(str(exc), EXIT_USAGE) from None


class _Roles:
    """The roles of a material's files before they are decoded (for parse_maps)."""

    def __init__(self, sources: dict[str, str]):
        from infinitex.engine.material import ordered
        self.maps = dict(sources)
        self.roles = ordered(sources)


def _run_streamed(session, doc, rect, tor: int, args, renderer: str, geometry: str, role: str = "") -> int:
    """--format tiles|tiff|zarr: tile by tile in bounded memory, resumable (infinitex.export.streamed)."""
    from infinitex.engine.material import map_path
    from infinitex.export import TiledExport
    from infinitex.export.jobs import export_key, project_synthesizer
    if session.controls.lattice is not None and geometry != "rectified" and not tor:
        raise CliError("Tiled exports of a lattice are written rectified: pass --geometry rectified.", EXIT_USAGE)
    synth = session.synth
    if tor:
        synth.set_params(replace(session.params, period=tor))
    if role:  # one map of a material: NAME_ROLE.tif, NAME_ROLE.1001.png..., NAME_ROLE.zarr
        synth.palette = session.material.stack(role)
        synth.normals = role == "normal"  # turned with a direction field
    out = map_path(args.output, role) if role else args.output
    job = TiledExport(synth, rect, out, args.format, args.tile, key=export_key(doc, synth.params, role),
                      coords=args.coords, L=session.analysis.L)
    progress = ProgressBar("export", args.quiet)
    t0 = time.perf_counter()
    init = None
    if args.workers or args.scheduler:
        init = project_synthesizer(doc, tor, role)
    job.run(lambda done, total: progress(done / total, f"tile {done}/{total}"), workers=args.workers,
            worker_init=init, scheduler=args.scheduler)
    if not args.quiet:
        where = " and ".join(printable(os.path.abspath(o)) for o in job.outputs())
        on = (f"on the Dask cluster at {args.scheduler}" if args.scheduler not in (None, "local")
              else "on a Dask LocalCluster" if args.scheduler else
              f"with {args.workers} worker processes" if args.workers else f"({renderer})")
        sys.stderr.write(f"{where}: {rect.w}x{rect.h} in {job.total} tiles of {args.tile} px "
                         f"({job.kept} kept from an earlier run) in {time.perf_counter() - t0:.1f} s {on}\n")
        for note in job.notes:  # a parts folder left in place (it holds files the export did not write)
            sys.stderr.write(f"note: {printable(note, 1000)}\n")
    return 0


def _tileset_plan(args):
    """The tile set asked for (--wang/--variants, --tile, --per-tile), checked
    before any work (its lattice cell is checked once the document is loaded);
    None for other exports."""
    if args.wang is None and args.variants is None:
        if args.per_tile or args.engines is not None:
            raise CliError(f"{'--per-tile' if args.per_tile else '--for'} goes with --wang or --variants.", EXIT_USAGE)
        return None
    from infinitex.export.engines import parse_engines
    try:
        if not isinstance(args.engines, tuple):  # parsed once
            args.engines = parse_engines("all" if args.engines is None else args.engines)
    except ValueError as exc:
        raise CliError(str(exc), EXIT_USAGE) from None
    from infinitex.export.wang import WANG_COLORS, TileSetError, TileSetPlan
    flag = "--wang" if args.wang is not None else "--variants"
    if args.wang is not None and args.wang not in WANG_COLORS:
        raise CliError(f"A corner Wang set has 2 or 3 corner colours (--wang 2 or --wang 3), not {args.wang}; "
                       "--variants K makes variants of one tile.", EXIT_USAGE)
    if args.format != "png" or args.coords or args.magnify != 1 or args.workers or args.scheduler is not None:
        raise CliError(f"{flag} writes PNG (or 32-bit TIFF) atlases at 1:1: it goes with none of --format, "
                       "--coords, --magnify, --workers and --scheduler.", EXIT_USAGE)
    plan = TileSetPlan(args.wang or 1, 256 if args.tile is None else args.tile, args.variants or 0)
    try:
        plan.validate()
    except TileSetError as exc:
        raise CliError(str(exc), EXIT_USAGE) from None
    return plan


def _run_tileset(session, plan, view, roles, args, renderer: str) -> int:
    """--wang/--variants: the set made from the texture around the project's view."""
    from infinitex.export.tileset import TileSetJob, plan_for
    from infinitex.export.wang import TileSetError
    origin = (int(view.x), int(view.y)) if view else (0, 0)
    try:
        plan = plan_for(session, plan.colors, plan.tile, plan.variants, origin)
    except TileSetError as exc:
        raise CliError(str(exc), EXIT_USAGE) from None
    job = TileSetJob(session, plan, args.output, maps=roles, depth=args.depth, per_tile=args.per_tile,
                     engines=args.engines)
    seconds = _run_job(job, "tile set", args.quiet)
    if not args.quiet:
        files = [p for _, p, _ in job.outputs] + [job.paths["json"], job.paths["preview"]] + job.engines.files
        names = ", ".join(printable(os.path.basename(p)) for p in files)
        kind = (f"corner Wang, {plan.colors} colours" if plan.colors > 1 else "variants of one toroidal tile")
        each = ", and each tile's own file" if args.per_tile else ""
        sys.stderr.write(f"{names}: {plan.count} tiles of {plan.tile} px ({kind}{each}) in "
                         f"{seconds:.1f} s ({renderer})\n")
        if args.engines and job.engines.skipped:
            sys.stderr.write(f"note: no engine resource for {', '.join(job.engines.skipped)}: Tiled and Godot "
                             "read PNG atlases (use --depth 8 or 16)\n")
    return 0


def _run_job(job, label: str, quiet: bool) -> float:
    """Run an in-memory export job to the end with a progress bar (Ctrl+C
    cancels it); its seconds."""
    t0 = time.perf_counter()
    try:
        job.run(ProgressBar(label, quiet))
    except KeyboardInterrupt:
        job.cancel()
        raise
    return time.perf_counter() - t0


def _run(job, args, rect, renderer: str) -> int:
    seconds = _run_job(job, "export", args.quiet)
    if not args.quiet:
        names = ", ".join(printable(os.path.basename(p)) for _, p, _ in job.outputs)
        scale = f", magnified {args.magnify}x" if args.magnify > 1 else ""
        sys.stderr.write(f"{names}: {rect.w}x{rect.h}{scale} in {seconds:.1f} s ({renderer})\n")
    return 0


def main(argv: list[str]) -> int:
    from infinitex.engine.controls.lattice import LatticeError
    from infinitex.export import ExportFailed
    from infinitex.project import ProjectError
    return guarded(run_export, argv, (ProjectError, LatticeError, ValueError, ExportFailed))
