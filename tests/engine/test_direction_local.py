"""Painting a direction field in the editor's way: each comb dab is a local
update of the held pyramid, the first one widening the state to sub-pixel
coordinates in place; the result always equals a fresh synthesis with the
same field (at Balanced, with pans and deferred pieces in between)."""
import numpy as np

from infinitex.engine.controls import Controls, DirectionField
from infinitex.engine.controls.direction import jacobian
from infinitex.engine.params import SynthParams, structure_params
from infinitex.engine.pyramid import Rect
from infinitex.engine.stages import Pacer
from infinitex.engine.synth import Synthesizer

FAR = 2 ** 30



class FixedPacer(Pacer):
    """Pieces of 8 rows whatever the timing (Pacer learns from the clock)."""

    def rows(self, prog, w: int) -> int:
        return 8

    def record(self, prog, px: int, seconds: float) -> None:
        pass

def test_direction_dabs_as_local_updates_equal_a_fresh_synthesis(analyses, gpu):
    an = analyses["gravel-appearance"]
    params = structure_params(SynthParams.default(an.L, seed=4), 2)
    view = Rect.of(FAR - 3000, -FAR + 500, 144, 112)
    vp = Synthesizer(an, params, gpu=gpu).viewport()
    pyr = vp.pyramid
    field = DirectionField()
    try:
        vp.show(view)
        orig = view
        assert pyr.state.channels == 2
        plain = vp.read(view)
        dabs = [(50, 40, 30.0), (110, 60, 75.0), (20, 100, -40.0), (900, 900, 10.0)]
        for i, (cx, cy, theta) in enumerate(dabs):
            old = field
            field, _ = field.painted(view.x0 + cx, view.y0 + cy, 22.0, jacobian(theta, 1.3), 0.9)
            held = [None if b is None else b.valid for b in pyr.buffers]
            pyr.update_controls(Controls(direction=field), [Rect(*r) for r in old.changed_rects(field)],
                                defer=True)
            # Widened in place at the first dab: every level still holds what it held.
            assert all(b.channels == 4 for b in pyr.buffers if b is not None)
            assert [None if b is None else b.valid for b in pyr.buffers] == held
            while not pyr.settle(0.0):
                pass
            if i == 1:  # a pan between dabs
                view = Rect.of(view.x0 + 23, view.y0 - 17, 144, 112)
                vp.show(view)
            fresh = Synthesizer(an, params, gpu=gpu, controls=Controls(direction=field)).window(view, remainder=True)
            got = pyr.read(an.L, view, remainder=True)
            assert np.array_equal(got, fresh), f"dab {i}"
        # The dabs changed the texture where they were, not far from them.
        first = Rect.of(orig.x0 + 35, orig.y0 + 25, 30, 30)
        assert np.mean(np.any(pyr.read(an.L, first) != plain[25:55, 35:65], axis=-1)) > 0.5
        far_view = Rect.of(view.x0 + 4000, view.y0, 32, 32)
        vp.show(far_view)
        with Synthesizer(an, params, gpu=gpu) as s:
            assert np.array_equal(vp.read(far_view), s.window(far_view))
    finally:
        vp.release()


def test_a_first_dab_during_a_local_update_equals_a_fresh_synthesis(analyses, gpu):
    """A randomness stroke's update is under way (paused after any of its
    steps, the write-back of a level included) when the first direction dab
    comes: the update is finished first, then the state widened; the end is a
    fresh synthesis."""
    from infinitex.engine.controls import CanvasField
    an = analyses["gravel-appearance"]
    params = SynthParams.default(an.L, seed=8)
    view = Rect.of(-FAR + 700, 200, 96, 80)
    rand, _ = CanvasField().painted(view.x0 + 40, view.y0 + 40, 36.0, 0)
    # The dab far from the view: what the stroke's update still has to do must not be lost.
    field, _ = DirectionField().painted(view.x0 + 3000, view.y0 + 30, 18.0, jacobian(50.0), 1.0)
    fresh = Synthesizer(an, params, gpu=gpu, controls=Controls(randomness_canvas=rand, direction=field))
    want = fresh.window(view, remainder=True)
    fresh.release()
    def run(pause: int | None) -> int:
        """Pause the stroke's update after ``pause`` steps (None: count its steps), dab, settle, compare."""
        vp = Synthesizer(an, params, gpu=gpu).viewport()
        try:
            vp.show(view)
            pyr = vp.pyramid
            pyr.pacer = FixedPacer()  # the same pieces in every run, however loaded the machine is
            pyr.update_controls(Controls(randomness_canvas=rand), defer=True)
            steps = 0
            while (pause is None or steps < pause) and not pyr.settle(0.0):
                steps += 1
            if pause is None:
                return steps
            assert not pyr.settled  # the update is under way
            pyr.update_controls(Controls(randomness_canvas=rand, direction=field), defer=True)
            while not pyr.settle(0.0):
                pass
            assert np.array_equal(pyr.read(an.L, view, remainder=True), want), f"paused after {pause} steps"
            return steps
        finally:
            vp.release()
    total = run(None)
    assert total > 30
    for pause in sorted(set(np.linspace(1, total - 2, 12).astype(int))):
        run(int(pause))
