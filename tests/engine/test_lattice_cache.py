"""The lattice search's answers kept on disk (engine/controls/lattice_cache.py):
the same Detection as the search itself, field for field, from the cache as
from a fresh search; damaged entries searched again; a cached answer needs
neither the search nor scipy."""
import dataclasses
import json
import os
import subprocess
import sys

import numpy as np
import pytest
from lattice_gen import stochastic, tiles

from infinitex.engine.controls.lattice_cache import cache_key, find_lattice
from infinitex.engine.controls.lattice_detect import detect

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))


def _fields(d):
    """A Detection's fields but the time it took."""
    return {k: v for k, v in dataclasses.asdict(d).items() if k != "seconds"}


@pytest.fixture(scope="module")
def images():
    rng = np.random.default_rng(5)
    return {"tiles": tiles(rng, side=128)[0].astype(np.float32), "noise": stochastic(rng, side=128).astype(np.float32)}


@pytest.mark.parametrize("kind", ["tiles", "noise"])
def test_cached_answers_are_the_search_s_answers(images, kind, tmp_path):
    img = images[kind]
    fresh = detect(img)
    assert (fresh.lattice is not None) == (kind == "tiles")
    first = find_lattice(img, cache_dir=str(tmp_path))  # searched, then kept
    entries = list(tmp_path.glob("lattice-*.json"))
    assert len(entries) == 1
    second = find_lattice(img, cache_dir=str(tmp_path))  # read back
    assert _fields(first) == _fields(second) == _fields(fresh)
    assert first.lattice == fresh.lattice and first == dataclasses.replace(second, seconds=first.seconds)
    # Another image (one pixel differs) is another entry.
    other = img.copy()
    other[0, 0, 0] = 1.0 - other[0, 0, 0]
    assert cache_key(other) != cache_key(img)
    find_lattice(other, cache_dir=str(tmp_path))
    assert len(list(tmp_path.glob("lattice-*.json"))) == 2


@pytest.mark.parametrize("damage", [
    b"", b"{", b"[]", b"null", b"\xff\xfe",
    json.dumps({"lattice": {"origin": [0, 0], "t1": [0, 0], "t2": [0, 0], "nx": 2, "ny": 2, "levels": None},
                "confidence": 1.0, "seconds": 0.1}).encode(),  # a degenerate lattice
    json.dumps({"lattice": None, "confidence": "high", "seconds": 0.1}).encode(),
    json.dumps({"lattice": {"origin": [0, 0], "t1": [1e400, 0], "t2": [0, 8], "nx": 2, "ny": 2},
                "confidence": 1.0, "seconds": 0.1}).encode().replace(b"Infinity", b"1e400"),
    json.dumps({"lattice": {"origin": [0, 0], "t1": [8, 0], "t2": [0, 8], "nx": True, "ny": 2},
                "confidence": 1.0, "seconds": 0.1}).encode(),
    b'{"lattice": null, "confidence": 1' + b"0" * 400 + b', "seconds": 0.1}',  # too large for a float
    b"[" * 100_000,  # deeper than the parser goes
    b" " * (1 << 17),  # larger than any entry
])
def test_a_damaged_entry_is_searched_again_and_replaced(images, damage, tmp_path):
    img = images["tiles"]
    path = tmp_path / f"lattice-{cache_key(img)}.json"
    path.write_bytes(damage)
    found = find_lattice(img, cache_dir=str(tmp_path))
    assert _fields(found) == _fields(detect(img))
    assert json.loads(path.read_bytes())["confidence"] == found.confidence  # replaced by the answer


def test_a_cached_answer_needs_neither_the_search_nor_scipy(images, tmp_path):
    """The point of the cache: a command or an editor opening an image again
    does not import the search (which imports scipy, about 0.5 s)."""
    np.save(tmp_path / "img.npy", images["tiles"])
    code = ("import sys, numpy as np\n"
            "from infinitex.engine.controls.lattice_cache import find_lattice\n"
            f"d = find_lattice(np.load({str(tmp_path / 'img.npy')!r}), cache_dir={str(tmp_path)!r})\n"
            "print(d.lattice is not None, 'infinitex.engine.controls.lattice_detect' in sys.modules,"
            " any(m.split('.')[0] == 'scipy' for m in sys.modules))\n")
    run = lambda: subprocess.run([sys.executable, "-c", code], cwd=ROOT, capture_output=True, text=True,  # noqa: E731
                                 check=True).stdout.split()
    assert run() == ["True", "True", "True"]  # searched
    assert run() == ["True", "False", "False"]  # answered from the cache
