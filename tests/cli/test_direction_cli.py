"""--direction-map on the command line: a flow map turns the texture exactly as
the engine's field of the same direction does; the map kinds and the Y
convention; one-line errors; export of a project that carries a field."""
import os
from clirun import infinitex

import numpy as np
from PIL import Image

from infinitex.engine.analysis import analyze
from infinitex.engine.controls import Controls
from infinitex.engine.controls.direction import DirectionField, jacobian
from infinitex.engine.exemplar import load_exemplar
from infinitex.engine.params import structure_params, SynthParams
from infinitex.engine.pyramid import Rect
from infinitex.engine.synth import Synthesizer

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
BRICK = os.path.join(ROOT, "infinitex", "assets", "brick.png")


def run(cmd, *args):
    return infinitex(cmd, *args)  # in this process (tests/clirun.py)


def test_flow_map_turns_the_texture_like_the_engine_field(tmp_path):
    flow = np.zeros((48, 64, 3), np.uint8)
    flow[..., 0] = 128
    flow[..., 1] = 255  # green up (OpenGL): the exemplar's +x runs up the screen, -90 degrees
    fmap = str(tmp_path / "flow.png")
    Image.fromarray(flow).save(fmap)
    out, coords = str(tmp_path / "o.png"), str(tmp_path / "c.npy")
    r = run("synth", BRICK, "-o", out, "--size", "64", "48", "--origin", "100", "-40", "--direction-map", fmap,
            "--direction-origin", "100", "-40", "--fidelity", "variety", "--coords", coords, "-q")
    assert r.returncode == 0, r.stderr
    c = np.load(coords)
    assert c.shape == (48, 64, 4)
    an = analyze(load_exemplar(BRICK))
    field = DirectionField.from_jacobians(np.broadcast_to(jacobian(-90.0), (48, 64, 4)).copy(), 100, -40)
    with Synthesizer(an, structure_params(SynthParams.default(an.L), 0), controls=Controls(direction=field)) as s:
        want = s.window(Rect.of(100, -40, 64, 48))
    assert np.array_equal(c, want)
    # DirectX-style green (down) is the other direction: another texture.
    r = run("synth", BRICK, "-o", out, "--size", "64", "48", "--origin", "100", "-40", "--direction-map", fmap,
            "--direction-origin", "100", "-40", "--fidelity", "variety", "--coords", coords, "--flow-y", "down", "-q")
    assert r.returncode == 0, r.stderr
    assert not np.array_equal(np.load(coords), want)


def test_angle_map_and_errors(tmp_path):
    gray = str(tmp_path / "angle.png")
    Image.fromarray(np.full((32, 32), 64, np.uint8)).save(gray)  # 90 degrees
    out = str(tmp_path / "o.png")
    r = run("synth", BRICK, "-o", out, "--size", "32", "32", "--direction-map", gray, "--fidelity", "variety", "-q")
    assert r.returncode == 0, r.stderr
    r = run("synth", BRICK, "-o", out, "--size", "32", "32", "--direction-map", gray, "--direction-kind", "flow", "-q")
    assert r.returncode != 0 and "grayscale" in r.stderr and len(r.stderr.strip().splitlines()) == 1
    r = run("synth", BRICK, "-o", out, "--size", "32", "32", "--direction-map", gray, "--direction-scale", "9", "-q")
    assert r.returncode == 2 and "0.25 and 4" in r.stderr and len(r.stderr.strip().splitlines()) == 1
    r = run("synth", BRICK, "-o", gray, "--size", "32", "32", "--direction-map", gray, "-q")
    assert r.returncode == 2 and len(r.stderr.strip().splitlines()) == 1  # would overwrite its own input


def test_export_follows_a_projects_field_also_magnified(tmp_path):
    from infinitex.project import Project, save_project
    from infinitex.project.document import Document, ExemplarSource
    field = DirectionField.uniform(30.0, 1.0, 1.0, -64, -64, 64, 64)
    proj = str(tmp_path / "p.itex")
    save_project(proj, Project(Document(ExemplarSource.from_file(BRICK), structure=0, direction=field)))
    out = str(tmp_path / "e.png")
    r = run("export", proj, "-o", out, "--rect", "-32", "-32", "64", "64", "-q")
    assert r.returncode == 0, r.stderr
    plain = str(tmp_path / "plain.png")
    save_project(proj, Project(Document(ExemplarSource.from_file(BRICK), structure=0)))
    assert run("export", proj, "-o", plain, "--rect", "-32", "-32", "64", "64", "-q").returncode == 0
    assert not np.array_equal(np.asarray(Image.open(out)), np.asarray(Image.open(plain)))
    save_project(proj, Project(Document(ExemplarSource.from_file(BRICK), structure=0, direction=field)))
    mag = str(tmp_path / "m.png")
    r = run("export", proj, "-o", mag, "--rect", "-32", "-32", "64", "64", "--magnify", "2", "-q")
    assert r.returncode == 0, r.stderr
    big = np.asarray(Image.open(mag))
    assert big.shape == (128, 128)
    # Exactly the engine's magnification through J (engine/material.py; the
    # render tests show it differs from extrapolating as if unturned).
    from infinitex.engine.imagefile import to_u8
    from infinitex.engine.material import single
    ex = load_exemplar(BRICK)
    an = analyze(ex)
    with Synthesizer(an, structure_params(SynthParams.default(an.L), 0), controls=Controls(direction=field)) as s:
        c = s.window(Rect.of(-33, -33, 66, 66))
    want = to_u8(single(ex).magnified("image", c, 2, field.region(0, -33, -33, 66, 66)))[..., 0]
    assert np.array_equal(big, want)
    assert not np.array_equal(big, to_u8(single(ex).magnified("image", c, 2))[..., 0])
