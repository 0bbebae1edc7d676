"""bench.device: the cross-machine check that a lent GPU runs (here on this machine's GL)."""
import json

import numpy as np
import pytest

from bench import device


@pytest.mark.slow
def test_run_measures_exact_dabs_and_compare_finds_a_changed_window(tmp_path):
    device.run(str(tmp_path), quick=True, presets=[0, 2], sizes=device.SMOKE)
    res = json.loads((tmp_path / "device.json").read_text())
    assert set(res["presets"]) == {"Variety", "Balanced"}
    for r in res["presets"].values():
        # painted in place (randomness, labels, direction) == synthesized fresh with the final controls
        assert r["dab_exact"] is True and r["label_dab_exact"] is True and r["comb_dab_exact"] is True
        assert r["jump_ms"] > 0 and r["release_ms"] > 0
        assert r["full_ms"] > 0 and r["dab_px"] > 0
    # Balanced's stage reaches further than Variety's correction: a dab re-synthesizes more.
    assert res["presets"]["Balanced"]["dab_px"] > res["presets"]["Variety"]["dab_px"]
    coords = tmp_path / "coords.npz"
    assert device.compare(str(coords)) == (12, 0)  # the same windows again: bit-identical
    theirs = dict(np.load(coords))
    theirs["weave_2_far"] = theirs["weave_2_far"].copy()
    theirs["weave_2_far"][5, 7, 0] ^= 1  # one coordinate off by one exemplar pixel
    np.savez_compressed(coords, **theirs)
    assert device.compare(str(coords)) == (11, 1)
