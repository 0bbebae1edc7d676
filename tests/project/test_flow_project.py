"""Texture in motion in documents and project files (format 12): the flow and
its velocity map round trip exactly, older files still open, damaged or
hostile data is refused with one sentence, a flow does not go with a lattice;
``infinitex animate PROJECT`` plays the project's flow."""
import base64
import json
import os
import zlib

import numpy as np
import pytest
from clirun import infinitex

from infinitex.engine.controls.flow import Flow, VelocityMap
from infinitex.engine.controls.lattice import Lattice
from infinitex.project import Project, ProjectError, load_project, save_project
from infinitex.project.document import Document, ExemplarSource
from infinitex.project.flow_json import Motion

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
GRAVEL = os.path.join(ROOT, "infinitex", "assets", "gravel.png")


def _motion():
    rng = np.random.default_rng(1)
    vmap = VelocityMap(rng.integers(-300, 300, (20, 30, 2)).astype(np.int32), -40, 75)
    return Motion(Flow(velocity=(128, -77), map=vmap, period=12, loop=48, distortion=0.5), frames=48, fps=30.0)


def _saved(tmp_path, motion):
    path = str(tmp_path / "m.itex")
    save_project(path, Project(Document(ExemplarSource.from_file(GRAVEL), motion=motion)))
    return path


def test_round_trip_keeps_the_flow_and_writes_format_12(tmp_path):
    m = _motion()
    path = _saved(tmp_path, m)
    raw = json.loads(open(path).read())
    assert raw["version"] == 12 and raw["motion"]["map"]["w"] == 30
    back = load_project(path).document.motion
    assert back == m and np.array_equal(back.flow.map.values, m.flow.map.values)
    path = _saved(tmp_path, None)
    raw = json.loads(open(path).read())
    assert "motion" not in raw and raw["version"] < 12


@pytest.mark.parametrize("case", ["not base64", "short", "bomb", "too fast", "period", "loop", "fps", "velocity"])
def test_damaged_or_hostile_flow_data_is_one_sentence(tmp_path, case):
    path = _saved(tmp_path, _motion())
    raw = json.loads(open(path).read())
    m = raw["motion"]
    if case == "not base64":
        m["map"]["v16"] = "%%%"
    elif case == "short":
        m["map"]["v16"] = base64.b64encode(zlib.compress(b"\0" * 100)).decode()
    elif case == "bomb":
        m["map"]["v16"] = base64.b64encode(zlib.compress(b"\0" * (30 * 20 * 4 * 50))).decode()
    elif case == "too fast":
        m["map"]["v16"] = base64.b64encode(zlib.compress(np.full((20, 30, 2), 9000, "<i2").tobytes())).decode()
    elif case == "period":
        m["period"] = 7  # does not divide the loop
    elif case == "loop":
        m["loop"] = -1
    elif case == "fps":
        m["fps"] = 1e9
    elif case == "velocity":
        m["velocity"] = [1, "x"]
    open(path, "w").write(json.dumps(raw))
    with pytest.raises(ProjectError) as err:
        load_project(path)
    assert "\n" not in str(err.value) and ("flow" in str(err.value) or "velocity map" in str(err.value))


def test_no_flow_on_a_lattice():
    with pytest.raises(ProjectError, match="lattice"):
        Document(ExemplarSource.from_file(GRAVEL), motion=_motion(),
                 lattice=Lattice((0.0, 0.0), (8.0, 0.0), (0.0, 8.0), 4, 4)).validate()


def test_animate_plays_the_projects_flow(tmp_path):
    m = Motion(Flow(velocity=(256, 0), period=4, loop=8), frames=8, fps=12.0)
    path = _saved(tmp_path, m)
    out = tmp_path / "p.png"
    r = infinitex("animate", path, "-o", out, "--toroidal", "32", "-q")
    assert r.returncode == 0, r.stderr
    desc = json.loads((tmp_path / "p.json").read_text())
    assert (desc["frames"], desc["fps"], desc["loop"]) == (8, 12.0, True)
