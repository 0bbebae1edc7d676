"""A model in documents and project files (format 11): round trip with the
randomness painted on it, damaged or hostile data refused with one sentence,
no lattice with a model (a direction field is combed over it), the paint kept in place when the
texture's size changes."""
import base64
import json
import os
import zlib

import numpy as np
import pytest

from infinitex.engine.controls import CanvasField
from infinitex.engine.controls.lattice import Lattice
from infinitex.engine.surface.shapes import cube
from infinitex.project import Project, ProjectError, load_project, save_project
from infinitex.project.document import Document, ExemplarSource
from infinitex.project.surface import SurfaceSettings

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
BRICK = os.path.join(ROOT, "infinitex", "assets", "brick.png")


def _doc():
    paint, _ = CanvasField().painted(120, 80, 20, 60000)
    s = SurfaceSettings(cube(n=3), 512, frame="uv", up=(0.0, 0.0, 1.0), repeats=3.5)
    return Document(ExemplarSource.from_file(BRICK), surface=s, randomness_canvas=paint)


def test_round_trip_keeps_the_model_and_writes_format_11(tmp_path):
    doc = _doc()
    path = str(tmp_path / "m.itex")
    save_project(path, Project(doc))
    raw = json.loads(open(path).read())
    assert raw["version"] == 11 and raw["surface"]["faces"] == len(doc.surface.model.faces)
    back = load_project(path).document
    assert back.surface == doc.surface and back.randomness_canvas == doc.randomness_canvas
    m0, m1 = doc.surface.model, back.surface.model
    assert all(np.array_equal(a, b) for a, b in ((m0.positions, m1.positions), (m0.faces, m1.faces), (m0.uvs, m1.uvs)))
    # The same atlas, bit for bit.
    a0, a1 = doc.surface.atlas(128), back.surface.atlas(128)
    assert np.array_equal(a0.links(0, 0, 0, 512, 512), a1.links(0, 0, 0, 512, 512))
    assert np.array_equal(a0.jacobians(0, 0, 0, 512, 512), a1.jacobians(0, 0, 0, 512, 512))
    save_project(path, Project(Document(ExemplarSource.from_file(BRICK))))
    assert "surface" not in json.loads(open(path).read())


def _damaged(tmp_path, change) -> str:
    path = str(tmp_path / "m.itex")
    save_project(path, Project(_doc()))
    raw = json.loads(open(path).read())
    change(raw["surface"])
    with open(path, "w") as f:
        json.dump(raw, f)
    return path


@pytest.mark.parametrize("name,change", [
    ("not base64", lambda s: s.update(mesh="%%%")),
    ("truncated", lambda s: s.update(mesh=s["mesh"][:40])),
    ("wrong counts", lambda s: s.update(faces=s["faces"] + 1)),
    ("huge counts", lambda s: s.update(vertices=10 ** 9, faces=10 ** 9)),
    ("counts of another type", lambda s: s.update(vertices="12")),
    ("checksum", lambda s: s.update(sha256="0" * 64)),
    ("bad size", lambda s: s.update(size=300)),
    ("bad frame", lambda s: s.update(frame="sideways")),
    ("bad up", lambda s: s.update(up=[0, 0, 0])),
    ("bad repeats", lambda s: s.update(repeats=1e9)),
    ("not an object", lambda s: s.clear()),
])
def test_damaged_models_are_one_sentence(tmp_path, name, change):
    path = _damaged(tmp_path, change)
    with pytest.raises(ProjectError) as e:
        load_project(path)
    assert "\n" not in str(e.value) and len(str(e.value)) < 200, name


def test_a_bomb_in_the_mesh_is_refused_before_it_is_decompressed(tmp_path):
    bomb = base64.b64encode(zlib.compress(b"\0" * (64 << 20), 9)).decode()  # 64 MB from ~64 KB

    def change(s):
        s.update(mesh=bomb)
    with pytest.raises(ProjectError, match="damaged"):
        load_project(_damaged(tmp_path, change))


def test_a_model_excludes_a_lattice_and_keeps_a_combed_direction_field(tmp_path):
    from infinitex.engine.controls.direction import DirectionField
    doc = _doc()
    lat = Lattice(origin=(0.0, 0.0), t1=(16.0, 0.0), t2=(0.0, 16.0), nx=2, ny=2)
    with pytest.raises(ProjectError, match="lattice"):
        Document(doc.exemplar, surface=doc.surface, lattice=lat).validate()
    combed = Document(doc.exemplar, surface=doc.surface, direction=DirectionField.uniform(30, 1, 1, 0, 0, 64, 64))
    combed.validate()  # combed over the model (its atlas texels)
    path = str(tmp_path / "combed.itex")
    save_project(path, Project(combed))
    back = load_project(path).document
    assert back.direction == combed.direction and back.surface == combed.surface


def test_a_combed_direction_field_keeps_its_place_when_the_texture_size_changes():
    from infinitex.engine.controls.direction import DirectionField
    f = DirectionField.uniform(30, 1.5, 1, 40, 20, 90, 70)
    g = f.rescaled(2.0, 128)
    assert np.array_equal(f.dense(30, 10, 80, 80), g.dense(60, 20, 160, 160)[::2, ::2])
    assert np.array_equal(g.rescaled(0.5, 256).dense(30, 10, 80, 80), f.dense(30, 10, 80, 80))
    # Tiles beyond the model's texture are never read: dropped, not blown up with it (a hostile
    # project's far tiles once made a dense box of gigabytes).
    far = f.replaced(np.broadcast_to(f.dense(50, 30, 1, 1), (64, 64, 4)).copy(), 250 * 64, 250 * 64)
    assert far.rescaled(0.5, 256) == f.rescaled(0.5, 256) and far.rescaled(1.0, 256) == f


def test_paint_keeps_its_place_when_the_texture_size_changes():
    f, _ = CanvasField().painted(100.5, 60.5, 12.0, 0)
    g = f.rescaled(2.0, 256)
    assert np.array_equal(f.region(0, 80, 40, 40, 40), g.region(0, 160, 80, 80, 80)[::2, ::2])
    assert g.rescaled(0.5, 512) == f
    assert CanvasField().rescaled(2.0, 256) == CanvasField()
    far, _ = f.painted(250 * 64 + 5, 250 * 64 + 5, 4.0, 0)
    assert far.rescaled(2.0, 256) == g
