"""Small widgets the panels share: the plain-words tooltip (``tip``, whose
last text the GUI tests read in ``LAST_TIP``), the size combo box and the
zoom as text (status bar and Display panel)."""
from __future__ import annotations

import time

from imgui_bundle import imgui

LAST_TIP: list[str] = [""]  # the last tooltip shown (read by the GUI tests)
TIP_FRAME = [-1]            # the frame it was last shown in
TIP_WIDTH_EM = 32           # tooltips wrap at this many font heights: never cut at the window's edge
QUIET_AFTER_WHEEL_S = 0.6   # no tooltip this long after the panel scrolled under a still mouse
_wheel = [0.0]


def tip(text: str) -> None:
    """A plain-words tooltip for the last item (the paper's name in brackets),
    wrapped to a readable width. None while the item is being dragged (a
    slider's tooltip would cover the canvas it tunes) or just after a scroll
    (the item that scrolled under the mouse was not pointed at)."""
    io = imgui.get_io()
    now = time.monotonic()
    if io.mouse_wheel or io.mouse_wheel_h:
        _wheel[0] = now
    if imgui.is_item_active() or now - _wheel[0] < QUIET_AFTER_WHEEL_S:
        return
    if imgui.is_item_hovered(imgui.HoveredFlags_.for_tooltip):
        imgui.begin_tooltip()
        imgui.push_text_wrap_pos(imgui.get_font_size() * TIP_WIDTH_EM)
        imgui.text_unformatted(text)
        imgui.pop_text_wrap_pos()
        imgui.end_tooltip()
        LAST_TIP[0] = text
        TIP_FRAME[0] = imgui.get_frame_count()


def modal_prompt(name: str, state: int, width: float, height_frac: float = 1 / 3) -> int:
    """A centred modal window with a state kept by its panel (1: open it
    now, 2: open, 0: closed). Begins it when open (the caller draws it and
    calls ``imgui.end_popup()``); returns the new state."""
    if state == 1:
        imgui.open_popup(name)
        state = 2
    if not state:
        return 0
    vp = imgui.get_main_viewport()
    imgui.set_next_window_pos((vp.pos.x + vp.size.x / 2, vp.pos.y + vp.size.y * height_frac), imgui.Cond_.always,
                              (0.5, 0.5))
    imgui.set_next_window_size((width, 0))
    opened, _ = imgui.begin_popup_modal(name, None, imgui.WindowFlags_.no_saved_settings)
    return 2 if opened else 0


def size_combo(label: str, sizes, value: int) -> int:
    """A combo box of sizes (px); returns the one chosen."""
    imgui.set_next_item_width(-90)
    changed, i = imgui.combo(label, list(sizes).index(value), [str(s) for s in sizes])
    return sizes[i] if changed else value


def zoom_text(z: float) -> str:
    """The zoom as a percentage, or 1/N when far out."""
    return f"{z * 100:.0f}%" if z >= 0.1 else f"1/{1 / z:.0f}"
