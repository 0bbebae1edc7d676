"""Issue 29, the inputs' side: 16-bit RGB TIFFs at full precision (item 6);
what a decoder will allocate checked from the header, a tile cap on canvas
maps, a whole-material budget (item 14); material maps that are links outside
their folder, FIFOs or folders (item 16); the editor's imgui.ini checked
before hello_imgui opens it (item 11). Every case is made here, in tmp_path."""
import io
import os
import struct
import subprocess
import sys
import textwrap
import time

import numpy as np
import pytest
import tifffile
from PIL import Image

from infinitex.engine.controls import NEUTRAL, CanvasField
from infinitex.engine.controls.fields import MAX_FIELD_TILES, TILE, FieldTooLarge
from infinitex.engine.controls.maps import load_field_map
from infinitex.engine.exemplar import ExemplarError, load_exemplar, load_exemplar_bytes
from infinitex.engine.material import (
    MATERIAL_BUDGET,
    MaterialError,
    assign_roles,
    folder_maps,
    load_material,
    open_material,
)

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))


def _tiff(a: np.ndarray, **kw) -> bytes:
    buf = io.BytesIO()
    tifffile.imwrite(buf, a, **kw)
    return buf.getvalue()


def _png(img: Image.Image) -> bytes:
    buf = io.BytesIO()
    img.save(buf, "PNG")
    return buf.getvalue()


def _distinct16(shape, seed=0) -> np.ndarray:
    """uint16 values, all different (a normal map's worth of precision)."""
    n = int(np.prod(shape))
    return (np.random.default_rng(seed).permutation(n) * (65535 // n)).astype(np.uint16).reshape(shape)


def _run(code: str, *args, env=None, timeout=300):
    """Python ``code`` in a fresh process: (completed process, its own peak RSS in MB)."""
    script = textwrap.dedent(code) + textwrap.dedent("""
        # VmHWM: this program's own peak (ru_maxrss keeps the forking pytest's across exec)
        print("maxrss", [int(x.split()[1]) for x in open("/proc/self/status") if x.startswith("VmHWM")][0] // 1024)
    """)
    r = subprocess.run([sys.executable, "-c", script, *args], capture_output=True, text=True, timeout=timeout,
                       cwd=ROOT, env=env)
    rss = [int(line.split()[1]) for line in r.stdout.splitlines() if line.startswith("maxrss")]
    return r, (rss[0] if rss else None)


def _cli(*args, timeout=600):
    r = subprocess.run([sys.executable, os.path.join(ROOT, "main.py"), *args, "-q"], capture_output=True,
                       text=True, timeout=timeout, cwd=ROOT)
    return r


# -- item 6: 16-bit RGB TIFFs keep their precision --------------------------------


@pytest.mark.parametrize("channels, kw", [(3, dict(photometric="rgb")), (4, dict(photometric="rgb")),
                                          (3, dict(photometric="rgb", compression="zlib")),
                                          (3, dict(photometric="rgb", planarconfig="separate"))])
def test_16bit_rgb_tiff_keeps_every_value(channels, kw):
    a = _distinct16((64, 64, channels))
    if kw.get("planarconfig") == "separate":
        data = _tiff(np.ascontiguousarray(a.transpose(2, 0, 1)), **kw)
    else:
        data = _tiff(a, **kw)
    ex = load_exemplar_bytes(data, name="normal.tif")
    assert ex.depth == 16
    assert ex.pixels.shape == (64, 64, channels)
    assert len(np.unique(ex.pixels)) == a.size  # 12,288 values for RGB; Pillow's 8 bits kept 256 at most
    assert np.array_equal(ex.pixels, (a / 65535.0).astype(np.float32))


def test_16bit_normal_map_of_a_material_keeps_its_precision(tmp_path):
    rng = np.random.default_rng(3)
    Image.fromarray((rng.random((64, 64, 3)) * 255).astype(np.uint8)).save(tmp_path / "wood_basecolor.png")
    n = _distinct16((64, 64, 3), seed=4)
    (tmp_path / "wood_normal.tif").write_bytes(_tiff(n, photometric="rgb"))
    mat = open_material(str(tmp_path / "wood_basecolor.png"))
    assert mat.maps["normal"].depth == 16
    assert len(np.unique(mat.maps["normal"].pixels)) > 10000


def test_8bit_and_one_channel_16bit_tiffs_are_read_as_before():
    a8 = (np.arange(64 * 64 * 3) % 251).astype(np.uint8).reshape(64, 64, 3)
    ex = load_exemplar_bytes(_tiff(a8, photometric="rgb"), name="rgb8.tif")
    assert ex.depth == 8 and np.array_equal(np.rint(ex.pixels * 255).astype(np.uint8), a8)
    g = _distinct16((64, 64))
    ex = load_exemplar_bytes(_tiff(g), name="gray16.tif")
    assert ex.depth == 16 and len(np.unique(ex.pixels)) == g.size


# -- item 14: what a decoder allocates, checked from the header -----------------


def _huge_tile_tiff(path, tile_length=32, dtype=np.uint8, samples=1, width_claim=16_777_216) -> bytes:
    """A small zlib-compressed tiled TIFF whose TileWidth is patched to claim 16,777,216 px."""
    shape = (32, 32, samples) if samples > 1 else (32, 32)
    kw = dict(photometric="rgb") if samples == 3 else {}
    data = bytearray(_tiff(np.zeros(shape, dtype), tile=(tile_length, 16), compression="zlib", **kw))
    off = struct.unpack("<I", data[4:8])[0]
    for i in range(struct.unpack("<H", data[off:off + 2])[0]):
        e = off + 2 + 12 * i
        if struct.unpack("<H", data[e:e + 2])[0] == 322:  # TileWidth, as a LONG
            data[e + 2:e + 4] = struct.pack("<H", 4)
            data[e + 8:e + 12] = struct.pack("<I", width_claim)
    path.write_bytes(bytes(data))
    return bytes(data)


def test_tiff_claiming_huge_tiles_is_refused_before_libtiff_allocates(tmp_path):
    data = _huge_tile_tiff(tmp_path / "tile.tif")
    assert len(data) < 1024
    # Before: libtiff allocated (and touched) a 512 MB tile, then failed ("decoder error -2").
    r, rss = _run("""
        import sys
        from infinitex.engine.exemplar import ExemplarError, load_exemplar
        try:
            load_exemplar(sys.argv[1])
        except ExemplarError as exc:
            print("refused:", exc)
    """, str(tmp_path / "tile.tif"))
    assert r.returncode == 0, r.stderr
    assert "refused: tile.tif claims tiles of 16777216x32 px" in r.stdout and "MB an import may use" in r.stdout
    assert rss is not None and rss < 300, rss


@pytest.mark.parametrize("reader", ["exemplar", "field map", "cli"])
def test_huge_tile_claims_are_refused_on_every_path(tmp_path, reader):
    path = tmp_path / "tile.tif"
    if reader == "exemplar":  # a float RGB TIFF, which Pillow cannot open: the tifffile path checks the same
        _huge_tile_tiff(path, dtype=np.float32, samples=3)
        with pytest.raises(ExemplarError, match="claims tiles of 16777216x32 px"):
            load_exemplar(path)
    elif reader == "field map":
        _huge_tile_tiff(path)
        with pytest.raises(ExemplarError, match="claims tiles of 16777216x32 px"):
            load_field_map(str(path), "avoid mask")
    else:
        _huge_tile_tiff(path)
        r = _cli("synth", os.path.join(ROOT, "infinitex", "assets", "gravel.png"), "-o", str(tmp_path / "o.png"),
                 "--size", "32", "32", "--randomness-canvas", str(path))
        assert r.returncode == 3 and r.stderr.count("\n") == 1 and "claims tiles of 16777216x32" in r.stderr


def test_a_tiff_cut_into_too_many_tiles_is_refused_from_its_header(tmp_path):
    """An LZW TIFF of 16 x 16 tiles (262,144 of them at 64 Mpixels) ran past
    60 s under load before any refusal; the tile count is read from the
    header and bounded (MAX_BLOCKS) before anything is decoded."""
    import time

    import tifffile

    from infinitex.engine.tiffinfo import MAX_BLOCKS
    side = 16 * 257  # 66,049 tiles
    assert (side // 16) ** 2 > MAX_BLOCKS
    tifffile.imwrite(tmp_path / "tiles.tif", np.zeros((side, side), np.uint8), tile=(16, 16), compression="lzw")
    t = time.monotonic()
    with pytest.raises(ExemplarError, match="cut into 66,049 tiles of 16x16 px; at most 65,536"):
        load_exemplar(tmp_path / "tiles.tif")
    assert time.monotonic() - t < 3


def test_ordinary_strips_and_tiles_still_load():
    a = (np.arange(96 * 80 * 3) % 253).astype(np.uint8).reshape(96, 80, 3)
    for kw in (dict(rowsperstrip=2 ** 32 - 1), dict(tile=(64, 64), compression="zlib"), dict(compression="zlib")):
        ex = load_exemplar_bytes(_tiff(a, photometric="rgb", **kw), name="ok.tif", fit="crop")
        assert ex.size == 64 and ex.depth == 8


# -- item 14: a tile cap on canvas maps --------------------------------------------


def test_canvas_field_refuses_more_tiles_than_the_cap_before_making_any():
    import tracemalloc
    wide = np.full((1, TILE * MAX_FIELD_TILES + 1), 1000, np.uint16)  # 65,537 tiles
    tracemalloc.start()
    try:
        with pytest.raises(FieldTooLarge, match=f"at most {MAX_FIELD_TILES}"):
            CanvasField.from_image(wide, 0, 0)
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert peak < 2 ** 20  # nothing allocated per tile (65,537 tiles would be 512 MB)
    with pytest.raises(FieldTooLarge):  # the placement counts: 2 tiles wide by one pixel
        CanvasField.from_image(np.full((2, TILE * (MAX_FIELD_TILES // 2)), 0, np.uint16), 5, TILE - 1)
    ok = CanvasField.from_image(np.full((100, 300), 0, np.uint16), -70, 45)
    assert len(ok.tiles) == 3 * 6 and ok.region(0, -70, 45, 300, 100).max() == 0
    assert CanvasField.from_image(np.full((64, 64), NEUTRAL, np.uint16), 0, 0).neutral


def test_a_65kb_png_of_64_mpixels_as_canvas_randomness_is_one_line(tmp_path):
    # 67,108,864 x 1 px: a million 64 x 64 tiles (over 5 GB) before.
    path = tmp_path / "wide.png"
    Image.new("L", (67_108_864, 1), 20).save(path)
    assert path.stat().st_size < 200_000
    r, rss = _run("""
        import subprocess, sys, resource
        r = subprocess.run([sys.executable, "main.py", "synth", "infinitex/assets/gravel.png", "-o", sys.argv[2],
                            "--size", "32", "32", "--randomness-canvas", sys.argv[1], "-q"],
                           capture_output=True, text=True, timeout=500)
        print("rc", r.returncode)
        print("err", r.stderr.strip())
        print("child", resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss // 1024)
    """, str(path), str(tmp_path / "o.png"), timeout=600)
    out = dict(line.split(" ", 1) for line in r.stdout.splitlines())
    assert out["rc"] == "3", r.stdout + r.stderr
    assert out["err"].startswith("error: The canvas randomness map (67108864x1 px) would cover")
    assert f"at most {MAX_FIELD_TILES}" in out["err"] and "\n" not in out["err"]
    assert int(out["child"]) < 1500  # the decoded map is bounded by the import budget; no tiles were made
    assert not (tmp_path / "o.png").exists()


# -- item 14: a whole-material import budget --------------------------------------


def _sparse_material(folder, n=7, size=500 * 2 ** 20):
    folder.mkdir()
    small = _png(Image.new("RGB", (64, 64), (90, 80, 70)))
    roles = ["basecolor", "normal", "height", "roughness", "ao", "metallic", "opacity"][:n]
    for role in roles:
        p = folder / f"stone_{role}.png"
        with open(p, "wb") as f:
            f.write(small)
            f.truncate(size)  # sparse: 500 MB on paper, nothing on disk
    return folder


def test_seven_500mb_maps_are_refused_before_any_is_read(tmp_path, monkeypatch):
    folder = _sparse_material(tmp_path / "stone")
    import infinitex.engine.material as material

    def no_read(*a, **k):
        raise AssertionError("a map was read")
    monkeypatch.setattr(material, "read_limited", no_read)
    for how in ([str(folder)], [str(folder / "stone_basecolor.png")],
                [str(p) for p in sorted(folder.iterdir())]):
        with pytest.raises(MaterialError, match=f"7 maps of this material would need about 3500 MB.*"
                                                f"{MATERIAL_BUDGET // 2 ** 20} MB a material may use"):
            assign_roles(how)
    with pytest.raises(MaterialError, match="3500 MB"):
        open_material(str(folder))


def test_seven_500mb_maps_on_the_command_line_are_one_line_in_bounded_memory(tmp_path):
    folder = _sparse_material(tmp_path / "stone")
    r, _ = _run("""
        import subprocess, sys, resource
        r = subprocess.run([sys.executable, "main.py", "export", sys.argv[1], "-o", sys.argv[2], "--size", "64", "64",
                            "-q"], capture_output=True, text=True, timeout=500)
        print("rc", r.returncode)
        print("err", r.stderr.strip())
        print("child", resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss // 1024)
    """, str(folder), str(tmp_path / "out.png"), timeout=600)
    out = dict(line.split(" ", 1) for line in r.stdout.splitlines())
    assert out["rc"] == "3" and "a material may use" in out["err"] and "\n" not in out["err"], r.stdout + r.stderr
    assert int(out["child"]) < 400  # peaked at about 4 GB before


def test_material_budget_is_checked_from_the_headers_before_decoding_any(tmp_path, monkeypatch):
    import infinitex.engine.material as material
    rng = np.random.default_rng(5)
    files = [(role, f"m_{role}.png", _png(Image.fromarray((rng.random((1024, 1024, 3)) * 255).astype(np.uint8))))
             for role in ("basecolor", "normal", "height", "roughness")]
    decoded = []
    real = material.load_exemplar_bytes
    monkeypatch.setattr(material, "load_exemplar_bytes", lambda *a, **k: decoded.append(1) or real(*a, **k))
    mat = load_material(files)  # within the real budget
    assert mat.roles == ["basecolor", "normal", "height", "roughness"] and len(decoded) == 4
    one = material.map_costs(files[0][2], "m.png", "resize")
    need = sum(len(d) for _, _, d in files) + one[0] + 4 * one[1]
    monkeypatch.setattr(material, "MATERIAL_BUDGET", need - 1)
    decoded.clear()
    with pytest.raises(MaterialError, match="4 maps of this material would need about"):
        load_material(files)
    assert decoded == []  # refused before any map was decoded
    monkeypatch.setattr(material, "MATERIAL_BUDGET", need)
    assert load_material(files).roles == mat.roles


# -- item 16: maps that are links outside their folder, FIFOs, folders ------------


def _material(folder, roles=("basecolor", "normal")):
    folder.mkdir(parents=True, exist_ok=True)
    rng = np.random.default_rng(7)
    for role in roles:
        Image.fromarray((rng.random((32, 32, 3)) * 255).astype(np.uint8)).save(folder / f"wood_{role}.png")
    return folder


def test_a_sibling_that_links_outside_the_folder_is_refused(tmp_path):
    folder = _material(tmp_path / "mat")
    secret = tmp_path / "elsewhere" / "private.png"
    secret.parent.mkdir()
    Image.new("RGB", (32, 32), 9).save(secret)
    os.symlink(secret, folder / "wood_height.png")
    for how in ([str(folder / "wood_basecolor.png")], [str(folder)]):
        with pytest.raises(MaterialError, match=r"wood_height\.png is a link to .*private\.png, outside the "
                                                r"material's folder"):
            assign_roles(how)
    # Chosen by name, the same link is the user's choice; a link inside the folder is fine.
    found = assign_roles([str(folder / "wood_height.png")])
    assert found["height"] == str(folder / "wood_height.png") and set(found) == {"basecolor", "normal", "height"}
    os.unlink(folder / "wood_height.png")
    (folder / "sub").mkdir()
    Image.new("RGB", (32, 32), 9).save(folder / "sub" / "h.png")
    os.symlink(folder / "sub" / "h.png", folder / "wood_height.png")
    assert set(assign_roles([str(folder)])) == {"basecolor", "normal", "height"}


@pytest.mark.parametrize("kind", ["fifo", "folder", "broken link"])
def test_a_fifo_folder_or_broken_link_in_place_of_a_map_is_an_error(tmp_path, kind):
    folder = _material(tmp_path / "mat")
    bad = folder / "wood_roughness.png"
    if kind == "fifo":
        os.mkfifo(bad)
    elif kind == "folder":
        bad.mkdir()
    else:
        os.symlink(tmp_path / "gone.png", bad)
    words = {"fifo": "is not a regular file", "folder": "is a folder", "broken link": "cannot be read"}[kind]
    t0 = time.monotonic()
    for how in ([str(folder / "wood_basecolor.png")], [str(folder)]):
        with pytest.raises(MaterialError, match=rf"wood_roughness\.png {words}"):
            assign_roles(how)
    with pytest.raises(MaterialError, match=words):
        folder_maps(str(folder))
    assert time.monotonic() - t0 < 10  # a FIFO is never opened


def test_a_map_linking_outside_on_the_command_line_is_one_line(tmp_path):
    folder = _material(tmp_path / "mat")
    os.symlink(os.path.join(ROOT, "infinitex", "assets", "gravel.png"), folder / "wood_height.png")
    r = _cli("export", str(folder / "wood_basecolor.png"), "-o", str(tmp_path / "o.png"), "--size", "32", "32")
    assert r.returncode == 3 and r.stderr.count("\n") == 1 and "outside the material's folder" in r.stderr


# -- item 11: the editor's imgui.ini is checked before hello_imgui opens it -------


@pytest.mark.parametrize("kind", ["fifo", "folder", "link to a fifo", "broken link", "too large"])
def test_config_file_that_would_block_or_mislead_is_set_aside(tmp_path, kind):
    from infinitex.app.settings import INI_MAX_BYTES, check_config_file
    ini = tmp_path / "imgui.ini"
    if kind == "fifo":
        os.mkfifo(ini)
    elif kind == "folder":
        ini.mkdir()
    elif kind == "link to a fifo":
        os.mkfifo(tmp_path / "pipe")
        os.symlink(tmp_path / "pipe", ini)
    elif kind == "broken link":
        os.symlink(tmp_path / "gone", ini)
    else:
        with open(ini, "wb") as f:
            f.truncate(INI_MAX_BYTES + 1)
    usable, note = check_config_file(str(ini))
    assert usable and note and "imgui.ini" in note and "moved to imgui.ini.set-aside-" in note
    assert not os.path.lexists(ini)
    aside = [p for p in tmp_path.iterdir() if p.name.startswith("imgui.ini.set-aside-")]
    assert len(aside) == 1  # kept, not deleted


def test_ordinary_config_file_is_left_as_it_is(tmp_path):
    from infinitex.app.settings import check_config_file
    ini = tmp_path / "imgui.ini"
    assert check_config_file(str(ini)) == (True, None)  # none yet
    ini.write_text("[Window][Lattice]\nPos=10,10\n")
    assert check_config_file(str(ini)) == (True, None) and ini.read_text().startswith("[Window]")
    os.symlink(ini, tmp_path / "linked.ini")  # a dotfile manager's link to a regular file
    assert check_config_file(str(tmp_path / "linked.ini")) == (True, None)


def test_editor_start_up_does_not_block_on_a_fifo_imgui_ini(tmp_path):
    cfg = tmp_path / "config"
    cfg.mkdir()
    os.mkfifo(cfg / "imgui.ini")
    env = dict(os.environ, INFINITEX_CONFIG=str(cfg), INFINITEX_STATE=str(tmp_path / "state"))
    r, _ = _run("""
        from infinitex.app.ui.editor import Editor
        ed = Editor()
        p = ed.runner_params()
        print("ini", p.ini_disable, p.ini_filename)
        print("notice", ed.notice[0] if ed.notice else None)
    """, env=env, timeout=120)
    assert r.returncode == 0, r.stderr
    assert f"ini False {cfg / 'imgui.ini'}" in r.stdout  # the layout is kept, in a fresh regular file
    assert "was not a regular file (a FIFO, device or socket); it was moved to imgui.ini.set-aside-" in r.stdout
    assert not os.path.lexists(cfg / "imgui.ini")


@pytest.mark.gui
def test_the_real_editor_starts_and_quits_with_a_fifo_imgui_ini(tmp_path, xdisplay):
    cfg = tmp_path / "config"
    cfg.mkdir()
    os.mkfifo(cfg / "imgui.ini")
    script = textwrap.dedent("""
        from imgui_bundle import hello_imgui
        from infinitex.app.ui.editor import Editor
        ed = Editor()
        params = ed.runner_params()
        gui = params.callbacks.show_gui
        frames = [0]
        def show():
            gui()
            frames[0] += 1
            if frames[0] >= 5:
                hello_imgui.get_runner_params().app_shall_exit = True
        params.callbacks.show_gui = show
        params.callbacks.confirm_exit = lambda: True
        from imgui_bundle import immapp
        immapp.run(params, immapp.AddOnsParams())
        print("frames", frames[0])
    """)
    env = dict(os.environ, INFINITEX_CONFIG=str(cfg), INFINITEX_STATE=str(tmp_path / "state"),
               INFINITEX_NO_NATIVE_DIALOGS="1", DISPLAY=xdisplay)
    r = subprocess.run([sys.executable, "-c", script], cwd=ROOT,
                       env=env, capture_output=True, text=True, timeout=300)  # blocked forever before
    assert "frames 5" in r.stdout, r.stdout[-2000:] + r.stderr[-2000:]
    assert (cfg / "imgui.ini").is_file() and not (cfg / "imgui.ini").is_symlink()  # written on exit, regular
    assert any(p.name.startswith("imgui.ini.set-aside-") for p in cfg.iterdir())


def _png_in_chunks(pixels: np.ndarray, size: int) -> bytes:
    import struct
    import zlib
    h, w, _ = pixels.shape
    z = zlib.compress(b"".join(b"\x00" + pixels[y].tobytes() for y in range(h)))

    def chunk(kind, d):
        return struct.pack(">I", len(d)) + kind + d + struct.pack(">I", zlib.crc32(kind + d) & 0xFFFFFFFF)
    body = b"".join(chunk(b"IDAT", z[i:i + size]) for i in range(0, len(z), size))
    return (b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", struct.pack(">IIBBBBB", w, h, 8, 2, 0, 0, 0)) + body
            + chunk(b"IEND", b""))


def test_a_png_cut_into_tiny_chunks_is_refused_from_its_headers():
    """1-byte IDAT chunks decode at about 10^5 a second (a 4096^2 image: minutes):
    refused in one line from the chunk headers, before any decoding; the same
    pixels in ordinary chunks read as usual."""
    from infinitex.engine.exemplar import ExemplarError, load_exemplar_bytes
    px = np.random.default_rng(6).integers(0, 256, (64, 64, 3), dtype=np.uint8)
    with pytest.raises(ExemplarError, match="too fragmented") as err:
        load_exemplar_bytes(_png_in_chunks(px, 1), name="frag.png")
    assert "\n" not in str(err.value) and "frag.png" in str(err.value)
    ex = load_exemplar_bytes(_png_in_chunks(px, 1024), name="ok.png", fit="crop")
    assert ex.size == 64


@pytest.mark.parametrize("planar", ["contig", "separate"])
def test_a_tiff_of_too_many_channels_is_refused_in_one_line(tmp_path, planar):
    """Pillow logs its own refusal (samples per pixel beyond its limit) before
    raising: without logging set up, Python printed it above ours (a process
    of its own: pytest's log capture would hide it)."""
    shape = (64, 64, 17) if planar == "contig" else (17, 64, 64)
    tifffile.imwrite(tmp_path / "many.tif", np.zeros(shape, np.uint8), planarconfig=planar)
    r = subprocess.run([sys.executable, "-m", "infinitex", "synth", str(tmp_path / "many.tif"), "-o",
                        str(tmp_path / "out.png"), "--size", "32", "32"], capture_output=True, text=True, timeout=120)
    assert r.returncode == 3 and len(r.stderr.strip().splitlines()) == 1, r.stderr
    assert "many.tif" in r.stderr and "not supported" in r.stderr
