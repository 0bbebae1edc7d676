"""Packaging: the checkout installs with pip into a fresh virtual environment
and gives the ``infinitex`` command; the package's API docstring and the
examples/ scripts stay true (each runs and writes what it says)."""
import os
import subprocess
import sys
import sysconfig

import numpy as np
import pytest
from PIL import Image

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))


@pytest.mark.slow
def test_pip_install_into_a_fresh_venv_gives_the_command(tmp_path):
    venv = tmp_path / "venv"
    subprocess.run([sys.executable, "-m", "venv", str(venv)], check=True)
    py = str(venv / "bin" / "python")
    purelib = subprocess.run([py, "-c", "import sysconfig; print(sysconfig.get_paths()['purelib'])"],
                             check=True, capture_output=True, text=True).stdout.strip()
    # Only the package is installed here (a wheel built from the checkout, with pip's
    # build isolation); its dependencies are those of the test environment, made
    # visible after the venv's own site-packages.
    deps = {sysconfig.get_paths()["purelib"], sysconfig.get_paths()["platlib"]}
    with open(os.path.join(purelib, "test-deps.pth"), "w") as f:
        f.write("\n".join(sorted(deps)) + "\n")
    r = subprocess.run([py, "-m", "pip", "install", "-q", "--no-deps", ROOT], capture_output=True, text=True,
                       timeout=600)
    assert r.returncode == 0, r.stderr[-2000:]
    exe = str(venv / "bin" / "infinitex")
    v = subprocess.run([exe, "--version"], capture_output=True, text=True, cwd=tmp_path, timeout=60)
    import infinitex
    assert v.returncode == 0 and v.stdout.strip() == f"infinitex {infinitex.__version__}"
    where = subprocess.run([py, "-c", "import infinitex.engine.gpu as g, os; print(os.path.realpath(g.SHADER_DIR))"],
                           capture_output=True, text=True, cwd=tmp_path, timeout=60).stdout.strip()
    assert where.startswith(os.path.realpath(str(venv))) and os.path.isfile(os.path.join(where, "upsample.frag"))
    gravel = subprocess.run([py, "-c", "import infinitex.app.ui.editor as e; print(e.DEFAULT_EXEMPLAR)"],
                            capture_output=True, text=True, cwd=tmp_path, timeout=60).stdout.strip()
    assert gravel.startswith(os.path.realpath(str(venv))) or gravel.startswith(str(venv))
    assert os.path.isfile(gravel)
    out = tmp_path / "out.png"
    s = subprocess.run([exe, "synth", gravel, "-o", str(out), "--size", "64", "48", "-q"], capture_output=True,
                       text=True, cwd=tmp_path, timeout=300, env=dict(os.environ, INFINITEX_CACHE=str(tmp_path / "c")))
    assert s.returncode == 0, s.stderr[-2000:]
    assert Image.open(out).size == (64, 48)


EXAMPLES = sorted(f for f in os.listdir(os.path.join(ROOT, "examples")) if f.endswith(".py"))


@pytest.mark.slow
@pytest.mark.parametrize("script", EXAMPLES)
def test_examples_run_and_write_what_they_say(script, tmp_path):
    """Each example takes an output folder, writes PNGs there and prints one
    line per file: 'wrote NAME WxH'."""
    r = subprocess.run([sys.executable, os.path.join(ROOT, "examples", script), str(tmp_path)],
                       capture_output=True, text=True, timeout=600, cwd=tmp_path)
    assert r.returncode == 0, r.stderr[-2000:]
    lines = [ln for ln in r.stdout.splitlines() if ln.startswith("wrote ")]
    assert lines, r.stdout
    for ln in lines:
        _, name, size = ln.split()
        w, h = (int(v) for v in size.split("x"))
        img = np.asarray(Image.open(tmp_path / name))
        assert img.shape[:2] == (h, w) and img.std() > 3, name


def test_the_api_docstring_example_runs(tmp_path):
    import infinitex as itx
    gravel = os.path.join(ROOT, "infinitex", "assets", "gravel.png")
    img = itx.synthesize(gravel, size=(96, 64), origin=(10_000, -3_000), seed=7)
    assert img.shape == (64, 96, 1) and img.dtype == np.uint8
    again = itx.synthesize(gravel, size=(32, 32), origin=(10_040, -2_990), seed=7)
    assert np.array_equal(again, img[10:42, 40:72])  # windows agree where they overlap
    ex = itx.load_exemplar(gravel)
    an = itx.analyze(ex)
    from infinitex.engine.params import structure_params
    with itx.Synthesizer(an, structure_params(itx.SynthParams.default(an.L, seed=7), 2)) as s:
        coords = s.window(itx.Rect.of(10_000, -3_000, 96, 64))
        assert np.array_equal(itx.to_u8(s.colors(coords)), img)  # the default is Balanced, as in the editor
    variety = itx.synthesize(gravel, size=(96, 64), origin=(10_000, -3_000), seed=7, structure="variety")
    with itx.Synthesizer(an, itx.SynthParams.default(an.L, seed=7)) as s:
        assert np.array_equal(itx.to_u8(s.colors(s.window(itx.Rect.of(10_000, -3_000, 96, 64)))), variety)
    assert not np.array_equal(variety, img)
    with pytest.raises(ValueError, match="not a Structure preset"):
        itx.synthesize(gravel, size=(8, 8), structure="sharp")
    t = itx.tile(gravel, 64)
    assert t.shape == (64, 64, 1)
    assert set(itx.__all__) <= set(dir(itx)) and callable(itx.detect_lattice)
