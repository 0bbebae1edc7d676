"""The Randomness panel: Structure / Variety (the fidelity stage's preset), the
randomness of every scale at once and of each scale (jitter, one undo step a
drag), Reset, the seed and New seed."""
from __future__ import annotations

from dataclasses import replace
from typing import TYPE_CHECKING

from imgui_bundle import imgui

from infinitex.engine.params import DEFAULT_JITTER, DEFAULT_STRUCTURE, STRUCTURE_LEVELS, STRUCTURE_NAMES

from .widgets import tip

if TYPE_CHECKING:
    from . import Panels


def draw(p: Panels) -> None:
    """The Randomness panel."""
    ed = p.ed
    doc, L = ed.doc, ed.session.L
    jit = doc.jitter_for(L)
    imgui.push_item_width(-90)
    changed, v = imgui.slider_int("Structure", doc.structure, 0, STRUCTURE_LEVELS - 1,
                                  STRUCTURE_NAMES[doc.structure])
    tip("How hard the synthesis keeps the exemplar's elements whole. Toward Variety: every pixel is "
        "chosen on its own, the most variety, but strands, cell walls, letters and bricks may break. "
        "Toward Maximum: whole patches are matched and their seams moved to where they show least, so "
        "elements come out whole; more copied, slower to settle. "
        f"Default {STRUCTURE_NAMES[DEFAULT_STRUCTURE]} (fidelity stage: patch optimization)")
    if changed:
        ed.edit(replace(ed.doc, structure=int(v)), "Structure", group="structure")
    if imgui.is_item_deactivated():
        ed.history.end_group()
    p.overall = sum(jit) / len(jit)
    changed, v = imgui.slider_float("All levels", p.overall, 0.0, 1.0, "%.2f")
    tip("Randomness at every scale at once: 0 repeats the exemplar as it is (a plain tiling), "
        "1 rearranges it the most (jitter r, LH05)")
    if changed:
        ed.edit(doc.with_all_jitter(L, v), "Randomness (all levels)", group="jitter-all")
    if imgui.is_item_deactivated():
        ed.history.end_group()
    for l in range(L + 1):
        size = 1 << (L - l)
        changed, v = imgui.slider_float(f"{size} px##jit{l}", jit[l], 0.0, 1.0, "%.2f")
        tip(f"How much features about {size} px across are moved: 0 keeps the exemplar's arrangement "
            f"at this scale, 1 moves them up to their own size (level {l}, jitter r_{l})")
        if changed:
            ed.edit(ed.doc.with_jitter(L, l, v), f"Randomness of level {l}", group=("jitter", l))
        if imgui.is_item_deactivated():
            ed.history.end_group()
    imgui.pop_item_width()
    if imgui.button("Reset"):
        ed.edit(replace(doc, jitter=()), "Reset randomness")
    tip(f"Back to the default randomness ({DEFAULT_JITTER}) at every scale")
    imgui.same_line()
    imgui.set_next_item_width(120)
    changed, seed = imgui.input_int("Seed", doc.seed, 1, 100, imgui.InputTextFlags_.enter_returns_true)
    tip("Another seed gives another texture with the same look; the same seed always gives the same one")
    if changed:
        ed.edit(replace(ed.doc, seed=int(seed) % (2 ** 32)), "Seed")
    imgui.same_line()
    if imgui.button("New seed"):
        ed.files.new_seed()
    tip("A random seed: a new variation")
