"""Make docs/direction.png: direction fields, the texture following curves.

    .venv/bin/python scripts/figure_direction.py [OUT.png]

Left: the bundled CC0 brick exemplar (its bricks stand upright); then three
384 x 384 windows at the default Structure, each with a direction field over
the whole window (drawn as short strokes over the first two): brick courses
going round in circles, courses following a wave, and gravel growing from
half size at the left to twice its size at the right.
"""
import os
import sys

import numpy as np
from PIL import Image, ImageDraw

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, ROOT)

import infinitex as itx  # noqa: E402
from infinitex.engine.imagefile import to_rgb8  # noqa: E402

SIZE = 384


def strokes(d: ImageDraw.ImageDraw, x0: int, y0: int, angle: np.ndarray) -> None:
    """Short strokes along the exemplar's +y (the courses) every 48 px."""
    for y in range(24, SIZE, 48):
        for x in range(24, SIZE, 48):
            a = np.radians(angle[y, x] + 90.0)
            dx, dy = 10 * np.cos(a), 10 * np.sin(a)
            d.line((x0 + x - dx, y0 + y - dy, x0 + x + dx, y0 + y + dy), fill=(255, 200, 60), width=2)


def main(out: str) -> None:
    brick = os.path.join(itx.ASSETS, "brick.png")
    gravel = os.path.join(itx.ASSETS, "gravel.png")
    ys, xs = np.mgrid[0:SIZE, 0:SIZE] + 0.5
    circle = np.degrees(np.arctan2(ys - SIZE / 2, xs - SIZE / 2))
    # courses along y = 40 sin(x / 50): +x across them, i.e. the wave's normal
    wave = np.degrees(np.arctan2(-np.ones_like(xs), 0.8 * np.cos(xs / 50.0))) + 180.0
    scale = np.exp(np.linspace(np.log(0.5), np.log(2.0), SIZE))[None, :].repeat(SIZE, axis=0)
    panels = []
    for src, field in ((brick, itx.direction_field(circle)), (brick, itx.direction_field(wave)),
                       (gravel, itx.DirectionField.from_jacobians(itx.jacobian(0.0, scale), 0, 0))):
        panels.append(itx.synthesize(src, (SIZE, SIZE), seed=2, controls=itx.Controls(direction=field)))
    pad, cell = 16, 128
    W = cell + SIZE * 3 + 5 * pad
    H = SIZE + 2 * pad + 24
    fig = Image.new("RGB", (W, H), (30, 30, 30))
    d = ImageDraw.Draw(fig)
    ex = itx.load_exemplar(brick).pixels
    fig.paste(Image.fromarray(to_rgb8(ex)), (pad, pad + 24))
    labels = ["exemplar", "courses round a circle", "courses along a wave", "gravel growing 0.5x to 2x"]
    d.text((pad, pad), labels[0], fill=(230, 230, 230))
    for i, img in enumerate(panels):
        x0 = cell + (i + 2) * pad + i * SIZE
        fig.paste(Image.fromarray(to_rgb8(img.astype(np.float32) / 255)), (x0, pad + 24))
        if i < 2:
            strokes(d, x0, pad + 24, (circle, wave)[i])
        d.text((x0, pad), labels[i + 1], fill=(230, 230, 230))
    itx.write_png(out, np.asarray(fig))
    print(f"wrote {out}")


if __name__ == "__main__":
    main(sys.argv[1] if len(sys.argv) > 1 else os.path.join(ROOT, "docs", "direction.png"))
