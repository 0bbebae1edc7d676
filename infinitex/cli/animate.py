"""``infinitex animate EXEMPLAR|PROJECT -o OUT --frames N ...``: the texture
flowing along a velocity field (LH06 section 7; engine/advect.py), headless,
written as an image sequence, a flipbook atlas (.png + .json), an animated
WebP or PNG, or an MP4 video (export/animation.py).

Every argument is checked before any work; progress on stderr; Ctrl+C
cancels and leaves nothing partial (the files are written at the end,
atomically).
"""
from __future__ import annotations

import os
import sys
import time
from dataclasses import replace

from infinitex.engine.safeio import WriteError, printable

from .common import (
    EXIT_USAGE,
    CliError,
    Parser,
    ProgressBar,
    add_structure_arg,
    analysis_progress,
    check_toroidal,
    check_window,
    guarded,
    integer,
    number,
    source_document,
)



def build_parser() -> Parser:
    p = Parser(prog="infinitex animate",
               description="The texture flowing along a velocity field: frames of an exemplar's or a project's "
                           "texture moved by a uniform velocity or a velocity map (texture advection, LH06 7).")
    p.add_argument("source", help="an exemplar image, a material (one of its maps, or its folder) or an .itex project")
    p.add_argument("-o", "--output", required=True,
                   help="a folder (OUT/frame_0000.png...), a .png flipbook atlas (with OUT.json), .webp, .apng or "
                        ".mp4; a material writes one per map (OUT_basecolor.png...)")
    p.add_argument("--frames", type=integer, default=None, metavar="N",
                   help="how many frames (1 to 4096; default: a project's animation's)")
    p.add_argument("--velocity", default=None, metavar="VX,VY|MAP",
                   help="a uniform velocity in canvas px per frame (+x right, +y down the image's rows), or a "
                        "velocity map image (red and green in [0, 1], mid-gray still) scaled by --speed; default: "
                        "a project's flow, else 1,0")
    p.add_argument("--speed", type=number, default=1.0, metavar="S",
                   help="with a velocity map: px per frame at red or green 0 and 1 (default 1)")
    p.add_argument("--velocity-origin", nargs=2, type=integer, default=[0, 0], metavar=("X", "Y"),
                   help="canvas position of the velocity map's top-left pixel (default 0 0)")
    p.add_argument("--flow-y", choices=("up", "down"), default="up",
                   help="the velocity map's green points up (OpenGL, default) or down (DirectX)")
    p.add_argument("--loop", action="store_true",
                   help="a seamless loop: frame N is frame 0 (the renewal period divides N)")
    p.add_argument("--period", type=integer, default=None, metavar="P",
                   help="frames between renewals of the advected texture (2 to 128; default: from the field's "
                        "shear, 12 to 32, 16 for a uniform velocity; with --loop a divisor of N)")
    p.add_argument("--size", nargs=2, type=integer, default=[256, 256], metavar=("W", "H"),
                   help="frame size in px (default 256 256)")
    p.add_argument("--origin", nargs=2, type=integer, default=[0, 0], metavar=("X", "Y"),
                   help="canvas position of the frames' top-left pixel")
    p.add_argument("--toroidal", type=integer, default=None, metavar="N",
                   help="frames of an N x N tile that tiles seamlessly (N a power of two, 32 to 4096); with "
                        "--loop, a flipbook that tiles in space and loops in time")
    p.add_argument("--fps", type=number, default=None,
                   help="frames per second of the file (default: a project's animation's, else 24)")
    p.add_argument("--start", type=integer, default=0, metavar="T", help="the first frame's number (default 0)")
    p.add_argument("--seed", type=integer, default=None, help="the synthesis seed (default: the project's, or 0)")
    p.add_argument("--maps", default=None, metavar="all|basecolor,height,...",
                   help="the maps of a material to write (default all)")
    add_structure_arg(p, None)
    p.add_argument("--allow-outside-exemplar", action="store_true",
                   help="a project may read an exemplar outside its folder")
    p.add_argument("-q", "--quiet", action="store_true")
    return p


def run_animate(argv: list[str]) -> int:
    args = build_parser().parse_args(argv)
    from infinitex.engine.controls.flow import MAX_FRAME, Flow, FlowError
    from infinitex.engine.rect import Rect
    from infinitex.export.animation import MAX_FRAMES, animation_format

    # Arguments first: nothing is computed before they are all good (a project's
    # animation gives the defaults).
    doc, inputs = source_document(args.source, args.allow_outside_exemplar,
                                  " Pass --allow-outside-exemplar to read it.")
    motion = doc.motion if args.velocity is None else None
    n = args.frames if args.frames is not None else doc.motion.frames if doc.motion is not None else None
    if n is None:
        raise CliError("--frames N is needed: the source holds no animation.", EXIT_USAGE)
    fps = args.fps if args.fps is not None else doc.motion.fps if doc.motion is not None else 24.0
    loop = args.loop or (motion is not None and motion.flow.loop > 0)
    if not 1 <= n <= MAX_FRAMES:
        raise CliError(f"--frames is 1 to {MAX_FRAMES}, not {n}.", EXIT_USAGE)
    if not 0 <= args.start or args.start + n > MAX_FRAME:
        raise CliError(f"Frames are numbered 0 to {MAX_FRAME - 1}; --start {args.start} with {n} frames is outside.",
                       EXIT_USAGE)
    if not 0 < fps <= 240:
        raise CliError(f"--fps is more than 0 and at most 240, not {fps:g}.", EXIT_USAGE)
    if args.toroidal is not None:
        check_toroidal(args.toroidal)
        w = h = args.toroidal
        rect = Rect(0, 0, w, h)
    else:
        w, h = args.size
        check_window(args.origin[0], args.origin[1], w, h, "--size")
        rect = Rect.of(args.origin[0], args.origin[1], w, h)
    if w * h * n > (1 << 30):
        raise CliError(f"{n} frames of {w}x{h} are over 1 Gpixel in all; write fewer or smaller frames.", EXIT_USAGE)
    try:
        from infinitex.engine.material import ROLES
        from infinitex.export.animation import check_animation_output
        fmt = animation_format(args.output)
        check_animation_output(args.output, fmt, [("", args.output)], n, w, h, ROLES if doc.maps else ())
    except WriteError as exc:
        raise CliError(str(exc), EXIT_USAGE) from None
    velocity_map = None
    vx = vy = 0.0
    text = (args.velocity or "1,0").strip()
    parts = text.split(",")
    if len(parts) == 2 and not os.path.exists(text):
        try:
            vx, vy = float(parts[0]), float(parts[1])
        except ValueError:
            raise CliError(f"--velocity is VX,VY (two numbers) or a map image, not {printable(text)}.",
                           EXIT_USAGE) from None
    else:
        velocity_map = text
        if not os.path.isfile(text):
            raise CliError(f"--velocity: {printable(text)} is neither VX,VY nor an image file.", EXIT_USAGE)
    try:
        flow = motion.flow if motion is not None else Flow.of(vx, vy)
        replace(flow, period=args.period or 16, loop=0).validate()
        if loop:
            flow.suggested_period(n)  # a loop needs a period that divides it
    except FlowError as exc:
        raise CliError(str(exc), EXIT_USAGE) from None
    if velocity_map is not None and not 0 < args.speed <= 32:
        raise CliError(f"--speed is more than 0 and at most 32 px per frame, not {args.speed:g}.", EXIT_USAGE)

    if doc.lattice is not None:
        raise CliError("animate does not go with a lattice yet: a near-regular texture keeps its grid, which a "
                       "flow would bend.", EXIT_USAGE)
    if args.fidelity is not None:
        doc = replace(doc, structure=args.fidelity)
    if args.seed is not None:
        doc = replace(doc, seed=args.seed)
    if velocity_map is not None:
        from infinitex.engine.controls.maps import load_velocity_map
        inputs.append(velocity_map)
        size = (w, h) if args.toroidal is not None else None
        x, y = (0, 0) if args.toroidal is not None else args.velocity_origin
        vmap = load_velocity_map(velocity_map, args.speed, args.flow_y == "up", x, y, size)
        flow = replace(flow, map=vmap)
    kept = motion is not None and (not loop or n % motion.flow.period == 0)  # the project's own period
    try:  # the period: asked for, the project's, or what the field's shear suggests (dividing a loop)
        flow = replace(flow, period=args.period or (flow.period if kept else flow.suggested_period(n if loop else 0)),
                       loop=n if loop else 0)
        flow.validate()
    except FlowError as exc:
        raise CliError(str(exc), EXIT_USAGE) from None
    from infinitex.engine.advect import MAX_STATIC_SIDE, static_side
    if static_side(flow, w, h) > MAX_STATIC_SIDE:
        raise CliError(f"Content travels up to {flow.reach(2 * flow.period)} px in a chain's life of "
                       f"{2 * flow.period} frames: with {w}x{h} frames that is more than the {MAX_STATIC_SIDE} px a "
                       "side one synthesis covers; use a shorter --period, a lower speed or smaller frames.",
                       EXIT_USAGE)
    # Decode and analyze before any GL: a bad exemplar fails fast.
    from infinitex.engine.analysis import analyze
    from infinitex.engine.gpu import Gpu
    from infinitex.engine.material import IMAGE, MaterialError, parse_maps
    from infinitex.export.loaded import LoadedDocument
    from infinitex.project.realize import exemplar_for, material_or_none
    material = material_or_none(doc)
    try:
        roles = parse_maps(args.maps, material) if material is not None else [IMAGE]
    except MaterialError as exc:
        raise CliError(str(exc), EXIT_USAGE) from None
    if material is None and args.maps is not None and args.maps.strip().lower() not in ("all", IMAGE):
        raise CliError("--maps chooses among a material's maps; this exemplar is a single image.", EXIT_USAGE)
    from infinitex.export.animation import animation_outputs
    outputs = animation_outputs(args.output, fmt, roles)
    _check_not_inputs(outputs, inputs)
    ex, settings = exemplar_for(doc, None, material)
    try:
        doc.validate()
        doc.controls(ex.size).validate(ex.size)
    except ValueError as exc:
        raise CliError(str(exc), EXIT_USAGE) from None
    an = analyze(ex, settings, progress=analysis_progress(args.quiet, ex, settings))
    gpu = Gpu()
    session = LoadedDocument(gpu)
    try:
        session.install(doc, ex, an, material)
        return _render(session, flow, rect, args, n, fps, fmt, roles, outputs, gpu.renderer)
    finally:
        session.release()
        gpu.release()


def _check_not_inputs(outputs, inputs) -> None:
    from infinitex.export.window import OwnInputError, Writes, check_own_inputs
    files = []
    for _, path in outputs:
        files.append(path)
        if path.lower().endswith(".png"):
            files.append(os.path.splitext(path)[0] + ".json")
    try:
        check_own_inputs(Writes(files=files), inputs)
    except OwnInputError as exc:
        raise CliError(str(exc), EXIT_USAGE) from None


def _render(session, flow, rect, args, n: int, fps: float, fmt: str, roles, outputs, renderer: str) -> int:
    from infinitex.engine.advect import FlowFrames, SynthSource
    source = SynthSource(session.synth, args.toroidal or 0)
    frames = FlowFrames(source, flow, session.params.seed)
    try:
        return _play(frames, session, rect, args, n, fps, fmt, outputs, renderer, flow)
    finally:
        frames.release()
        source.release()


def _play(frames, session, rect, args, n: int, fps: float, fmt: str, outputs, renderer: str, flow) -> int:
    from infinitex.engine.material import IMAGE
    from infinitex.export.animation import AnimationWriter, render_animation
    writers = {role: AnimationWriter(path, fmt, fps, bool(flow.loop), make_parent=role != IMAGE)
               for role, path in outputs}
    bar = ProgressBar(f"animate {n} frames", args.quiet)
    t0 = time.perf_counter()
    written = render_animation(frames, session.material, rect, args.start, n, writers,
                               progress=lambda f, t: bar(f, f"frame {t}"))
    bar(1.0)
    if not args.quiet:
        dt = time.perf_counter() - t0
        sys.stderr.write(f"{printable(', '.join(written))}: {n} frames of {rect.w}x{rect.h} in {dt:.1f} s "
                         f"({renderer})\n")
    return 0


def main(argv: list[str]) -> int:
    import moderngl

    from infinitex.engine.controls.flow import FlowError
    return guarded(run_animate, argv, (FlowError, moderngl.Error))
