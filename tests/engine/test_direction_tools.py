"""The direction field's editing operations (what the editor's Direction tool
does): comb, grow, erase, smooth and curve guides, in direction / scale /
aspect space; no GL."""
import numpy as np
import pytest

from infinitex.engine.controls.direction import (
    IDENTITY,
    DirectionField,
    comb,
    decompose,
    erase,
    grow,
    jacobian,
    smooth,
    valid_jacobians,
)


def angle_at(f, x, y):
    return float(decompose(f.dense(x, y, 1, 1))[0][0, 0])


def test_jacobian_and_decompose_are_inverse():
    th = np.array([-170.0, -45.0, 0.0, 30.0, 90.0, 179.0])
    j = jacobian(th, 1.7, 0.8)
    t2, s2, a2 = decompose(j)
    assert np.allclose(t2, th, atol=0.05) and np.allclose(s2, 1.7, atol=2e-3) and np.allclose(a2, 0.8, atol=2e-3)
    assert valid_jacobians(j)
    with pytest.raises(ValueError):
        jacobian(0.0, 3.0, 2.0)  # 6x along the direction: beyond the limit


def test_comb_turns_along_the_shorter_arc_and_erase_goes_back():
    f = DirectionField()
    w = np.ones((10, 10))
    f, rect = f.edited(0, 0, w, comb(170.0))
    assert rect == (0, 0, 10, 10) and abs(angle_at(f, 5, 5) - 170.0) < 0.05
    half, _ = f.edited(0, 0, 0.5 * w, comb(-150.0))  # 170 -> -150 is 40 degrees through 180, not 320 back
    assert abs(((angle_at(half, 5, 5) + 180.0) % 360.0) - 10.0) < 0.1  # 190, i.e. -170
    g, _ = f.edited(0, 0, w, grow(2.0))
    assert abs(float(decompose(g.dense(3, 3, 1, 1))[1][0, 0]) - 2.0) < 0.01
    back, _ = g.edited(0, 0, w, erase())
    assert back.identity and back.tiles == {}
    # A zero weight leaves the pixel exactly as it was.
    part = np.zeros((10, 10))
    part[:, :5] = 1.0
    p, _ = f.edited(0, 0, part, comb(0.0))
    assert abs(angle_at(p, 2, 2)) < 0.05 and np.array_equal(p.dense(7, 0, 3, 10), f.dense(7, 0, 3, 10))


def test_smooth_blends_two_combed_halves():
    f = DirectionField()
    left = np.zeros((40, 40))
    left[:, :20] = 1.0
    f, _ = f.edited(0, 0, left, comb(0.0))
    f, _ = f.edited(0, 0, 1.0 - left, comb(60.0))
    before = [angle_at(f, x, 20) for x in (18, 19, 20, 21)]
    s, _ = f.edited(0, 0, np.ones((40, 40)), smooth(15))
    after = [angle_at(s, x, 20) for x in (18, 19, 20, 21)]
    assert before[1] < 1 and before[2] > 59  # a hard step
    assert 10 < after[1] < after[2] < 50  # a gentle ramp
    assert np.all(np.diff(after) > 0)


def test_a_guide_is_followed_within_its_width_and_two_guides_blend_smoothly():
    f = DirectionField()
    # A guide down a slope of 1/2 (its tangent at -26.6 degrees), and a vertical one along x = 200.
    f = f.guided([(-300, 150), (0, 0), (150, -75)], width=20, blend=120)
    slope = float(np.degrees(np.arctan2(-0.5, 1.0)))
    assert abs(angle_at(f, -50, 25) - slope) < 0.1 and abs(angle_at(f, -50, 33) - slope) < 0.1
    assert f.dense(-50, 200, 1, 1).tolist() == [[IDENTITY.tolist()]]  # beyond width + blend: untouched
    g = f.guided([(200, -200), (200, 200)], width=20, blend=120)
    assert abs(angle_at(g, 200, 100) - 90.0) < 0.1
    # Between them (y = 60, from the first guide to the second), the direction
    # turns from the first's to the second's, steadily.
    a = [angle_at(g, x, 60) for x in range(-110, 200, 15)]
    assert abs(a[0] - slope) < 0.5 and abs(a[-1] - 90.0) < 0.5
    assert np.all(np.diff(a) >= -0.01) and sum(slope + 5 < v < 85 for v in a) >= 8
    with pytest.raises(ValueError):
        f.guided([(0, 0), (100000, 100000)], width=10, max_area=10 ** 6)
