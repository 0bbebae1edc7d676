"""The status bar under the canvas (timings, cursor, zoom, level, the last
notice), the canvas overlay (analysis progress, Refining...) and the export
progress window."""
from __future__ import annotations

import os
import time
from typing import TYPE_CHECKING

import numpy as np
from imgui_bundle import imgui

from infinitex.export.jobs import duration_text

from ..tips import current_hint
from .widgets import tip, zoom_text

if TYPE_CHECKING:
    from . import Panels


def status_bar(p: Panels) -> None:
    ed = p.ed
    imgui.separator()
    s = ed.session
    if ed.refined and ed.waits.idle:
        # Nothing to do: the editor sleeps until input comes, so a frame rate means nothing.
        parts = ["idle"]
    else:
        parts = [f"{ed.canvas_state.update_ms:5.1f} ms/update", f"{ed.canvas_state.pixels:>8,} px synthesized", f"{ed.frame_pacer.fps:5.1f} fps"]
    pv = s.model if ed.model_mode else None
    if pv is not None:  # a model: its texture's size and the finest level shown (the plane's view is elsewhere)
        parts.append(f"model texture {ed.doc.surface.size} px")
        if pv.image_level >= 0:
            parts.append(f"level {pv.image_level}/{s.L}")
    else:
        if ed.canvas_state.cursor is not None:
            cx, cy = ed.canvas_state.cursor
            parts.append(f"x {int(np.floor(cx))}  y {int(np.floor(cy))}")
        parts.append(f"zoom {zoom_text(ed.view.zoom)}")
        if ed.frame is not None:
            parts.append(f"level {ed.frame.level}/{s.L}")
    parts.append(ed.files.title.rsplit(" - ", 1)[0])
    said = current_hint()  # a tool bar item's explanation (a tooltip there would cover the canvas): the whole line
    if said:
        imgui.text_colored((0.95, 0.85, 0.45, 1.0), said)
        return
    imgui.text("   |   ".join(parts))
    if ed.notice is not None:
        text, t = ed.notice
        if time.monotonic() - t < 15.0:
            imgui.same_line()
            imgui.text_colored((0.55, 0.9, 0.55, 1.0), f"   {text}")


def canvas_overlay(p: Panels, p0, w, h) -> None:
    ed = p.ed
    job = ed.session.job
    text = None
    if job is not None and ed.session.quick_analysis:
        text = f"Quick preview; the full analysis of {job.doc.exemplar.name}: {job.progress * 100:.0f}%"
    elif job is not None:
        text = f"Analyzing {job.doc.exemplar.name}: {job.progress * 100:.0f}%  {job.message}"
    elif not ed.refined:
        text = "Refining..."
    if text:
        dl = imgui.get_window_draw_list()
        tw = imgui.calc_text_size(text).x
        dl.add_rect_filled((p0.x + 8, p0.y + 8), (p0.x + 24 + tw, p0.y + 30), imgui.get_color_u32((0, 0, 0, 0.55)), 4)
        dl.add_text((p0.x + 16, p0.y + 11), imgui.get_color_u32((1, 1, 1, 1)), text)


def progress_modals(p: Panels) -> None:
    """The tile dialogs, and the running export's progress: a modal window
    while it runs in the editor's own frames (a model export), a window of
    its own beside the canvas while it runs in other processes (the canvas
    stays live)."""
    p.tile_prompt_window()
    p.tileset_window()
    ed = p.ed
    job = ed.exports.job
    name = "Exporting###export"
    apart = job is not None and ed.exports.apart()
    if job is None or apart:
        if p._export_popup:  # the modal export ended: close its window
            opened, _ = imgui.begin_popup_modal(name, None, imgui.WindowFlags_.no_saved_settings)
            if opened:
                imgui.close_current_popup()
                imgui.end_popup()
            p._export_popup = False
        if apart:
            vp = imgui.get_main_viewport()
            imgui.set_next_window_pos((vp.pos.x + vp.size.x - 16, vp.pos.y + vp.size.y - 40), imgui.Cond_.always,
                                      (1.0, 1.0))
            imgui.set_next_window_size((420, 0))
            flags = (imgui.WindowFlags_.no_saved_settings | imgui.WindowFlags_.no_collapse
                     | imgui.WindowFlags_.no_focus_on_appearing | imgui.WindowFlags_.no_move)
            if imgui.begin(name, None, flags)[0]:
                _progress(ed, job)
            imgui.end()
        return
    if not p._export_popup:
        imgui.open_popup(name)
        p._export_popup = True
    vp = imgui.get_main_viewport()
    imgui.set_next_window_pos((vp.pos.x + vp.size.x / 2, vp.pos.y + vp.size.y / 3), imgui.Cond_.always, (0.5, 0.5))
    imgui.set_next_window_size((420, 0))
    opened, _ = imgui.begin_popup_modal(name, None, imgui.WindowFlags_.no_saved_settings)
    if opened:
        if _progress(ed, job):
            ed.exports.closed()
            imgui.close_current_popup()
        imgui.end_popup()


def _progress(ed, job) -> bool:
    """An export's name, progress, time left and Cancel; True when an export
    running in the editor's frames was cancelled (it ends at once)."""
    imgui.text(f"{os.path.basename(job.out_path)}: {job.out_rect.w} x {job.out_rect.h}")
    elapsed = time.monotonic() - job.started
    streamed = hasattr(job, "done_tiles")
    apart = ed.exports.apart()
    if streamed:
        total = job.job.total
        label = f"{job.done_tiles} / {total} tiles  ({elapsed:.0f} s)"
        imgui.progress_bar(job.progress, (-1, 0), label)
        rate, left = job.rate(), job.seconds_left()
        if job.kept:
            imgui.text_disabled(f"{job.kept} tiles kept from an earlier run")
        if rate is not None:
            imgui.text(f"{rate / 1e6:.2f} Mpixel/s with {job.workers} worker{'s' * (job.workers > 1)}, "
                       f"{'?' if left is None else duration_text(left)} left")
        else:
            imgui.text_disabled(f"Starting {job.workers} worker{'s' * (job.workers > 1)}...")
    else:
        imgui.progress_bar(job.progress, (-1, 0), f"{job.progress * 100:.0f} %  ({elapsed:.0f} s)")
        if 0.02 < job.progress < 1.0 and elapsed > 2.0:  # time left, from the rate so far
            imgui.text(f"About {duration_text(elapsed * (1.0 - job.progress) / job.progress)} left")
        else:
            imgui.text_disabled("Estimating the time left..." if job.progress < 1.0 else "Writing...")
    if ed.exports.queue:
        imgui.text_disabled(f"{len(ed.exports.queue)} more export{'s' * (len(ed.exports.queue) > 1)} waiting")
    if streamed and job.cancelling:
        imgui.text_disabled("Stopping after the tiles being rendered...")
        return False
    if imgui.button("Cancel", (120, 0)):
        job.cancel()
        return not apart
    if streamed:
        tip("Stops after the tiles being rendered; they and every finished tile are kept, and the "
            "same export continues from them")
    elif apart:
        tip("The export runs in a process of its own: the canvas stays live meanwhile. Cancel writes nothing")
    return False
