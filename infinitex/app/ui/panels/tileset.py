"""File > Export tile set: a corner Wang set (or variants of the seamless
tile) for game engines. Its settings and, before any file is chosen, a
preview of the tiles laid out at random as an engine would (Shuffle for
another layout); the set is made while the editor stays live (a slice of
work per frame) and, once a file is chosen, written in the background."""
from __future__ import annotations

from typing import TYPE_CHECKING

import moderngl
import numpy as np
from imgui_bundle import imgui

from infinitex.engine.imagefile import to_u8
from infinitex.engine.pyramid import SynthesisError
from infinitex.export.wang import MAX_VARIANTS, WANG_SIZES, TileSetError

from ..dialogs import PNG_FILTER
from .widgets import modal_prompt, size_combo, tip

if TYPE_CHECKING:
    from . import Panels

FRAME_BUDGET_S = 0.030  # the set's work per frame while the dialog shows its progress
PREVIEW_PX = 440        # the preview's side in the dialog
KINDS = [
    ("wang2", "Corner Wang set, 2 colours (16 tiles)",
     "16 tiles, every combination of 2 corner colours: two tiles fit side by side wherever their shared corners "
     "have the same colours, and each is different inside. The engine draws a valid one per cell (at random)"),
    ("wang3", "Corner Wang set, 3 colours (81 tiles)",
     "81 tiles with 3 corner colours: less repetition than 16, in an atlas 9 tiles a side"),
    ("variants", "Variants of one seamless tile",
     "Tiles with the same borders as one seamless (toroidal) tile and different insides: any of them fits next "
     "to any other, for engines that only pick which tile to draw"),
]


class TileSetDialog:
    """The dialog's state: its settings, the set being made (``job``, for the
    settings and document of ``key``) and the preview's texture."""

    def __init__(self):
        self.state = 0          # 1: open the window, 2: open
        self.kind = "wang2"
        self.size = 256
        self.variants = 4
        self.per_tile = False
        self.tiled = True       # Tiled's .tsx (per map) and an example .tmx
        self.godot = True       # Godot 4's TileSet .tres
        self.job = None
        self.key = None
        self.seed = 0
        self.tex = None
        self.tex_seed: int | None = None
        self.zoom = 0.0         # the preview's screen px per preview px; 0: fit, filtered
        self.error: str | None = None

    @property
    def building(self) -> bool:
        return self.state == 2 and self.job is not None and not self.job.built and self.job.error is None

    def drop(self) -> None:
        if self.job is not None and not self.job.built:
            self.job.cancel()
        self.job, self.key = None, None
        self._release_tex()

    def _release_tex(self) -> None:
        if self.tex is not None:
            self.tex.release()
        self.tex, self.tex_seed = None, None


def open_dialog(p: Panels) -> None:
    p.tileset.state = 1


def _plan(p: Panels):
    from infinitex.export.tileset import plan_for
    d, ed = p.tileset, p.ed
    colors = {"wang2": 2, "wang3": 3}.get(d.kind, 1)
    view = ed.view
    return plan_for(ed.session, colors, d.size, d.variants, (int(view.x), int(view.y)))


def _start(p: Panels, plan) -> None:
    from infinitex.export.tileset import TileSetJob
    d, ed = p.tileset, p.ed
    d.drop()
    d.key = _key(p)
    d.job = TileSetJob(ed.session, plan)


def _key(p: Panels) -> tuple:
    d, ed = p.tileset, p.ed
    return d.kind, d.size, d.variants, id(ed.doc), ed.session.generation


def _show_preview(p: Panels) -> None:
    """Upload the preview (the first map, laid out with the current seed) when it changes."""
    d = p.tileset
    if d.tex_seed == d.seed and d.tex is not None:
        return
    d._release_tex()
    img = to_u8(d.job.arranged(d.seed))
    if img.shape[2] == 1:
        img = np.repeat(img, 3, axis=2)
    if img.shape[2] == 2:  # grey and alpha
        img = np.concatenate([np.repeat(img[..., :1], 3, axis=2), img[..., 1:]], axis=2)
    if img.shape[2] == 3:
        img = np.concatenate([img, np.full(img.shape[:2] + (1,), 255, np.uint8)], axis=2)
    d.tex = p.ed.session.gpu.ctx.texture((img.shape[1], img.shape[0]), 4, np.ascontiguousarray(img).tobytes())
    d.tex.build_mipmaps()  # fitted, a 2048 px layout is filtered down, not point-sampled into noise
    d.tex.filter = (moderngl.LINEAR_MIPMAP_LINEAR, moderngl.NEAREST)
    d.tex_seed = d.seed


def window(p: Panels) -> None:
    d, ed = p.tileset, p.ed
    d.state = modal_prompt("Export tile set###tileset", d.state, PREVIEW_PX + 30, 1 / 2)
    if not d.state:
        return
    keys = [k for k, _, _ in KINDS]
    imgui.set_next_item_width(-90)
    changed, i = imgui.combo("Kind", keys.index(d.kind), [label for _, label, _ in KINDS])
    if changed:
        d.kind = keys[i]
    tip(KINDS[keys.index(d.kind)][2])
    d.size = size_combo("Tile size", WANG_SIZES, d.size)
    tip("Side of each tile, in texture pixels")
    if d.kind == "variants":
        imgui.set_next_item_width(-90)
        _, d.variants = imgui.slider_int("Variants", d.variants, 2, MAX_VARIANTS)
        tip("How many tiles: the same borders, different insides")
    _, d.per_tile = imgui.checkbox("Also one file per tile", d.per_tile)
    tip("Beside the atlas: NAME_0110.png (corner colours nw ne sw se) or NAME_v3.png; the JSON lists them")
    _, d.tiled = imgui.checkbox("Tiled terrain", d.tiled)
    tip("NAME.tsx: a Tiled tileset whose corner Wang set the Terrain brush paints with (one per map of a "
        "material), and NAME.tmx: an example map of the preview's layout")
    imgui.same_line()
    _, d.godot = imgui.checkbox("Godot 4 terrain", d.godot)
    tip("NAME.tres: a Godot 4 TileSet over the atlas with a Match Corners terrain set (the normal map of a "
        "material lights it): drop the folder into a project and paint with the terrain")
    problem = None
    try:
        plan = _plan(p)
        if ed.session.controls.directed:
            problem = "A tile set follows no direction field (its tiles meet in any order): turn it off first."
    except TileSetError as exc:
        plan, problem = None, str(exc)
    if d.job is not None and d.key != _key(p):
        d.drop()  # other settings or another document: the preview is stale
    if problem:
        imgui.push_text_wrap_pos(0)
        imgui.text_colored((1.0, 0.55, 0.35, 1.0), problem)
        imgui.pop_text_wrap_pos()
    _preview_area(p, plan, problem)
    imgui.begin_disabled(problem is not None)
    go = imgui.button("Export...", (140, 0))
    imgui.end_disabled()
    tip("Choose the file: the atlas (NAME.png; a material: one per map), NAME.json (each tile's corner colours "
        "and place), NAME_preview.png (8 x 8 tiles at random) and the engines' files ticked above")
    imgui.same_line()
    close = imgui.button("Close", (100, 0)) or imgui.is_key_pressed(imgui.Key.escape, False)
    if go or close:
        d.state = 0
        imgui.close_current_popup()
    imgui.end_popup()
    if close:
        d.drop()
    elif go:
        if d.job is None:
            _start(p, plan)
        job, d.job, d.key = d.job, None, None
        d._release_tex()
        per_tile, seed = d.per_tile, d.seed
        engines = tuple(e for e, on in (("tiled", d.tiled), ("godot", d.godot)) if on)
        ed.dialogs.ask_path("Export tile set", True, PNG_FILTER,
                            lambda path: ed.exports.start_tileset(path, job, per_tile, seed, engines=engines),
                            default=f"tileset{d.size}.png")


def _preview_area(p: Panels, plan, problem: str | None) -> None:
    d, ed = p.tileset, p.ed
    job = d.job
    if job is not None and not job.built and job.error is None:
        job.step(FRAME_BUDGET_S)
        ed.screen_fbo.use()
    if job is not None and job.error:
        d.error, d.job = job.error, None
        job = None
    if job is not None and job.built:
        _show_preview(p)
        _zoomable(d)
        cols, rows = job.plan.grid
        n = job.plan.tile
        side = 8 * n
        scale = d.tex.width / side
        imgui.text_disabled(f"{job.plan.count} tiles of {n} px, an atlas of {cols * n} x {rows * n}; "
                            f"8 x 8 of them at random above" + ("" if scale == 1 else f" (at 1:{round(1 / scale)})"))
        if imgui.button("Shuffle", (140, 0)):
            d.seed += 1
        tip("Another random layout of the same tiles (the preview file is written with the one shown)")
        imgui.same_line()
        if imgui.button("Fit" if d.zoom else "1:1", (70, 0)):
            d.zoom = 0.0 if d.zoom else 1.0
        tip("1:1: every pixel of the layout shown (drag it, or the scroll bars, to look around; the wheel "
            "zooms); Fit: the whole layout, filtered")
        return
    imgui.dummy((PREVIEW_PX, 8))
    if job is not None:
        imgui.progress_bar(job.progress, (-1, 0), f"Making the set: {job.progress * 100:.0f} %")
        return
    if d.error:
        imgui.push_text_wrap_pos(0)
        imgui.text_colored((1.0, 0.55, 0.35, 1.0), d.error)
        imgui.pop_text_wrap_pos()
    imgui.begin_disabled(problem is not None)
    if imgui.button("Preview", (140, 0)):
        d.error = None
        try:
            _start(p, plan)
        except (SynthesisError, ValueError) as exc:
            d.error = str(exc)
    imgui.end_disabled()
    tip("Make the set now and show 8 x 8 of its tiles laid out at random, as an engine would")


def _zoomable(d: TileSetDialog) -> None:
    """The preview: fitted (filtered by its mipmaps) or zoomed in a scrolling
    view that a drag pans and the mouse wheel zooms (1/4x to 4x)."""
    w = d.tex.width
    if not d.zoom:
        imgui.image(imgui.ImTextureRef(d.tex.glo), (PREVIEW_PX, PREVIEW_PX))
        if imgui.is_item_hovered() and imgui.get_io().mouse_wheel > 0:
            d.zoom = 1.0
        return
    imgui.begin_child("tileset-preview", (PREVIEW_PX, PREVIEW_PX), imgui.ChildFlags_.borders,
                      imgui.WindowFlags_.horizontal_scrollbar | imgui.WindowFlags_.no_scroll_with_mouse)
    imgui.image(imgui.ImTextureRef(d.tex.glo), (w * d.zoom, w * d.zoom))
    io = imgui.get_io()
    if imgui.is_item_hovered():
        if imgui.is_mouse_dragging(imgui.MouseButton_.left, 0.0):
            imgui.set_scroll_x(imgui.get_scroll_x() - io.mouse_delta.x)
            imgui.set_scroll_y(imgui.get_scroll_y() - io.mouse_delta.y)
        if io.mouse_wheel:
            step = 2.0 if io.mouse_wheel > 0 else 0.5
            fit = PREVIEW_PX / w
            zoom = min(4.0, max(0.25, d.zoom * step))
            d.zoom = 0.0 if zoom <= fit else zoom
    imgui.end_child()
