"""Colors of sub-pixel coordinates (engine/subpixel.py) and magnification
through J: what a direction field's output is drawn and exported with."""
import os

import numpy as np

from infinitex.engine.analysis import analyze
from infinitex.engine.controls import Controls
from infinitex.engine.controls.direction import DirectionField, jacobian
from infinitex.engine.exemplar import load_exemplar
from infinitex.engine.material import single
from infinitex.engine.params import SynthParams, structure_params
from infinitex.engine.pyramid import Rect
from infinitex.engine.subpixel import sample, turn_normals
from infinitex.engine.synth import Synthesizer

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
BRICK = os.path.join(ROOT, "infinitex", "assets", "brick.png")


def test_sample_is_plain_lookup_without_remainders_and_bilinear_with():
    rng = np.random.default_rng(1)
    arr = rng.integers(0, 256, (16, 16, 3)).astype(np.uint8)
    c = rng.integers(0, 16, (5, 7, 2)).astype(np.int32)
    assert np.array_equal(sample(arr, c, True), arr[c[..., 1], c[..., 0]])
    c4 = np.concatenate([c, np.zeros_like(c)], axis=-1)
    assert np.array_equal(sample(arr, c4, True), arr[c[..., 1], c[..., 0]])
    # Half a pixel to the right: the mean of the two texels (wrapped at the border).
    c4[..., 2] = 128
    want = (arr[c[..., 1], c[..., 0]].astype(float) + arr[c[..., 1], (c[..., 0] + 1) % 16]) / 2
    assert np.abs(sample(arr, c4, True).astype(float) - want).max() <= 0.5
    # Clamped on a non-toroidal exemplar: at the last column, the same texel.
    c4[..., 0] = 15
    assert np.array_equal(sample(arr, c4, False), arr[c[..., 1], 15])


def test_normals_turn_with_the_texture():
    n = np.zeros((1, 1, 3))
    n[..., 0], n[..., 1], n[..., 2] = (0.8 + 1) / 2, 0.5, (0.6 + 1) / 2  # tilted towards +x
    same = turn_normals(n, jacobian(0.0)[None, None])
    assert np.allclose(same, n, atol=1e-3)
    # The texture turned 90 degrees clockwise on screen: +x of the exemplar runs down
    # the screen, so the tilt points down, i.e. -Y in an OpenGL normal map.
    t = turn_normals(n, jacobian(90.0)[None, None]) * 2 - 1
    assert np.allclose(t[0, 0], [0.0, -0.8, 0.6], atol=2e-3)
    # A uniform scale leaves normals as they are.
    assert np.allclose(turn_normals(n, jacobian(0.0, 2.0)[None, None]), n, atol=1e-3)


def test_magnification_follows_j():
    """Zoomed in, each texel's coordinate is extrapolated through its J: the 4
    corners agree inside a patch and the image stays sharp; extrapolated as if
    the texture were not turned, they disagree and blend into a blur."""
    ex = load_exemplar(BRICK)
    an = analyze(ex)
    f = DirectionField.uniform(45.0, 0.5, 1.0, -64, -64, 64, 64)
    with Synthesizer(an, structure_params(SynthParams.default(an.L), 0), controls=Controls(direction=f)) as s:
        c = s.window(Rect(-17, -17, 17, 17))
    assert c.shape == (34, 34, 4) and np.any(c[..., 2:])
    mat = single(ex)
    jac = f.region(0, -17, -17, 34, 34)

    def sharpness(J):
        big = mat.magnified("image", c, 8, J)[..., 0]
        return np.abs(np.diff(big, axis=0)).mean() + np.abs(np.diff(big, axis=1)).mean()
    assert sharpness(jac) > 1.25 * sharpness(None)


def test_streamed_tiles_of_a_normal_map_turn_with_the_field():
    """Tiles, BigTIFF and Zarr exports render through encode_tile: a material's
    normal map there turns with the texture too (as in whole exports)."""
    import io

    from PIL import Image

    from infinitex.export.formats import encode_tile
    ex = load_exemplar(BRICK)
    an = analyze(ex)
    f = DirectionField.uniform(90.0, 1.0, 1.0, 0, 0, 32, 32)
    tilted = np.zeros((an.size, an.size, 3), np.float32)
    tilted[...] = ((0.8 + 1) / 2, 0.5, (0.6 + 1) / 2)  # every normal tilted towards +x
    with Synthesizer(an, structure_params(SynthParams.default(an.L), 0), controls=Controls(direction=f)) as s:
        s.palette = [tilted] * (an.L + 1)
        plain = np.asarray(Image.open(io.BytesIO(encode_tile(s, "tiles", 32, Rect(0, 0, 32, 32))[0])))
        s.normals = True
        turned = np.asarray(Image.open(io.BytesIO(encode_tile(s, "tiles", 32, Rect(0, 0, 32, 32))[0])))
    assert np.all(np.abs(plain[..., 1].astype(int) - 128) <= 1)  # as sampled: no Y
    # Turned 90 degrees clockwise on screen: the tilt points down the image, -Y in an OpenGL map.
    assert np.all(turned[..., 1] < 40) and np.all(np.abs(turned[..., 0].astype(int) - 128) <= 2)
