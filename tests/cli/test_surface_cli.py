"""``infinitex surface``: a model textured from an exemplar or a material, the
GLB that carries the maps, exactness against the engine, one-line errors."""
import os
import sys

import numpy as np
import pytest
from clirun import infinitex
import trimesh
from PIL import Image

from infinitex.engine.analysis import analyze
from infinitex.engine.exemplar import load_exemplar
from infinitex.engine.params import SynthParams, structure_params
from infinitex.engine.surface import AtlasDomain
from infinitex.engine.surface.bake import atlas_coords
from infinitex.engine.surface.shapes import cube
from infinitex.engine.synth import Synthesizer
from infinitex.export.surface import plan

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
BRICK = os.path.join(ROOT, "infinitex", "assets", "brick.png")


def run(*args):
    return infinitex("surface", *args)  # in this process (tests/clirun.py)


@pytest.fixture(scope="module")
def cube_obj(tmp_path_factory):
    m = cube(n=3)
    path = str(tmp_path_factory.mktemp("models") / "cube.obj")
    trimesh.Trimesh(m.positions, m.faces, visual=trimesh.visual.TextureVisuals(uv=m.uvs), process=False).export(path)
    return path


def test_an_exemplar_on_a_model_gives_a_glb_and_the_engines_atlas(tmp_path, cube_obj):
    out, coords = str(tmp_path / "cube_brick.glb"), str(tmp_path / "c.npy")
    r = run(cube_obj, BRICK, "-o", out, "--size", "256", "--fidelity", "variety", "--coords", coords, "-q")
    assert r.returncode == 0, r.stderr
    assert r.stderr == ""
    tex = np.asarray(Image.open(str(tmp_path / "cube_brick_basecolor.png")))
    assert tex.shape[:2] == (256, 256)
    scene = trimesh.load(out)
    mesh = next(iter(scene.geometry.values()))
    assert len(mesh.faces) == len(cube(n=3).faces)
    base = mesh.visual.material.baseColorTexture
    assert base.size == (256, 256)
    # The GLB's texture is the map written beside it.
    assert np.array_equal(np.asarray(base.convert("L")), tex if tex.ndim == 2 else np.asarray(Image.fromarray(tex).convert("L")))
    # The same coordinates as the engine's, from the same settings.
    an = analyze(load_exemplar(BRICK))
    from infinitex.engine.surface import load_model
    model = load_model(cube_obj)
    pl = plan(model, 256, an.size)
    atlas = AtlasDomain(model, 256, pl.sigma)
    with Synthesizer(an, structure_params(SynthParams.default(an.L), 0)) as s:
        want = atlas_coords(s, atlas)
    assert np.array_equal(np.load(coords), want)
    # Without reads across seams: another texture (the comparison of bench/surface.py).
    r = run(cube_obj, BRICK, "-o", str(tmp_path / "naive.png"), "--size", "256", "--fidelity", "variety",
            "--coords", coords, "--no-seams", "-q")
    assert r.returncode == 0, r.stderr
    assert not np.array_equal(np.load(coords), want)


def test_a_material_on_a_model_writes_every_map_and_a_pbr_glb(tmp_path, cube_obj):
    # A generated 128 px material with the four maps of the bundled cobbles (an
    # analysis of 128 px, not 512: the maps, the GLB and the normals are the same question).
    sys.path.insert(0, os.path.join(ROOT, "scripts"))
    from make_material import cobbles

    from infinitex.engine.imagefile import encode_image
    for role, px in cobbles(128, seed=5, stones=10).items():
        (tmp_path / f"mat_{role}.png").write_bytes(encode_image(px, 16 if role == "height" else 8))
    out = str(tmp_path / "stones.glb")
    r = run(cube_obj, str(tmp_path / "mat_basecolor.png"), "-o", out, "--size", "512", "--fidelity", "variety",
            "--repeats", "2")
    assert r.returncode == 0, r.stderr
    assert "cube.obj: 108 triangles, 6 charts" in r.stderr
    for role in ("basecolor", "height", "normal", "roughness"):
        assert os.path.exists(str(tmp_path / f"stones_{role}.png")), role
    height = Image.open(str(tmp_path / "stones_height.png"))
    assert height.mode.startswith("I;16") and height.size == (512, 512)  # its own 16 bits
    mat = next(iter(trimesh.load(out).geometry.values())).visual.material
    assert mat.baseColorTexture is not None and mat.normalTexture is not None
    assert mat.metallicRoughnessTexture is not None
    # Normals point out of the surface (z up in tangent space), turned with the texture but still unit.
    n = np.asarray(Image.open(str(tmp_path / "stones_normal.png")).convert("RGB")).astype(np.float64) / 127.5 - 1
    length = np.linalg.norm(n, axis=-1)
    assert np.median(n[..., 2]) > 0.5 and abs(np.median(length) - 1) < 0.05


def test_surface_errors_are_one_line(tmp_path, cube_obj):
    nouv = str(tmp_path / "nouv.obj")
    with open(nouv, "w") as f:
        f.write("v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nf 1 2 3\nf 1 3 4\nf 1 4 2\nf 2 4 3\n")
    garbage = str(tmp_path / "bad.glb")
    with open(garbage, "wb") as f:
        f.write(b"glTF" + os.urandom(64))
    out = str(tmp_path / "o.glb")
    for args, text in (
        ([nouv, BRICK, "-o", out], "--unwrap"),
        ([garbage, BRICK, "-o", out], "bad.glb"),
        ([cube_obj, BRICK, "-o", str(tmp_path / "o.jpg")], ".glb"),
        ([cube_obj, BRICK, "-o", out, "--size", "300"], "power of two"),
        ([cube_obj, BRICK, "-o", out, "--size", "64"], "exemplar"),
        ([cube_obj, BRICK, "-o", out, "--texel-ratio", "9"], "texel-ratio"),
        ([cube_obj, BRICK, "-o", cube_obj.replace(".obj", ".png")], None),  # fine: the maps only
        ([str(tmp_path / "missing.obj"), BRICK, "-o", out], "missing.obj"),
        ([cube_obj, str(tmp_path / "nothing.png"), "-o", out], "nothing.png"),
    ):
        r = run(*args, "--fidelity", "variety", "-q")
        if text is None:
            assert r.returncode == 0, r.stderr
            continue
        assert r.returncode != 0, args
        lines = r.stderr.strip().splitlines()
        assert len(lines) == 1 and lines[0].startswith("error:") and text in lines[0], (args, r.stderr)
    # An output that would replace an input is refused before any work.
    model_copy = str(tmp_path / "m_basecolor.png")
    Image.open(BRICK).save(model_copy)
    r = run(cube_obj, model_copy, "-o", str(tmp_path / "m.glb"), "-q")
    assert r.returncode != 0 and "m_basecolor.png" in r.stderr
    # --unwrap textures a model without coordinates.
    r = run(nouv, BRICK, "-o", out, "--size", "128", "--unwrap", "--fidelity", "variety")
    assert r.returncode == 0, r.stderr
    assert "xatlas" in r.stderr and os.path.exists(out)


def test_a_project_with_a_model_brings_its_settings_and_its_paint(tmp_path, cube_obj):
    """An .itex source: the project's texture size (magnified to --size), scale,
    direction, the randomness painted, the features placed and the direction
    combed on its model; the same atlas as the engine's. At a smaller size the
    paint is left out (said); the features and the combed field keep their places."""
    from dataclasses import replace

    from infinitex.engine.controls import CanvasField, DirectionField, Feature, rescaled_features
    from infinitex.engine.surface import load_model
    from infinitex.export.surface import surface_controls
    from infinitex.project import Project, save_project
    from infinitex.project.document import Document, ExemplarSource
    from infinitex.project.surface import SurfaceSettings
    model = load_model(cube_obj)
    paint, _ = CanvasField().painted(90, 90, 40, 65535)
    doc = Document(ExemplarSource.from_file(BRICK), structure=0, seed=5, randomness_canvas=paint,
                   surface=SurfaceSettings(model, 256, frame="uv", repeats=1.5),
                   features=(Feature((30, 40), (200, 60), 12, 24), Feature((5, 9), (60, 150), 30, 30, (0, 7))),
                   direction=DirectionField.uniform(60.0, 1.3, 1.0, 20, 130, 110, 220))
    proj = str(tmp_path / "cube.itex")
    save_project(proj, Project(doc))
    coords = str(tmp_path / "c.npy")
    r = run(cube_obj, proj, "-o", str(tmp_path / "p.png"), "--size", "512", "--coords", coords, "-q")
    assert r.returncode == 0, r.stderr
    assert Image.open(str(tmp_path / "p.png")).size == (512, 512)  # magnified from the project's 256
    an = analyze(load_exemplar(BRICK))
    controls, _ = surface_controls(doc.controls(an.size))
    with Synthesizer(an, doc.params(an.L)) as s:
        want = atlas_coords(s, doc.surface.atlas(an.size), controls)
    assert np.array_equal(np.load(coords), want)
    for left_out in ("features", "direction"):  # the features and the combed field are there
        assert np.any(want != _without(doc, an, replace(controls, **{left_out: None if left_out == "direction" else ()})),
                      axis=-1).sum() > 100
    # A smaller size than the project's cannot keep its paint: said, and left out; the features stay.
    small = str(tmp_path / "c2.npy")
    r = run(cube_obj, proj, "-o", str(tmp_path / "q.png"), "--size", "128", "--coords", small)
    assert r.returncode == 0 and "left out" in r.stderr, r.stderr
    assert "features" not in r.stderr
    kept = replace(controls, randomness_canvas=None, features=rescaled_features(doc.features, 0.5),
                   direction=doc.direction.rescaled(0.5, 256))
    with Synthesizer(an, doc.params(an.L)) as s:
        want = atlas_coords(s, doc.surface.atlas(an.size, 128), kept)
    assert np.array_equal(np.load(small), want)


def _without(doc, an, controls):
    with Synthesizer(an, doc.params(an.L)) as s:
        return atlas_coords(s, doc.surface.atlas(an.size), controls)


def test_a_damaged_project_is_one_line_as_in_export(tmp_path, cube_obj):
    """Every command refuses what it cannot read the same way (cli/common.py guarded)."""
    bad = tmp_path / "bad.itex"
    bad.write_text("not a project")
    for cmd in (("surface", cube_obj, str(bad), "-o", str(tmp_path / "o.glb")),
                ("export", str(bad), "-o", str(tmp_path / "o.png"), "--size", "64", "64")):
        r = infinitex(*cmd)
        assert r.returncode == 3, (cmd[0], r.stderr)
        assert r.stderr.count("\n") == 1 and "not an Infinitex project" in r.stderr, (cmd[0], r.stderr)
        assert "Traceback" not in r.stderr


@pytest.mark.parametrize("up", [("1e300", "1e300", "0"), ("0", "1e-300", "0")])
def test_any_magnitude_of_up_is_a_direction(tmp_path, cube_obj, up):
    r = run(cube_obj, BRICK, "-o", str(tmp_path / "o.glb"), "--size", "128", "--fidelity", "variety", "--up", *up, "-q")
    assert r.returncode == 0, r.stderr
    assert r.stderr == ""
    from infinitex.engine.surface.atlas import unit_up
    assert np.allclose(unit_up([float(v) for v in up]), np.array([1.0, 1.0, 0.0]) / np.sqrt(2) if up[0] != "0"
                       else [0.0, 1.0, 0.0])


def test_the_files_a_model_names_are_inputs_and_never_fifos(tmp_path):
    """An OBJ's .mtl and the maps it names are inputs (no output replaces them:
    ``chair_basecolor.png`` was overwritten, rc 0), and a FIFO among them is
    refused in one line instead of blocking the loader."""
    m = cube(n=2)
    obj = tmp_path / "chair.obj"
    trimesh.Trimesh(m.positions, m.faces, visual=trimesh.visual.TextureVisuals(uv=m.uvs), process=False).export(obj)
    text = obj.read_text()
    obj.write_text("mtllib chair.mtl\n" + "\n".join(l for l in text.splitlines() if not l.startswith("mtllib")) + "\n")
    (tmp_path / "chair.mtl").write_text("newmtl m\nmap_Kd -s 1 1 1 chair_basecolor.png\n")
    own = np.full((8, 8, 3), 77, np.uint8)
    Image.fromarray(own).save(tmp_path / "chair_basecolor.png")
    r = run(str(obj), BRICK, "-o", str(tmp_path / "chair.glb"), "--size", "128", "--fidelity", "variety", "-q")
    assert r.returncode == 2 and "chair_basecolor.png" in r.stderr and r.stderr.count("\n") == 1, r.stderr
    assert np.array_equal(np.asarray(Image.open(tmp_path / "chair_basecolor.png")), own)  # untouched
    # trimesh finds "textures/chair_basecolor.png" by its base name when that folder does not exist: an input too.
    (tmp_path / "chair.mtl").write_text("newmtl m\nMAP_KD textures/chair_basecolor.png\n")
    r = run(str(obj), BRICK, "-o", str(tmp_path / "chair_basecolor.png"), "--size", "128", "--fidelity", "variety",
            "-q")
    assert r.returncode == 2 and "chair_basecolor.png" in r.stderr and r.stderr.count("\n") == 1, r.stderr
    assert np.array_equal(np.asarray(Image.open(tmp_path / "chair_basecolor.png")), own)
    os.remove(tmp_path / "chair.mtl")
    os.mkfifo(tmp_path / "chair.mtl")
    r = run(str(obj), BRICK, "-o", str(tmp_path / "other.glb"), "--size", "128", "--fidelity", "variety", "-q")
    assert r.returncode == 3 and "not a regular file" in r.stderr and r.stderr.count("\n") == 1, r.stderr
