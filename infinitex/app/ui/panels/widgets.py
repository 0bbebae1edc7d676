"""Small widgets the panels share: the plain-words tooltip (``tip``, whose
last text the GUI tests read in ``LAST_TIP``), the size combo box and the
zoom as text (status bar and Display panel)."""
from __future__ import annotations

from imgui_bundle import imgui


LAST_TIP: list[str] = [""]  # the last tooltip shown (read by the GUI tests)


def tip(text: str) -> None:
    """A plain-words tooltip for the last item (the paper's name in brackets)."""
    if imgui.is_item_hovered(imgui.HoveredFlags_.for_tooltip):
        imgui.set_tooltip(text)
        LAST_TIP[0] = text


def size_combo(label: str, sizes, value: int) -> int:
    """A combo box of sizes (px); returns the one chosen."""
    imgui.set_next_item_width(-90)
    changed, i = imgui.combo(label, list(sizes).index(value), [str(s) for s in sizes])
    return sizes[i] if changed else value


def zoom_text(z: float) -> str:
    """The zoom as a percentage, or 1/N when far out."""
    return f"{z * 100:.0f}%" if z >= 0.1 else f"1/{1 / z:.0f}"
