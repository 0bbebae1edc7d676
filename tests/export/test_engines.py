"""A tile set as the game engines' own resources (infinitex/export/engines.py):
Tiled's .tsx/.tmx checked by Tiled itself (tmxrasterizer draws the example
map exactly as we assemble it; tiled --export-tileset reads the Wang set), Godot's .tres parsed by an
independent parser (godot_parser) and checked against the engine's
documented keys and each tile's corners."""
from __future__ import annotations

import json
import os
import re
import shutil
import subprocess
import sys
import xml.etree.ElementTree as ET

import numpy as np
import pytest
from PIL import Image

from infinitex.export.engines import godot_tileset, parse_engines, tiled_tileset
from infinitex.export.wang import TileSetPlan, assemble

sys.path.insert(0, os.path.dirname(os.path.dirname(__file__)))
from clirun import infinitex  # noqa: E402

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
GRAVEL = os.path.join(ROOT, "infinitex", "assets", "gravel.png")
CORNERS = ("nw", "ne", "sw", "se")
# TileSet, TileSetAtlasSource and TileData properties as Godot 4's class reference names them
GODOT_KEYS = [r"resource_name", r"tile_size", r"terrain_set_\d+/mode", r"terrain_set_\d+/terrain_\d+/(name|color)",
              r"sources/\d+", r"texture", r"texture_region_size", r"\d+:\d+/0",
              r"\d+:\d+/0/(terrain_set|terrain|probability)",
              r"\d+:\d+/0/terrains_peering_bit/(top_left|top_right|bottom_left|bottom_right)_corner",
              r"diffuse_texture", r"normal_texture"]


def _tiled_wangs(tsx: bytes) -> tuple[ET.Element, dict[int, tuple[int, ...]]]:
    root = ET.fromstring(tsx)
    ws = root.find("wangsets/wangset")
    assert ws.get("type") == "corner"
    wang = {int(t.get("tileid")): tuple(int(v) for v in t.get("wangid").split(",")) for t in ws.findall("wangtile")}
    return root, wang


@pytest.mark.parametrize("colors", [2, 3])
def test_tiled_wang_ids_name_each_tiles_corners(colors):
    plan = TileSetPlan(colors, 64)
    root, wang = _tiled_wangs(tiled_tileset(plan, "set", "set.png", (64 * colors ** 2,) * 2))
    tiles = plan.tiles()
    assert int(root.get("tilecount")) == len(tiles) == len(wang) and int(root.get("columns")) == colors ** 2
    colours = root.findall("wangsets/wangset/wangcolor")
    assert len(colours) == colors
    for i, t in enumerate(tiles):
        assert t["x"] // 64 + t["y"] // 64 * colors ** 2 == i  # Tiled numbers tiles row by row
        top, ne, right, se, bottom, sw, left, nw = wang[i]
        assert (top, right, bottom, left) == (0, 0, 0, 0)  # a corner set: edges unset
        assert (nw, ne, sw, se) == tuple(t[k] + 1 for k in CORNERS)
    assert len(set(wang.values())) == colors ** 4  # every combination once
    for c, colour in enumerate(colours):  # each colour shown by its uniform tile
        assert set(wang[int(colour.get("tile"))][1::2]) == {c + 1}


def _godot(text: str):
    from godot_parser import parse
    sections = parse(text).get_sections()
    assert sections[0].header.name == "gd_resource" and sections[0].header["type"] == "TileSet"
    assert sections[0].header["format"] == 3 and sections[0].header["load_steps"] == len(sections) - 1
    for s in sections[1:]:
        for key in s.properties:
            assert any(re.fullmatch(k, key) for k in GODOT_KEYS), key
    return sections


@pytest.mark.parametrize("colors, normal", [(2, False), (3, True)])
def test_godot_terrain_bits_are_each_tiles_corners(colors, normal):
    plan = TileSetPlan(colors, 128)
    textures = {"diffuse": "set_basecolor.png", **({"normal": "set_normal.png"} if normal else {})}
    sections = _godot(godot_tileset(plan, "set", textures).decode())
    by = {s.header.name: s for s in sections}
    ext = [s.header["path"] for s in sections if s.header.name == "ext_resource"]
    assert ext == list(textures.values())
    atlas = next(s for s in sections if s.header.name == "sub_resource" and s.header["type"] == "TileSetAtlasSource")
    res = by["resource"]
    assert res["terrain_set_0/mode"] == 1  # TERRAIN_MODE_MATCH_CORNERS
    assert [res[f"terrain_set_0/terrain_{c}/name"] for c in range(colors)] == [f"set {n}" for n in "ABC"[:colors]]
    assert f"terrain_set_0/terrain_{colors}/name" not in res.properties
    if normal:  # a CanvasTexture: the colour map lit by the normal map
        canvas = next(s for s in sections if s.header.name == "sub_resource" and s.header["type"] == "CanvasTexture")
        assert atlas["texture"].args == [canvas.header["id"]]
    tiles = plan.tiles()
    assert sum(1 for k in atlas.properties if re.fullmatch(r"\d+:\d+/0", k)) == len(tiles)
    for t in tiles:
        key = f"{t['x'] // 128}:{t['y'] // 128}/0"
        bits = tuple(atlas[f"{key}/terrains_peering_bit/{side}_corner"]
                     for side in ("top_left", "top_right", "bottom_left", "bottom_right"))
        assert bits == tuple(t[k] for k in CORNERS) and atlas[f"{key}/terrain_set"] == 0
        assert atlas[f"{key}/terrain"] in bits


def test_variants_are_one_terrain_drawn_at_random():
    plan = TileSetPlan(1, 64, 5)
    root, wang = _tiled_wangs(tiled_tileset(plan, "v", "v.png", (192, 128)))
    assert set(wang) == set(range(5)) and set(wang.values()) == {(0, 1) * 4}
    assert [t.get("probability") for t in root.findall("tile")] == ["1"] * 5
    atlas = _godot(godot_tileset(plan, "v", {"diffuse": "v.png"}).decode())[2]
    assert {atlas[f"{t['x'] // 64}:{t['y'] // 64}/0/probability"] for t in plan.tiles()} == {1.0}


def test_engine_choices():
    assert parse_engines("all") == ("tiled", "godot") and parse_engines("none") == ()
    assert parse_engines("godot,tiled") == ("tiled", "godot")
    with pytest.raises(ValueError, match="tiled, godot, all or none"):
        parse_engines("unity")


def _tmxrasterizer() -> str:
    found = shutil.which("tmxrasterizer")
    if found is None:
        if os.environ.get("INFINITEX_REQUIRE_TILED"):
            pytest.fail("tmxrasterizer (Debian package tiled) is not installed: scripts/setup.sh --tests installs it")
        pytest.skip("tmxrasterizer (Debian package tiled) is not installed")
    return found


def _colour_exemplar(path, m: int = 64) -> None:
    rng = np.random.default_rng(5)
    f = np.fft.fft2(rng.standard_normal((m, m, 3)), axes=(0, 1))
    fy, fx = np.fft.fftfreq(m)[:, None], np.fft.fftfreq(m)[None, :]
    img = np.real(np.fft.ifft2(f * np.exp(-(fx ** 2 + fy ** 2) * (m / 6.0) ** 2)[:, :, None], axes=(0, 1)))
    Image.fromarray(((img - img.min()) / np.ptp(img) * 255).astype(np.uint8)).save(path)


def test_tiled_draws_the_example_map_as_we_assemble_it(tmp_path):
    raster = _tmxrasterizer()
    src = tmp_path / "stone.png"
    _colour_exemplar(src)
    out = tmp_path / "set.png"
    r = infinitex("export", src, "-o", out, "--wang", "2", "--tile", "64", "--for", "tiled")
    assert r.returncode == 0, r.stderr
    assert "set.tsx, set.tmx" in r.stderr and not (tmp_path / "set.tres").exists()
    desc = json.loads((tmp_path / "set.json").read_text())
    assert desc["engines"] == {"tiled": {"tilesets": {"image": "set.tsx"}, "map": "set.tmx"}}
    env = dict(os.environ, QT_QPA_PLATFORM="offscreen", XDG_RUNTIME_DIR=str(tmp_path))
    r = subprocess.run([raster, "set.tmx", "render.png"], cwd=tmp_path, env=env, capture_output=True, timeout=60)
    assert r.returncode == 0, r.stderr
    drawn = np.asarray(Image.open(tmp_path / "render.png").convert("RGB"))
    layer = ET.parse(tmp_path / "set.tmx").getroot().find("layer/data").text
    layout = np.array([[int(g) - 1 for g in row.strip(",").split(",")] for row in layer.split()])
    plan = TileSetPlan(2, 64)
    ours = assemble(np.asarray(Image.open(out).convert("RGB")), plan, layout)
    assert drawn.shape == ours.shape == (512, 512, 3)
    assert np.array_equal(drawn, ours)
    assert np.array_equal(ours, np.asarray(Image.open(tmp_path / "set_preview.png").convert("RGB")))
    # Tiled reads the corner Wang set as we mean it (its own export of the tileset to JSON)
    r = subprocess.run([shutil.which("tiled") or "tiled", "--export-tileset", "json", "set.tsx", "set.tsj"],
                       cwd=tmp_path, env=env, capture_output=True, timeout=60)
    assert r.returncode == 0, r.stderr
    wangset, = json.loads((tmp_path / "set.tsj").read_text())["wangsets"]
    assert wangset["type"] == "corner" and len(wangset["colors"]) == 2
    read = {w["tileid"]: w["wangid"] for w in wangset["wangtiles"]}
    assert read == {i: [0, t["ne"] + 1, 0, t["se"] + 1, 0, t["sw"] + 1, 0, t["nw"] + 1]
                    for i, t in enumerate(desc["tiles"])}
    tiles = plan.tiles()  # the example map is a valid arrangement: shared corners agree
    for j in range(8):
        for i in range(7):
            a, b = tiles[layout[j, i]], tiles[layout[j, i + 1]]
            assert (a["ne"], a["se"]) == (b["nw"], b["sw"])


def test_a_material_gives_a_tileset_per_map_and_one_lit_godot_tileset(tmp_path):
    rng = np.random.default_rng(2)
    ex = (rng.random((48, 48)) * 255).astype(np.uint8)
    Image.fromarray(np.stack([ex, ex // 2, 255 - ex], -1)).save(tmp_path / "stone_basecolor.png")
    Image.fromarray(np.stack([ex // 4 + 96, 128 + ex // 4, np.full_like(ex, 255)], -1)).save(
        tmp_path / "stone_normal.png")
    out = tmp_path / "set.png"
    r = infinitex("export", tmp_path / "stone_basecolor.png", "-o", out, "--variants", "2", "--tile", "64", "-q")
    assert r.returncode == 0, r.stderr
    for role in ("basecolor", "normal"):
        root, wang = _tiled_wangs((tmp_path / f"set_{role}.tsx").read_bytes())
        assert root.find("image").get("source") == f"set_{role}.png" and len(wang) == 2
    assert ET.parse(tmp_path / "set.tmx").getroot().find("tileset").get("source") == "set_basecolor.tsx"
    sections = _godot((tmp_path / "set.tres").read_text())
    assert [s.header["path"] for s in sections if s.header.name == "ext_resource"] == ["set_basecolor.png",
                                                                                         "set_normal.png"]
    r = infinitex("export", GRAVEL, "-o", tmp_path / "g.png", "--wang", "2", "--tile", "64", "--for", "none", "-q")
    assert r.returncode == 0, r.stderr
    assert not [f for f in os.listdir(tmp_path) if f.startswith("g.") and f.endswith((".tsx", ".tmx", ".tres"))]
    assert json.loads((tmp_path / "g.json").read_text())["engines"] == {}
    r = infinitex("export", GRAVEL, "-o", tmp_path / "x.png", "--wang", "2", "--for", "unity")
    assert r.returncode == 2 and "tiled, godot, all or none" in r.stderr
    r = infinitex("export", GRAVEL, "-o", tmp_path / "x.png", "--for", "godot")
    assert r.returncode == 2 and "--for goes with --wang or --variants" in r.stderr


def test_the_api_writes_what_the_command_line_writes(tmp_path):
    import infinitex as itx
    (tmp_path / "cli").mkdir()
    (tmp_path / "api").mkdir()
    r = infinitex("export", GRAVEL, "-o", tmp_path / "cli" / "set.png", "--variants", "3", "--tile", "64", "-q")
    assert r.returncode == 0, r.stderr
    atlas, desc = itx.tile_set(GRAVEL, colors=1, n=64, variants=3)
    written = itx.save_tile_set(atlas, desc, tmp_path / "api" / "set.png")
    names = sorted(os.path.basename(f) for f in written)
    assert names == sorted(os.listdir(tmp_path / "cli")) == ["set.json", "set.png", "set.tmx", "set.tres",
                                                            "set.tsx", "set_preview.png"]
    for name in ("set.tsx", "set.tmx", "set.tres"):
        assert (tmp_path / "api" / name).read_bytes() == (tmp_path / "cli" / name).read_bytes(), name
    assert (json.loads((tmp_path / "api" / "set.json").read_text())
            == json.loads((tmp_path / "cli" / "set.json").read_text()))
    with pytest.raises(ValueError, match="written as PNG"):
        itx.save_tile_set(atlas, desc, tmp_path / "set.tif")
