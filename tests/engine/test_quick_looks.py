"""Quick looks at local updates (engine/looks.py): a dab shows at once as a
patch synthesized on its own buffers; the held levels, and so the exact result,
are untouched; the patch goes once the level is exact under it."""
import numpy as np
import pytest

from infinitex.engine.controls import CanvasField, Controls
from infinitex.engine.pyramid import Rect
from infinitex.engine.synth import Synthesizer
from test_fidelity import FAR, with_fidelity


@pytest.fixture
def viewport(analyses, gpu):
    an = analyses["gravel-appearance"]
    vp = Synthesizer(an, with_fidelity(an, seed=4), gpu=gpu).viewport()
    yield vp
    vp.release()


@pytest.mark.parametrize("coarser", [0, 1])
def test_a_look_from_exact_levels_is_exact(viewport, coarser):
    """From exact coarser levels, with the same controls, a patch is exactly
    the level it stands for: it is real synthesis, not an approximation of one."""
    view = Rect.of(FAR - 3000, -FAR + 200, 160, 120)
    viewport.show(view)
    pyr = viewport.pyramid
    d = pyr.an.L - coarser
    rect = Rect(view.x0 + 50 >> coarser, view.y0 + 40 >> coarser, view.x0 + 110 >> coarser, view.y0 + 75 >> coarser)
    assert pyr.looks.make_patch(d, rect) > 0
    patch = pyr.looks.patches[-1]
    assert (patch.level, patch.rect) == (d, rect)
    assert np.array_equal(pyr.state.read_rect(patch.buf, rect), pyr.state.read_rect(pyr.buffers[d], rect))


def test_a_dab_shows_at_once_and_its_patch_goes_when_exact(viewport, analyses, gpu):
    an = analyses["gravel-appearance"]
    pyr = viewport.pyramid
    view = Rect.of(-FAR + 900, 3000, 160, 120)
    viewport.show(view)
    L = an.L
    held = pyr.read(L, view)
    field, _ = CanvasField().painted(view.x0 + 70, view.y0 + 60, 16.0, 0)
    controls = Controls(randomness_canvas=field)
    pyr.update_controls(controls, defer=True)
    assert pyr.looks.look(L, view) > 0
    assert len(pyr.looks.patches) == 1
    patch = pyr.looks.patches[0]
    assert patch.rect.contains(Rect.of(view.x0 + 56, view.y0 + 46, 28, 28))
    look = pyr.state.read_rect(patch.buf, patch.rect)
    assert np.array_equal(pyr.read(L, view), held)  # the held levels are untouched
    assert np.mean(np.any(look != pyr.state.read_rect(pyr.buffers[L], patch.rect), axis=-1)) > 0.2  # it shows the dab
    fresh = Synthesizer(an, viewport.synth.params, gpu=gpu, controls=controls).window(view)
    r = patch.rect
    jobs = 0
    while pyr.looks.patches:
        pyr.settle(None, regions=1)
        jobs += 1
    # Gone (once a job of its level that started after it ended, with none left
    # to do under it): the level is exact there.
    assert jobs > 1
    exact = fresh[r.y0 - view.y0:r.y1 - view.y0, r.x0 - view.x0:r.x1 - view.x0]
    assert np.array_equal(pyr.read(L, r), exact)
    while not pyr.settle(None, regions=1):
        pass
    assert np.array_equal(pyr.read(L, view), fresh)


def test_looks_of_another_level_or_outside_the_view_are_dropped(viewport):
    pyr = viewport.pyramid
    view = Rect.of(500, 500, 160, 120)
    viewport.show(view)
    L = pyr.an.L
    field, _ = CanvasField().painted(580, 560, 16.0, 65535)
    pyr.update_controls(Controls(randomness_canvas=field), defer=True)
    pyr.looks.look(L, view)
    assert len(pyr.looks.patches) == 1
    pyr.looks.look(L - 1, view.half())  # zoomed out: the shown level changed
    assert not pyr.looks.patches
    pyr.settle()
    assert pyr.settled and not pyr.looks.patches


def _dabs(kind: str, an, x0: int, y0: int):
    """Three dabs' controls of one kind, in the order made (a feature: placed, then moved twice)."""
    from infinitex.engine.controls import CanvasLabels, DirectionField, Feature
    from infinitex.engine.controls.direction import jacobian
    from test_labels import halves
    out, le = [], halves(an.size)
    field, labels, comb = CanvasField(), CanvasLabels(), DirectionField()
    for i, (cx, cy) in enumerate([(x0 + 30, y0 + 30), (x0 + 38, y0 + 34), (x0 + 60, y0 + 50)]):
        if kind == "randomness":
            field, _ = field.painted(cx, cy, 12.0, 65535 * (i % 2))
            out.append(Controls(randomness_canvas=field))
        elif kind == "labels":
            labels, _ = labels.painted(cx, cy, 12.0, 1 + 2 * (i % 2))
            out.append(Controls(labels_exemplar=le, labels_canvas=labels))
        elif kind == "comb":
            comb, _ = comb.painted(cx, cy, 12.0, jacobian(60.0 * (i + 1), 1.0), 0.9)
            out.append(Controls(direction=comb))
        else:
            out.append(Controls(features=(Feature((20, 30), (int(cx), int(cy)), 6, 14, None),)))
    return out


@pytest.mark.parametrize("kind", ["randomness", "labels", "comb", "feature"])
def test_dabs_at_balanced_shown_as_looks_end_as_a_fresh_synthesis(analyses, gpu, kind):
    """The editor's way at the default preset, per kind of edit: each dab
    recorded, looked at, a few pieces of its update done, the next dab; the
    view ends as a fresh synthesis with the last controls, and no patch stays."""
    from infinitex.engine.params import DEFAULT_STRUCTURE, SynthParams, structure_params
    an = analyses["gravel-appearance"]
    params = structure_params(SynthParams.default(an.L, seed=8), DEFAULT_STRUCTURE)
    view = Rect.of(FAR - 5000, 700, 96, 80)
    steps = _dabs(kind, an, view.x0, view.y0)
    vp = Synthesizer(an, params, gpu=gpu, controls=Controls(labels_exemplar=steps[0].labels_exemplar)
                     if kind == "labels" else Controls()).viewport()
    pyr = vp.pyramid
    looks = 0
    try:
        vp.show(view)
        for controls in steps:
            pyr.update_controls(controls, None, defer=True)
            pyr.looks.look(an.L, view)
            looks = max(looks, len(pyr.looks.patches))
            for _ in range(3):
                pyr.settle(0.0)
        while not pyr.settle(0.0):
            pass
        assert looks > 0 and not pyr.looks.patches
        fresh = Synthesizer(an, params, gpu=gpu, controls=steps[-1]).window(view, remainder=kind == "comb")
        assert np.array_equal(pyr.read(an.L, view, remainder=kind == "comb"), fresh)
    finally:
        vp.release()
