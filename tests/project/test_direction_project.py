"""Direction fields in documents and project files (format 10): round trip,
damaged or hostile data refused with one sentence, no lattice with a field."""
import base64
import json
import os
import zlib

import numpy as np
import pytest

from infinitex.engine.controls import TILE
from infinitex.engine.controls.direction import IDENTITY, DirectionField, jacobian
from infinitex.engine.controls.lattice import Lattice
from infinitex.project import Project, ProjectError, load_project, save_project
from infinitex.project.document import Document, ExemplarSource

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
BRICK = os.path.join(ROOT, "infinitex", "assets", "brick.png")


def _field():
    ys, xs = np.mgrid[0:100, 0:150]
    return DirectionField.from_jacobians(jacobian(np.degrees(np.arctan2(ys - 50, xs - 75)), 1.5, 1.2), -70, 30)


def test_round_trip_keeps_the_field_and_writes_format_10(tmp_path):
    f = _field()
    doc = Document(ExemplarSource.from_file(BRICK), direction=f)
    path = str(tmp_path / "d.itex")
    save_project(path, Project(doc))
    raw = json.loads(open(path).read())
    assert raw["version"] == 10 and len(raw["direction"]["tiles"]) == len(f.tiles) == 12
    back = load_project(path).document
    assert back.direction == f and back.controls(128).direction == f
    # Without a field nothing is written and the version stays lower.
    save_project(path, Project(Document(ExemplarSource.from_file(BRICK))))
    raw = json.loads(open(path).read())
    assert "direction" not in raw and raw["version"] < 10


def _with_tile(tmp_path, text):
    doc = Document(ExemplarSource.from_file(BRICK), direction=_field())
    path = str(tmp_path / "d.itex")
    save_project(path, Project(doc))
    raw = json.loads(open(path).read())
    raw["direction"]["tiles"][0]["j16"] = text
    open(path, "w").write(json.dumps(raw))
    return path


def _pack(t):
    return base64.b64encode(zlib.compress(np.ascontiguousarray(t, dtype="<i2").tobytes())).decode()


@pytest.mark.parametrize("case", ["not base64", "short", "mirror", "stretch", "singular", "bomb", "number"])
def test_damaged_or_hostile_direction_data_is_one_sentence(tmp_path, case):
    good = np.broadcast_to(IDENTITY, (TILE, TILE, 4)).copy()
    text = {
        "not base64": "%%%",
        "short": _pack(good[:10]),
        "mirror": _pack(np.where(np.arange(4) == 0, -good, good)),  # det < 0
        "stretch": _pack(good * 5),  # the texture shown 5 times smaller: beyond the limits (entries 20480)
        "singular": _pack(np.broadcast_to(np.array([4096, 4096, 4096, 4096], np.int16), (TILE, TILE, 4))),
        "bomb": base64.b64encode(zlib.compress(b"\0" * (1 << 24))).decode(),
        "number": 12,
    }[case]
    with pytest.raises(ProjectError) as e:
        load_project(_with_tile(tmp_path, text))
    assert "direction field is damaged" in str(e.value) and "\n" not in str(e.value)


def test_a_field_on_a_lattice_is_refused():
    doc = Document(ExemplarSource.from_file(BRICK), direction=_field(),
                   lattice=Lattice((0.0, 0.0), (32.0, 0.0), (0.0, 32.0), 2, 2))
    with pytest.raises(ProjectError, match="direction field does not work on a lattice"):
        doc.validate()
    # An identity field is no field: allowed.
    replace_doc = Document(ExemplarSource.from_file(BRICK), direction=DirectionField(),
                           lattice=Lattice((0.0, 0.0), (32.0, 0.0), (0.0, 32.0), 2, 2))
    replace_doc.validate()
