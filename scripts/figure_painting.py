"""Make docs/painting.png: windows without and with a painted canvas map.

    .venv/bin/python scripts/figure_painting.py [OUT.png]

For each exemplar: a 384 x 192 window with no map, and the same window with
the left third painted calm (0) and the right third rough (2), side by side
vertically; exemplars side by side horizontally.
"""
import os
import sys

import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, ROOT)

from infinitex.engine.analysis import analyze  # noqa: E402
from infinitex.engine.controls import NEUTRAL, CanvasField, Controls  # noqa: E402
from infinitex.engine.exemplar import load_exemplar  # noqa: E402
from infinitex.engine.imagefile import to_u8, write_png  # noqa: E402
from infinitex.engine.params import DEFAULT_STRUCTURE, SynthParams, structure_params  # noqa: E402
from infinitex.engine.pyramid import Rect  # noqa: E402
from infinitex.engine.synth import Synthesizer  # noqa: E402


def main(out: str) -> None:
    w, h, gap = 384, 192, 6
    columns = []
    for name in ("brick", "gravel"):
        ex = load_exemplar(os.path.join(ROOT, "infinitex", "assets", f"{name}.png"))
        an = analyze(ex)
        field = np.full((h, w), NEUTRAL, np.uint16)
        field[:, : w // 3] = 0
        field[:, 2 * w // 3:] = 65535
        rows = []
        for controls in (Controls(), Controls(None, CanvasField.from_image(field, 0, 0))):
            synth = Synthesizer(an, structure_params(SynthParams.default(an.L, seed=3), DEFAULT_STRUCTURE),
                                controls=controls)
            img = to_u8(synth.colors(synth.window(Rect.of(0, 0, w, h))))
            synth.release()
            rows.append(np.repeat(img, 3, axis=2) if img.shape[2] == 1 else img[..., :3])
        columns.append(np.concatenate([rows[0], np.full((gap, w, 3), 255, np.uint8), rows[1]], axis=0))
    sheet = np.concatenate([columns[0], np.full((columns[0].shape[0], gap, 3), 255, np.uint8), columns[1]], axis=1)
    write_png(out, sheet)
    print(f"wrote {out}")


if __name__ == "__main__":
    main(sys.argv[1] if len(sys.argv) > 1 else os.path.join(ROOT, "docs", "painting.png"))
