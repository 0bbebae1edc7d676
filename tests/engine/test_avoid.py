"""Avoided exemplar regions (controls.ExemplarMask): never copied while any
candidate outside them is left; exact (GL equals the oracle, windows agree
near 0 and +-2^30, local and full updates agree); documents, projects, CLI."""
import json
import os
import subprocess
import sys
from dataclasses import replace

import numpy as np
import oracle
import pytest
from PIL import Image

from infinitex.project import Document, ExemplarSource, Project, ProjectError, load_project, save_project
from infinitex.engine.controls import CanvasField, Controls, ExemplarMask
from infinitex.engine.params import DEFAULT_WALK, SynthParams
from infinitex.engine.pyramid import Rect
from infinitex.engine.synth import Synthesizer

FAR = 2 ** 30
ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
GRAVEL = os.path.join(ROOT, "infinitex", "assets", "gravel.png")


def crevice(m: int) -> ExemplarMask:
    """Gravel's dark diagonal crevice (README: it recurs once per exemplar area), 32 x 32 centered on (66, 22)."""
    v = np.zeros((m, m), np.uint8)
    v[6:38, 50:82] = 1
    return ExemplarMask(v)


def share(mask: ExemplarMask, coords: np.ndarray) -> float:
    m = mask.size
    return float(mask.values[coords[..., 1] % m, coords[..., 0] % m].mean())


@pytest.mark.parametrize("name", ["gravel-appearance", "gravel-color", "torus-color-k3"])
@pytest.mark.parametrize("x, y", [(-20, 30), (FAR - 150, -FAR + 60)])
def test_gl_matches_oracle_with_a_mask(analyses, gpu, name, x, y):
    an = analyses[name]
    controls = Controls(avoid=crevice(an.size) if an.size == 128 else ExemplarMask.blank(an.size).painted(20, 30, 9))
    params = SynthParams.default(an.L, seed=4)
    gl = Synthesizer(an, params, gpu=gpu, controls=controls).window(Rect.of(x, y, 40, 36))
    assert np.array_equal(gl, oracle.synthesize(an, params, x, y, 40, 36, controls=controls))


def test_avoided_regions_are_not_copied(analyses, gpu):
    """The crevice makes 6% of a plain 256^2 window; with the mask, none (both
    models, a toroidal tile too, and a mask over half the exemplar)."""
    for name in ("gravel-appearance", "gravel-color"):
        an = analyses[name]
        mask = crevice(an.size)
        params = SynthParams.default(an.L, seed=1)
        rect = Rect.of(10007, -20011, 256, 256)
        plain = Synthesizer(an, params, gpu=gpu).window(rect)
        assert share(mask, plain) > 0.02
        synth = Synthesizer(an, params, gpu=gpu, controls=Controls(avoid=mask))
        assert share(mask, synth.window(rect)) == 0.0
        tile = synth.toroidal(128)
        assert share(mask, tile) == 0.0
        half = np.zeros((an.size, an.size), np.uint8)
        half[:, : an.size // 2] = 1
        wide = Synthesizer(an, params, gpu=gpu, controls=Controls(avoid=ExemplarMask(half)))
        assert share(ExemplarMask(half), wide.window(rect)) < 0.001


def test_a_mask_turns_the_random_walk_on_unless_asked_otherwise():
    p = SynthParams.default(7)
    assert p.walk_steps(2) == 0 and p.walk_steps(2, avoiding=True) == DEFAULT_WALK
    assert replace(p, walk=0).walk_steps(2, avoiding=True) == 0


@pytest.mark.parametrize("ox, oy", [(0, 0), (FAR - 300, -FAR + 100), (-FAR + 10, FAR - 400)])
def test_overlapping_windows_agree_with_a_mask(analyses, gpu, ox, oy):
    an = analyses["gravel-appearance"]
    synth = Synthesizer(an, SynthParams.default(an.L), gpu=gpu, controls=Controls(avoid=crevice(an.size)))
    big = synth.window(Rect.of(ox, oy, 200, 160))
    small = synth.window(Rect.of(ox + 37, oy + 21, 90, 101))
    assert np.array_equal(small, big[21:122, 37:127])
    viewport = synth.viewport()
    try:
        viewport.show(Rect.of(ox + 100, oy + 80, 100, 80))
        viewport.show(Rect.of(ox, oy, 120, 100))
        assert np.array_equal(viewport.read(Rect.of(ox, oy, 120, 100)), big[:100, :120])
    finally:
        viewport.release()


def test_changing_the_mask_under_a_viewport_equals_a_fresh_synthesis(analyses, gpu):
    an = analyses["gravel-appearance"]
    params = SynthParams.default(an.L, seed=6)
    rect = Rect.of(-70, 40, 128, 96)
    paint = Controls(randomness_canvas=CanvasField.from_image(np.full((40, 40), 0, np.uint16), -50, 50))
    synth = Synthesizer(an, params, gpu=gpu, controls=paint)
    viewport = synth.viewport()
    try:
        viewport.show(rect)
        for mask in (crevice(an.size), crevice(an.size).painted(10, 100, 12), None):
            controls = replace(paint, avoid=mask)
            viewport.pyramid.update_controls(controls)
            viewport.show(rect)
            fresh = Synthesizer(an, params, gpu=gpu, controls=controls).window(rect)
            assert np.array_equal(viewport.read(rect), fresh)
    finally:
        viewport.release()


def test_mask_values_and_errors():
    m = 64
    a = ExemplarMask.blank(m).painted(10.5, 20.5, 3)
    assert a.values[20, 10] == 1 and a.values[20, 14] == 0 and int(a.values.sum()) == 29  # the disc of radius 3
    assert a.painted(10.5, 20.5, 3, avoid=False).empty
    assert ExemplarMask.blank(m).painted(-50, -50, 3) == ExemplarMask.blank(m)  # outside: nothing
    assert a.scaled(128).fraction == pytest.approx(a.fraction) and a.scaled(128).values[41, 21] == 1
    assert Controls(avoid=ExemplarMask.blank(m)).normalized() == Controls()
    with pytest.raises(ValueError, match="0 \\(usable\\) and 1"):
        ExemplarMask(np.full((m, m), 2, np.uint8))
    with pytest.raises(ValueError, match="power-of-two square"):
        ExemplarMask(np.zeros((m, m + 1), np.uint8))
    with pytest.raises(ValueError, match="whole exemplar"):
        Controls(avoid=ExemplarMask(np.ones((m, m), np.uint8))).validate(m)
    with pytest.raises(ValueError, match="the exemplar is 128x128"):
        Controls(avoid=a).validate(128)


def test_documents_and_projects_keep_the_mask(tmp_path):
    doc = Document(ExemplarSource.from_file(GRAVEL), structure=0)  # Variety: a version-5 file
    mask = crevice(128)
    d = replace(doc, avoid_exemplar=mask)
    assert d.controls(128).avoid == mask and d.controls(256).avoid == mask.scaled(256)
    path = tmp_path / "p.itex"
    save_project(str(path), Project(d))
    back = load_project(str(path))
    assert back.document.avoid_exemplar == mask
    saved = json.loads(path.read_text())
    assert saved["version"] == 5
    for bad in ({"png16": "x"}, "mask", {"png16": None}):
        saved["avoid"] = bad
        path.write_text(json.dumps(saved))
        with pytest.raises(ProjectError, match="avoided exemplar regions"):
            load_project(str(path))
    del saved["avoid"]
    path.write_text(json.dumps(saved))
    assert load_project(str(path)).document.avoid_exemplar is None
    with pytest.raises(ProjectError, match="whole exemplar"):
        replace(doc, avoid_exemplar=ExemplarMask(np.ones((128, 128), np.uint8))).validate()


def test_synth_avoid_exemplar_option(tmp_path):
    mask_png, coords = str(tmp_path / "mask.png"), str(tmp_path / "c.npy")
    v = np.zeros((128, 128), np.uint8)
    v[22:54, 66:98] = 255
    Image.fromarray(v).save(mask_png)
    run = [sys.executable, os.path.join(ROOT, "main.py"), "synth", GRAVEL, "--size", "128", "128", "-q"]
    r = subprocess.run(run + ["-o", str(tmp_path / "o.png"), "--coords", coords, "--avoid-exemplar", mask_png],
                       capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stderr
    c = np.load(coords)
    assert not (v[c[..., 1], c[..., 0]] != 0).any()
    Image.fromarray(np.full((128, 128), 255, np.uint8)).save(mask_png)
    r = subprocess.run(run + ["-o", str(tmp_path / "o.png"), "--avoid-exemplar", mask_png],
                       capture_output=True, text=True, timeout=300)
    assert r.returncode == 2 and "whole exemplar" in r.stderr and "Traceback" not in r.stderr
    assert len(r.stderr.strip().splitlines()) == 1


def test_export_avoid_exemplar_option(tmp_path):
    """export --avoid-exemplar replaces the project's mask: the exact coordinate
    map it writes beside the image copies nothing from the avoided region."""
    mask_png, out = str(tmp_path / "mask.png"), str(tmp_path / "e.png")
    v = np.zeros((128, 128), np.uint8)
    v[22:54, 66:98] = 255
    Image.fromarray(v).save(mask_png)
    r = subprocess.run([sys.executable, os.path.join(ROOT, "main.py"), "export", GRAVEL, "-o", out,
                        "--size", "160", "96", "--coords", "--avoid-exemplar", mask_png, "-q"],
                       capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stderr
    c = np.asarray(Image.open(str(tmp_path / "e_coords.png"))).astype(np.int64)
    x = c[..., 0] + 256 * (c[..., 2] & 15)
    y = c[..., 1] + 256 * (c[..., 2] >> 4)
    assert c.shape[:2] == (96, 160) and x.max() < 128 and y.max() < 128
    assert not (v[y, x] != 0).any()
