"""Materials: every map follows the one synthesis, at its own precision, from
import to export (issue 11)."""
import io
import json
import os
import subprocess
import sys
from dataclasses import replace

import imagecodecs
import numpy as np
import pytest
import tifffile
from PIL import Image

import infinitex.engine.material as material_module
from infinitex.app.render.canvas import Canvas
from infinitex.app.session import Session, frame_for
from infinitex.engine.exemplar import ExemplarError, from_array, load_exemplar_bytes
from infinitex.engine.imagefile import encode_image
from infinitex.engine.material import (
    IMAGE,
    MaterialError,
    assign_roles,
    folder_maps,
    load_material,
    role_of,
    siblings,
    single,
)
from infinitex.engine.pyramid import Rect, SynthesisError
from infinitex.export import decode_coords
from infinitex.export.window import ExportJob
from infinitex.project import (
    Display,
    Document,
    ExemplarSource,
    Project,
    ProjectError,
    View,
    load_project,
    project_from_json,
    project_to_json,
    save_project,
)
from infinitex.project.realize import material_for

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
sys.path.insert(0, os.path.join(ROOT, "scripts"))
from make_material import cobbles  # noqa: E402

M = 64


def _u16(px):
    return np.clip(np.rint(px * 65535.0), 0, 65535).astype(np.uint16)


def _u8(px):
    return np.clip(np.rint(px * 255.0), 0, 255).astype(np.uint8)


@pytest.fixture(scope="module")
def maps():
    """A generated material: color, 16-bit height and 16-bit normals from the same shapes."""
    return cobbles(M, seed=3, stones=12)


@pytest.fixture(scope="module")
def folder(tmp_path_factory, maps):
    d = tmp_path_factory.mktemp("stones")
    for role, depth in (("basecolor", 8), ("height", 16), ("normal", 16)):
        (d / f"stones_{role}.png").write_bytes(encode_image(maps[role], depth))
    return d


@pytest.fixture(scope="module")
def session(gpu, folder):
    found = assign_roles([str(folder / "stones_basecolor.png")])
    doc = Document(ExemplarSource.from_file(found["basecolor"])).with_maps(
        [(r, ExemplarSource.from_file(p)) for r, p in found.items()])
    s = Session(gpu)
    s.load_now(doc)
    s.doc = doc
    yield s
    s.release()


def _read(path):
    data = open(path, "rb").read()
    if path.endswith(".tif"):
        return tifffile.imread(io.BytesIO(data))
    if data[24] == 16:
        return imagecodecs.png_decode(data)
    return np.asarray(Image.open(io.BytesIO(data)))


# -- naming and loading ------------------------------------------------------------


def test_roles_come_from_the_naming_rule():
    assert role_of("wood_basecolor.png") == ("wood", "basecolor")
    assert role_of("Wood_Albedo.PNG") == ("wood", "basecolor")
    assert role_of("wood-diffuse.jpg") == ("wood", "basecolor")
    assert role_of("wood_color.png") == ("wood", "basecolor")
    assert role_of("wood_nrm.png") == ("wood", "normal")
    assert role_of("wood.disp.tif") == ("wood", "height")
    assert role_of("brick_wall_rough_2k.png") == ("brick_wall", "roughness")
    assert role_of("Bricks076C_1K-PNG_AmbientOcclusion.png") == ("bricks076c_1k-png", "ao")
    assert role_of("wood_metallic.png")[1] == "metallic" and role_of("wood_opacity.png")[1] == "opacity"
    assert role_of("wood.png") is None and role_of("wood_grain.png") is None and role_of("x_normal.txt") is None


def test_siblings_folders_and_chosen_files(folder, tmp_path):
    found = siblings(str(folder / "stones_height.png"))
    assert sorted(found) == ["basecolor", "height", "normal"]
    assert assign_roles([str(folder)]) == folder_maps(str(folder)) == found
    assert assign_roles([str(folder / "stones_normal.png"), str(folder / "stones_height.png")]) == {
        "normal": str(folder / "stones_normal.png"), "height": str(folder / "stones_height.png")}
    lone = tmp_path / "lone.png"
    lone.write_bytes((folder / "stones_basecolor.png").read_bytes())
    assert assign_roles([str(lone)]) == {IMAGE: str(lone)}


def _one_sentence(exc):
    msg = str(exc.value)
    assert "\n" not in msg and msg.endswith(".") and len(msg) < 300, msg
    return msg


def test_bad_material_sets_get_one_sentence(folder, tmp_path, maps):
    d = tmp_path / "bad"
    d.mkdir()
    for role in ("basecolor", "height"):
        (d / f"w_{role}.png").write_bytes((folder / f"stones_{role}.png").read_bytes())
    # duplicate roles
    (d / "w_albedo.png").write_bytes((folder / "stones_basecolor.png").read_bytes())
    with pytest.raises(MaterialError) as e:
        siblings(str(d / "w_height.png"))
    assert "basecolor" in _one_sentence(e).replace("base color", "basecolor") and "w_albedo.png" in str(e.value)
    os.unlink(d / "w_albedo.png")
    # mismatched sizes
    small = encode_image(cobbles(32, seed=3, stones=6)["height"], 16)
    files = [("basecolor", "w_basecolor.png", (folder / "stones_basecolor.png").read_bytes()),
             ("height", "w_height.png", small)]
    with pytest.raises(MaterialError) as e:
        load_material(files)
    assert "same size" in _one_sentence(e)
    # an unreadable sibling
    files[1] = ("height", "w_height.png", b"\x89PNG\r\n\x1a\n not really")
    with pytest.raises(MaterialError) as e:
        load_material(files)
    assert "height" in _one_sentence(e)
    # duplicate roles given explicitly, a normal map that is gray, several materials in a folder
    with pytest.raises(MaterialError) as e:
        load_material([files[0], ("basecolor", "b.png", files[0][2])])
    _one_sentence(e)
    with pytest.raises(MaterialError) as e:
        load_material([files[0], ("normal", "n.png", encode_image(maps["height"], 16))])
    assert "RGB" in _one_sentence(e)
    (d / "other_normal.png").write_bytes((folder / "stones_normal.png").read_bytes())
    with pytest.raises(MaterialError) as e:
        folder_maps(str(d))
    assert "several materials" in _one_sentence(e)
    with pytest.raises(MaterialError) as e:
        assign_roles([str(d / "w_basecolor.png"), str(tmp_path / "nothing.png")])
    _one_sentence(e)


def test_a_failed_material_leaves_the_session_as_it_was(gpu, session, folder, maps):
    """Nothing is half-loaded: a bad set fails whole, and the open material stays."""
    before = (session.material, session.analysis, session.key)
    bad = [("basecolor", ExemplarSource.from_bytes((folder / "stones_basecolor.png").read_bytes(), "b_basecolor.png")),
           ("height", ExemplarSource.from_bytes(encode_image(cobbles(32, seed=1)["height"], 16), "b_height.png"))]
    doc = Document(bad[0][1]).with_maps(bad)
    with pytest.raises(ExemplarError, match="same size"):
        session.load_now(doc)
    assert (session.material, session.analysis, session.key) == before


# -- precision ------------------------------------------------------------------------


def test_16_bit_and_float_maps_keep_their_precision(tmp_path):
    rng = np.random.default_rng(5)
    rgb16 = rng.integers(0, 65536, (40, 40, 3), dtype=np.uint16)
    ex = load_exemplar_bytes(imagecodecs.png_encode(rgb16), name="n.png", fit="crop")
    assert ex.depth == 16
    assert np.array_equal(_u16(ex.pixels), rgb16[4:36, 4:36])  # Pillow alone would keep 8 bits
    gray16 = rng.integers(0, 65536, (40, 40), dtype=np.uint16)
    ex = load_exemplar_bytes(encode_image(gray16[..., None] / 65535.0, 16), name="h.png", fit="crop")
    assert ex.depth == 16 and np.array_equal(_u16(ex.pixels[..., 0]), gray16[4:36, 4:36])
    flt = rng.uniform(-3.0, 250.0, (40, 40, 3)).astype(np.float32)
    buf = io.BytesIO()
    tifffile.imwrite(buf, flt, photometric="rgb")
    ex = load_exemplar_bytes(buf.getvalue(), name="f.tif", fit="crop")
    lo, hi = ex.value_range
    assert ex.depth == 32 and lo == pytest.approx(flt.min()) and hi == pytest.approx(flt.max())
    assert np.allclose(lo + ex.pixels * (hi - lo), flt[4:36, 4:36], rtol=0, atol=1e-4)
    # and a float export writes the source's units back
    back = tifffile.imread(io.BytesIO(encode_image(ex.pixels, 32, ex.value_range)))
    assert back.dtype == np.float32 and np.allclose(back, flt[4:36, 4:36], atol=1e-4)


# -- exports: every map through the same coordinates ------------------------------------


def _check_maps_follow(job_outputs, coords, maps, period=None):
    """Each exported map is the input map looked up through the coordinate map, exactly."""
    got = {role: _read(path) for role, path, _ in job_outputs}
    ys, xs = coords[..., 1], coords[..., 0]
    assert np.array_equal(got["basecolor"], _u8(maps["basecolor"])[ys, xs])
    assert got["height"].dtype == np.uint16
    assert np.array_equal(got["height"], _u16(maps["height"][..., 0])[ys, xs])
    assert np.array_equal(got["normal"], _u16(maps["normal"])[ys, xs])
    assert len(np.unique(got["height"])) > 256 and len(np.unique(_u16(maps["height"]))) > 256
    return got


@pytest.mark.parametrize("kind", ["view", "rect", "toroidal"])
def test_every_exported_map_is_its_map_through_the_coordinates(session, maps, tmp_path, kind):
    out = str(tmp_path / "t.png")
    if kind == "toroidal":
        rect, tor = Rect(0, 0, 64, 64), 64
    elif kind == "view":
        rect, tor = Rect.of(-2 ** 30, 2 ** 30 - 50, 120, 90), 0
    else:
        rect, tor = Rect.of(-37, 11, 150, 70), 0
    job = ExportJob(session, rect, out, toroidal=tor, coords_path=str(tmp_path / "t_coords.png"))
    job.run()
    assert [os.path.basename(p) for _, p, _ in job.outputs] == ["t_basecolor.png", "t_normal.png", "t_height.png"]
    coords = decode_coords(np.asarray(Image.open(tmp_path / "t_coords.png")))
    assert coords.shape[:2] == (rect.h, rect.w)
    got = _check_maps_follow(job.outputs, coords, maps)
    if tor:  # every map tiles seamlessly: the periodic canvas around the tile's edges is the tile repeated
        big = session.synth
        saved = big.params
        big.set_params(replace(saved, period=tor))
        try:
            around = big.window(Rect.of(tor // 2, tor // 2, tor, tor))
        finally:
            big.set_params(saved)
        rolled = np.roll(coords, (-tor // 2, -tor // 2), axis=(0, 1))
        assert np.array_equal(around, rolled)
        for role, img in got.items():
            wrapped = np.concatenate([img, img], axis=1)
            # across the seam the map continues as it does inside: no jump larger than inside
            seam = np.abs(wrapped[:, tor].astype(float) - wrapped[:, tor - 1].astype(float)).mean()
            inner = np.abs(np.diff(img.astype(float), axis=1)).mean()
            assert seam <= 3 * inner + 1, role


def test_overlapping_material_exports_agree_far_from_the_origin(session, tmp_path):
    a = ExportJob(session, Rect.of(2 ** 30 - 80, -2 ** 30, 100, 60), str(tmp_path / "a.png"), maps=["height"])
    b = ExportJob(session, Rect.of(2 ** 30 - 40, -2 ** 30 + 20, 100, 60), str(tmp_path / "b.png"), maps=["height"])
    a.run()
    b.run()
    ha, hb = _read(a.outputs[0][1]), _read(b.outputs[0][1])
    assert np.array_equal(ha[20:, 40:], hb[:40, :60])


def test_depth_choice_and_naming(session, maps, tmp_path):
    job = ExportJob(session, Rect.of(0, 0, 40, 30), str(tmp_path / "d.png"), maps=["height", "basecolor"], depth=32,
                    coords_path=str(tmp_path / "d_coords.png"))
    job.run()
    assert [os.path.basename(p) for _, p, _ in job.outputs] == ["d_height.tif", "d_basecolor.tif"]
    coords = decode_coords(np.asarray(Image.open(tmp_path / "d_coords.png")))
    h = _read(str(tmp_path / "d_height.tif"))
    assert h.dtype == np.float32
    assert np.allclose(h, maps["height"][..., 0][coords[..., 1], coords[..., 0]], atol=1.0 / 65535)
    job = ExportJob(session, Rect.of(0, 0, 40, 30), str(tmp_path / "e.png"), maps=["basecolor"], depth=16)
    job.run()
    assert _read(job.outputs[0][1]).dtype == np.uint16


def test_a_tile_set_gives_every_map_the_same_tiles(session, maps, tmp_path):
    """A material's tile set: one atlas per map at its own depth, every map
    through the same coordinates (the height follows the base color's cuts)."""
    from infinitex.export.tileset import TileSetJob, plan_for
    job = TileSetJob(session, plan_for(session, 2, 64), str(tmp_path / "set.png"), per_tile=True)
    job.run()
    assert job.error is None
    files = {role: path for role, path, _ in job.outputs}
    assert sorted(os.path.basename(p) for p in files.values()) == ["set_basecolor.png", "set_height.png",
                                                                   "set_normal.png"]
    height = _read(files["height"])
    assert height.dtype == np.uint16 and height.shape == (256, 256)
    coords = job.atlas
    assert np.array_equal(height, _u16(maps["height"][..., 0][coords[..., 1], coords[..., 0]]))
    assert np.array_equal(_read(files["basecolor"]), _u8(maps["basecolor"][coords[..., 1], coords[..., 0]]))
    desc = json.loads((tmp_path / "set.json").read_text())
    first = desc["tiles"][0]
    assert set(first["files"]) == {"basecolor", "height", "normal"}
    assert np.array_equal(_read(str(tmp_path / first["files"]["height"])), height[:64, :64])


def test_magnified_normals_have_unit_length(session, tmp_path):
    for depth, tol in ((16, 1.0 / 255), (8, 2.0 / 255)):
        job = ExportJob(session, Rect.of(-20, 7, 48, 40), str(tmp_path / f"m{depth}.png"), maps=["normal", "height"],
                        depth=depth, magnify=4)
        job.run()
        n = _read(job.outputs[0][1]).astype(np.float64) / (65535.0 if depth == 16 else 255.0) * 2.0 - 1.0
        assert n.shape == (160, 192, 3)
        assert np.abs(np.linalg.norm(n, axis=-1) - 1.0).max() <= tol
        h = _read(job.outputs[1][1])
        assert h.shape == (160, 192)
    with pytest.raises(SynthesisError):
        ExportJob(session, Rect.of(0, 0, 4000, 4000), str(tmp_path / "x.png"), magnify=8)


def test_a_single_image_keeps_writing_one_file(gpu, tmp_path, folder):
    s = Session(gpu)
    try:
        s.load_now(Document(ExemplarSource.from_file(str(folder / "stones_height.png"))))
        assert s.material.single and s.material.maps[IMAGE].depth == 16
        job = ExportJob(s, Rect.of(0, 0, 30, 20), str(tmp_path / "one.png"))
        job.run()
        assert [p for _, p, _ in job.outputs] == [str(tmp_path / "one.png")]
        assert _read(str(tmp_path / "one.png")).dtype == np.uint16  # its own 16 bits
        with pytest.raises(SynthesisError, match="TIFF"):
            ExportJob(s, Rect.of(0, 0, 30, 20), str(tmp_path / "one.png"), depth=32)
    finally:
        s.release()


# -- projects ------------------------------------------------------------------------------


def test_projects_embed_or_reference_every_map_hash_checked(session, tmp_path, folder):
    doc = session.doc
    proj = Project(doc, View(), Display(mode="lit", map="height", light_azimuth=200.0))
    back = project_from_json(json.loads(json.dumps(project_to_json(proj))))
    assert back.document == doc and back.document.analysis_key() == doc.analysis_key()
    assert back.display.mode == "lit" and back.display.map == "height" and back.display.light_azimuth == 200.0
    # referenced maps, relative to the project
    p = str(folder / "ref.itex")
    save_project(p, proj, embed=False)
    d = json.load(open(p))
    assert d["material"]["maps"][0]["path"] == "stones_normal.png" and d["version"] == (4 if doc.structure == 0 else 6)
    assert load_project(p).document == doc
    # a changed map is refused
    tampered = tmp_path / "t"
    tampered.mkdir()
    for name in os.listdir(folder):
        if name.endswith(".png"):
            (tampered / name).write_bytes((folder / name).read_bytes())
    copied = [(r, ExemplarSource.from_file(str(tampered / os.path.basename(src.path)))) for r, src in doc.maps]
    save_project(str(tampered / "p.itex"), replace(proj, document=doc.with_maps(copied)), embed=False)
    data = bytearray((tampered / "stones_height.png").read_bytes())
    (tampered / "stones_height.png").write_bytes(encode_image(cobbles(M, seed=9, stones=12)["height"], 16))
    with pytest.raises(ProjectError, match="does not match"):
        load_project(str(tampered / "p.itex"))
    os.unlink(tampered / "stones_height.png")
    with pytest.raises(ProjectError, match="cannot be found"):
        load_project(str(tampered / "p.itex"))
    assert data


def test_analysis_weights_decide_the_guide(session, folder):
    mat = session.material
    assert session.exemplar.channels == 4  # base color and height by default
    g = mat.guide({"normal": 1.0})
    assert g.channels == 3 and np.array_equal(g.pixels, mat.maps["normal"].pixels)
    doc = replace(session.doc, weights=(("basecolor", 1.0), ("normal", 0.5), ("height", 0.0)))
    assert doc.analysis_key() != session.doc.analysis_key()
    from infinitex.project.realize import exemplar_for
    ex, _ = exemplar_for(doc, material=material_for(doc))
    assert ex.channels == 6 and np.allclose(ex.pixels[..., 3:], 0.5 * mat.maps["normal"].pixels)
    with pytest.raises(MaterialError, match="4 channels"):
        exemplar_for(replace(doc, model="color"), material=mat)
    with pytest.raises(ProjectError):
        replace(doc, weights=(("basecolor", 0.0),)).validate()
    with pytest.raises(ProjectError):
        replace(doc, weights=(("roughness", 1.0),)).validate()


# -- display ----------------------------------------------------------------------------


def test_lit_preview_follows_the_light(gpu, tmp_path):
    """A ramp lit from the side its slope faces is brighter than lit from behind,
    with normals or with heights, at 1:1 and magnified."""
    m = 64
    ramp = np.tile((np.arange(m, dtype=np.float32) / m)[None, :, None], (m, 1, 1))  # rises to the right
    color = np.full((m, m, 3), 0.7, dtype=np.float32)
    slope = np.array([-0.5, 0.0, 1.0]) / np.sqrt(1.25)  # faces left (x), as the ramp does
    normal = np.broadcast_to((slope * 0.5 + 0.5).astype(np.float32), (m, m, 3)).copy()
    for role, px in (("basecolor", color), ("height", ramp), ("normal", normal)):
        (tmp_path / f"r_{role}.png").write_bytes(encode_image(px, 16 if role != "basecolor" else 8))
    for drop in ("height", "normal"):  # normal-shaded, then height-shaded
        found = {r: p for r, p in assign_roles([str(tmp_path)]).items() if r != drop}
        doc = Document(ExemplarSource.from_file(found["basecolor"])).with_maps(
            [(r, ExemplarSource.from_file(p)) for r, p in found.items()])
        s = Session(gpu)
        canvas = Canvas(gpu)
        try:
            s.load_now(replace(doc, jitter=(0.0,) * 7))
            assert s.shape_map()[0] == ("height" if drop == "normal" else "normal")
            kind, role = s.shape_map()
            canvas.set_exemplar(s.display_stack("basecolor"), s.analysis.toroidal, None, s.generation)
            canvas.set_shape(s.shape_stack(role), kind, s.analysis.toroidal, (s.generation, role))
            canvas.ensure_size(48, 32)
            for zoom in (1.0, 4.0):
                view = View(10.0, 40.0, zoom)
                frame = frame_for(view, 48, 32, s.L)
                while not s.refine(frame, 0.05):
                    pass
                lum = {}
                for az in (180.0, 0.0):  # from the left (the slope's side), from the right
                    canvas.render(s.pyramid, frame, view, Display(mode="lit", light_azimuth=az, light_elevation=30.0))
                    lum[az] = canvas.read().astype(float).mean()
                assert lum[180.0] > lum[0.0] + 20, (drop, zoom, lum)
        finally:
            canvas.release()
            s.release()


# -- the command line ----------------------------------------------------------------------


def _cli(*args):
    return subprocess.run([sys.executable, os.path.join(ROOT, "main.py"), "export", *args],
                          capture_output=True, text=True, timeout=600)


def test_cli_finds_siblings_and_writes_each_map(folder, tmp_path, maps):
    out = str(tmp_path / "c.png")
    r = _cli(str(folder / "stones_basecolor.png"), "-o", out, "--size", "64", "48", "--coords", "-q")
    assert r.returncode == 0, r.stderr
    names = sorted(os.listdir(tmp_path))
    assert names == ["c_basecolor.png", "c_coords.png", "c_height.png", "c_normal.png"]
    coords = decode_coords(np.asarray(Image.open(tmp_path / "c_coords.png")))
    _check_maps_follow([(r_, str(tmp_path / f"c_{r_}.png"), 0) for r_ in ("basecolor", "height", "normal")],
                       coords, maps)
    r = _cli(str(folder), "-o", str(tmp_path / "f.png"), "--size", "32", "32", "--maps", "height", "--depth", "32",
             "-q")
    assert r.returncode == 0, r.stderr
    assert _read(str(tmp_path / "f_height.tif")).dtype == np.float32
    r = _cli(str(folder), "-o", str(tmp_path / "g.png"), "--maps", "gloss")
    assert r.returncode != 0 and len(r.stderr.strip().splitlines()) == 1 and "gloss" in r.stderr
    r = _cli(str(folder), "-o", str(tmp_path / "g.tif"), "--format", "tiff")
    assert r.returncode != 0 and "--maps" in r.stderr


def test_magnification_warps_a_1px_shear_instead_of_doubling_it():
    """Two patches 1 px apart (a sheared seam: the right half reads one row
    lower) magnified 8x: a thin dark line stays one line at full depth that
    steps smoothly by a pixel, where LH05's plain blend drew two half-dark
    copies (the comb or zipper lines of 800%). Texel centers keep their colors."""
    m, z = 32, 8
    px = np.full((m, m, 1), 0.8, np.float32)
    px[16] = 0.1                                     # a 1 px dark line, row 16
    mat = single(from_array(px, toroidal=False))
    ys, xs = np.mgrid[0:10, 0:12]
    coords = np.stack([xs + 10, ys + 10 + (xs >= 6)], axis=-1)  # columns 6.. read one row lower
    out = mat.magnified(mat.primary, coords, z)[..., 0]
    depth = 0.8 - out.min(axis=0)                    # how dark the line gets in each output column
    assert depth.min() >= depth[:z].max() - 1e-6 > 0.6  # as dark across the seam as away from it
    rows = out.argmin(axis=0)
    assert np.all(np.diff(rows) <= 0) and rows[0] - rows[-1] == z  # one line, moving up by one texel
    straight = mat.magnified(mat.primary, np.stack([xs + 10, ys + 10], axis=-1), z)[..., 0]
    assert np.array_equal(out[:, :3 * z], straight[:, :3 * z])  # away from the seam: LH05's magnification
    saved = material_module.shear_pull
    material_module.shear_pull = lambda pred, wgt, c, *_: np.zeros_like(pred[c])
    try:
        plain = mat.magnified(mat.primary, coords, z)[..., 0]
    finally:
        material_module.shear_pull = saved
    assert (0.8 - plain.min(axis=0)).min() < 0.75 * depth[:z].max()  # the plain blend: two fainter copies
