"""The Flow tool's strokes on a document, without a window: the Brush paints
its dial's direction at the speed set (the uniform velocity counted in), the
Eraser brings the velocity back to the uniform one and leaves no map, a
stroke and its renewal period are one undo step, and a lattice refuses."""
import math
import os
from dataclasses import replace
from types import SimpleNamespace

import numpy as np
import pytest

from infinitex.app.ui.tools.flow import FlowTool
from infinitex.engine.controls.flow import Q, Flow
from infinitex.project import Document, ExemplarSource, History, View
from infinitex.project.flow_json import Motion

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))


class FakeEditor:
    def __init__(self, doc):
        self.history = History(doc)
        self.view = View(0.0, 0.0, 1.0)
        self.panels = SimpleNamespace(auto_period=True)
        self.told: list[str] = []

    @property
    def doc(self):
        return self.history.current

    def edit(self, doc, label, group=None, region=None):
        self.history.apply(doc, label, group, region)

    def tell(self, text):
        self.told.append(text)


@pytest.fixture
def ed():
    doc = Document(ExemplarSource.from_file(os.path.join(ROOT, "infinitex", "assets", "gravel.png")))
    return FakeEditor(replace(doc, motion=Motion(Flow.of(0.5, 0.0))))


def velocity(ed, x, y):
    vx, vy = ed.doc.motion.flow.sample(np.array([int(x * Q)]), np.array([int(y * Q)]))
    return vx[0] / Q, vy[0] / Q


def stroke(tool, points):
    tool.press(points[0], points[0])
    for p in points[1:]:
        tool.drag(p, p)
    tool.release()


def test_the_brush_paints_its_direction_and_the_eraser_takes_it_away(ed):
    tool = FlowTool(ed)
    tool.mode, tool.angle, tool.speed = "brush", 90.0, 2.0  # up the screen
    tool.brush.radius, tool.brush.strength, tool.brush.hardness = 30.0, 1.0, 0.9
    steps = len(ed.history.undo_stack)
    stroke(tool, [(0.0, 0.0), (40.0, 0.0), (80.0, 0.0)])
    assert len(ed.history.undo_stack) == steps + 1  # the stroke and its renewal period: one step
    vx, vy = velocity(ed, 40, 0)
    assert abs(vx) < 0.02 and abs(vy + 2.0) < 0.02  # 2 px a frame up, the uniform 0.5 right counted in
    assert velocity(ed, 40, 200) == (0.5, 0.0)  # far from the stroke: the uniform velocity
    flow = ed.doc.motion.flow
    assert flow.period == flow.suggested_period()  # automatic renewal from the stroke's shear
    tool.mode = "erase"
    tool.brush.radius = 120.0
    stroke(tool, [(-40.0, 0.0), (40.0, 0.0), (120.0, 0.0)])
    assert ed.doc.motion.flow.map is None and velocity(ed, 40, 0) == (0.5, 0.0)  # back to the uniform velocity
    ed.history.undo()
    assert velocity(ed, 40, 0) != (0.5, 0.0)


def test_the_comb_follows_the_stroke_and_a_lattice_refuses(ed):
    tool = FlowTool(ed)
    tool.speed = 3.0
    tool.brush.radius, tool.brush.strength, tool.brush.hardness = 24.0, 1.0, 0.9
    pts = [(10.0 * i, 10.0 * i) for i in range(12)]  # down and right
    stroke(tool, pts)
    vx, vy = velocity(ed, 60, 60)
    assert abs(math.degrees(math.atan2(vy, vx)) - 45.0) < 2 and abs(math.hypot(vx, vy) - 3.0) < 0.05
    from infinitex.engine.controls.lattice import Lattice
    lat_doc = replace(ed.doc, motion=None, lattice=Lattice.__new__(Lattice))
    ed.history.current = lat_doc
    before = ed.doc
    stroke(tool, pts)
    assert ed.doc is before and "lattice" in ed.told[-1]
