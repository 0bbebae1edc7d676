"""Lattices in project files (format version 3): the origin, the two
translation vectors and the cell counts of engine/controls/lattice.py, and how
many levels are lattice levels. Untrusted data: every number checked, a
damaged entry is one sentence."""
from __future__ import annotations

from infinitex.engine.controls.lattice import Lattice, LatticeError

from .document import ProjectError, is_number


def lattice_to_json(lat: Lattice) -> dict:
    return {"origin": list(lat.origin), "t1": list(lat.t1), "t2": list(lat.t2),
            "cells": [lat.nx, lat.ny], "levels": lat.levels}


def lattice_from_json(d: object) -> Lattice | None:
    if d is None:
        return None
    bad = ProjectError("The project's lattice is damaged.")
    if not isinstance(d, dict):
        raise bad
    vecs = []
    for key in ("origin", "t1", "t2"):
        v = d.get(key)
        if not (isinstance(v, list) and len(v) == 2 and all(is_number(x) and abs(x) < 1e6 for x in v)):
            raise bad
        vecs.append((float(v[0]), float(v[1])))
    cells, levels = d.get("cells"), d.get("levels")
    if not (isinstance(cells, list) and len(cells) == 2
            and all(isinstance(c, int) and not isinstance(c, bool) and 1 <= c <= 16 for c in cells)):
        raise bad
    if levels is not None and not (isinstance(levels, int) and not isinstance(levels, bool) and 0 <= levels <= 10):
        raise bad
    lat = Lattice(vecs[0], vecs[1], vecs[2], cells[0], cells[1], levels)
    try:
        lat.check_shape()
    except LatticeError as exc:
        raise ProjectError(f"The project's lattice: {exc}") from None
    return lat
