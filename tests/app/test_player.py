"""Texture in motion in the editor, without a window: the player process
(app/player.py) gives exactly the frames the engine composes, played in order
without skipping one, and says in one line what it cannot play."""
import os
import time
from dataclasses import replace

import numpy as np
import pytest

from infinitex.app.player import MAX_PLAY_PIXELS, SNAP, Playback, play_rect
from infinitex.engine.advect import FlowFrames, SynthSource
from infinitex.engine.controls.flow import Q, Flow, VelocityMap
from infinitex.engine.imagefile import to_u8
from infinitex.engine.rect import Rect
from infinitex.export.loaded import LoadedDocument
from infinitex.project import Document, ExemplarSource
from infinitex.project.flow_json import Motion

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
RECT = Rect(-40, 1000, 56, 1072)


@pytest.fixture(scope="module")
def doc():
    base = Document(ExemplarSource.from_file(os.path.join(ROOT, "infinitex", "assets", "gravel.png")))
    v = np.zeros((60, 80, 2), np.int32)
    v[..., 0], v[20:40, :, 1] = 2 * Q, -Q // 2
    return replace(base, motion=Motion(Flow(velocity=(64, 0), map=VelocityMap(v, -30, 1010), period=8), 24, 24.0))


@pytest.fixture(scope="module")
def playback():
    pb = Playback()
    yield pb
    pb.close()


def _engine(gpu, doc, t: int, rect: Rect) -> np.ndarray:
    loaded = LoadedDocument(gpu)
    try:
        loaded.load_now(replace(doc, motion=None))
        src = SynthSource(loaded.synth, 0)
        frames = FlowFrames(src, doc.motion.flow, loaded.params.seed)
        rgb = to_u8(loaded.material.lookup(loaded.material.primary, frames.frame(t, rect)))
        frames.release()
        src.release()
        return np.repeat(rgb, 3, axis=2) if rgb.shape[2] == 1 else rgb[..., :3]
    finally:
        loaded.release()


def _until(pb, doc, rect, cond, seconds=120.0, period=0):
    t0 = time.monotonic()
    shown = []
    while time.monotonic() - t0 < seconds:
        if pb.tick(doc, period, rect, ""):
            shown.append(pb.shown.t)
        if cond():
            return shown
        time.sleep(0.005)
    raise AssertionError(f"timed out: t {pb.t}, error {pb.player.error}")


def test_played_frames_are_the_engines_in_order(gpu, doc, playback):
    pb = playback
    pb.seek(21, doc.motion.frames)
    _until(pb, doc, RECT, lambda: pb.shown is not None and pb.shown.t == 21)
    np.testing.assert_array_equal(pb.shown.rgb, _engine(gpu, doc, 21, RECT))  # a frame reached alone
    pb.play()
    shown = _until(pb, doc, RECT, lambda: pb.t == 3)  # on through the animation's end, back to 0
    assert shown == [22, 23, 0, 1, 2, 3]  # in order, none skipped, wrapping at the frame count
    assert not pb.shown.exact  # drafts while playing (the cuts not mended)
    pb.pause()
    _until(pb, doc, RECT, lambda: pb.shown.exact and pb.shown.t == 3)  # paused: the exact frame
    np.testing.assert_array_equal(pb.shown.rgb, _engine(gpu, doc, 3, RECT))  # the same played in order
    # Another window (a pan) and an edit of the flow are taken at the next request.
    moved = Rect(RECT.x0 + 17, RECT.y0 - 9, RECT.x1 + 17, RECT.y1 - 9)
    faster = replace(doc, motion=replace(doc.motion, flow=replace(doc.motion.flow, velocity=(300, 0))))
    _until(pb, faster, moved, lambda: pb.shown is not None and pb.shown.rect == moved and not pb.player.busy
           and pb.shown.doc_id == pb.player.doc_id)
    np.testing.assert_array_equal(pb.shown.rgb, _engine(gpu, faster, 3, moved))


def test_what_cannot_play_is_one_line_asked_once(doc, playback):
    pb = playback
    pb.seek(2, doc.motion.frames)
    # A painted flow in tile mode (period 64): the map does not cover the tile.
    _until(pb, doc, Rect(0, 0, 64, 64), lambda: pb.player.error is not None, period=64)
    assert "toroidal tile" in pb.player.error and "\n" not in pb.player.error
    asked = pb.player.doc_id, pb.player.asked
    for _ in range(20):
        pb.tick(doc, 64, Rect(0, 0, 64, 64), "")
    assert pb.player.asked is None and (pb.player.doc_id, pb.player.asked) == asked  # not asked again
    _until(pb, doc, RECT, lambda: pb.shown is not None and pb.shown.rect == RECT and pb.shown.t == 2)  # no tile mode: it plays
    assert pb.player.error is None


def test_a_zoomed_out_view_plays_its_middle():
    r = play_rect(RECT)  # widened to the grid: a small pan keeps the window
    assert r.contains(RECT) and r == play_rect(Rect(RECT.x0 - 20, RECT.y0 + 5, RECT.x1 - 20, RECT.y1 + 5))
    assert r.x0 % SNAP == 0 and r.y1 % SNAP == 0 and r.w < RECT.w + 2 * SNAP
    big = Rect(-2000, -1000, 2000, 1000)
    r = play_rect(big)
    assert r.w * r.h <= MAX_PLAY_PIXELS and abs(r.w / r.h - 2.0) < 0.25
    assert abs((r.x0 + r.x1) // 2) <= SNAP and abs((r.y0 + r.y1) // 2) <= SNAP


def test_a_frame_of_another_document_is_never_shown(gpu, doc, playback):
    pb = playback
    other = replace(doc, seed=doc.seed + 11)  # another still texture
    pb.seek(4, doc.motion.frames)
    pb.tick(doc, 0, RECT, "")  # asked for doc's frame...
    assert pb.player.busy
    # ...then the document changes before it comes: what shows is only ever the new one's.
    shown_ids = set()
    t0 = time.monotonic()
    while not (pb.shown is not None and pb.shown.doc_id == pb.player.doc_id and not pb.player.busy):
        assert time.monotonic() - t0 < 120, pb.player.error
        pb.tick(other, 0, RECT, "")
        if pb.shown is not None:
            shown_ids.add(pb.shown.doc_id)
        time.sleep(0.005)
    assert shown_ids == {pb.player.doc_id}  # the first document's frame came, and was dropped
    np.testing.assert_array_equal(pb.shown.rgb, _engine(gpu, other, 4, RECT))
