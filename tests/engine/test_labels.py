"""Texture by numbers (engine/controls/labels.py): the synthesis follows labels
painted on the canvas; exact (GL equals the oracle with and without the
fidelity stage, near 0 and +-2^30, toroidal tiles; overlapping windows agree;
a local update equals a fresh synthesis)."""
from dataclasses import replace

import numpy as np
import oracle
import pytest
from clirun import infinitex

from infinitex.engine.controls import CanvasLabels, Controls, ExemplarLabels
from infinitex.engine.controls.labels import mix_distance, pack_mix, top_two
from infinitex.engine.params import SynthParams, structure_params
from infinitex.engine.pyramid import Rect
from infinitex.engine.synth import Synthesizer

FAR = 2 ** 30


def halves(m: int) -> ExemplarLabels:
    """Label 0 on the exemplar's left half, label 2 on its right half."""
    v = np.zeros((m, m), np.uint8)
    v[:, m // 2:] = 2
    return ExemplarLabels(v)


def stripes(x: int, y: int, w: int, h: int, band: int = 24) -> CanvasLabels:
    """Vertical bands of label 0 and 2 (canvas values 1 and 3) over a rectangle, free around it."""
    xs = np.arange(w)[None, :].repeat(h, axis=0)
    v = np.where((xs // band) % 2 == 0, 1, 3).astype(np.uint8)
    return CanvasLabels.from_image(v, x, y)


def test_mixes_and_their_distance():
    w = np.array([[5, 0, 3], [0, 0, 7], [2, 2, 0]])
    i1, i2, w1, w2 = top_two(w)
    assert list(i1) == [0, 2, 0] and list(i2) == [2, 2, 1]       # ties: the lower label first
    assert list(w1) == [159, 255, 128] and list(w2) == [96, 0, 127]
    a = pack_mix(np.array([0]), np.array([0]), np.array([255]), np.array([0])).astype(np.int64)
    b = pack_mix(np.array([2]), np.array([2]), np.array([255]), np.array([0])).astype(np.int64)
    assert mix_distance(a, a)[0] == 0 and mix_distance(a, b)[0] == 2 * 255 * 255
    half = pack_mix(np.array([0]), np.array([2]), np.array([128]), np.array([127])).astype(np.int64)
    assert mix_distance(a, half)[0] == 127 ** 2 + 127 ** 2


@pytest.mark.parametrize("name", ["gravel-appearance", "gravel-color", "torus-color-k3"])
@pytest.mark.parametrize("x, y", [(-20, 30), (FAR - 150, -FAR + 60)])
def test_gl_matches_oracle_with_labels(analyses, gpu, name, x, y):
    an = analyses[name]
    controls = Controls(labels_exemplar=halves(an.size), labels_canvas=stripes(x - 30, y - 10, 90, 70))
    params = SynthParams.default(an.L, seed=4)
    gl = Synthesizer(an, params, gpu=gpu, controls=controls).window(Rect.of(x, y, 40, 36))
    assert np.array_equal(gl, oracle.synthesize(an, params, x, y, 40, 36, controls=controls))


@pytest.mark.parametrize("x, y", [(-20, 30), (FAR - 150, -FAR + 60)])
def test_gl_matches_oracle_with_a_background_label(analyses, gpu, x, y):
    """A palette's background (what is not painted is label 2 here): GL equals
    the oracle across the painted stripes and the unpainted rest, and windows
    that overlap agree (local updates: the test below)."""
    an = analyses["gravel-appearance"]
    canvas = replace(stripes(x - 30, y - 10, 40, 70), background=3)
    controls = Controls(labels_exemplar=halves(an.size), labels_canvas=canvas)
    params = SynthParams.default(an.L, seed=4)
    gl = Synthesizer(an, params, gpu=gpu, controls=controls).window(Rect.of(x, y, 40, 36))
    assert np.array_equal(gl, oracle.synthesize(an, params, x, y, 40, 36, controls=controls))
    other = Synthesizer(an, params, gpu=gpu, controls=controls).window(Rect.of(x + 13, y - 7, 40, 36))
    assert np.array_equal(gl[:29, 13:], other[7:, :27])


def test_nothing_painted_over_a_background_is_its_label(analyses, gpu):
    """Unpainted canvas with a background takes that label (a palette with
    nothing painted shows its first exemplar), and without one is free."""
    an = analyses["gravel-appearance"]
    m = an.size
    for bg, want in ((1, 0), (3, 2)):
        controls = Controls(labels_exemplar=halves(m), labels_canvas=CanvasLabels(background=bg))
        assert controls.labels_active and controls.labels_canvas.used == (want,)
        with Synthesizer(an, SynthParams.default(an.L, seed=2), gpu=gpu, controls=controls) as s:
            S = s.window(Rect.of(500, -300, 96, 64))
        got = halves(m).values[S[..., 1], S[..., 0]]
        assert (got == want).mean() > 0.97
    assert not Controls(labels_exemplar=halves(m), labels_canvas=CanvasLabels()).normalized().labels_active


@pytest.mark.parametrize("vote", [False, True])  # the search alone; search and vote
@pytest.mark.parametrize("name", ["gravel-appearance", "torus-color-k3"])
def test_gl_matches_oracle_with_labels_and_the_fidelity_stage(analyses, gpu, name, vote):
    an = analyses[name]
    controls = Controls(labels_exemplar=halves(an.size), labels_canvas=stripes(-40, -20, 80, 60),
                        label_strength=2.0)
    params = replace(structure_params(SynthParams.default(an.L, seed=2), 1), fidelity_vote=vote)
    gl = Synthesizer(an, params, gpu=gpu, controls=controls).window(Rect.of(-20, -10, 32, 28))
    assert np.array_equal(gl, oracle.synthesize(an, params, -20, -10, 32, 28, controls=controls))


def test_the_synthesis_follows_the_labels(analyses, gpu):
    """Exemplar texels of the painted label: about half without labels, all
    of them (but a few at the bands' edges) with them, at Variety and Balanced."""
    an = analyses["gravel-appearance"]
    m = an.size
    le = halves(m)
    lc = stripes(0, 0, 192, 160, band=48)
    want = (np.arange(192)[None, :].repeat(160, axis=0) // 48) % 2 * 2
    for structure in (0, 2):
        params = structure_params(SynthParams.default(an.L, seed=3), structure)
        plain = Synthesizer(an, params, gpu=gpu, controls=Controls(labels_exemplar=le)).window(Rect.of(0, 0, 192, 160))
        follow = Synthesizer(an, params, gpu=gpu, controls=Controls(labels_exemplar=le, labels_canvas=lc)).window(
            Rect.of(0, 0, 192, 160))
        assert abs(np.mean(le.values[plain[..., 1], plain[..., 0]] == want) - 0.5) < 0.2
        assert np.mean(le.values[follow[..., 1], follow[..., 0]] == want) > 0.95, structure


def test_windows_agree_and_toroidal_tiles_wrap_the_labels(analyses, gpu):
    an = analyses["torus-appearance"]
    controls = Controls(labels_exemplar=halves(an.size), labels_canvas=stripes(FAR - 300, 40, 400, 200))
    params = SynthParams.default(an.L, seed=8)
    synth = Synthesizer(an, params, gpu=gpu, controls=controls)
    a = synth.window(Rect.of(FAR - 260, 60, 150, 120))
    b = synth.window(Rect.of(FAR - 200, 100, 180, 130))
    assert np.array_equal(a[40:, 60:], b[:80, :90])
    # A toroidal tile reads the labels of [0, n)^2 modulo its period: it repeats and follows them.
    n = 64
    tile = replace(params, period=n)
    le = halves(an.size)
    one = Synthesizer(an, tile, gpu=gpu, controls=Controls(labels_exemplar=le, labels_canvas=stripes(0, 0, n, n, 16)))
    t1 = one.window(Rect.of(0, 0, n, n))
    assert np.array_equal(t1, one.window(Rect.of(n, 2 * n, n, n)))
    assert np.array_equal(t1, one.toroidal(n))
    want = (np.arange(n)[None, :].repeat(n, axis=0) // 16) % 2 * 2
    assert np.mean(le.values[t1[..., 1], t1[..., 0]] == want) > 0.9


def test_local_updates_after_label_strokes_equal_a_fresh_synthesis(analyses, gpu):
    an = analyses["gravel-appearance"]
    rng = np.random.default_rng(5)
    le = halves(an.size)
    for structure, background in ((0, 0), (1, 0), (0, 3)):  # (3: a palette's background, label 2)
        params = structure_params(SynthParams.default(an.L, seed=6), structure)
        view = Rect.of(-FAR + 1000, 500, 160, 120)
        vp = Synthesizer(an, params, gpu=gpu).viewport()
        labels = CanvasLabels(background=background)
        vp.set_params(params, Controls(labels_exemplar=le, labels_canvas=labels))
        try:
            for i in range(6):
                vp.show(view)
                old = labels
                cx = view.x0 + float(rng.integers(-40, 200))
                cy = view.y0 + float(rng.integers(-40, 160))
                value = int(rng.choice([0, 1, 3]))
                for d in range(3):
                    labels, _ = labels.painted(cx + 9 * d, cy + 4 * d, float(rng.integers(6, 30)), value,
                                               hardness=float(rng.uniform(0.2, 1)), seed=i)
                controls = Controls(labels_exemplar=le, labels_canvas=labels)
                # Given the changed rectangles, or found by comparing the controls.
                changed = [Rect(*r) for r in old.changed_rects(labels)] if i % 2 else None
                vp.pyramid.update_controls(controls, changed)
                after = vp.read(view)
                fresh = Synthesizer(an, params, gpu=gpu, controls=controls).window(view)
                assert np.array_equal(after, fresh), f"stroke {i}, structure {structure}, background {background}"
        finally:
            vp.release()


def test_bad_labels_are_refused_in_one_sentence(analyses):
    an = analyses["gravel-appearance"]
    m = an.size
    with pytest.raises(ValueError, match="label 3, which the exemplar"):
        Controls(labels_exemplar=ExemplarLabels(np.zeros((m, m), np.uint8)),
                 labels_canvas=stripes(0, 0, 64, 64)).validate(m)
    with pytest.raises(ValueError, match="32x32"):
        Controls(labels_exemplar=ExemplarLabels(np.zeros((32, 32), np.uint8))).validate(m)
    with pytest.raises(ValueError):
        ExemplarLabels(np.full((m, m), 16, np.uint8))
    with pytest.raises(ValueError):
        CanvasLabels.from_image(np.full((8, 8), 17, np.uint8), 0, 0)
    painted, rect = CanvasLabels().painted(10, 10, 6, 2)
    assert painted.used == (1,) and rect[0] <= 4 and rect[2] >= 16
    assert painted.painted(10, 10, 8, 0)[0].empty  # the eraser frees it again


def _two_textures(tmp_path):
    """A 128 px exemplar of two textures side by side, its label map (black |
    green), and a canvas map: a black band across green, transparent corner."""
    import os

    from PIL import Image
    root = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
    g = np.asarray(Image.open(os.path.join(root, "infinitex", "assets", "gravel.png")).convert("RGB"))[:128, :128]
    img = g // 2  # a dark texture on the left, a light one on the right
    img[:, 64:] = 150 + (255 - g[:, 64:]) // 3
    Image.fromarray(img).save(tmp_path / "two.png")
    lab = np.zeros((128, 128, 3), np.uint8)
    lab[:, 64:] = (40, 200, 40)
    Image.fromarray(lab).save(tmp_path / "labels.png")
    c = np.zeros((96, 160, 4), np.uint8)
    c[..., :3], c[..., 3] = (40, 200, 40), 255
    c[30:60, :, :3] = 0
    c[:10, :10, 3] = 0
    Image.fromarray(c).save(tmp_path / "canvas.png")
    return tmp_path / "two.png", tmp_path / "labels.png", tmp_path / "canvas.png"


def test_documents_and_projects_keep_the_labels(tmp_path):
    import json

    from infinitex.project import Document, ExemplarSource, Project, ProjectError, load_project, save_project
    from infinitex.project.document import LabelMaps
    ex, _, _ = _two_textures(tmp_path)
    lab = LabelMaps(halves(128), ((0, 0, 0), (9, 9, 9), (40, 200, 40)), ("stones", "", "grass"),
                    stripes(-30, 20, 100, 60), 2.5)
    doc = Document(ExemplarSource.from_file(str(ex)), labels=lab)
    c = doc.controls(128)
    assert c.labels_active and c.label_strength == 2.5 and c.labels_canvas == lab.canvas
    assert doc.controls(64).labels_exemplar.size == 64  # another fit: scaled, nearest
    path = tmp_path / "p.itex"
    save_project(str(path), Project(doc))
    saved = json.loads(path.read_text())
    assert saved["version"] == 8 and saved["labels"]["names"] == ["stones", "", "grass"]
    back = load_project(str(path)).document
    assert back.labels == lab and back.labels.name(1) == "Label 2" and back.controls(128) == c
    with pytest.raises(ProjectError, match="uses grass, which the exemplar"):  # the canvas uses a label it lacks
        replace(lab, exemplar=ExemplarLabels(np.zeros((128, 128), np.uint8))).validate()
    for damage in (lambda d: d["labels"].update(strength=99), lambda d: d["labels"].update(colors=[[0, 0]]),
                   lambda d: d["labels"].update(exemplar="AAAA"),
                   lambda d: d["labels"]["canvas"]["tiles"][0].update(x=True),
                   lambda d: d["labels"].update(colors=[[0, 0, 0]])):  # labels 1 and 2 lose their colors
        bad = json.loads(path.read_text())
        damage(bad)
        path.write_text(json.dumps(bad))
        with pytest.raises(ProjectError):
            load_project(str(path))


def test_both_commands_take_label_maps(tmp_path):
    from PIL import Image
    ex, labels, canvas = _two_textures(tmp_path)

    cli = infinitex  # in this process (tests/clirun.py)
    r = cli("synth", str(ex), "-o", str(tmp_path / "o.png"), "--size", "160", "96", "--coords",
            str(tmp_path / "c.npy"), "--labels-exemplar", str(labels), "--labels-canvas", str(canvas), "-q")
    assert r.returncode == 0, r.stderr
    coords = np.load(tmp_path / "c.npy")
    got = coords[..., 0] >= 64  # the right half of the exemplar: green
    assert got[30:60].mean() < 0.1 and got[65:].mean() > 0.9
    r = cli("export", str(ex), "-o", str(tmp_path / "e.png"), "--rect", "0", "0", "160", "96",
            "--labels-exemplar", str(labels), "--labels-canvas", str(canvas), "--fidelity", "0", "-q")
    assert r.returncode == 0, r.stderr
    a = np.asarray(Image.open(tmp_path / "o.png").convert("L"), np.float64)
    b = np.asarray(Image.open(tmp_path / "e.png").convert("L"), np.float64)
    assert abs(a[30:60].mean() - b[30:60].mean()) < 15 and b[70:].mean() - b[35:55].mean() > 60
    # Refused in one sentence: anti-aliased label maps, a color the exemplar's map lacks, a canvas map alone.
    from PIL import ImageFilter
    Image.open(labels).filter(ImageFilter.GaussianBlur(4)).save(tmp_path / "smooth.png")  # anti-aliased edges
    odd = np.asarray(Image.open(canvas)).copy()
    odd[50, 70, :3] = (1, 2, 3)
    Image.fromarray(odd).save(tmp_path / "odd.png")
    for args, code, words in (((("--labels-exemplar", str(tmp_path / "smooth.png"))), 3, "colors"),
                              (("--labels-exemplar", str(labels), "--labels-canvas", str(tmp_path / "odd.png")),
                               3, "#010203 at (70, 50)"),
                              (("--labels-canvas", str(canvas)), 2, "needs --labels-exemplar")):
        r = cli("synth", str(ex), "-o", str(tmp_path / "x.png"), "--size", "32", "32", "-q", *args)
        assert r.returncode == code and words in r.stderr and len(r.stderr.strip().splitlines()) == 1, r.stderr
    # A project keeps its label strength unless --label-strength is given; Make tileable is refused with labels.
    from infinitex.project import Document, ExemplarSource, Project, save_project
    from infinitex.project.document import LabelMaps
    proj = tmp_path / "p.itex"
    save_project(str(proj), Project(Document(ExemplarSource.from_file(str(ex)), structure=0, labels=LabelMaps(
        halves(128), ((0, 0, 0), (9, 9, 9), (40, 200, 40)), (), stripes(0, 0, 64, 64), 2.5))))
    from infinitex.cli.common import label_maps
    from infinitex.project import load_project
    import argparse
    doc = load_project(str(proj)).document
    args = argparse.Namespace(labels_exemplar=None, labels_canvas=str(canvas), labels_origin=[0, 0], label_strength=None)
    got = label_maps(args, (128, 128), "resize", 128, doc.labels)  # a new canvas map in the project's colors
    assert got.strength == 2.5 and got.canvas != doc.labels.canvas and got.colors == doc.labels.colors
    assert label_maps(argparse.Namespace(labels_exemplar=None, labels_canvas=None, labels_origin=[0, 0],
                                         label_strength=None), (128, 128), "resize", 128, doc.labels).strength == 2.5
    r = cli("export", str(proj), "-o", str(tmp_path / "t.png"), "--toroidal", "64", "--make-tileable", "-q")
    assert r.returncode == 2 and "Make tileable" in r.stderr and len(r.stderr.strip().splitlines()) == 1, r.stderr


def test_a_label_image_placed_over_painted_labels_keeps_them_where_it_is_free():
    base = stripes(0, 0, 100, 40)
    block = np.zeros((30, 30), np.uint8)
    block[10:20, 10:20] = 3
    placed = base.replaced(block, 5, 5, keep_free=True)
    over = base.replaced(block, 5, 5)
    xs, ys = np.arange(0, 40), np.arange(0, 40)
    a, b, c = base.sample(xs, ys), placed.sample(xs, ys), over.sample(xs, ys)
    assert np.all(b[15:25, 15:25] == 3) and np.array_equal(b[:15], a[:15])       # free pixels keep what is there
    assert np.all(c[5:15, 5:35] == 0) and np.all(c[15:25, 15:25] == 3)        # else they free it
    assert CanvasLabels.from_image(block, -7, 3) == CanvasLabels().replaced(block, -7, 3)


def test_canvas_mixes_from_kept_tiles_equal_the_mixes_computed_anew():
    """CanvasLabels.features assembles tiles kept between calls and between
    label maps; they equal the mixes computed from the samples, for any
    region and level, before and after dabs (which share untouched tiles)."""
    rng = np.random.default_rng(3)
    labels = CanvasLabels.from_image(rng.integers(0, 4, (150, 230)).astype(np.uint8), -90, 40)
    for step in range(4):
        for _ in range(6):
            k = int(rng.integers(0, 5))
            x0, y0 = int(rng.integers(-300, 100)) >> k, int(rng.integers(-50, 250)) >> k
            w, h = int(rng.integers(1, 150)), int(rng.integers(1, 150))
            kept = labels.features(k, x0, y0, w, h)
            anew = labels._features(k, x0, y0, w, h, 0)
            anew = anew if anew is not None and anew.any() else None
            assert (kept is None) == (anew is None)
            if kept is not None:
                assert np.array_equal(kept, anew)
        labels, _ = labels.painted(float(rng.integers(-80, 120)), float(rng.integers(40, 190)), 20.0, step + 1)
