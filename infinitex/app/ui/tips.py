"""Tooltips that never cover the canvas: the plain-words tooltip of the last
item (``tip``), placed inside the window the item is in (the side panel, a
tool's window) and wrapped to its width, under the item, or, for the tool bar
drawn over the canvas, said in the status bar instead (``hint``). The GUI
tests read the last text in ``LAST_TIP``."""
from __future__ import annotations

import time

from imgui_bundle import imgui

LAST_TIP: list[str] = [""]  # the last tooltip shown (read by the GUI tests)
TIP_FRAME = [-1]            # the frame it was last shown in
HINT: list = ["", -1]       # the status bar's hint (text, frame): a tool bar item's tooltip
TIP_WIDTH_EM = 32           # tooltips wrap at this many font heights at most
QUIET_AFTER_WHEEL_S = 0.6   # no tooltip this long after the panel scrolled under a still mouse
_wheel = [0.0]
_released: dict = {"id": None, "pos": None}  # the control last released, and where the mouse was


def _wanted() -> bool:
    io = imgui.get_io()
    now = time.monotonic()
    if io.mouse_wheel or io.mouse_wheel_h:
        _wheel[0] = now
    item = imgui.get_item_id()
    mouse = (io.mouse_pos.x, io.mouse_pos.y)
    if imgui.is_item_deactivated():
        _released["id"], _released["pos"] = item, mouse
    if imgui.is_item_active() or now - _wheel[0] < QUIET_AFTER_WHEEL_S:
        return False
    if _released["id"] == item:
        if _released["pos"] == mouse:
            return False  # just released, the mouse still: the eyes are on the canvas, not on this
        _released["id"] = None
    return imgui.is_item_hovered(imgui.HoveredFlags_.for_tooltip)


def tip(text: str) -> None:
    """A plain-words tooltip for the last item (the paper's name in brackets).
    None while the item is dragged or just released under a still mouse (a
    slider's tooltip would cover the canvas it tunes), or just after a scroll
    (the item that scrolled under the mouse was not pointed at). Shown inside
    the item's window, under it, as wide as the window: never over the canvas."""
    if not _wanted():
        return
    pad = imgui.get_style().window_padding.x
    x0 = imgui.get_window_pos().x
    width = max(8 * imgui.get_font_size(), min(imgui.get_window_width() - 2 * pad,
                                               imgui.get_font_size() * TIP_WIDTH_EM))
    imgui.set_next_window_pos((x0 + pad, imgui.get_item_rect_max().y + 2))
    imgui.begin_tooltip()
    imgui.push_text_wrap_pos(imgui.get_cursor_pos().x + width - 2 * imgui.get_style().window_padding.x)
    imgui.text_unformatted(text)
    imgui.pop_text_wrap_pos()
    imgui.end_tooltip()
    LAST_TIP[0] = text
    TIP_FRAME[0] = imgui.get_frame_count()


def hint(text: str) -> None:
    """The last item's explanation in the status bar while it is hovered (an
    item drawn over the canvas: its tooltip would cover the canvas)."""
    if imgui.is_item_hovered() and not imgui.is_item_active():
        HINT[0], HINT[1] = text, imgui.get_frame_count()
        LAST_TIP[0] = text
        TIP_FRAME[0] = imgui.get_frame_count()


def current_hint() -> str:
    """The hint set this frame, or ''."""
    return HINT[0] if HINT[1] == imgui.get_frame_count() else ""
