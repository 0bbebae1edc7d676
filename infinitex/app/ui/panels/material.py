"""The Material panel: the document's maps, their roles and analysis weights;
adding and removing maps (each change analyzes the exemplar again, one undo
step)."""
from __future__ import annotations

from dataclasses import replace
from typing import TYPE_CHECKING

from imgui_bundle import imgui

from infinitex.engine.material import IMAGE, ROLE_LABELS, ROLES, role_of
from infinitex.project import ExemplarSource

from ..dialogs import MAPS_FILTER
from .widgets import tip

if TYPE_CHECKING:
    from . import Panels


def draw(p: Panels) -> None:
    """The maps of the document, their roles and analysis weights."""
    ed = p.ed
    doc, mat = ed.doc, ed.session.material
    sources = list(doc.sources())
    single = not doc.is_material
    weights = doc.weight_dict() or mat.default_weights()
    imgui.push_text_wrap_pos(0)
    if single:
        imgui.text_disabled("A single image. Add its other maps (normal, height, roughness...) to make a "
                            "material: every map follows the same synthesis.")
    imgui.pop_text_wrap_pos()
    busy = ed.files.pending is not None
    imgui.begin_disabled(busy or doc.lattice is not None)
    for i, (role, src) in enumerate(sources):
        imgui.push_id(f"map{i}")
        roles = [IMAGE, *ROLES] if single else list(ROLES)
        imgui.set_next_item_width(140)
        changed, j = imgui.combo("##role", roles.index(role), [ROLE_LABELS[r] for r in roles])
        tip("What this map is; a role another map has swaps the two")
        if changed and roles[j] != role:
            _set_role(ed, sources, i, roles[j])
        imgui.same_line()
        imgui.text(src.name)
        mp = mat.maps.get(role)
        if mp is not None:
            ex = mp.exemplar
            chans = {1: "gray", 2: "gray + alpha", 3: "RGB", 4: "RGBA"}[ex.channels]
            kind = "float" if ex.depth == 32 else f"{ex.depth}-bit"
            imgui.text_disabled(f"{ex.original_size[0]}x{ex.original_size[1]}, {kind} {chans}")
        if not single:
            imgui.same_line(150)
            imgui.set_next_item_width(70)
            w = float(weights.get(role, 0.0))
            changed, v = imgui.slider_float("Analysis", w, 0.0, 2.0, "%.2f")
            tip("How much this map decides which exemplar spots look alike (0: it only follows). "
                "Applied when you let go: the exemplar is analyzed again")
            if imgui.is_item_deactivated_after_edit():
                nw = {**weights, role: float(v)}
                _set_weights(ed, nw)
            imgui.same_line()
            if imgui.small_button("Remove"):
                rest = [m for k, m in enumerate(sources) if k != i]
                ed.files.begin_load("exemplar", doc.with_maps(rest), None, None, f"Remove the {role} map")
            tip("Drop this map from the material")
        imgui.pop_id()
    if imgui.button("Add map...", (-1, 0)):
        ed.dialogs.ask_path("Add a map", False, MAPS_FILTER, lambda path: _add_map(ed, path))
    tip("Another map aligned with these (same size): its role comes from its name (NAME_normal, "
        "NAME_height...), else the first free role")
    imgui.end_disabled()
    if doc.lattice is not None:
        imgui.text_disabled("A lattice works on a single image.")


def _set_role(ed, sources, i: int, new: str) -> None:
    maps = list(sources)
    role, src = maps[i]
    taken = next((k for k, (r, _) in enumerate(maps) if r == new), None)
    if taken is not None:
        maps[taken] = (role, maps[taken][1])
    maps[i] = (new, src)
    ed.files.begin_load("exemplar", ed.doc.with_maps(maps), None, None, "Map role")


def _set_weights(ed, weights: dict) -> None:
    w = tuple((r, float(weights.get(r, 0.0))) for r, _ in ed.doc.sources())
    if not any(v > 0 for _, v in w):
        ed.dialogs.message("Analysis weights", "At least one map must feed the analysis (a weight above 0).")
        return
    ed.files.begin_load("exemplar", replace(ed.doc, weights=w), None, None, "Analysis weights")


def _add_map(ed, path: str) -> None:
    try:
        src = ExemplarSource.from_file(path)
    except OSError as exc:
        ed.dialogs.message("Add a map", str(exc))
        return
    maps = list(ed.doc.sources())
    used = {r for r, _ in maps}
    named = role_of(path)
    if maps[0][0] == IMAGE:  # a single image becomes the base color (or the first free role)
        new_role = named[1] if named else None
        first = "basecolor" if new_role != "basecolor" else next(r for r in ROLES if r != "basecolor")
        maps = [(first, maps[0][1])]
        used = {first}
    role = named[1] if named and named[1] not in used else next((r for r in ROLES if r not in used), None)
    if role is None:
        ed.dialogs.message("Add a map", "The material already has a map for every role.")
        return
    ed.files.begin_load("exemplar", ed.doc.with_maps(maps + [(role, src)]), None, None, f"Add the {role} map")
