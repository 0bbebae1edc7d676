"""Make tileable (engine/tileable.py): a photo that does not wrap becomes a
toroidal exemplar; its interior is kept; the synthesis zoomed out no longer
repeats its borders; the setting reaches projects and both commands."""
from __future__ import annotations

import json
import os
from dataclasses import replace

import numpy as np
import pytest
from clirun import infinitex
from PIL import Image
from scipy import ndimage

from infinitex.engine.exemplar import from_array
from infinitex.engine.wrap import guess_toroidal, seam_ratios
from infinitex.engine.tileable import (
    _column_cut,
    _wrap_columns,
    make_tileable,
    periodic_component,
    recommended,
    tileable_exemplar,
)

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))


def photo(side: int = 128, seed: int = 3) -> np.ndarray:
    """A wood-like image that does not wrap: wavy grain, a light-to-dark
    shading across it and a dark corner (what a photo's lighting does)."""
    rng = np.random.default_rng(seed)
    y, x = np.mgrid[0:side, 0:side].astype(np.float64)
    grain = 0.12 * np.sin(2 * np.pi * y / 9.0 + 2.5 * np.sin(2 * np.pi * x / 61.0 + 1.0))
    shade = 0.25 * x / side - 0.2 * np.exp(-((x - side) ** 2 + (y - side) ** 2) / (0.2 * side) ** 2)
    g = 0.5 + grain + shade + 0.03 * rng.standard_normal((side, side))
    return np.clip(np.stack([g, 0.8 * g, 0.6 * g], axis=2), 0, 1).astype(np.float32)


def test_the_periodic_component_removes_the_wrap_around_step_only():
    """A smooth image that already wraps hardly changes (the jump across its
    border is one neighbour difference); a ramp's wrap-around step goes."""
    rng = np.random.default_rng(0)
    img = ndimage.gaussian_filter(rng.random((64, 64, 1)), (3, 3, 0), mode="wrap")
    ramp = np.linspace(0, 1, 64)[None, :, None] * np.ones((64, 64, 1))
    assert np.abs(periodic_component(img) - img).max() < 0.1 * np.ptp(img)
    p = periodic_component(ramp)
    assert abs(p[:, 0] - p[:, -1]).max() < 0.1 * abs(ramp[:, 0] - ramp[:, -1]).max()
    assert np.abs(np.diff(p, axis=0)).max() < 1e-9  # rows stay alike: only a smooth field was taken away


def test_the_border_cut_is_exact_when_the_overlap_repeats():
    """An image whose last ``band`` columns repeat its first ones comes out as
    exactly one period: the cut finds the zero-error overlap."""
    rng = np.random.default_rng(1)
    period = rng.random((40, 50, 3))
    img = period[:, np.arange(50 + 12) % 50]
    assert np.array_equal(_wrap_columns_(img, 12), period)


def test_a_photo_becomes_toroidal_and_keeps_its_interior():
    img = photo()
    assert not guess_toroidal(img)
    b = 16
    out = make_tileable(img, band=b)
    assert out.shape == (128 - b, 128 - b, 3) and out.dtype == np.float32
    # Its seams look like its interior up to blocks of 4 px (at 8 the grain's
    # phase, 9 px a period, cannot continue over 112 rows; guess_toroidal sees that).
    assert max(seam_ratios(out, (1, 2, 4))) < 1.5 < min(seam_ratios(img, (1, 2, 4)))
    # Everything past the band is the periodic component, untouched by the cut.
    p = np.clip(periodic_component(img), 0, 1)
    assert np.allclose(out[b:, b:], p[b:128 - b, b:128 - b], atol=1e-6)
    # Wrap-around neighbours differ no more than interior ones (both axes).
    inner = np.abs(np.diff(out, axis=1)).mean()
    assert np.abs(out[:, 0] - out[:, -1]).mean() <= 1.3 * inner
    assert np.abs(out[0] - out[-1]).mean() <= 1.3 * np.abs(np.diff(out, axis=0)).mean()
    assert np.array_equal(make_tileable(img, band=b), out)  # deterministic
    with pytest.raises(ValueError, match="band"):
        make_tileable(img, band=100)
    assert make_tileable(img[:, :, 0]).ndim == 2  # gray in, gray out


def test_tileable_exemplar_keeps_its_size_and_its_hires_copy_agrees():
    ex = tileable_exemplar(from_array(photo()))
    assert ex.size == 128 and ex.toroidal and ex.pixels.shape == (128, 128, 3)
    assert 0.0 <= ex.pixels.min() and ex.pixels.max() <= 1.0
    big = from_array(photo(300))  # resized to 256, the 300 px original kept for magnification
    assert big.hires is not None
    t = tileable_exemplar(big)
    assert t.size == 256 and t.hires.shape[:2] == (300 - 38, 300 - 38)
    small = ndimage.zoom(t.hires[:, :, 0].astype(np.float64), 256 / t.hires.shape[0], order=1, mode="grid-wrap",
                         grid_mode=True)
    assert np.abs(small - t.pixels[:, :, 0]).mean() < 0.02  # the same picture at both resolutions


def test_it_is_offered_for_unevenly_lit_photos_only():
    """Offered where it helps (a photo's shading, repeated, makes blotches),
    not for an evenly lit stochastic image that fails the seam test, nor for
    one that tiles."""
    lit = from_array(photo())
    rng = np.random.default_rng(5)
    even = from_array(np.clip(0.5 + 0.15 * rng.standard_normal((128, 128, 3)), 0, 1))
    even.toroidal_guess = False  # as if the seam test had failed
    tiles = from_array(ndimage.gaussian_filter(rng.random((128, 128, 3)), (2, 2, 0), mode="wrap"))
    assert recommended(lit) and not recommended(even)
    assert tiles.toroidal_guess and not recommended(tiles)
    assert not recommended(tileable_exemplar(lit))


def test_zoomed_out_the_synthesis_no_longer_repeats_the_photo_s_shading(gpu):
    """The photo's dark corner and shading come back once per exemplar width
    in a plain synthesis (blotches when zoomed out); made tileable, the
    large-scale variation of a 512^2 window drops by more than a third."""
    from infinitex.engine.analysis import analyze
    from infinitex.engine.params import SynthParams
    from infinitex.engine.pyramid import Rect
    from infinitex.engine.synth import Synthesizer
    lows = []
    for ex in (from_array(photo()), tileable_exemplar(from_array(photo()))):
        an = analyze(ex)
        with Synthesizer(an, SynthParams.default(an.L, seed=4), gpu=gpu) as s:
            out = s.colors(s.window(Rect.of(7_000, -3_000, 512, 512)))
        lows.append(float(ndimage.gaussian_filter(out.mean(axis=2), 24).std()))
    assert lows[1] < 0.66 * lows[0], lows


def test_documents_projects_and_commands_carry_it(tmp_path):
    from infinitex.project import Document, ExemplarSource, Project, load_project, save_project
    from infinitex.project.realize import exemplar_for
    path = tmp_path / "wood.png"
    Image.fromarray((photo() * 255).astype(np.uint8)).save(path)
    doc = Document(ExemplarSource.from_file(str(path)))
    plain, _ = exemplar_for(doc)
    made, _ = exemplar_for(replace(doc, make_tileable=True))
    assert not plain.toroidal and made.toroidal and not np.array_equal(plain.pixels, made.pixels)
    assert replace(doc, make_tileable=True).analysis_key() != doc.analysis_key()
    proj = tmp_path / "w.itex"
    save_project(str(proj), Project(replace(doc, make_tileable=True)))
    saved = json.loads(proj.read_text())
    assert saved["version"] == 7 and saved["exemplar"]["make_tileable"] is True
    assert load_project(str(proj)).document.make_tileable
    save_project(str(proj), Project(doc))
    assert "make_tileable" not in json.loads(proj.read_text())["exemplar"]
    saved["exemplar"]["make_tileable"] = "yes"
    proj.write_text(json.dumps(saved))
    with pytest.raises(Exception, match="make_tileable"):
        load_project(str(proj))

    cli = infinitex  # in this process (tests/clirun.py)
    out = tmp_path / "o.png"
    r = cli("synth", str(path), "-o", str(out), "--size", "64", "64", "--make-tileable", "-q")
    assert r.returncode == 0, r.stderr
    r = cli("synth", str(path), "-o", str(tmp_path / "n.png"), "--size", "64", "64", "--lattice", "none")
    assert r.returncode == 0 and "--make-tileable evens out" in r.stderr  # offered (the planks' rows left aside)
    r2 = cli("synth", str(path), "-o", str(tmp_path / "p.png"), "--size", "64", "64", "-q")
    assert r2.returncode == 0 and not np.array_equal(np.asarray(Image.open(out)),
                                                     np.asarray(Image.open(tmp_path / "p.png")))
    r = cli("synth", str(path), "-o", str(out), "--make-tileable", "--lattice", "auto", "-q")
    assert r.returncode == 2 and "--make-tileable" in r.stderr and len(r.stderr.strip().splitlines()) == 1
    r = cli("export", str(path), "-o", str(tmp_path / "e.png"), "--toroidal", "64", "--make-tileable", "-q")
    assert r.returncode == 0, r.stderr
    assert np.asarray(Image.open(tmp_path / "e.png")).shape[:2] == (64, 64)


def _wrap_columns_(img, band):
    return _wrap_columns(img, band, _column_cut(img, band))


def test_a_materials_maps_are_cut_together_and_stay_aligned(tmp_path):
    """One cut for every map of a material: a height map that is the base
    color's red channel stays exactly that after Make tileable (cut alone, its
    seams would run elsewhere); normals stay unit length; documents, their
    analysis exemplar and every map come out toroidal."""
    from infinitex.engine.material import Material, MaterialMap
    from infinitex.engine.tileable import make_tileable_maps, tileable_material
    from infinitex.project import Document, ExemplarSource
    from infinitex.project.realize import exemplar_for, material_for
    base = photo(128, seed=4)
    base[:, :, 1:] = np.roll(photo(128, seed=7), 50, axis=0)[:, :, 1:]  # green, blue: other content
    height = np.ascontiguousarray(base[:, :, :1])
    gy, gx = np.gradient(ndimage.gaussian_filter(height[:, :, 0].astype(np.float64), 2) * 40)
    n = np.stack([-gx, -gy, np.ones_like(gx)], axis=2)
    normal = (n / np.linalg.norm(n, axis=2, keepdims=True) * 0.5 + 0.5).astype(np.float32)
    b, hgt = make_tileable_maps([base, height])
    assert np.abs(hgt - b[:, :, :1]).max() < 1e-5
    alone = make_tileable_maps([height])[0]  # cut on its own: elsewhere
    assert np.abs(alone - hgt).max() > 0.05
    mat = Material({r: MaterialMap(r, from_array(px, toroidal=False)) for r, px in
                    (("basecolor", base), ("height", height), ("normal", normal))}, False)
    made = tileable_material(mat)
    assert made.toroidal and all(mp.exemplar.toroidal for mp in made.maps.values())
    assert np.abs(made.maps["height"].pixels - made.maps["basecolor"].pixels[:, :, :1]).max() < 1e-5
    length = np.linalg.norm(made.maps["normal"].pixels * 2.0 - 1.0, axis=2)
    assert np.abs(length - 1.0).max() < 1e-3
    for name, px in (("b.png", base), ("h.png", height[:, :, 0]), ("n.png", normal)):
        Image.fromarray((px * 255).round().astype(np.uint8)).save(tmp_path / name)
    src = {r: ExemplarSource.from_file(str(tmp_path / f)) for r, f in
           (("basecolor", "b.png"), ("height", "h.png"), ("normal", "n.png"))}
    doc = Document(src["basecolor"]).with_maps(list(src.items()))
    plain, _ = exemplar_for(doc)
    ex, _ = exemplar_for(replace(doc, make_tileable=True))
    assert not plain.toroidal and ex.toroidal and ex.size == plain.size
    assert all(mp.exemplar.toroidal for mp in material_for(replace(doc, make_tileable=True)).maps.values())
