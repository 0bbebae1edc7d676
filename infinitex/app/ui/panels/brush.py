"""The active tool's options section (Brush, Features or Lattice, titled after
the tool): the tool's own options, and for the paint tools a button that
clears the painted randomness."""
from __future__ import annotations

from dataclasses import replace
from typing import TYPE_CHECKING

from imgui_bundle import imgui

if TYPE_CHECKING:
    from . import Panels


def draw(p: Panels) -> None:
    """The options of the active tool."""
    ed = p.ed
    ed.tool.options()
    doc = ed.doc
    if ed.tool.name.startswith("paint") and (doc.randomness_canvas is not None
                                             or doc.randomness_exemplar is not None):
        if imgui.button("Clear painted randomness", (-1, 0)):
            ed.edit(replace(doc, randomness_canvas=None, randomness_exemplar=None), "Clear painted randomness")
