"""Lattice detection on real near-regular images (tests/near_regular.py):
the issue's target is a correct lattice on at least 80% of them and none on
stochastic images; the set measured 27/27 and 0/8 when it was built, so the
test allows two misses before it fails."""
from __future__ import annotations

import math

import numpy as np
import pytest

import near_regular
from infinitex.engine.controls.lattice_detect import Detection, detect


def test_manifest_is_well_formed():
    m = near_regular.manifest()
    kinds = [e["kind"] for e in m["images"]]
    assert kinds.count("none") >= 5 and len(kinds) - kinds.count("none") >= 20
    for e in m["images"]:
        assert len(e["sha256"]) == 64
        assert len(e["vectors"]) == {"grid": 2, "rows": 1, "none": 0}[e["kind"]]
        if e["kind"] == "grid":
            (a, b), (c, d) = e["vectors"]
            assert abs(a * d - b * c) > 4.0  # two independent vectors


def test_scoring_tells_right_from_wrong():
    """The scoring itself: the right lattice passes, a sub-lattice, a cell that
    cuts rows in two and a 4% error fail."""
    weave = {"kind": "grid", "vectors": [[16, 16], [16, -16]]}
    rows = {"kind": "rows", "vectors": [[0, 12.0]]}
    lat = object()  # any non-None lattice
    ok = near_regular.correct
    assert ok(weave, Detection(lat, 1.0, 0.0, (32.0, 0.0), (16.0, 16.0)))
    assert not ok(weave, Detection(lat, 1.0, 0.0, (16.0, 0.0), (0.0, 16.0)))
    assert not ok(weave, Detection(lat, 1.0, 0.0, (16.64, 16.64), (16.64, -16.64)))
    assert not ok(weave, Detection(None, 0.0, 0.0, (16.0, 16.0), (16.0, -16.0)))
    assert ok(rows, Detection(lat, 1.0, 0.0, (12.0, 0.0), (3.0, 12.1)))
    assert not ok(rows, Detection(lat, 1.0, 0.0, (12.0, 0.0), (0.0, 6.0)))
    assert not ok(rows, Detection(lat, 1.0, 0.0, (12.0, 0.0), (0.0, 24.0)))
    assert near_regular.rows_error((1, 0), (0, 24), (0, 12)) == math.inf
    assert ok({"kind": "none", "vectors": []}, Detection(None, 0.1, 0.0))


def test_real_images():
    try:
        images = near_regular.fetch()
    except near_regular.Unavailable as e:
        pytest.skip(f"the real image set could not be fetched: {e}")
    misses, false_pos, n = [], [], 0
    for entry, path in images:
        img = near_regular.load(path)
        assert img.ndim == 3 and np.isfinite(img).all()
        d = detect(img)
        if entry["kind"] == "none":
            if d.lattice is not None:
                false_pos.append(entry["path"])
            continue
        n += 1
        if not near_regular.correct(entry, d):
            misses.append(f"{entry['path']}: truth {entry['vectors']}, found {d.t1} {d.t2} "
                          f"({'accepted' if d.lattice else 'rejected'}, confidence {d.confidence:.2f})")
    assert not false_pos, f"a lattice on stochastic images: {false_pos}"
    assert len(misses) <= 2, f"{n - len(misses)}/{n} found; missed:\n" + "\n".join(misses)
