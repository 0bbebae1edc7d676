"""Small widgets the panels share: the plain-words tooltip (``tip``, whose
last text the GUI tests read in ``LAST_TIP``), the size combo box and the
zoom as text (status bar and Display panel)."""
from __future__ import annotations

from imgui_bundle import imgui

from ..tips import LAST_TIP, TIP_FRAME, tip  # noqa: F401 (where the panels have always found them)


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
