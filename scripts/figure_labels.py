"""Make docs/labels.png: texture by numbers.

    .venv/bin/python scripts/figure_labels.py [OUT.png]

Left to right: the exemplar (the bundled CC0 grass and gravel side by side,
tinted green and warm, shown 2x) with its label map in color over its lower half, the label map
painted on the canvas (a gravel path through grass, a gravel pond), and the
synthesized 384 x 384 window at the default Structure (bench/labels.py's
exemplar and path).
"""
import os
import sys

import numpy as np
from PIL import Image, ImageDraw

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, ROOT)

from bench.labels import ORIGIN, SIZE, exemplar  # noqa: E402
from infinitex.engine.analysis import analyze  # noqa: E402
from infinitex.engine.controls import CanvasLabels, Controls, ExemplarLabels  # noqa: E402
from infinitex.engine.exemplar import from_array  # noqa: E402
from infinitex.engine.imagefile import to_rgb8, write_png  # noqa: E402
from infinitex.engine.params import SynthParams, structure_params, DEFAULT_STRUCTURE  # noqa: E402
from infinitex.engine.pyramid import Rect  # noqa: E402
from infinitex.engine.synth import Synthesizer  # noqa: E402

COLORS = np.array([(60, 180, 75), (245, 130, 48)], np.uint8)  # grass green, gravel orange


def main(out: str) -> None:
    gray = exemplar("grass", "gravel")[..., :1]
    tint = np.where(np.arange(128)[None, :, None] < 64, [[[0.55, 0.85, 0.35]]], [[[0.95, 0.8, 0.6]]])
    px = np.ascontiguousarray(np.clip(gray * tint * 1.1, 0, 1), dtype=np.float32)  # green grass, warm gravel
    ids = np.zeros((128, 128), np.uint8)
    ids[:, 64:] = 1
    ys, xs = np.mgrid[0:SIZE, 0:SIZE]
    target = (np.abs(ys - SIZE / 2 - 70 * np.sin(xs / 55.0)) < 26) | (np.hypot(xs - 290, ys - 90) < 55)
    target = target.astype(np.uint8)
    an = analyze(from_array(px, toroidal=False))
    controls = Controls(labels_exemplar=ExemplarLabels(ids),
                        labels_canvas=CanvasLabels.from_image(target + 1, *ORIGIN))
    params = structure_params(SynthParams.default(an.L, seed=1), DEFAULT_STRUCTURE)
    with Synthesizer(an, params, controls=controls) as s:
        result = to_rgb8(s.colors(s.window(Rect.of(ORIGIN[0], ORIGIN[1], SIZE, SIZE))))
    ex = np.asarray(Image.fromarray(to_rgb8(px)).resize((256, 256), Image.NEAREST)).copy()
    lab = COLORS[np.repeat(np.repeat(ids, 2, 0), 2, 1)]
    ex[128:] = (0.45 * ex[128:] + 0.55 * lab[128:]).astype(np.uint8)
    pad = 16
    W = 256 + SIZE * 2 + 4 * pad
    H = SIZE + 2 * pad + 24
    canvas = Image.new("RGB", (W, H), (30, 30, 30))
    canvas.paste(Image.fromarray(ex), (pad, pad + 24))
    canvas.paste(Image.fromarray(COLORS[target]), (256 + 2 * pad, pad + 24))
    canvas.paste(Image.fromarray(result), (256 + SIZE + 3 * pad, pad + 24))
    d = ImageDraw.Draw(canvas)
    for x, text in ((pad, "exemplar and its labels"), (256 + 2 * pad, "labels painted on the canvas"),
                    (256 + SIZE + 3 * pad, "synthesized")):
        d.text((x, pad), text, fill=(230, 230, 230))
    write_png(out, np.asarray(canvas))
    print(f"wrote {out}")


if __name__ == "__main__":
    main(sys.argv[1] if len(sys.argv) > 1 else os.path.join(ROOT, "docs", "labels.png"))
