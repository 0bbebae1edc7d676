"""Placed features (LH05 4.4): exact copies, oracle agreement, overlapping
windows, local updates after edits, the exemplar border, the spatial index."""
import numpy as np
import oracle
import pytest
from clirun import infinitex

from infinitex.engine.controls import Controls, Feature
from infinitex.engine.params import DEFAULT_STRUCTURE, SynthParams, structure_params
from infinitex.engine.pyramid import Rect
from infinitex.engine.synth import Synthesizer

FAR = 2 ** 30


@pytest.mark.parametrize("px, py", [(40, -30), (FAR - 500, -FAR + 700), (-FAR + 900, FAR - 333)])
def test_feature_on_every_level_is_a_verbatim_copy(analyses, gpu, px, py):
    an = analyses["gravel-appearance"]
    m = an.size
    f = Feature(exemplar=(70, 50), canvas=(px, py), inner=20, outer=30, levels=(0, an.L))
    synth = Synthesizer(an, SynthParams.default(an.L, seed=3), gpu=gpu, controls=Controls(features=(f,)))
    S = synth.window(Rect.of(px - 40, py - 40, 80, 80))
    ys, xs = np.mgrid[py - 40:py + 40, px - 40:px + 40]
    inside = (xs + 0.5 - px) ** 2 + (ys + 0.5 - py) ** 2 <= 20 ** 2
    want_x = (70 + xs - px) % m
    want_y = (50 + ys - py) % m
    assert inside.sum() > 1000
    assert np.array_equal(S[..., 0][inside], want_x[inside]) and np.array_equal(S[..., 1][inside], want_y[inside])
    plain = Synthesizer(an, SynthParams.default(an.L, seed=3), gpu=gpu).window(Rect.of(px - 40, py - 40, 80, 80))
    assert (S != plain).any(axis=-1)[inside].mean() > 0.9  # the feature replaced what was there


def features_around(x, y, n=6, seed=0, L=7):
    rng = np.random.default_rng(seed)
    m = 1 << L
    out = []
    for i in range(n):
        inner = int(rng.integers(3, 25))
        levels = [None, (0, L), (2, L - 1), (3, 5)][i % 4]
        out.append(Feature((int(rng.integers(0, m)), int(rng.integers(0, m))),
                           (x + int(rng.integers(-60, 60)), y + int(rng.integers(-50, 50))),
                           inner, inner + int(rng.integers(0, 40)), levels))
    return tuple(out)


@pytest.mark.parametrize("name, structure", [("gravel-appearance", 0), ("torus-color-k3", 0),
                                             ("gravel-appearance", DEFAULT_STRUCTURE)])
@pytest.mark.parametrize("x, y", [(-20, 15), (FAR - 120, -FAR + 80)])
def test_gl_matches_oracle_with_features(analyses, gpu, name, structure, x, y):
    an = analyses[name]
    controls = Controls(features=features_around(x + 20, y + 18, L=an.L))
    params = structure_params(SynthParams.default(an.L, seed=5), structure)
    gl = Synthesizer(an, params, gpu=gpu, controls=controls).window(Rect.of(x, y, 40, 36))
    ref = oracle.synthesize(an, params, x, y, 40, 36, controls=controls)
    assert np.array_equal(gl, ref)


def test_overlapping_windows_agree_with_features(analyses, gpu):
    an = analyses["gravel-appearance"]
    ox, oy = FAR - 400, -FAR + 300
    controls = Controls(features=features_around(ox + 80, oy + 70, n=12, seed=3, L=an.L))
    synth = Synthesizer(an, SynthParams.default(an.L), gpu=gpu, controls=controls)
    big = synth.window(Rect.of(ox, oy, 200, 160))
    assert np.array_equal(synth.window(Rect.of(ox + 37, oy + 21, 90, 101)), big[21:122, 37:127])
    vp = synth.viewport()
    try:
        vp.show(Rect.of(ox + 100, oy + 80, 100, 80))
        vp.show(Rect.of(ox, oy, 120, 100))
        assert np.array_equal(vp.read(Rect.of(ox, oy, 120, 100)), big[:100, :120])
    finally:
        vp.release()


def test_toroidal_tile_with_features_is_periodic(analyses, gpu):
    an = analyses["gravel-appearance"]
    f = Feature((60, 60), (62, 3), 12, 20, (0, an.L))  # crosses the tile's edge
    synth = Synthesizer(an, SynthParams.default(an.L), gpu=gpu, controls=Controls(features=(f,)))
    tile = synth.toroidal(64)
    from dataclasses import replace
    params = synth.params
    synth.params = replace(params, period=64)
    shifted = synth.window(Rect.of(-64, 128, 64, 64))
    synth.params = params
    assert np.array_equal(shifted, tile)
    ref = oracle.synthesize(an, replace(params, period=64), 0, 0, 64, 64, controls=Controls(features=(f,)))
    assert np.array_equal(tile, ref)


def test_feature_near_the_border_of_a_non_toroidal_exemplar_does_not_wrap(analyses, gpu):
    an = analyses["gravel-appearance"]
    assert not an.toroidal
    m = an.size
    f = Feature(exemplar=(3, m - 2), canvas=(0, 0), inner=15, outer=15, levels=(0, an.L))
    S = Synthesizer(an, SynthParams.default(an.L), gpu=gpu, controls=Controls(features=(f,))).window(Rect.of(-20, -20, 40, 40))
    ys, xs = np.mgrid[-20:20, -20:20]
    inside = (xs + 0.5) ** 2 + (ys + 0.5) ** 2 <= 15 ** 2
    u = f.clamped(m, False).exemplar
    assert u == (15, m - 16)
    # A continuous copy: S = u + (p - p_F) with no wrap.
    assert np.array_equal(S[..., 0][inside], (u[0] + xs)[inside]) and np.array_equal(S[..., 1][inside], (u[1] + ys)[inside])
    assert S[..., 0][inside].min() >= 0 and S[..., 1][inside].max() < m


def test_local_updates_after_feature_edits_equal_a_fresh_synthesis(analyses, gpu):
    an = analyses["gravel-appearance"]
    rng = np.random.default_rng(21)
    params = SynthParams.default(an.L, seed=2)
    x0, y0 = -FAR + 2000, FAR - 4000
    view = Rect.of(x0, y0, 180, 140)
    synth = Synthesizer(an, params, gpu=gpu)
    vp = synth.viewport()
    controls = Controls()
    try:
        for i in range(20):
            zoom = int(rng.integers(0, 3))
            lv = Rect(view.x0 >> zoom, view.y0 >> zoom, (view.x1 >> zoom) + 1, (view.y1 >> zoom) + 1)
            vp.show(lv, zoom)
            before = vp.read(lv, zoom)
            feats = list(controls.features)
            op = rng.choice(["add", "move", "delete"] if feats else ["add"])
            if op == "add":
                inner = int(rng.integers(2, 20))
                feats.append(Feature((int(rng.integers(0, 128)), int(rng.integers(0, 128))),
                                     (x0 + int(rng.integers(-100, 280)), y0 + int(rng.integers(-100, 240))),
                                     inner, inner + int(rng.integers(0, 30)), [None, (0, an.L), (3, 6)][i % 3]))
            elif op == "move":
                j = int(rng.integers(0, len(feats)))
                f = feats[j]
                feats[j] = Feature(f.exemplar, (f.canvas[0] + int(rng.integers(-30, 30)), f.canvas[1] + int(rng.integers(-30, 30))),
                                   f.inner, f.outer, f.levels)
            else:
                feats.pop(int(rng.integers(0, len(feats))))
            new = Controls(features=tuple(feats))
            changed = [Rect(*r) for r in controls.changed_rects(new)]
            vp.pyramid.update_controls(new, None)
            controls = new
            after = vp.read(lv, zoom)
            fresh = Synthesizer(an, params, gpu=gpu, controls=new).window(lv, an.L - zoom)
            assert np.array_equal(after, fresh), f"edit {i} ({op}, zoom 1/{1 << zoom})"
            ys, xs = np.mgrid[lv.y0:lv.y1, lv.x0:lv.x1]
            near = np.zeros(xs.shape, bool)
            for c in changed:
                rr = oracle.reach_bound(vp.pyramid, c)
                near |= ((xs >= rr.x0 >> zoom) & (xs < -((-rr.x1) >> zoom)) & (ys >= rr.y0 >> zoom)
                         & (ys < -((-rr.y1) >> zoom)))
            assert np.array_equal(after[~near], before[~near])
    finally:
        vp.release()


def test_spatial_index_finds_exactly_the_features_that_reach_a_rectangle():
    rng = np.random.default_rng(4)
    feats = tuple(Feature((1, 1), (int(rng.integers(-5000, 5000)), int(rng.integers(-5000, 5000))), 5,
                          int(rng.integers(5, 200))) for _ in range(1000))
    c = Controls(features=feats)
    for _ in range(50):
        x0, y0 = int(rng.integers(-6000, 6000)), int(rng.integers(-6000, 6000))
        x1, y1 = x0 + int(rng.integers(1, 900)), y0 + int(rng.integers(1, 900))
        brute = [i for i, f in enumerate(feats)
                 if f.bbox()[0] < x1 and x0 < f.bbox()[2] and f.bbox()[1] < y1 and y0 < f.bbox()[3]]
        assert c.features_in(x0, y0, x1, y1) == brute


def test_features_in_projects_and_on_the_command_line(tmp_path):
    import json
    import os

    from PIL import Image

    from infinitex.project import Document, ExemplarSource, Project, ProjectError, load_project, save_project
    root = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
    gravel = os.path.join(root, "infinitex", "assets", "gravel.png")
    feats = (Feature((60, 40), (100, 80), 20, 40), Feature((10, 100), (150, 60), 10, 30, (0, 7)))
    doc = Document(ExemplarSource.from_file(gravel), features=feats)
    p = tmp_path / "p.itex"
    save_project(str(p), Project(doc))
    assert load_project(str(p)).document.features == feats
    d = json.loads(p.read_text())
    for bad in ([{"exemplar": [1, 2]}], [{"exemplar": [1, 2], "canvas": [0, 0], "radius": [30, 10]}],
                {"not": "a list"}, [{"exemplar": [1, 2], "canvas": [0, 0], "radius": [1, 2], "levels": [5, 2]}]):
        d["features"] = bad
        p.write_text(json.dumps(d))
        with pytest.raises(ProjectError, match="features"):
            load_project(str(p))
    # The command line: synth and export agree; bad data is one line.
    fj = tmp_path / "f.json"
    fj.write_text(json.dumps([{"exemplar": [60, 40], "canvas": [20, 16], "radius": [12, 24], "levels": [0, 7]}]))

    def run(*a):
        return infinitex(*a, "-q")  # in this process (tests/clirun.py)
    r = run("synth", gravel, "-o", str(tmp_path / "a.png"), "--size", "64", "48", "--features", str(fj))
    assert r.returncode == 0, r.stderr
    r = run("export", gravel, "-o", str(tmp_path / "b.png"), "--rect", "0", "0", "64", "48", "--features", str(fj))
    assert r.returncode == 0, r.stderr
    a, b = np.asarray(Image.open(tmp_path / "a.png")), np.asarray(Image.open(tmp_path / "b.png"))
    assert np.array_equal(a, b)
    ex = np.asarray(Image.open(gravel))
    assert np.array_equal(a[16, 20], ex[40, 60])  # the exact copy at the feature's center
    fj.write_text("[{\"exemplar\": [1]}]")
    r = run("synth", gravel, "-o", str(tmp_path / "c.png"), "--features", str(fj))
    assert r.returncode == 3 and len(r.stderr.strip().splitlines()) == 1 and "features" in r.stderr
