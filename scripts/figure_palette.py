"""Make docs/palette.png: texture by numbers across a palette of exemplars.

    .venv/bin/python scripts/figure_palette.py [OUT.png]

Left: three separate exemplars (the bundled CC0 grass, gravel and brick,
tinted green, warm and red), each one label (its color beside it); middle:
the labels painted on the canvas (a gravel path between grass and a brick
plaza); right: the synthesized 384 x 384 window at the default Structure.
"""
import os
import sys

import numpy as np
from PIL import Image, ImageDraw

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, ROOT)

import infinitex as itx  # noqa: E402
from infinitex.engine.controls.labels import LABEL_COLORS  # noqa: E402
from infinitex.engine.imagefile import to_rgb8  # noqa: E402

SIZE = 384
TINTS = {"grass": (0.55, 0.85, 0.35), "gravel": (0.95, 0.8, 0.6), "brick": (0.95, 0.55, 0.45)}


def main(out: str) -> None:
    exs = []
    for name, tint in TINTS.items():
        gray = itx.load_exemplar(os.path.join(itx.ASSETS, f"{name}.png")).pixels[..., :1]
        exs.append(np.clip(gray * np.array(tint, np.float32) * 1.1, 0, 1).astype(np.float32))
    ex, layout = itx.palette(exs)
    ys, xs = np.mgrid[0:SIZE, 0:SIZE]
    path = np.abs(ys - SIZE / 2 - 60 * np.sin(xs / 60.0)) < 22
    plaza = np.maximum(np.abs(xs - 280), np.abs(ys - 290)) < 70
    canvas = np.where(path, 1, np.where(plaza, 2, 0))
    result = itx.synthesize(ex, (SIZE, SIZE), (1000, -2000), seed=1, labels=(layout.labels(), canvas, (1000, -2000)))
    colors = np.array(LABEL_COLORS[:3], np.uint8)
    pad, cell = 16, 112
    W = cell + 24 + SIZE * 2 + 4 * pad
    H = SIZE + 2 * pad + 24
    fig = Image.new("RGB", (W, H), (30, 30, 30))
    d = ImageDraw.Draw(fig)
    for i, px in enumerate(exs):
        y = pad + 24 + i * (cell + 24)
        fig.paste(Image.fromarray(to_rgb8(px)).resize((cell, cell), Image.LANCZOS), (pad, y))
        d.rectangle((pad + cell + 6, y, pad + cell + 18, y + cell - 1), fill=tuple(int(c) for c in colors[i]))
    fig.paste(Image.fromarray(colors[canvas]), (cell + 24 + 2 * pad, pad + 24))
    fig.paste(Image.fromarray(to_rgb8(result.astype(np.float32) / 255)), (cell + 24 + SIZE + 3 * pad, pad + 24))
    for x, text in ((pad, "three exemplars"), (cell + 24 + 2 * pad, "labels painted on the canvas"),
                    (cell + 24 + SIZE + 3 * pad, "synthesized")):
        d.text((x, pad), text, fill=(230, 230, 230))
    itx.write_png(out, np.asarray(fig))
    print(f"wrote {out}")


if __name__ == "__main__":
    main(sys.argv[1] if len(sys.argv) > 1 else os.path.join(ROOT, "docs", "palette.png"))
