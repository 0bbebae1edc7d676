"""Near-regular textures: lattice detection, rectification and lattice-aware synthesis."""
from dataclasses import replace

import numpy as np
import oracle
import pytest
from clirun import infinitex
from lattice_gen import (
    bricks,
    lattice_error,
    near_regular,
    random_basis,
    rows,
    stochastic,
    tiles,
)

from infinitex.engine.analysis import AnalysisSettings, analyze
from infinitex.engine.controls import Controls
from infinitex.engine.controls.lattice import (
    Lattice,
    LatticeError,
    autocorrelation_at,
    rectified_exemplar,
)
from infinitex.engine.controls.lattice_block import exact_block, fit_block
from infinitex.engine.controls.lattice_detect import detect
from infinitex.engine.params import DEFAULT_STRUCTURE, SynthParams, structure_params
from infinitex.engine.pyramid import Rect
from infinitex.engine.synth import Synthesizer

FAR = 2 ** 30


# -- detection ----------------------------------------------------------------


@pytest.mark.slow
def test_detection_finds_generated_lattices():
    """80 near-regular images: rotations to 45 degrees, 60-120 degree angles
    (shear), aspect up to 3:1, cells 8 to 96 px, pixel noise, per-cell colour
    and position variation. Both vectors within 2% (0.5 px for short ones),
    and the cell area too, in at least 95% of the cases."""
    rng = np.random.default_rng(3)
    good = 0
    n = 80
    for _ in range(n):
        t1, t2 = random_basis(rng)
        d = detect(near_regular(rng, t1, t2))
        good += d.lattice is not None and lattice_error(d.t1, d.t2, t1, t2) <= 0.02
    assert good >= 0.95 * n, f"{good}/{n} lattices found"


@pytest.mark.parametrize("kind", ["planks", "stripes"])
def test_rows_stripes_and_planks_are_one_dimensional_lattices(kind):
    """Rows (planks, stripes) at periods 6 to 60 px and any angle, straight or
    slightly curved (8 px over the image): the period
    across them within 3% and at most 3 degrees off (10 when curved); the other vector along the
    rows, at least 8 px (not an arbitrary 2 px cut of them)."""
    rng = np.random.default_rng(7)
    for period, angle, bend in [(6, 0, 0), (10, 40, 0), (16, 90, 0), (24, 0, 0), (24, 17, 0), (31, 69, 0),
                                (45, 0, 0), (60, 120, 0), (16, 0, 6), (24, 30, 8)]:  # the last two: curved
        img, along = rows(rng, period=period, angle=angle, kind=kind, bend=bend)
        d = detect(img)
        assert d.lattice is not None, (kind, period, angle, d)
        t1, t2 = np.array(d.t1), np.array(d.t2)
        tol = 0.05 if not bend else 0.18  # 3 degrees; 10 for bent rows (their direction changes by 10)
        across = [t for t in (t1, t2) if abs(t @ along) < tol * np.hypot(*t)]
        lengthwise = [t for t in (t1, t2) if abs(t[0] * along[1] - t[1] * along[0]) < tol * np.hypot(*t)]
        assert across and lengthwise, (kind, period, angle, d.t1, d.t2)
        assert abs(np.hypot(*across[0]) - period) <= 0.03 * period, (kind, period, angle, d.t1, d.t2)
        assert np.hypot(*lengthwise[0]) >= 8.0


@pytest.mark.parametrize("cell", [12, 25, 40])
def test_a_grid_of_thin_lines_gives_its_own_cell_not_a_larger_one(cell):
    rng = np.random.default_rng(cell)
    y, x = np.mgrid[0:256, 0:256]
    img = np.where((y % cell == 0) | (x % cell == 0), 0.1, 0.8) + 0.05 * rng.standard_normal((256, 256))
    d = detect(np.clip(img, 0, 1).astype(np.float32))
    assert d.lattice is not None
    assert lattice_error(d.t1, d.t2, np.array([cell, 0.0]), np.array([0.0, cell])) <= 0.03, (d.t1, d.t2)


def test_stochastic_images_have_no_lattice():
    rng = np.random.default_rng(11)
    for _ in range(30):
        d = detect(stochastic(rng))
        assert d.lattice is None and d.confidence < 0.3


def test_detected_brick_lattice_keeps_rows_horizontal():
    img, t1, t2 = bricks(np.random.default_rng(1), side=256, bw=40, bh=18)
    d = detect(img)
    assert d.lattice is not None and d.confidence > 0.6
    lat = d.lattice
    assert abs(lat.t1[1]) < 0.2 and abs(lat.t1[0] - 40) < 0.4   # the row vector
    assert abs(abs(lat.t2[0]) - 20) < 0.4 and abs(lat.t2[1] - 18) < 0.4
    lat.validate(256, 256)  # the chosen block fits


def test_a_page_of_text_is_not_a_lattice():
    """Letter strokes a few pixels apart along lines correlate a little at
    that pitch; that is no grid of cells (lattice mode garbled the letters)."""
    from PIL import Image, ImageDraw, ImageFont
    rng = np.random.default_rng(5)
    words = "texture synthesis keeps every glyph whole and the lines straight on a page".split()
    img = Image.new("L", (160, 160), 236)
    draw, font = ImageDraw.Draw(img), ImageFont.load_default(size=11)
    for y in range(1, 150, 13):
        x = 1
        while x < 180:
            w = words[int(rng.integers(len(words)))]
            draw.text((x, y), w, fill=20, font=font)
            x += draw.textlength(w + " ", font=font)
    assert detect(np.asarray(img, np.float32)[..., None] / 255.0).lattice is None


def test_a_whole_pixel_lattice_is_copied_exactly():
    """Staggered cells of whole pixels (32 x 16, each row shifted by 16): the
    block becomes their axis-aligned supercell at a whole-pixel origin, so
    the rectified exemplar is the image's own pixels, not a sheared resample;
    vectors off whole pixels keep their block."""
    rng = np.random.default_rng(4)
    motif = rng.uniform(0.2, 0.8, (16, 32, 3))
    motif[:2], motif[:, :2] = 0.95, 0.95
    y, x = np.mgrid[0:200, 0:200]
    img = motif[y % 16, (x + 16 * (y // 16)) % 32] + rng.normal(0, 0.01, (200, 200, 3))
    img = np.clip(img, 0, 1).astype(np.float32)
    d = detect(img)
    lat = d.lattice
    assert lat is not None and lat.t1 == (32.0, 0.0) and lat.t2 == (0.0, 32.0)
    assert all(float(v).is_integer() for v in lat.origin)
    side = lat.nx * 32
    assert side == lat.ny * 32 and lat.exemplar_size() == side
    x0, y0 = int(lat.origin[0]), int(lat.origin[1])
    ex = rectified_exemplar(img, lat)
    assert np.abs(ex.pixels - img[y0:y0 + side, x0:x0 + side]).max() < 1e-5
    # Off whole pixels (a photo's): the block as it was.
    shear = Lattice((20.3, 30.1), (32.4, 0.2), (16.1, 16.3), 2, 2)
    assert exact_block(shear, 200, 200) is shear


@pytest.mark.parametrize("text, message", [
    ("0,0,10,0,20,0.5,2,2", "collinear"),
    ("0,0,2,0,0,10,2,2", "at least"),
    ("0,0,10,0,0,10,3,2", "power of two"),
    ("0,0,10,0,0,10,2", "8 numbers"),
    ("0,0,ten,0,0,10,2,2", "8 numbers"),
    ("0,0,nan,0,0,10,2,2", "finite"),
])
def test_degenerate_lattices_are_refused(text, message):
    with pytest.raises(LatticeError, match=message):
        Lattice.parse(text)


def test_block_outside_the_image_is_refused():
    lat = Lattice.parse("10,10,40,0,0,40,4,2")
    lat.validate(200, 100)
    with pytest.raises(LatticeError, match="does not fit"):
        lat.validate(160, 100)
    assert Lattice.parse(lat.to_text()) == lat


@pytest.mark.parametrize("t1, t2", [((20.0, 0.0), (0.0, 14.0)), ((23.5, 3.0), (-4.0, 19.25)), ((7.0, 0.0), (0.0, 7.0))])
@pytest.mark.parametrize("origin", [(10.0, 12.0), (150.0, 90.0), (-40.0, 300.0)])
def test_fit_block_keeps_the_cells_and_fits_the_most(origin, t1, t2):
    W, H = 160, 120
    lat = fit_block(origin, t1, t2, W, H)
    assert lat is not None and lat.t1 == t1 and lat.t2 == t2
    lat.validate(W, H)  # fits
    # The same cells: the block starts a whole number of cells from the origin.
    basis = np.array([t1, t2]).T
    ij = np.linalg.solve(basis, np.subtract(lat.origin, origin))
    assert np.allclose(ij, np.round(ij), atol=1e-3)
    # No block with more cells (aspect within 2:1) fits anywhere on those cells.
    more = [(nx, ny) for nx in (1, 2, 4, 8, 16) for ny in (1, 2, 4, 8, 16) if nx * ny > lat.nx * lat.ny
            and 0.5 <= nx * np.hypot(*t1) / (ny * np.hypot(*t2)) <= 2.0]
    for nx, ny in more:
        alt = fit_block(origin, t1, t2, W, H, most=(nx, ny))
        assert alt.nx * alt.ny < nx * ny


def test_fit_block_keeps_a_dropped_origin_and_refuses_a_cell_larger_than_the_image():
    lat = fit_block((120.0, 90.0), (20.0, 0.0), (0.0, 14.0), 160, 120, most=(4, 4), keep_origin=True)
    assert lat.origin == (120.0, 90.0) and (lat.nx, lat.ny) == (2, 2)  # shrunk, not moved
    moved = fit_block((120.0, 90.0), (20.0, 0.0), (0.0, 14.0), 160, 120, most=(4, 4))
    assert (moved.nx, moved.ny) == (4, 4) and moved.origin != (120.0, 90.0)
    assert fit_block((0.0, 0.0), (200.0, 0.0), (0.0, 14.0), 160, 120) is None


def test_rectification_maps_the_block_onto_the_square():
    """A lattice drawn at a slant comes out axis-aligned: the rectified
    exemplar's cells are m/nx x m/ny and it tiles (it is a block of whole cells)."""
    rng = np.random.default_rng(5)
    t1, t2 = np.array([30.0, 8.0]), np.array([-6.0, 26.0])
    img = near_regular(rng, t1, t2, side=256, noise=0.0, variation=0.0)
    lat = Lattice((40.0, 30.0), tuple(t1), tuple(t2), 4, 4)
    ex = rectified_exemplar(img, lat)
    m = ex.size
    cx, cy = lat.cell(m)
    assert ex.toroidal and m == lat.exemplar_size()
    px = ex.pixels
    assert autocorrelation_at(px, (cx, 0)) > 0.9 and autocorrelation_at(px, (0, cy)) > 0.9
    assert autocorrelation_at(px, (cx // 2, cy // 3)) < 0.7
    wrapped = np.concatenate([px, px], axis=1)
    seam = np.abs(wrapped[:, m - 1] - wrapped[:, m]).mean()
    assert seam < 1.5 * np.abs(np.diff(px, axis=1)).mean()


# -- synthesis ----------------------------------------------------------------


def _lattice_case(kind: str):
    rng = np.random.default_rng(1)
    if kind == "bricks":
        img, _, _ = bricks(rng, side=256, bw=40, bh=18)
    else:
        img, _, _ = tiles(rng, side=256, cell=32)
    lat = detect(img).lattice
    ex = rectified_exemplar(img, lat)
    an = analyze(ex, AnalysisSettings(lattice=(lat.nx, lat.ny)))
    return lat, ex, an


@pytest.fixture(scope="module")
def cases():
    return {kind: _lattice_case(kind) for kind in ("bricks", "tiles")}


def _regularity(synth, lat, an, ex) -> np.ndarray:
    cx, cy = lat.cell(an.size)
    out = synth.colors(synth.window(Rect.of(-200, 300, 384, 384))).astype(np.float64) / 255.0
    ref = np.array([autocorrelation_at(ex.pixels, (cx, 0)), autocorrelation_at(ex.pixels, (0, cy))])
    got = np.array([autocorrelation_at(out, (cx, 0)), autocorrelation_at(out, (0, cy))])
    return got / ref


@pytest.mark.parametrize("kind", ["bricks", "tiles"])
def test_lattice_mode_keeps_the_lattice_and_plain_mode_breaks_it(cases, gpu, kind):
    lat, ex, an = cases[kind]
    params = SynthParams.default(an.L)
    with_lattice = Synthesizer(an, params, gpu=gpu, controls=Controls(lattice=lat))
    plain = Synthesizer(an, params, gpu=gpu)
    kept = _regularity(with_lattice, lat, an, ex)
    broken = _regularity(plain, lat, an, ex)
    assert (np.abs(kept - 1.0) <= 0.2).all(), f"lattice mode: {kept}"
    assert (broken < 0.6).any(), f"plain mode kept the rows too: {broken}"


def test_coarse_offsets_are_whole_cells(cases, gpu):
    """On every lattice level, S_l(p) - h_l p is the same modulo the cell
    everywhere (the unjittered tiling's phase): coarse structure moved by
    whole cells only. Finer levels move freely."""
    lat, ex, an = cases["bricks"]
    ctl = Controls(lattice=lat)
    synth = Synthesizer(an, SynthParams.default(an.L), gpu=gpu, controls=ctl)
    m = an.size
    cx, cy = lat.cell(m)
    K = lat.level_count(m)
    assert 1 <= K <= an.L
    for level in range(an.L + 1):
        h = an.h(level)
        S = synth.window(Rect.of(-40, 17, 48, 40), level=level).astype(np.int64)
        gy, gx = np.mgrid[17:57, -40:8]
        off_x = (S[..., 0] - h * gx) % cx
        off_y = (S[..., 1] - h * gy) % cy
        same = (off_x == off_x[0, 0]).all() and (off_y == off_y[0, 0]).all()
        if level < K:
            assert same, f"level {level} moved by a fraction of a cell"
        elif level >= K + 1:
            assert not same, f"level {level} should jitter freely"


def test_finer_levels_jitter_less_so_grid_lines_stay_straight(gpu, monkeypatch):
    """Below the lattice levels the randomness is LATTICE_FINE_JITTER of the
    document's: a basket weave's grid lines then run on across its cells
    (0.99 of the exemplar's regularity at the cell), where the full randomness
    moved parts of cells a pixel or two out of step (0.90-0.91)."""
    import infinitex.engine.controls as controls_module
    from bench.exemplars import weave
    img = weave().astype(np.float32)
    lat = detect(img).lattice
    ex = rectified_exemplar(img, lat)
    an = analyze(ex, AnalysisSettings(lattice=(lat.nx, lat.ny)))
    ctl = Controls(lattice=lat)
    params = structure_params(SynthParams.default(an.L), DEFAULT_STRUCTURE)
    fine = lat.level_count(an.size)
    assert fine <= an.L and ctl.jitter_at(params, an.size, fine) == params.jitter[fine] * controls_module.LATTICE_FINE_JITTER
    assert ctl.jitter_at(params, an.size, fine - 1) == params.jitter[fine - 1]
    regularity = {}
    for f in (controls_module.LATTICE_FINE_JITTER, 1.0):
        monkeypatch.setattr(controls_module, "LATTICE_FINE_JITTER", f)
        regularity[f] = _regularity(Synthesizer(an, params, gpu=gpu, controls=ctl), lat, an, ex)
    kept, full = regularity[min(regularity)], regularity[1.0]
    assert (kept > 0.97).all() and (full < 0.95).all(), regularity


@pytest.mark.parametrize("ox, oy", [(0, 0), (FAR - 200, -FAR + 50), (-FAR + 3, FAR - 300)])
def test_windows_agree_in_lattice_mode(cases, gpu, ox, oy):
    lat, ex, an = cases["tiles"]
    synth = Synthesizer(an, replace(SynthParams.default(an.L), seed=4), gpu=gpu, controls=Controls(lattice=lat))
    big = synth.window(Rect.of(ox, oy, 120, 100))
    small = synth.window(Rect.of(ox + 37, oy + 21, 50, 61))
    assert np.array_equal(small, big[21:82, 37:87])


@pytest.mark.parametrize("levels, structure", [(None, 0), (2, 0), (None, DEFAULT_STRUCTURE)])
def test_gl_matches_oracle_in_lattice_mode(cases, gpu, levels, structure):
    """Also with the fidelity stage (the default Structure): on lattice levels it
    tries the neighbors' predictions only."""
    lat, ex, an = cases["bricks"]
    ctl = Controls(lattice=replace(lat, levels=levels))
    params = structure_params(replace(SynthParams.default(an.L), seed=7), structure)
    synth = Synthesizer(an, params, gpu=gpu, controls=ctl)
    for x, y in [(5, -9), (-FAR + 17, FAR - 64)]:
        gl = synth.window(Rect.of(x, y, 24, 20))
        assert np.array_equal(gl, oracle.synthesize(an, params, x, y, 24, 20, controls=ctl))


def test_toroidal_tile_of_whole_cells_wraps(cases, gpu):
    lat, ex, an = cases["tiles"]
    synth = Synthesizer(an, SynthParams.default(an.L), gpu=gpu, controls=Controls(lattice=lat))
    n = 256
    cx, cy = lat.cell(an.size)
    assert n % cx == 0 and n % cy == 0
    tile = synth.toroidal(n)
    periodic = replace(synth.params, period=n)
    saved, synth.params = synth.params, periodic
    try:
        wide = synth.window(Rect.of(-n // 2, -n // 4, 2 * n, n))
    finally:
        synth.params = saved
    assert np.array_equal(wide, np.tile(tile, (3, 3, 1))[3 * n // 4:7 * n // 4, n // 2:5 * n // 2])
    img = synth.colors(tile).astype(np.float64)
    seam = np.abs(img[:, 0] - img[:, -1]).mean()
    assert seam <= 1.3 * np.abs(np.diff(img, axis=1)).mean()


def test_lattice_controls_must_match_the_analysis(cases, gpu):
    lat, ex, an = cases["tiles"]
    with pytest.raises(ValueError, match="analyzed for"):
        Synthesizer(an, SynthParams.default(an.L), gpu=gpu, controls=Controls(lattice=replace(lat, nx=lat.nx * 2)))


# -- command line and projects ----------------------------------------------------


def _cli(*args):
    import os
    root = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
    return infinitex(*args, cwd=root)  # in this process (tests/clirun.py)


@pytest.mark.slow
def test_cli_prints_the_lattice_and_reuses_it(tmp_path):
    from PIL import Image

    from infinitex.engine.imagefile import to_u8, write_png
    img, _, _ = bricks(np.random.default_rng(1), side=256, bw=40, bh=18, angle=20)
    src = str(tmp_path / "bricks.png")
    write_png(src, to_u8(img))
    a = _cli("synth", src, "--lattice", "auto", "-o", str(tmp_path / "a.png"), "--size", "160", "96", "-q")
    assert a.returncode == 0, a.stderr
    lines = [ln for ln in a.stdout.splitlines() if ln.startswith("lattice: ")]
    assert len(lines) == 1
    spec = lines[0][len("lattice: "):]
    lat = Lattice.parse(spec)
    assert lat.nx >= 2 and lat.ny >= 2
    b = _cli("synth", src, "--lattice", spec, "-o", str(tmp_path / "b.png"), "--size", "160", "96", "-q")
    assert b.returncode == 0 and b.stdout.strip() == lines[0]
    pa, pb = (np.asarray(Image.open(tmp_path / n)) for n in ("a.png", "b.png"))
    assert pa.shape == (96, 160, 3) and np.array_equal(pa, pb)
    # export shares the code: the same rectangle in the input's geometry is the same image
    c = _cli("export", src, "--lattice", spec, "-o", str(tmp_path / "c.png"), "--rect", "0", "0", "160", "96", "-q")
    assert c.returncode == 0, c.stderr
    assert np.array_equal(np.asarray(Image.open(tmp_path / "c.png")), pa)
    bad = _cli("synth", src, "--lattice", "0,0,30,0,60,0.5,2,2", "-o", str(tmp_path / "d.png"))
    assert bad.returncode == 2 and bad.stderr.count("\n") == 1 and "collinear" in bad.stderr
    far = _cli("synth", src, "--lattice", "0,0,130,0,0,60,2,2", "-o", str(tmp_path / "d.png"))
    assert far.returncode == 3 and "does not fit" in far.stderr
    tor = _cli("synth", src, "--lattice", spec, "--toroidal", "--size", "32", "32", "-o", str(tmp_path / "d.png"))
    assert tor.returncode == 2 and "whole cells" in tor.stderr


def test_cli_reports_no_lattice_on_a_stochastic_image(tmp_path):
    import os
    root = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
    r = _cli("synth", os.path.join(root, "infinitex", "assets", "gravel.png"), "--lattice", "auto", "-o", str(tmp_path / "g.png"), "-q")
    assert r.returncode == 0 and r.stdout.strip() == "lattice: none"


def test_lattice_in_projects():
    import io

    from PIL import Image

    from infinitex.engine.imagefile import to_u8
    from infinitex.project import (
        Document,
        ExemplarSource,
        Project,
        ProjectError,
        project_from_json,
        project_to_json,
    )
    img, _, _ = tiles(np.random.default_rng(2), side=128, cell=32)
    buf = io.BytesIO()
    Image.fromarray(to_u8(img)).save(buf, format="PNG")
    lat = Lattice((0.5, 0.0), (32.0, 0.0), (0.0, 32.0), 2, 2, levels=3)
    doc = Document(ExemplarSource.from_bytes(buf.getvalue(), "tiles.png"), lattice=lat, structure=0)
    d = project_to_json(Project(doc))
    assert d["version"] == 3  # with Variety; any other Structure preset needs 6
    back = project_from_json(d).document
    assert back.lattice == lat and back.analysis_key() == doc.analysis_key()
    assert back.controls(64).lattice == lat
    assert doc.analysis_key() == Document(doc.exemplar, lattice=replace(lat, levels=None)).analysis_key()
    for damage in ({"origin": [0, 0], "t1": [10, 0], "t2": [20, 0.1], "cells": [2, 2]},
                   {"origin": [0, 0], "t1": [10, 0], "t2": [0, 10], "cells": [3, 2]},
                   {"origin": "x"}, [1, 2]):
        bad = dict(d, lattice=damage)
        with pytest.raises(ProjectError):
            project_from_json(bad)


def test_session_with_a_lattice_paints_locally_and_exports_in_both_geometries(gpu, tmp_path):
    """A lattice document in the session: canvas paint is re-synthesized
    locally and equals a fresh synthesis; changing the lattice levels keeps
    the analysis; the view exported in the input's geometry equals main.py
    export; a toroidal tile that is not whole cells is refused."""
    import io

    from PIL import Image

    from infinitex.app.session import Frame, Session
    from infinitex.engine.controls import CanvasField
    from infinitex.engine.imagefile import to_u8
    from infinitex.engine.pyramid import SynthesisError
    from infinitex.export.window import ExportJob
    from infinitex.project import Document, ExemplarSource

    img, _, _ = bricks(np.random.default_rng(1), side=256, bw=40, bh=18)
    buf = io.BytesIO()
    Image.fromarray(to_u8(img)).save(buf, format="PNG")
    path = tmp_path / "bricks.png"
    path.write_bytes(buf.getvalue())
    lat = replace(detect(img).lattice, nx=2)  # cells 64 x 32 px of a 128 px exemplar
    doc = Document(ExemplarSource.from_file(str(path)), lattice=lat)
    s = Session(gpu)
    s.load_now(doc)
    assert s.analysis.settings.lattice == (lat.nx, lat.ny) and s.controls.lattice == lat
    frame = Frame(level=s.L, want=Rect.of(-150, -100, 300, 200))
    while not s.refine(frame, 1.0):
        pass
    field = CanvasField()
    d = doc
    for i in range(5):
        field, _ = field.painted(-60 + 30 * i, 12.0 * i, 20.0, 65535)
        d = replace(d, randomness_canvas=field)
        s.sync(d)
        assert any(s.refine(frame, 1.0) for _ in range(10))  # a dab settles in a few budgets (a busy machine)
    fresh = Synthesizer(s.analysis, s.params, gpu=gpu, controls=d.controls(s.analysis.size)).window(frame.want)
    assert np.array_equal(s.pyramid.read(s.L, frame.want), fresh)
    key = s.key
    d2 = replace(d, lattice=replace(lat, levels=2))
    s.sync(d2)
    assert s.key == key  # no new analysis: only which levels are lattice levels
    while not s.refine(frame, 1.0):
        pass
    assert not np.array_equal(s.pyramid.read(s.L, frame.want), fresh)
    s.sync(d)
    job = ExportJob(s, Rect.of(0, 0, 160, 96), str(tmp_path / "view.png"), geometry="original")
    while not job.step(1.0):
        pass
    assert job.error is None
    with pytest.raises(SynthesisError, match="whole cells"):
        ExportJob(s, Rect(0, 0, 32, 32), str(tmp_path / "t.png"), toroidal=32)
    s.release()
    from infinitex.project import Project, save_project
    proj = tmp_path / "bricks.itex"
    save_project(str(proj), Project(d))
    r = _cli("export", str(proj), "-o", str(tmp_path / "cli.png"), "--rect", "0", "0", "160", "96", "-q")
    assert r.returncode == 0, r.stderr
    assert r.stdout.strip() == f"lattice: {lat.to_text()}"
    assert np.array_equal(np.asarray(Image.open(tmp_path / "cli.png")), np.asarray(Image.open(tmp_path / "view.png")))


def test_a_marked_cell_finds_the_rows_offset():
    """A cell marked by hand over one running-bond brick (stack-bond vectors):
    the rows' offset is found from the image; stacked tiles and a stochastic
    image propose none."""
    from lattice_gen import bricks, stochastic, tiles

    from infinitex.engine.controls.lattice import row_offset
    rng = np.random.default_rng(5)
    img, _, _ = bricks(rng, side=256, bw=40, bh=18)
    found = row_offset(img, 40, 18)
    assert found is not None and abs(found[0] - 20) <= 1 and found[1] > found[2] + 0.1
    img, _, _ = bricks(rng, side=256, bw=36, bh=16)
    assert abs(row_offset(img, 36, 16)[0] - 18) <= 1
    img, _, _ = tiles(rng, side=256, cell=32)
    assert row_offset(img, 32, 32) is None
    assert row_offset(stochastic(rng, side=256), 30, 20) is None
