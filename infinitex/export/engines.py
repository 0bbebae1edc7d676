"""A tile set as the game engines' own terrain resources, written beside its
atlas (``tileset.py``), so a level designer drags the folder into their
editor and paints with the terrain at once:

- **Tiled** (the map editor most 2D games use): a ``.tsx`` tileset per map's
  atlas with a corner Wang set (one ``<wangcolor>`` per corner colour, a
  ``<wangtile>`` per tile whose ``wangid`` lists the corner colours in Tiled's
  order: top, top-right, right, bottom-right, bottom, bottom-left, left,
  top-left; edges 0, colours from 1), and an example ``.tmx`` map: the
  preview's random valid arrangement, which Tiled's renderer
  (``tmxrasterizer``) draws pixel for pixel as we assemble it (tested).
- **Godot 4**: a ``TileSet`` resource (``.tres``, text format 3) with one
  ``TileSetAtlasSource`` over the atlas and a terrain set in *Match Corners*
  mode, each tile's four corner peering bits and its centre terrain. For a
  material whose normal map is written, the source's texture is a
  ``CanvasTexture`` (the colour map as diffuse, the normal map as normals, so
  2D lights shade it); the other maps have no place in a 2D tile set.

Variants (one colour) are a terrain of one colour whose tiles all match each
other: both engines' terrain brushes then draw among them at random, weighted
by each tile's probability (Tiled's ``probability``, Godot's
``probability``), which are written, equal.

Only PNG atlases are referenced: neither engine imports 32-bit float TIFF."""
from __future__ import annotations

import json
import os
import xml.etree.ElementTree as ET
from dataclasses import dataclass, field

import numpy as np

from infinitex.engine.safeio import atomic_write

from .wang import TileSetPlan

ENGINES = ("tiled", "godot")
# Display colours of the corner colours in the engines' terrain panels.
_SWATCHES = ((0xE0, 0x4A, 0x3A), (0x3A, 0x8F, 0xE0), (0x5C, 0xC0, 0x4F))
_COLOR_NAMES = ("A", "B", "C")


def parse_engines(text: str) -> tuple[str, ...]:
    """``tiled``, ``godot``, ``all`` or ``none`` (or a comma list) as a tuple of engines."""
    if text == "all":
        return ENGINES
    if text == "none":
        return ()
    names = [t.strip() for t in text.split(",") if t.strip()]
    bad = [n for n in names if n not in ENGINES]
    if bad or not names:
        raise ValueError(f"A tile set is written for tiled, godot, all or none, not {text!r}.")
    return tuple(e for e in ENGINES if e in names)


@dataclass
class EngineFiles:
    """Where a set's engine resources go: a ``.tsx`` beside each PNG map's
    atlas (``tilesets``: role -> path), the example map ``tmx`` and the Godot
    resource ``tres`` beside the output (None when not written)."""

    tilesets: dict[str, str] = field(default_factory=dict)
    tmx: str | None = None
    tres: str | None = None
    skipped: list[str] = field(default_factory=list)  # maps no engine reads (not PNG)

    @property
    def files(self) -> list[str]:
        return list(self.tilesets.values()) + [p for p in (self.tmx, self.tres) if p]

    def describe(self, rel) -> dict:
        """The set's JSON "engines" entry, paths made relative by ``rel``."""
        out: dict = {}
        if self.tilesets:
            out["tiled"] = {"tilesets": {role: rel(p) for role, p in self.tilesets.items()}, "map": rel(self.tmx)}
        if self.tres:
            out["godot"] = {"tileset": rel(self.tres)}
        return out


def engine_files(out_path: str, outputs: list[tuple[str, str, int]], primary: str,
                 engines: tuple[str, ...]) -> EngineFiles:
    """The engine files of a set written to ``out_path`` whose maps' atlases
    are ``outputs`` [(role, path, depth)]; none when the primary map is not a PNG."""
    png = {role: path for role, path, _ in outputs if path.lower().endswith(".png")}
    if not engines or primary not in png:
        return EngineFiles(skipped=[role for role, _, _ in outputs])
    files = EngineFiles(skipped=[role for role, _, _ in outputs if role not in png])
    base = os.path.splitext(out_path)[0]
    if "tiled" in engines:
        files.tilesets = {role: os.path.splitext(path)[0] + ".tsx" for role, path in png.items()}
        files.tmx = base + ".tmx"
    if "godot" in engines:
        files.tres = base + ".tres"
    return files


def _uniform_tiles(plan: TileSetPlan) -> list[int]:
    """Per corner colour, the index of the tile whose four corners have it."""
    tiles = plan.tiles()
    return [next(i for i, t in enumerate(tiles) if (t["nw"], t["ne"], t["sw"], t["se"]) == (c,) * 4)
            for c in range(max(1, plan.colors))]


def _xml(root: ET.Element) -> bytes:
    ET.indent(root, " ")
    return b'<?xml version="1.0" encoding="UTF-8"?>\n' + ET.tostring(root, encoding="utf-8") + b"\n"


def tiled_tileset(plan: TileSetPlan, name: str, image: str, size: tuple[int, int]) -> bytes:
    """A Tiled ``.tsx`` over the atlas ``image`` (its path relative to the
    .tsx) of ``size`` (w, h) px, with the set's corner Wang set."""
    n = plan.tile
    cols, rows = plan.grid
    tiles = plan.tiles()
    root = ET.Element("tileset", version="1.5", tiledversion="1.8.2", name=name, tilewidth=str(n),
                      tileheight=str(n), tilecount=str(plan.count), columns=str(cols))
    ET.SubElement(root, "image", source=image, width=str(size[0]), height=str(size[1]))
    # a tile's id is its place in plan.tiles(): the atlas row by row, as Tiled counts
    for i, t in enumerate(tiles):
        if "variant" in t:  # the random-tile weight of Tiled's brushes
            ET.SubElement(root, "tile", id=str(i), probability="1")
    uniform = _uniform_tiles(plan)
    sets = ET.SubElement(root, "wangsets")
    ws = ET.SubElement(sets, "wangset", name=name, type="corner", tile=str(uniform[0]))
    for c, u in enumerate(uniform):
        ET.SubElement(ws, "wangcolor", name=_COLOR_NAMES[c], color="#%02x%02x%02x" % _SWATCHES[c],
                      tile=str(u), probability="1")
    for i, t in enumerate(tiles):
        ne, se, sw, nw = (t[k] + 1 for k in ("ne", "se", "sw", "nw"))
        ET.SubElement(ws, "wangtile", tileid=str(i), wangid=f"0,{ne},0,{se},0,{sw},0,{nw}")
    return _xml(root)


def tiled_map(plan: TileSetPlan, tileset: str, layout: np.ndarray, name: str) -> bytes:
    """A Tiled ``.tmx`` map of ``layout`` (rows, cols) tile indices of the
    set's ``tileset`` (.tsx, relative path)."""
    n = plan.tile
    rows, cols = layout.shape
    root = ET.Element("map", version="1.5", tiledversion="1.8.2", orientation="orthogonal", renderorder="right-down",
                      width=str(cols), height=str(rows), tilewidth=str(n), tileheight=str(n), infinite="0",
                      nextlayerid="2", nextobjectid="1")
    ET.SubElement(root, "tileset", firstgid="1", source=tileset)
    layer = ET.SubElement(root, "layer", id="1", name=name, width=str(cols), height=str(rows))
    data = ET.SubElement(layer, "data", encoding="csv")
    data.text = "\n" + ",\n".join(",".join(str(1 + int(k)) for k in row) for row in layout) + "\n"  # gid: id + 1
    return _xml(root)


def _gd_string(text: str) -> str:
    """A Godot string literal (C escapes; Godot reads \\uXXXX)."""
    return json.dumps(text)


def godot_tileset(plan: TileSetPlan, name: str, textures: dict[str, str]) -> bytes:
    """A Godot 4 ``TileSet`` (.tres, format 3) over the atlas: ``textures``
    maps ``diffuse`` (and optionally ``normal``) to paths relative to the .tres."""
    n = plan.tile
    lines: list[str] = []
    ext = [("diffuse", textures["diffuse"])] + ([("normal", textures["normal"])] if "normal" in textures else [])
    canvas = len(ext) > 1
    lines.append(f'[gd_resource type="TileSet" load_steps={len(ext) + 2 + canvas} format=3]')
    lines.append("")
    for i, (role, path) in enumerate(ext):
        lines.append(f'[ext_resource type="Texture2D" path={_gd_string(path)} id="{i + 1}_{role}"]')
    lines.append("")
    texture = 'ExtResource("1_diffuse")'
    if canvas:
        lines += ['[sub_resource type="CanvasTexture" id="CanvasTexture_1"]',
                  'diffuse_texture = ExtResource("1_diffuse")', 'normal_texture = ExtResource("2_normal")', ""]
        texture = 'SubResource("CanvasTexture_1")'
    lines += ['[sub_resource type="TileSetAtlasSource" id="TileSetAtlasSource_1"]',
              f"resource_name = {_gd_string(name)}", f"texture = {texture}",
              f"texture_region_size = Vector2i({n}, {n})"]
    for t in plan.tiles():
        key = f"{t['x'] // n}:{t['y'] // n}/0"
        corners = [t[k] for k in ("nw", "ne", "sw", "se")]
        centre = max(range(plan.colors if plan.colors > 1 else 1), key=lambda c: (corners.count(c), -c))
        lines += [f"{key} = 0", f"{key}/terrain_set = 0", f"{key}/terrain = {centre}",
                  f"{key}/terrains_peering_bit/top_left_corner = {t['nw']}",
                  f"{key}/terrains_peering_bit/top_right_corner = {t['ne']}",
                  f"{key}/terrains_peering_bit/bottom_left_corner = {t['sw']}",
                  f"{key}/terrains_peering_bit/bottom_right_corner = {t['se']}",
                  f"{key}/probability = 1.0"]
    lines += ["", "[resource]", f"resource_name = {_gd_string(name)}", f"tile_size = Vector2i({n}, {n})",
              "terrain_set_0/mode = 1"]  # TileSet.TERRAIN_MODE_MATCH_CORNERS
    for c in range(max(1, plan.colors)):
        r, g, b = (v / 255 for v in _SWATCHES[c])
        lines += [f"terrain_set_0/terrain_{c}/name = {_gd_string(f'{name} {_COLOR_NAMES[c]}')}",
                  f"terrain_set_0/terrain_{c}/color = Color({r:.4g}, {g:.4g}, {b:.4g}, 1)"]
    lines += ['sources/0 = SubResource("TileSetAtlasSource_1")', ""]
    return "\n".join(lines).encode()


def write_engine_files(plan: TileSetPlan, files: EngineFiles, atlases: dict[str, tuple[str, tuple[int, int]]],
                       primary: str, layout: np.ndarray, write=atomic_write) -> None:
    """Write ``files`` (with ``write(path, data)``: the set's staged writes):
    ``atlases`` maps each role to its atlas path and size; ``layout`` is the
    example map's arrangement (the preview's)."""
    name = os.path.splitext(os.path.basename(atlases[primary][0]))[0]
    for role, tsx in files.tilesets.items():
        path, size = atlases[role]
        rel = os.path.relpath(path, os.path.dirname(tsx) or os.curdir)
        write(tsx, tiled_tileset(plan, os.path.splitext(os.path.basename(path))[0], rel, size))
    if files.tmx:
        rel = os.path.relpath(files.tilesets[primary], os.path.dirname(files.tmx) or os.curdir)
        write(files.tmx, tiled_map(plan, rel, layout, name))
    if files.tres:
        here = os.path.dirname(files.tres) or os.curdir
        textures = {"diffuse": os.path.relpath(atlases[primary][0], here)}
        if "normal" in atlases and primary != "normal":
            textures["normal"] = os.path.relpath(atlases["normal"][0], here)
        write(files.tres, godot_tileset(plan, name, textures))
