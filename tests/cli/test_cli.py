"""The synth command: outputs, coordinate maps, one-line errors."""
import os

import numpy as np
import pytest
from clirun import infinitex
from PIL import Image

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
GRAVEL = os.path.join(ROOT, "infinitex", "assets", "gravel.png")


def run(*args):
    return infinitex("synth", *args)  # in this process (tests/clirun.py)


def test_synth_writes_image_and_coords(tmp_path):
    out, coords = str(tmp_path / "o.png"), str(tmp_path / "c.npy")
    r = run(GRAVEL, "-o", out, "--size", "96", "64", "--origin", "-5000", "123456", "--seed", "7",
            "--coords", coords, "-q")
    assert r.returncode == 0, r.stderr
    img = np.asarray(Image.open(out))
    c = np.load(coords)
    assert img.shape == (64, 96) and c.shape == (64, 96, 2) and c.dtype == np.int32
    ex = np.asarray(Image.open(GRAVEL))
    assert np.array_equal(img, ex[c[..., 1], c[..., 0]])  # pixel = E[S[p]]
    # Same arguments, same bytes; another seed, another texture.
    out2 = str(tmp_path / "o2.png")
    assert run(GRAVEL, "-o", out2, "--size", "96", "64", "--origin", "-5000", "123456", "--seed", "7",
               "-q").returncode == 0
    assert np.array_equal(np.asarray(Image.open(out2)), img)
    run(GRAVEL, "-o", out2, "--size", "96", "64", "--origin", "-5000", "123456", "--seed", "8", "-q")
    assert not np.array_equal(np.asarray(Image.open(out2)), img)


def test_synth_toroidal_and_per_level_jitter(tmp_path):
    out = str(tmp_path / "t.png")
    r = run(GRAVEL, "-o", out, "--size", "64", "64", "--toroidal", "--jitter", "1,1,1,0.5,0.5,0.2,0.2,0", "-q")
    assert r.returncode == 0, r.stderr
    assert np.asarray(Image.open(out)).shape == (64, 64)


def test_zero_jitter_color_model(tmp_path):
    out, coords = str(tmp_path / "z.png"), str(tmp_path / "z.npy")
    r = run(GRAVEL, "-o", out, "--size", "40", "40", "--jitter", "0", "--model", "color",
            "--coords", coords, "-q")
    assert r.returncode == 0, r.stderr


@pytest.mark.parametrize("args, words", [
    (["/no/such.png", "-o", "X"], "No such file"),
    ([__file__, "-o", "X"], "not an image format"),
    ([GRAVEL, "-o", "X", "--jitter", "0.1,0.2"], "one per level"),
    ([GRAVEL, "-o", "X", "--toroidal", "--size", "100", "100"], "power-of-two"),
    ([GRAVEL, "-o", "/no/such/dir/o.png"], "does not exist"),
    ([GRAVEL, "-o", "X", "--size", "0", "10"], "--size"),
    ([GRAVEL, "-o", "X", "--origin", "2147483000", "0"], "within"),
    ([GRAVEL, "-o", "X", "--kappa", "-3"], "kappa"),
    ([GRAVEL, "-o", "X", "--jitter", "abc"], "not a number"),
    ([GRAVEL, "-o", "X", "--feature-weight", "5"], "feature-distance weight"),
    ([GRAVEL, "-o", "X", "--passes", "2,3"], "one per level"),
    ([GRAVEL, "-o", "X", "--passes", "9"], "from 0 to 8"),
    ([GRAVEL, "-o", "X", "--passes", "2,x"], "comma-separated list of integers"),
    ([GRAVEL, "-o", "X", "--k", "0", "--lattice", "0,0,32,0,0,32,2,2"], "lattice needs similarity sets"),
])
def test_bad_input_one_line_no_traceback(tmp_path, args, words):
    args = [a if a != "X" else str(tmp_path / "x.png") for a in args]
    r = run(*args, "-q")
    assert r.returncode != 0
    assert "Traceback" not in r.stderr
    assert words in r.stderr
    assert len([ln for ln in r.stderr.splitlines() if ln.startswith("error") or "error:" in ln]) == 1
    assert not os.path.exists(tmp_path / "x.png")


def test_no_gl_gives_a_clear_message(tmp_path, monkeypatch, capsys):
    import moderngl

    from infinitex.cli import common as cli, synth

    def broken(*args, **kwargs):
        raise Exception("libEGL.so not loaded")
    monkeypatch.setattr(moderngl, "create_standalone_context", broken)
    code = synth.main([GRAVEL, "-o", str(tmp_path / "o.png"), "-q"])
    err = capsys.readouterr().err
    assert code == cli.EXIT_GL
    assert "No usable OpenGL 3.3" in err and "libegl1" in err and "Traceback" not in err
    assert not (tmp_path / "o.png").exists()


def test_synth_random_walk_option(tmp_path):
    """--walk N adds TBN10's random walk (another texture, the same for the same
    arguments); out of range is a one-line usage error."""
    a, b, c = (str(tmp_path / f"{n}.png") for n in "abc")
    for out, extra in ((a, []), (b, ["--walk", "6"]), (c, ["--walk", "6"])):
        r = run(GRAVEL, "-o", out, "--size", "64", "48", *extra, "-q")
        assert r.returncode == 0, r.stderr
    ia, ib, ic = (np.asarray(Image.open(p)) for p in (a, b, c))
    assert np.array_equal(ib, ic) and not np.array_equal(ia, ib)
    r = run(GRAVEL, "-o", a, "--walk", "13")
    assert r.returncode == 2 and len(r.stderr.strip().splitlines()) == 1 and "walk" in r.stderr.lower()


def test_synth_passes_per_level(tmp_path):
    """--passes with one count per level (coarse to fine) is the same texture as
    one count when the lists agree (0 on the 3 coarsest), another otherwise."""
    a, b, c = (str(tmp_path / f"{n}.png") for n in "abc")
    for out, passes in ((a, "2"), (b, "0,0,0,2,2,2,2,2"), (c, "0,0,0,4,4,4,2,3")):  # gravel: 128 px, 8 levels
        r = run(GRAVEL, "-o", out, "--size", "64", "48", "--passes", passes, "-q")
        assert r.returncode == 0, r.stderr
    ia, ib, ic = (np.asarray(Image.open(p)) for p in (a, b, c))
    assert np.array_equal(ia, ib) and not np.array_equal(ia, ic)


def test_synth_fidelity_presets(tmp_path):
    """--fidelity takes a Structure preset by number or name (the same texture
    either way, another per preset, the default being Balanced); anything else
    is a one-line usage error."""
    outs = {k: str(tmp_path / f"{k}.png") for k in ("default", "balanced", "two", "variety", "strong")}
    for key, extra in (("default", []), ("balanced", ["--fidelity", "Balanced"]), ("two", ["--fidelity", "2"]),
                       ("variety", ["--fidelity", "variety"]), ("strong", ["--fidelity", "3"])):
        r = run(GRAVEL, "-o", outs[key], "--size", "64", "48", *extra, "-q")
        assert r.returncode == 0, r.stderr
    img = {k: np.asarray(Image.open(p)) for k, p in outs.items()}
    assert np.array_equal(img["default"], img["balanced"]) and np.array_equal(img["two"], img["balanced"])
    assert not np.array_equal(img["variety"], img["balanced"]) and not np.array_equal(img["strong"], img["balanced"])
    for bad in ("5", "extreme", "-1"):
        r = run(GRAVEL, "-o", outs["default"], "--fidelity", bad)
        assert r.returncode == 2 and len(r.stderr.strip().splitlines()) == 1 and "fidelity" in r.stderr.lower()
