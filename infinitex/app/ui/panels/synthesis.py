"""The Advanced panel (collapsed at first): the synthesis's internals,
correction passes, subpasses, coherence, similar spots, feature distance,
the matching model, and the passes of each scale."""
from __future__ import annotations

from dataclasses import replace
from typing import TYPE_CHECKING

from imgui_bundle import imgui

from infinitex.engine.params import FIRST_CORRECTED_LEVEL

from .widgets import tip

if TYPE_CHECKING:
    from . import Panels

# The Advanced section's sliders: document field, label, range, what it does in plain words.
ADVANCED_SLIDERS = [
    ("passes", "Correction passes", 0, 4, "How many times each scale is cleaned up to look like the exemplar: "
     "more looks closer to it, costs more; sets every cleaned-up scale (each has its own under Passes per scale) "
     "(correction passes, LH05 3.3)"),
    ("subgrid", "Subpasses (s x s)", 1, 4, "In how many interleaved groups a clean-up pass visits the pixels; "
     "2 x 2 is the paper's choice (subpasses s^2, LH05 3.3)"),
    ("kappa", "Coherence", 0.0, 2.0, "Preference for continuing the current patch of exemplar over jumping to a "
     "similar spot: higher gives larger intact patches and less variety (coherence kappa, LH05)"),
    ("k", "Similar spots", 0, 4, "How many similar exemplar spots each pixel may jump to: more gives more variety "
     "and a longer analysis (k-coherence candidates k, LH05); 0: none, a random walk over the whole exemplar "
     "searches instead, with no analysis time (random-walk search, TBN10). Exemplars over 512 px always use it"),
    ("feature_weight", "Feature distance", 0.0, 2.0, "How much each pixel's distance to the exemplar's elements "
     "(the bright shapes against their background) counts when matching: keeps spots, cells and glyphs more "
     "whole, at some cost in fine detail; 0 off (feature-distance channel, LH06; Appearance matching only)"),
]


def draw(p: Panels) -> None:
    """The Advanced panel."""
    ed = p.ed
    doc, L = ed.doc, ed.session.L
    imgui.push_text_wrap_pos(0)
    imgui.text_disabled("How the synthesis works inside; the defaults suit most exemplars.")
    imgui.pop_text_wrap_pos()
    imgui.push_item_width(-150)
    for field, label, lo, hi, text in ADVANCED_SLIDERS:
        value = getattr(ed.doc, field)
        if isinstance(value, float):
            changed, v = imgui.slider_float(label, value, lo, hi, "%.2f")
            v = round(v, 3)
        else:
            changed, v = imgui.slider_int(label, value, lo, hi)
        tip(text)
        if changed:  # a drag is one undo step
            change = {field: v}
            if field == "passes" and ed.doc.level_passes:  # every cleaned-up scale gets the new count
                change["level_passes"] = tuple(v if c else 0 for c in ed.doc.passes_for(L))
            ed.edit(replace(ed.doc, **change), label, group=field)
        if imgui.is_item_deactivated():
            ed.history.end_group()
        an = ed.session.analysis
        if field == "k" and an is not None and an.k != ed.doc.k:
            imgui.push_text_wrap_pos(0)
            imgui.text_disabled(f"The exemplar is {an.size} px: a random walk searches it (k = 0).")
            imgui.pop_text_wrap_pos()
    models = ["appearance", "color"]
    changed, i = imgui.combo("Matching", models.index(doc.model), ["Appearance (LH06)", "Colors 5x5 (LH05)"])
    tip("What 'looks alike' means when cleaning up: Appearance compares smoothed, compressed "
        "neighborhoods (better; appearance space, LH06); Colors compares 5x5 colors (LH05)")
    if changed:
        ed.edit(replace(ed.doc, model=models[i]), "Neighborhood model")
    imgui.pop_item_width()
    if imgui.tree_node("Passes per scale"):
        imgui.push_text_wrap_pos(0)
        imgui.text_disabled("Clean-up passes at each scale, finest last; 0 leaves a scale as jittered. "
                            "Coarse scales cost little.")
        imgui.pop_text_wrap_pos()
        counts = ed.doc.passes_for(L)
        imgui.push_item_width(-150)
        for l in range(L + 1):
            size = 1 << (L - l)
            changed, v = imgui.slider_int(f"{size} px##pass{l}", counts[l], 0, 8)
            tip(f"How many times features about {size} px across are cleaned up (level {l}); "
                "0: not at all (correction passes per level, LH05 3.3)")
            if changed:
                ed.edit(ed.doc.with_level_passes(L, l, v), f"Passes of level {l}", group=("passes", l))
            if imgui.is_item_deactivated():
                ed.history.end_group()
        imgui.pop_item_width()
        if imgui.small_button("Default passes"):
            ed.edit(replace(ed.doc, level_passes=(), corrected=None), "Default passes")
        tip(f"Back to {ed.doc.passes} passes (Correction passes) on every scale but the coarsest "
            f"{FIRST_CORRECTED_LEVEL}")
        imgui.tree_pop()
