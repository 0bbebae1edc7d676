"""Issue 29, "writes, deletes and reads outside the output": a streamed
export's working folder (OUT.parts, OUT.zarr.parts) and the files in it are
untrusted. Each test plants what the issue describes (links to files and
folders outside, FIFOs, garbage listed with its true size and hash) and checks
that nothing outside changed, the output is the right one (or the export was
refused in one line before any work) and it ended in bounded time."""
import hashlib
import json
import os
import stat
import subprocess
import sys
import zlib

import numpy as np
import fuzzing
import pytest
import tifffile

from infinitex.engine.analysis import analyze
from infinitex.engine.exemplar import load_exemplar
from infinitex.engine.imagefile import to_u8
from infinitex.engine.pyramid import Rect
from infinitex.engine.safeio import WriteError
from infinitex.engine.synth import Synthesizer
from infinitex.export import ExportInterrupted, TiledExport, read_tiles, udim_name
from infinitex.export.formats import png_bytes, tiff_tile_bytes
from infinitex.export.streamed import MANIFEST_NAMES, parse_manifest

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
GRAVEL = os.path.join(ROOT, "infinitex", "assets", "gravel.png")
RECT = Rect.of(0, 0, 512, 512)
TILE = 256


@pytest.fixture(scope="module")
def synth(gpu):
    return Synthesizer(analyze(load_exemplar(GRAVEL)), gpu=gpu)


@pytest.fixture(scope="module")
def whole(synth):
    return to_u8(synth.colors(synth.window(RECT)))


def snapshot(folder) -> dict:
    """Every entry under ``folder``: kind, and the bytes' hash of regular files (links not followed)."""
    out = {}
    for dirpath, dirnames, filenames in os.walk(folder):
        for n in dirnames + filenames:
            p = os.path.join(dirpath, n)
            st = os.lstat(p)
            if stat.S_ISREG(st.st_mode):
                with open(p, "rb") as f:
                    out[p] = ("file", hashlib.sha256(f.read()).hexdigest(), st.st_mtime_ns)
            elif stat.S_ISLNK(st.st_mode):
                out[p] = ("link", os.readlink(p))
            else:
                out[p] = (stat.S_IFMT(st.st_mode),)
    return out


def outside(tmp_path):
    """A folder outside the export's, with a file and a Zarr-like folder the user cares about."""
    d = tmp_path / "outside"
    (d / "data.zarr" / "0").mkdir(parents=True)
    (d / "precious.bin").write_bytes(b"the user's own bytes\n" * 1000)
    (d / "data.zarr" / ".zgroup").write_text('{"zarr_format": 2}')
    (d / "data.zarr" / "0" / "0.0").write_bytes(b"\x02" * 100)
    (d / "manifest.jsonl").write_text("not yours\n")
    return d


def job(synth, out, fmt="tiff", **kw) -> TiledExport:
    return TiledExport(synth, RECT, str(out), fmt, TILE, key="k", **kw)


def interrupted(synth, out, fmt="tiff", after: int = 4) -> TiledExport:
    """An export stopped once ``after`` tiles are done (as by Ctrl+C), its parts kept."""
    j = job(synth, out, fmt)

    def stop(done, total):
        if done == after:
            raise ExportInterrupted()
    with pytest.raises(ExportInterrupted):
        j.run(stop)
    return j


def parts_of(synth, out, fmt="tiff") -> tuple[TiledExport, str]:
    """A fresh parts folder (as a first run makes it) and the manifest's key line."""
    j = job(synth, out, fmt)
    os.mkdir(j.parts, 0o700)
    return j, json.dumps({"key": j.export_key()}) + "\n"


def line(name: str, data: bytes, j: TiledExport | None = None) -> str:
    """A manifest line for ``data``: its size and plain SHA-256 (what anyone can
    compute), or with ``j`` the export's own keyed hash (an attacker who has
    the user's key: only the decoding checks stand in the way)."""
    h = j.sign(name, data) if j is not None else hashlib.sha256(data).hexdigest()
    return json.dumps([name, len(data), h]) + "\n"


def tiff_equals(path, whole) -> bool:
    return np.array_equal(tifffile.imread(path), whole[..., 0])


# -- item 7: OUT.parts/assembling.tif as a link elsewhere ---------------------------


def test_a_link_at_the_assembling_file_is_replaced_never_written_through(synth, whole, tmp_path):
    out = tmp_path / "o.tif"
    far = outside(tmp_path)
    before = snapshot(far)
    j, _ = parts_of(synth, out)
    os.symlink(far / "precious.bin", os.path.join(j.parts, "assembling.tif"))
    j.run()
    assert snapshot(far) == before  # the whole TIFF did not go into the link's target
    assert tiff_equals(out, whole) and not os.path.lexists(j.parts)


# -- item 8: the parts folder itself a link ------------------------------------------


@pytest.mark.parametrize("fmt,name", [("zarr", "o.zarr"), ("tiff", "o.tif"), ("tiles", "o.png")])
def test_a_parts_folder_that_is_a_link_is_refused_and_its_target_untouched(synth, tmp_path, fmt, name):
    far = outside(tmp_path)
    before = snapshot(far)
    out = tmp_path / "x" / name
    out.parent.mkdir()
    os.symlink(far, str(out) + ".parts")
    with pytest.raises(WriteError) as e:
        job(synth, out, fmt).run()
    msg = str(e.value)
    assert "symbolic link" in msg and "\n" not in msg and "finished tiles are kept" not in msg
    assert snapshot(far) == before  # its data.zarr not deleted, its manifest.jsonl not overwritten
    assert sorted(os.listdir(out.parent)) == [name + ".parts"]  # nothing rendered: refused before any work


def test_a_parts_folder_that_is_a_file_or_another_users_is_refused(synth, tmp_path):
    out = tmp_path / "f.tif"
    (tmp_path / "f.tif.parts").write_bytes(b"a file of the user's")
    with pytest.raises(WriteError, match="is not a folder"):
        job(synth, out).run()
    assert (tmp_path / "f.tif.parts").read_bytes() == b"a file of the user's"
    if os.geteuid() != 0:
        pytest.skip("another user's folder needs root to make")
    theirs = tmp_path / "t.tif.parts"
    theirs.mkdir()
    (theirs / "manifest.jsonl").write_text("theirs\n")
    os.chown(theirs, 65534, 65534)
    with pytest.raises(WriteError, match="belongs to another user"):
        job(synth, tmp_path / "t.tif").run()
    assert (theirs / "manifest.jsonl").read_text() == "theirs\n"


def test_a_new_parts_folder_is_private(synth, tmp_path):
    def stop(done, total):
        raise ExportInterrupted()
    old = os.umask(0o022)
    try:
        j = job(synth, tmp_path / "p.tif")
        with pytest.raises(ExportInterrupted):
            j.run(stop)
    finally:
        os.umask(old)
    assert stat.S_IMODE(os.lstat(j.parts).st_mode) == 0o700


def test_cli_refuses_a_linked_parts_folder_in_one_line(tmp_path):
    far = outside(tmp_path)
    before = snapshot(far)
    os.symlink(far, tmp_path / "c.tif.parts")
    r = subprocess.run([sys.executable, os.path.join(ROOT, "main.py"), "export", GRAVEL, "-o",
                        str(tmp_path / "c.tif"), "--format", "tiff", "--rect", "0", "0", "512", "512",
                        "--tile", "256", "-q"], capture_output=True, text=True, timeout=600)
    assert r.returncode == 3, r.stderr[-2000:]
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: ") and "c.tif.parts is a symbolic link" in lines[0]
    assert snapshot(far) == before and not os.path.lexists(tmp_path / "c.tif")


# -- item 9: an unfinished tile or the manifest as a link -----------------------------


def test_links_at_a_tile_and_at_the_manifest_are_not_written_through(synth, whole, tmp_path):
    far = outside(tmp_path)
    before = snapshot(far)
    out = tmp_path / "l.tif"
    j, _ = parts_of(synth, out)
    os.symlink(far / "precious.bin", os.path.join(j.parts, "1_0.zz"))        # an unfinished tile
    os.symlink(far / "manifest.jsonl", os.path.join(j.parts, "manifest.jsonl"))
    j.run()
    assert snapshot(far) == before
    assert tiff_equals(out, whole) and not os.path.lexists(j.parts)


def test_links_at_png_tiles_are_replaced_not_written_through(synth, whole, tmp_path):
    far = outside(tmp_path)
    before = snapshot(far)
    out = tmp_path / "t.png"
    os.symlink(far / "precious.bin", udim_name(str(tmp_path / "t"), 1, 1, 2))
    job(synth, out, "tiles").run()
    assert snapshot(far) == before
    assert not os.path.islink(udim_name(str(tmp_path / "t"), 1, 1, 2))
    assert np.array_equal(read_tiles(str(out), 512, 512, TILE, whole.shape[2]), whole)


# -- item 10: a manifest line claiming a linked outside file, or garbage ---------------


def test_a_listed_link_to_an_outside_file_is_not_kept(synth, whole, tmp_path):
    far = outside(tmp_path)
    precious = (far / "precious.bin").read_bytes()
    before = snapshot(far)
    out = tmp_path / "c.tif"
    j, head = parts_of(synth, out)
    os.symlink(far / "precious.bin", os.path.join(j.parts, "0_0.zz"))
    with open(os.path.join(j.parts, "manifest.jsonl"), "w") as f:
        f.write(head + line("0,0", precious, j) + line("1,0", precious))  # its true size and (keyed) hash
    os.symlink(far / "precious.bin", os.path.join(j.parts, "1_0.zz"))
    j.run()
    assert j.kept == 0 and j.rendered == 4
    assert snapshot(far) == before
    assert tiff_equals(out, whole)  # not the outside bytes inside the BigTIFF


def test_listed_garbage_and_foreign_tiles_are_rendered_again(synth, whole, tmp_path):
    out = tmp_path / "g.tif"
    j, head = parts_of(synth, out)
    garbage = os.urandom(5000)
    three = tiff_tile_bytes(np.full((TILE, TILE, 3), 7, np.uint8), TILE)  # a valid tile, but RGB
    short = zlib.compress(b"\x00" * (TILE * TILE - 1))                     # one byte short
    trailing = tiff_tile_bytes(whole[:TILE, :TILE], TILE) + b"junk"
    files = {"0_0.zz": three, "1_0.zz": garbage, "0_1.zz": short, "1_1.zz": trailing}
    for n, data in files.items():
        with open(os.path.join(j.parts, n), "wb") as f:
            f.write(data)
    names = {"0_0.zz": "0,0", "1_0.zz": "1,0", "0_1.zz": "0,1", "1_1.zz": "1,1"}
    with open(os.path.join(j.parts, "manifest.jsonl"), "w") as f:
        f.write(head + "".join(line(names[n], d, j) for n, d in files.items()))
    j.run()
    assert j.kept == 0 and j.rendered == 4
    assert tiff_equals(out, whole)


def test_listed_png_tiles_of_another_size_or_mode_are_rendered_again(synth, whole, tmp_path):
    out = tmp_path / "s.png"
    j, head = parts_of(synth, out, "tiles")
    base = str(tmp_path / "s")
    wrong = {(0, 0): png_bytes(np.zeros((TILE, TILE - 1, whole.shape[2]), np.uint8)),
             (1, 0): png_bytes(np.zeros((TILE, TILE, 4), np.uint8)),
             (0, 1): png_bytes(whole[TILE:, :TILE])[:-20]}  # truncated
    good = png_bytes(whole[TILE:, TILE:])
    for (col, row), data in [*wrong.items(), ((1, 1), good)]:
        with open(udim_name(base, col, row, 2), "wb") as f:
            f.write(data)
    with open(os.path.join(j.parts, "manifest.jsonl"), "w") as f:
        f.write(head + "".join(line(f"{c},{r}", d, j) for (c, r), d in [*wrong.items(), ((1, 1), good)]))
    j.run()
    assert j.kept == 1 and j.rendered == 3
    assert np.array_equal(read_tiles(str(out), 512, 512, TILE, whole.shape[2]), whole)


def test_the_manifest_is_bounded_strict_and_lists_plain_names_only():
    key = "k" * 64
    sha = "a" * 64
    head = json.dumps({"key": key}).encode() + b"\n"
    tiff = MANIFEST_NAMES["tiff"]
    ok = head + json.dumps(["0,1", 10, sha]).encode() + b"\n"
    assert parse_manifest(ok, key, tiff, 10, 100) == {"0,1": [10, sha]}
    assert parse_manifest(ok + b'["1,1", 1', key, tiff, 10, 100) == {"0,1": [10, sha]}  # a torn last line
    for bad in (["../0,1", 10, sha], ["0,1/..", 10, sha], ["/etc/passwd", 10, sha], ["0,1", True, sha],
                ["0,1", 10 ** 30, sha], ["0,1", -5, sha], ["0,1", 10, sha.upper()], ["0,1", 10, sha, 1],
                ["00,1", 10, sha], ["0,1_x", 10, sha], {"0,1": [10, sha]}):
        assert parse_manifest(ok + json.dumps(bad).encode() + b"\n", key, tiff, 10, 100) == {}, bad
    assert parse_manifest(ok + b'["0,1", NaN, "x"]\n', key, tiff, 10, 100) == {}
    assert parse_manifest(ok * 1, "other", tiff, 10, 100) == {}
    assert parse_manifest(head + json.dumps(["0,1", 10, sha]).encode() + b"\n" * 1, key, tiff, 1, 100) == {}
    assert parse_manifest(head + b"[" + b" " * 300 + b"]\n", key, tiff, 10, 100) == {}


def test_a_manifest_vouches_only_for_what_this_users_exports_wrote(synth, whole, tmp_path):
    """Valid tiles of the right size and channels, but not this export's pixels
    (another place's, swapped between names, listed with their plain SHA-256):
    the keyed hash of each file's name and bytes keeps none of them."""
    out = tmp_path / "v.tif"
    first = interrupted(synth, out)
    a, b = (os.path.join(first.parts, n) for n in ("0_0.zz", "1_1.zz"))
    da, db = open(a, "rb").read(), open(b, "rb").read()
    with open(a, "wb") as f:
        f.write(db)
    with open(b, "wb") as f:
        f.write(da)  # swapped: the manifest's lines for them no longer hold
    other = tiff_tile_bytes(whole[TILE:, TILE:] // 2 + 1, TILE)
    with open(os.path.join(first.parts, "1_0.zz"), "wb") as f:
        f.write(other)
    man = os.path.join(first.parts, "manifest.jsonl")
    lines = open(man).read().splitlines(keepends=True)
    with open(man, "w") as f:  # a plain hash claimed for the foreign one
        f.write("".join(line("1,0", other) if ln.startswith('["1,0",') else ln for ln in lines))
    again = job(synth, out)
    again.run()
    assert again.kept == 1 and again.rendered == 3 and tiff_equals(out, whole)


def test_the_manifest_key_is_private_and_never_read_or_written_through_a_link(tmp_path):
    from infinitex.export.workdir import KEY_FILE, manifest_key
    d = tmp_path / "cache"
    k = manifest_key(str(d))
    assert len(k) == 32 and manifest_key(str(d)) == k  # made once, then kept
    assert stat.S_IMODE(os.lstat(d / KEY_FILE).st_mode) == 0o600
    far = outside(tmp_path)
    before = snapshot(far)
    os.unlink(d / KEY_FILE)
    os.symlink(far / "precious.bin", d / KEY_FILE)
    k2 = manifest_key(str(d))
    assert k2 != k and len(k2) == 32 and snapshot(far) == before
    assert not os.path.islink(d / KEY_FILE) and manifest_key(str(d)) == k2


# -- item 11: a FIFO where a listed tile should be -------------------------------------


@pytest.mark.parametrize("fmt", ["tiff", "tiles"])
def test_a_fifo_at_a_listed_tile_does_not_block_the_export(synth, whole, tmp_path, fmt):
    out = tmp_path / ("f.tif" if fmt == "tiff" else "f.png")
    first = job(synth, out, fmt)
    seen = []

    def stop(done, total):
        seen.append(done)
        if done == 4:
            raise ExportInterrupted()  # every tile finished, the TIFF not assembled
    with pytest.raises(ExportInterrupted):
        first.run(stop)
    tile = (os.path.join(first.parts, "1_0.zz") if fmt == "tiff" else udim_name(str(tmp_path / "f"), 1, 0, 2))
    os.unlink(tile)
    os.mkfifo(tile)  # listed in the manifest, now a FIFO: no writer will ever come
    again = job(synth, out, fmt)
    with fuzzing.time_limit(300):  # fails (Hang) instead of blocking on the FIFO
        again.run()
    assert again.kept == 3 and again.rendered == 1
    if fmt == "tiff":
        assert tiff_equals(out, whole) and not os.path.lexists(again.parts)
    else:
        assert np.array_equal(read_tiles(str(out), 512, 512, TILE, whole.shape[2]), whole)


# -- item 13: a listed first tile that is not valid compressed data --------------------


def test_a_listed_first_tile_that_is_not_compressed_data_is_rendered_again(synth, whole, tmp_path):
    out = tmp_path / "z.tif"
    first = interrupted(synth, out)
    bad = b"II*\x00 this is not zlib data" * 40
    with open(os.path.join(first.parts, "0_0.zz"), "wb") as f:
        f.write(bad)
    man = os.path.join(first.parts, "manifest.jsonl")
    lines = open(man).read().splitlines(keepends=True)
    with open(man, "w") as f:  # the manifest claims the damaged tile's own size and hash
        f.write("".join(line("0,0", bad, first) if ln.startswith('["0,0",') else ln for ln in lines))
    again = job(synth, out)
    again.run()  # no zlib.error
    assert again.kept == 3 and again.rendered == 1 and tiff_equals(out, whole)


# -- item 16: a full disk during assembly names the output ----------------------------


def test_a_failed_assembly_names_the_output_not_the_parts_folder(tmp_path):
    import resource
    env = dict(os.environ, INFINITEX_CACHE=str(tmp_path / "cache"))
    args = [sys.executable, os.path.join(ROOT, "main.py"), "export", GRAVEL, "-o", str(tmp_path / "d.tif"),
            "--format", "tiff", "--rect", "0", "0", "1024", "1024", "--tile", "256", "--fidelity", "variety", "-q"]

    def small_files():  # no file above 400 kB: the tiles fit, the assembled TIFF does not
        resource.setrlimit(resource.RLIMIT_FSIZE, (400_000, 400_000))
    r = subprocess.run(args, env=env, capture_output=True, text=True, timeout=600, preexec_fn=small_files)
    assert r.returncode == 3, r.stderr[-2000:]
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: Writing ") and "d.tif failed" in lines[0], lines
    assert ".parts" not in lines[0] and "The finished tiles are kept" in lines[0]
    assert not os.path.exists(tmp_path / "d.tif")
    assert not os.path.lexists(tmp_path / "d.tif.parts" / "assembling.tif")  # the partial file is removed


# -- deleting only what the export knows ------------------------------------------------


def test_foreign_files_in_the_parts_folder_are_left_with_a_note(synth, whole, tmp_path):
    out = tmp_path / "n.tif"
    j, _ = parts_of(synth, out)
    keep = os.path.join(j.parts, "notes.txt")
    with open(keep, "w") as f:
        f.write("the user's notes")
    os.mkdir(os.path.join(j.parts, "sub"))
    j.run()
    assert tiff_equals(out, whole)
    assert sorted(os.listdir(j.parts)) == ["notes.txt", "sub"] and open(keep).read() == "the user's notes"
    assert len(j.notes) == 1 and "n.tif.parts was left in place" in j.notes[0] and "notes.txt" in j.notes[0]


def test_a_folder_where_a_tile_goes_is_refused_before_any_work(synth, tmp_path):
    out = tmp_path / "d.tif"
    j, _ = parts_of(synth, out)
    os.mkdir(os.path.join(j.parts, "1_1.zz"))
    with pytest.raises(WriteError, match=r"1_1\.zz is a folder where this export writes a file"):
        j.run()
    assert sorted(os.listdir(j.parts)) == ["1_1.zz"]


def test_a_zarr_store_with_a_link_inside_is_refused_and_its_target_untouched(synth, tmp_path):
    far = outside(tmp_path)
    before = snapshot(far)
    out = tmp_path / "s.zarr"
    j = job(synth, out, "zarr")
    (tmp_path / "s.zarr.parts" / "data.zarr" / "0").mkdir(parents=True, mode=0o700)
    os.chmod(tmp_path / "s.zarr.parts", 0o700)
    (tmp_path / "s.zarr.parts" / "data.zarr" / ".zgroup").write_text('{"zarr_format": 2}')
    os.symlink(far / "precious.bin", tmp_path / "s.zarr.parts" / "data.zarr" / "0" / "0.0")
    with pytest.raises(WriteError, match="is not a Zarr store this export made"):
        j.run()
    assert snapshot(far) == before and os.path.islink(tmp_path / "s.zarr.parts" / "data.zarr" / "0" / "0.0")
    os.symlink(far / "data.zarr", tmp_path / "t.zarr.parts")
    with pytest.raises(WriteError, match="symbolic link"):
        job(synth, tmp_path / "t.zarr", "zarr").run()
    assert snapshot(far) == before


def test_an_earlier_zarr_store_is_reused_only_if_it_fits(synth, whole, tmp_path):
    import zarr
    out = tmp_path / "r.zarr"
    interrupted(synth, out, "zarr", after=3)
    meta = tmp_path / "r.zarr.parts" / "data.zarr" / "0" / ".zarray"
    d = json.loads(meta.read_text())
    d["chunks"] = [512, 512]  # a store of another export's tiles: its chunks would decode to other pixels
    meta.write_text(json.dumps(d))
    again = job(synth, out, "zarr")
    again.run()
    assert again.kept == 0
    assert np.array_equal(zarr.open_group(str(out), mode="r")["0"][:], whole[..., 0])
    assert not os.path.lexists(tmp_path / "r.zarr.parts")


def test_temporaries_of_a_killed_run_are_removed_and_the_parts_folder_with_them(synth, whole, tmp_path):
    out = tmp_path / "k.tif"
    j, _ = parts_of(synth, out)
    dead = os.path.join(j.parts, ".0_0.zz.999999999.abcdefabcdef.infinitex-tmp")  # no such process
    with open(dead, "wb") as f:
        f.write(b"half a tile")
    j.run()
    assert tiff_equals(out, whole) and not os.path.lexists(j.parts) and not j.notes
