"""The Export panel: the coordinate map, depth and scale of exports, Export
view, a rectangle of the canvas (one PNG, PNG tiles, BigTIFF or Zarr, its
size and time estimated first), the seamless (toroidal) tile and, when the
texture flows, its animation (panels/motion.py); also the File menu's Export
view and Export toroidal tile."""
from __future__ import annotations

import os
from typing import TYPE_CHECKING

from imgui_bundle import imgui

from infinitex.engine.pyramid import Rect

from ..dialogs import PNG_FILTER, TIFF_FILTER, ZARR_FILTER
from .widgets import modal_prompt, size_combo, tip

if TYPE_CHECKING:
    from . import Panels

DEPTH_CHOICES = [(None, "Each map's own depth"), (8, "8-bit PNG"), (16, "16-bit PNG"), (32, "32-bit float TIFF")]
MAGNIFY_CHOICES = [1, 2, 4, 8]
TILE_SIZES = [64, 128, 256, 512, 1024, 2048, 4096]
# Formats of rectangle exports: key, label, tooltip.
EXPORT_FORMATS = [
    ("png", "PNG image", "One PNG, made in memory: up to 16384 px a side and 64 Mpixels"),
    ("tiles", "PNG tiles (UDIM)", "A set of PNG tiles, NAME.1001.png, NAME.1002.png... (1001 + column + 10 x row; "
                                  "past 10 columns NAME_u1_v1.png): any size up to 2^20 px a side"),
    ("tiff", "BigTIFF (tiled)", "One tiled, compressed BigTIFF that GIS and terrain tools open: any size up to "
                                "2^20 px a side"),
    ("zarr", "Zarr pyramid", "A multiscale Zarr store (NAME.zarr, OME-NGFF 0.4) that napari and other zarr viewers "
                             "open: full resolution, then the synthesis's own coarser levels (the mipmap comes "
                             "free); any size up to 2^20 px a side"),
]


def draw(p: Panels) -> None:
    """The Export panel."""
    ed = p.ed
    _, ed.exports.settings.write_coords = imgui.checkbox("Also write the coordinate map", ed.exports.settings.write_coords)
    tip("NAME_coords.png: the exemplar position of every pixel, exactly "
        "(x = R + 256 (B & 15), y = G + 256 (B >> 4)); to look up other maps through the same synthesis")
    keys = [k for k, _ in DEPTH_CHOICES]
    imgui.set_next_item_width(-70)
    changed, i = imgui.combo("Depth", keys.index(ed.exports.settings.depth), [lbl for _, lbl in DEPTH_CHOICES])
    tip("Bits per channel of the exported maps: each map's own (8-bit sources 8, 16-bit 16, float 32), "
        "or the same for all; 32-bit maps are float TIFFs")
    if changed:
        ed.exports.settings.depth = keys[i]
    imgui.set_next_item_width(-70)
    changed, i = imgui.combo("Scale", MAGNIFY_CHOICES.index(ed.exports.settings.magnify),
                             ["1:1"] + [f"{f}x (magnified)" for f in MAGNIFY_CHOICES[1:]])
    tip("View and tile exports: N x N pixels per synthesized pixel, sharp from the full-resolution maps "
        "(synthesis magnification, LH05 5); normals stay unit length")
    if changed:
        ed.exports.settings.magnify = MAGNIFY_CHOICES[i]
    mat = ed.session.material
    if mat is not None and not mat.single:
        imgui.push_text_wrap_pos(0)
        imgui.text_disabled(f"A material: one file per map, NAME_{mat.roles[0]}.png, ... ({', '.join(mat.roles)}); "
                            "tile sets, BigTIFFs and Zarr write the map shown.")
        imgui.pop_text_wrap_pos()
    if imgui.button("Export view as PNG...", (-1, 0)):
        export_view(p)
    tip("What the canvas shows now, at 1:1 (or the scale above); a material: every map")
    imgui.separator_text("Rectangle")
    rectangle(p)
    imgui.separator_text("Seamless tile")
    ed.exports.settings.tile_size = size_combo("Tile size", TILE_SIZES, ed.exports.settings.tile_size)
    tip("Side of the seamless tile")
    ed.viewer.show_tile(imgui.checkbox("Show the tile on the canvas (T)", ed.viewer.tile_mode)[1])
    tip("The canvas shows the periodic texture this tile size makes, tile borders drawn: "
        "tune exactly what the toroidal export will write")
    if imgui.button("Export toroidal tile...", (-1, 0)):
        export_tile(p)
    tip("A square that repeats without a seam (a periodic synthesis of the same look)")
    if imgui.button("Tile set for game engines...", (-1, 0)):
        p.tileset_dialog()
    tip("Tiles that fit together in any valid order (a corner Wang set), so a level never shows the same tile "
        "twice in a row; previewed before the file is chosen")
    m = ed.doc.motion
    if m is not None and not m.flow.still and ed.doc.lattice is None:
        from .motion import ANIMATION_FILTER, FORMAT_NOTE, start_export
        if imgui.button("Animation (flipbook, video)...", (-1, 0)):
            ed.dialogs.ask_path("Export animation", True, ANIMATION_FILTER, lambda path: start_export(ed, path),
                                default="animation.png")
        tip(f"The texture flowing, {m.frames} frames (the Motion panel sets them). " + FORMAT_NOTE)
    lat = ed.session.controls.lattice if ed.session is not None and ed.session.ready else None
    if lat is not None:
        cx, cy = lat.cell(ed.session.analysis.size)
        imgui.push_text_wrap_pos(0)
        imgui.text_disabled(f"Lattice: the view and PNG rectangles export as the canvas shows them "
                            f"({'input geometry' if ed.geometry() is not None else 'rectified'}); "
                            f"tile sets, BigTIFFs and seamless tiles are rectified (tiles: whole {cx}x{cy} px "
                            f"cells).")
        imgui.pop_text_wrap_pos()


def rectangle(p: Panels) -> None:
    """A rectangle of the infinite canvas as one PNG, a UDIM tile set or a
    BigTIFF, with its size and time estimated before it starts."""
    from infinitex.engine.synth import MAX_WINDOW_PIXELS, MAX_WINDOW_SIDE
    from infinitex.export import MAX_SIDE
    from infinitex.export import TILE_SIZES as STREAM_TILES

    from infinitex.export.jobs import ExportEstimate
    ed = p.ed
    imgui.set_next_item_width(-90)
    _, ed.exports.settings.rect = imgui.input_int4("x y w h", ed.exports.settings.rect)
    tip("A rectangle of the infinite canvas: its top-left corner and size, in texture pixels")
    if imgui.small_button("The view"):
        r = ed.exports.view_rect()
        ed.exports.settings.rect = [r.x0, r.y0, r.w, r.h]
    tip("The rectangle the canvas shows now")
    for n, label in ((8192, "8k"), (32768, "32k"), (65536, "64k")):
        imgui.same_line()
        if imgui.small_button(f"{label}##square"):
            ed.exports.settings.rect = [ed.exports.settings.rect[0], ed.exports.settings.rect[1], n, n]
            if ed.exports.settings.format == "png":
                ed.exports.settings.format = "tiff"
        tip(f"{n} x {n} px from the same corner")
    keys = [k for k, _, _ in EXPORT_FORMATS]
    imgui.set_next_item_width(-90)
    changed, i = imgui.combo("Format", keys.index(ed.exports.settings.format), [label for _, label, _ in EXPORT_FORMATS])
    if changed:
        ed.exports.settings.format = keys[i]
    tip(EXPORT_FORMATS[keys.index(ed.exports.settings.format)][2])
    x, y, w, h = ed.exports.settings.rect
    streamed = ed.exports.settings.format != "png"
    problem = None
    if w < 1 or h < 1:
        problem = "The rectangle is empty."
    elif streamed and (w > MAX_SIDE or h > MAX_SIDE):
        problem = f"At most {MAX_SIDE} px a side."
    elif not streamed and (w > MAX_WINDOW_SIDE or h > MAX_WINDOW_SIDE or w * h > MAX_WINDOW_PIXELS):
        problem = (f"Too large for one PNG (at most {MAX_WINDOW_SIDE} px a side and "
                   f"{MAX_WINDOW_PIXELS // 2**20} Mpixels): choose PNG tiles or BigTIFF.")
    elif abs(x) > 2**30 or abs(y) > 2**30:
        problem = "The corner must be within +-2^30."
    low = False
    if streamed:
        ed.exports.settings.stream_tile = size_combo("Tile##stream", STREAM_TILES, ed.exports.settings.stream_tile)
        tip("Side of the tiles the export is rendered in (and, for PNG tiles, of each file)")
        imgui.set_next_item_width(-90)
        cores = os.cpu_count() or 1
        _, ed.exports.settings.workers = imgui.slider_int("Workers", ed.exports.settings.workers, 1, max(2, cores))
        tip("Processes rendering tiles, each with its own GL context, while the editor stays live "
            f"(this machine has {cores} cores)")
        if problem is None and ed.session is not None and ed.session.ready:
            key = (ed.doc.analysis_key(), ed.exports.settings.format, ed.exports.settings.stream_tile)
            if ed.exports.settings.estimate is None or ed.exports.settings.estimate.key != key:
                if ed.exports.settings.estimate is not None:
                    ed.exports.settings.estimate.close()
                ed.exports.settings.estimate = ExportEstimate(ed.doc, ed.exports.settings.format, ed.exports.settings.stream_tile)
            ed.exports.settings.estimate.poll()
            text, low = ed.exports.settings.estimate.describe(w, h, ed.exports.settings.workers, ed.dialogs.start_dir())
            imgui.push_text_wrap_pos(0)
            if low:
                imgui.text_colored((1.0, 0.55, 0.35, 1.0), text)
            else:
                imgui.text_disabled(text)
            imgui.pop_text_wrap_pos()
    elif problem is None:
        imgui.text_disabled(f"{w} x {h} px, {w * h / 1e6:.1f} Mpixels")
    if problem:
        imgui.push_text_wrap_pos(0)
        imgui.text_colored((1.0, 0.55, 0.35, 1.0), problem)
        imgui.pop_text_wrap_pos()
    imgui.begin_disabled(problem is not None or (ed.exports.job is not None and (streamed or not ed.exports.apart())))
    if imgui.button("Export rectangle...", (-1, 0)):
        r = Rect.of(x, y, w, h)
        if streamed:
            fmt = ed.exports.settings.format
            filt = {"tiff": TIFF_FILTER, "zarr": ZARR_FILTER}.get(fmt, PNG_FILTER)
            ed.dialogs.ask_path("Export rectangle", True, filt, lambda path: ed.exports.start_streamed(path, r),
                                default="rectangle" + {"tiff": ".tif", "zarr": ".zarr"}.get(fmt, ".png"))
        else:
            flt, ext = _export_filter(ed)
            ed.dialogs.ask_path("Export rectangle", True, flt, lambda path: ed.exports.start(path, r),
                                default="rectangle" + ext)
    imgui.end_disabled()
    if streamed:
        tip("Rendered tile by tile in bounded memory. Stopped (Cancel, a crash), the same export continues "
            "where it stopped: the finished tiles are kept in NAME.parts beside it")


def export_view(p: Panels) -> None:
    ed = p.ed
    r = ed.exports.view_rect()
    flt, ext = _export_filter(ed)
    ed.dialogs.ask_path("Export view", True, flt, lambda path: ed.exports.start(path, r), default="view" + ext)


def _export_filter(ed) -> tuple[list[str], str]:
    """A single image exported at 32 bits is a float TIFF; everything else is named .png."""
    if ed.exports.settings.depth == 32 and ed.session.material is not None and ed.session.material.single:
        return ["Float TIFF", "*.tif *.tiff"], ".tif"
    return PNG_FILTER, ".png"


def tile_prompt(p: Panels) -> None:
    """File > Export toroidal tile: a small window with the tile's size (and the
    canvas preview of it) before the file is chosen."""
    p._tile_prompt = 1


def tile_prompt_window(p: Panels) -> None:
    ed = p.ed
    p._tile_prompt = modal_prompt("Export toroidal tile###tileprompt", p._tile_prompt, 380)
    if not p._tile_prompt:
        return
    ed.exports.settings.tile_size = size_combo("Tile size", TILE_SIZES, ed.exports.settings.tile_size)
    tip("Side of the seamless tile, in pixels")
    ed.viewer.show_tile(imgui.checkbox("Show the tile on the canvas (T)", ed.viewer.tile_mode)[1])
    tip("The canvas shows the periodic texture this tile size makes, tile borders drawn")
    go = imgui.button("Choose file...", (150, 0))
    imgui.same_line()
    cancel = imgui.button("Cancel", (110, 0)) or imgui.is_key_pressed(imgui.Key.escape, False)
    if go or cancel:
        p._tile_prompt = 0
        imgui.close_current_popup()
    imgui.end_popup()
    if go:
        export_tile(p)


def export_tile(p: Panels) -> None:
    ed = p.ed
    n = ed.exports.settings.tile_size
    flt, ext = _export_filter(ed)
    ed.dialogs.ask_path("Export toroidal tile", True, flt,
                        lambda path: ed.exports.start(path, Rect(0, 0, n, n), toroidal=n), default=f"tile{n}{ext}")
