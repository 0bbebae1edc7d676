"""Make docs/direction.png: direction fields, the texture following curves.

    .venv/bin/python scripts/figure_direction.py [OUT.png]

Left: two exemplars, the bundled CC0 brick (its bricks stand upright) and a
wood grain generated here (CC0, ours: horizontal grain). Then four 320 x 320
windows at the default Structure, each with a direction field (drawn as short
strokes over the first three): brick courses going round in circles, courses
along a wave, wood grain flowing around a knot (the flow around a disc, and
rings inside it), and gravel growing from half to twice its size, left to right.
"""
import os
import sys

import numpy as np
from PIL import Image, ImageDraw
from scipy import ndimage

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, ROOT)

import infinitex as itx  # noqa: E402
from infinitex.engine.imagefile import to_rgb8  # noqa: E402

SIZE = 320
CELL = 128


def wood_grain(m: int = 128) -> np.ndarray:
    """A toroidal wood grain (m x m RGB floats): dark lines along x, wavering,
    of uneven spacing, with pores."""
    rng = np.random.default_rng(7)
    ys, xs = np.mgrid[0:m, 0:m] / m

    def noise(scale, seed):
        r = np.random.default_rng(seed).standard_normal((m, m))
        return ndimage.gaussian_filter(r, scale, mode="wrap") * scale
    phase = 14.0 * ys + 0.5 * noise(10.0, 1) + 0.08 * np.sin(2 * np.pi * xs)
    rings = 0.5 + 0.5 * np.cos(2 * np.pi * phase)
    late = rings ** 10 + 0.3 * rings ** 2
    pores = (rng.random((m, m)) < 0.03) * late
    v = 0.78 - 0.35 * late - 0.15 * ndimage.gaussian_filter(pores.astype(float), 0.6, mode="wrap") \
        + 0.04 * noise(3.0, 2)
    base = np.array([0.72, 0.45, 0.25])
    return np.clip(v[..., None] * base[None, None, :] * 1.25, 0.0, 1.0).astype(np.float32)


def knot_angles(size: int) -> np.ndarray:
    """Grain around a knot: the potential flow around a disc of radius R at the
    centre (direction of the flow, degrees), rings round the centre inside it."""
    ys, xs = np.mgrid[0:size, 0:size] + 0.5
    x, y = xs - size / 2, ys - size / 2
    R = size * 0.13
    r2 = np.maximum(x * x + y * y, 1e-6)
    vx = 1 - R * R * (x * x - y * y) / (r2 * r2)
    vy = -2 * R * R * x * y / (r2 * r2)
    flow = np.degrees(np.arctan2(vy, vx))
    ring = np.degrees(np.arctan2(y, x)) + 90.0
    return np.where(r2 < (0.8 * R) ** 2, ring, flow)


def strokes(d: ImageDraw.ImageDraw, x0: int, y0: int, angle: np.ndarray, across: bool) -> None:
    """Short strokes every 40 px along the exemplar's x (or across it)."""
    for y in range(20, SIZE, 40):
        for x in range(20, SIZE, 40):
            a = np.radians(angle[y, x] + (90.0 if across else 0.0))
            dx, dy = 9 * np.cos(a), 9 * np.sin(a)
            d.line((x0 + x - dx, y0 + y - dy, x0 + x + dx, y0 + y + dy), fill=(255, 200, 60), width=2)


def main(out: str) -> None:
    brick = itx.load_exemplar(os.path.join(itx.ASSETS, "brick.png"))
    wood = wood_grain()
    gravel = os.path.join(itx.ASSETS, "gravel.png")
    ys, xs = np.mgrid[0:SIZE, 0:SIZE] + 0.5
    circle = np.degrees(np.arctan2(ys - SIZE / 2, xs - SIZE / 2))
    wave = np.degrees(np.arctan2(-np.ones_like(xs), 0.8 * np.cos(xs / 45.0))) + 180.0
    knot = knot_angles(SIZE)
    scale = np.exp(np.linspace(np.log(0.5), np.log(2.0), SIZE))[None, :].repeat(SIZE, axis=0)
    cases = [(brick, itx.direction_field(circle), circle, True), (brick, itx.direction_field(wave), wave, True),
             (wood, itx.direction_field(knot), knot, False),
             (gravel, itx.DirectionField.from_jacobians(itx.jacobian(0.0, scale), 0, 0), None, False)]
    panels = [itx.synthesize(src.pixels if hasattr(src, "pixels") else src, (SIZE, SIZE), seed=2,
                             controls=itx.Controls(direction=f)) for src, f, _, _ in cases]
    pad = 16
    W = CELL + SIZE * 4 + 6 * pad
    H = SIZE + 2 * pad + 24
    fig = Image.new("RGB", (W, H), (30, 30, 30))
    d = ImageDraw.Draw(fig)
    fig.paste(Image.fromarray(to_rgb8(brick.pixels)), (pad, pad + 24))
    fig.paste(Image.fromarray(to_rgb8(wood)), (pad, pad + 24 + CELL + 24))
    d.text((pad, pad), "exemplars", fill=(230, 230, 230))
    labels = ["courses round a circle", "courses along a wave", "wood grain around a knot",
              "gravel growing 0.5x to 2x"]
    for i, img in enumerate(panels):
        x0 = CELL + (i + 2) * pad + i * SIZE
        fig.paste(Image.fromarray(to_rgb8(img.astype(np.float32) / 255)), (x0, pad + 24))
        angle, across = cases[i][2], cases[i][3]
        if angle is not None:
            strokes(d, x0, pad + 24, angle, across)
        d.text((x0, pad), labels[i], fill=(230, 230, 230))
    itx.write_png(out, np.asarray(fig))
    print(f"wrote {out}")


if __name__ == "__main__":
    main(sys.argv[1] if len(sys.argv) > 1 else os.path.join(ROOT, "docs", "direction.png"))
