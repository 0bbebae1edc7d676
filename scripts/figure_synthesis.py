"""Make docs/synthesis.png: exemplar | 256 x 256 window at (123456, -98765),
default settings, for gravel, brick and grass, side by side.

    .venv/bin/python scripts/figure_synthesis.py [OUT.png]
"""
import os
import sys

import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, ROOT)

from infinitex.engine.analysis import analyze  # noqa: E402
from infinitex.engine.exemplar import load_exemplar  # noqa: E402
from infinitex.engine.imagefile import to_rgb8, write_png  # noqa: E402
from infinitex.engine.params import DEFAULT_STRUCTURE, SynthParams, structure_params  # noqa: E402
from infinitex.engine.pyramid import Rect  # noqa: E402
from infinitex.engine.synth import Synthesizer  # noqa: E402


def main(out: str) -> None:
    n, gap = 256, 8
    pairs = []
    for name in ("gravel", "brick", "grass"):
        ex = load_exemplar(os.path.join(ROOT, "infinitex", "assets", f"{name}.png"))
        an = analyze(ex)
        with Synthesizer(an, structure_params(SynthParams.default(an.L), DEFAULT_STRUCTURE)) as synth:
            img = to_rgb8(synth.colors(synth.window(Rect.of(123456, -98765, n, n))))
        exu = np.full((n, ex.size, 3), 255, np.uint8)
        exu[:ex.size] = to_rgb8(ex.pixels)
        pairs.append(np.concatenate([exu, np.full((n, 4, 3), 255, np.uint8), img,
                                     np.full((n, gap, 3), 255, np.uint8)], axis=1))
    write_png(out, np.concatenate(pairs, axis=1)[:, :-gap])


if __name__ == "__main__":
    main(sys.argv[1] if len(sys.argv) > 1 else os.path.join(ROOT, "docs", "synthesis.png"))
