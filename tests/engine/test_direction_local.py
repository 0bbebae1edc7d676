"""Painting a direction field in the editor's way: each comb dab is a local
update of the held pyramid, the first one widening the state to sub-pixel
coordinates in place; the result always equals a fresh synthesis with the
same field (at Balanced, with pans and deferred pieces in between)."""
import numpy as np

from infinitex.engine.controls import Controls, DirectionField
from infinitex.engine.controls.direction import jacobian
from infinitex.engine.params import SynthParams, structure_params
from infinitex.engine.pyramid import Rect
from infinitex.engine.synth import Synthesizer

FAR = 2 ** 30


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
        assert pyr.channels == 2
        plain = vp.read(view)
        dabs = [(50, 40, 30.0), (110, 60, 75.0), (20, 100, -40.0), (900, 900, 10.0)]
        for i, (cx, cy, theta) in enumerate(dabs):
            old = field
            field, _ = field.painted(view.x0 + cx, view.y0 + cy, 22.0, jacobian(theta, 1.3), 0.9)
            pyr.update_controls(Controls(direction=field), [Rect(*r) for r in old.changed_rects(field)],
                                defer=True)
            assert pyr.channels == 4  # widened in place at the first dab, not dropped
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
