"""The editor's Export animation (export/animation_job.py): the document's
frames written by a process of its own, the same frames the command line
writes; a cancel leaves nothing behind."""
import json
import os
from dataclasses import replace

import numpy as np
import pytest
from PIL import Image

from infinitex.engine.controls.flow import Flow
from infinitex.engine.material import IMAGE
from infinitex.engine.rect import Rect
from infinitex.export.animation_job import AnimationExport
from infinitex.project import Document, ExemplarSource
from infinitex.project.flow_json import Motion

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))


@pytest.fixture(scope="module")
def doc():
    base = Document(ExemplarSource.from_file(os.path.join(ROOT, "infinitex", "assets", "gravel.png")))
    return replace(base, motion=Motion(Flow.of(1.5, -0.5, period=4, loop=8), frames=8, fps=12.0))


def test_an_atlas_is_the_frames_the_api_makes(doc, tmp_path):
    import infinitex as itx
    out = str(tmp_path / "flow.png")
    job = AnimationExport(doc, Rect(-20, 30, 28, 62), 0, "atlas", [(IMAGE, out)])
    job.start()
    assert job.wait(300) and job.error is None and not job.cancelled and job.progress == 1.0
    meta = json.loads((tmp_path / "flow.json").read_text())
    assert (meta["frames"], meta["frame_width"], meta["frame_height"], meta["fps"], meta["loop"]) == (8, 48, 32, 12.0, True)
    atlas = np.asarray(Image.open(out))
    frames = itx.animate(os.path.join(ROOT, "infinitex", "assets", "gravel.png"), 8, (1.5, -0.5), size=(48, 32),
                         origin=(-20, 30), period=4, loop=True)
    c = meta["columns"]
    for t in (0, 5):
        r, q = divmod(t, c)
        got = atlas[r * 32:(r + 1) * 32, q * 48:(q + 1) * 48]
        want = frames[t]
        assert np.array_equal(got.reshape(want.shape), want)


def test_a_cancelled_export_writes_nothing(doc, tmp_path):
    out = str(tmp_path / "never.webp")
    long = replace(doc, motion=Motion(Flow.of(1.5, -0.5, period=4), frames=400, fps=12.0))
    job = AnimationExport(long, Rect(0, 0, 384, 384), 0, "webp", [(IMAGE, out)])
    job.start()
    job.cancel()  # (400 frames: it is still on its first ones)
    assert job.wait(300) and job.cancelled and job.error is None
    assert os.listdir(tmp_path) == []
