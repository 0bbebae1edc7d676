"""Lattice detection on the photo-like scenes of tests/lattice_scenes.py:
staggered cells (running bond with long bricks, shingles) come out as their
staggered grid, not as a square grid of the row height; a hexagonal plate as
its primitive cell, not one three times as large; stochastic scenes as no
lattice."""
from __future__ import annotations

import numpy as np
import pytest

import lattice_scenes
import near_regular
from infinitex.engine.controls.lattice_correlation import autocorrelation, lobe_radius
from infinitex.engine.controls.lattice_detect import _primitive, detect


@pytest.mark.parametrize("index", [2, 6, 10])  # running bond (31 x 11, 87 x 23 px), shingles
def test_staggered_cells_are_found(index):
    img, entry = lattice_scenes.scene(index)
    assert entry["what"] in ("running_bond", "shingles")
    d = detect(img)
    assert near_regular.correct(entry, d), (entry["vectors"], d.t1, d.t2, d.confidence)


def test_a_hexagonal_cell_is_primitive():
    """Hexagons whose repeat (0, 24), (24, 12) hides in a cell three times as
    large, (48, 0), (24, 36): the cell's third is found."""
    y, x = np.mgrid[0:240, 0:240].astype(float)
    B = np.array([[0.0, 24.0], [24.0, 12.0]]).T
    n = np.linalg.solve(B, np.stack([x.ravel(), y.ravel()]))
    f = (n - np.rint(n)).reshape(2, 240, 240)
    off = np.einsum("ij,jkl->ikl", B, f)
    img = np.exp(-(off[0] ** 2 + off[1] ** 2) / 20.0)
    ac = autocorrelation(img)
    c = (ac.shape[0] // 2, ac.shape[1] // 2)
    a, b = _primitive(ac, c, np.array([48.0, 0.0]), np.array([24.0, 36.0]), lobe_radius(ac))
    assert abs(abs(a[0] * b[1] - a[1] * b[0]) - 24.0 * 24.0) < 5.0, (a, b)


def test_stochastic_scenes_have_no_lattice():
    for index in (72, 74, 80, 82):
        img, entry = lattice_scenes.scene(index)
        assert entry["kind"] == "none"
        assert detect(img).lattice is None, index
