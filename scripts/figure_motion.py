"""docs/motion.png: every 4th frame of 32 of the bundled gravel bed and grass
swirling in a vortex (the field bench.flow measures), ours (engine/advect.py).

    .venv/bin/python scripts/figure_motion.py
"""
import os
import sys

import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, ROOT)

from bench.flow import ORIGIN, fields, velocity_map  # noqa: E402
from infinitex import ASSETS  # noqa: E402
from infinitex.engine.advect import FlowFrames, SynthSource  # noqa: E402
from infinitex.engine.analysis import analyze  # noqa: E402
from infinitex.engine.controls.flow import Flow  # noqa: E402
from infinitex.engine.exemplar import load_exemplar  # noqa: E402
from infinitex.engine.imagefile import to_rgb8, write_png  # noqa: E402
from infinitex.engine.pyramid import Rect  # noqa: E402
from infinitex.engine.synth import Synthesizer  # noqa: E402

rows = []
flow = Flow(map=velocity_map(fields(256)["vortex"]))
flow = Flow(map=flow.map, period=flow.suggested_period())
for name in ("gravel_bed.png", "grass.png"):
    with Synthesizer(analyze(load_exemplar(os.path.join(ASSETS, name)))) as s:
        ff = FlowFrames(SynthSource(s), flow, seed=1)
        frames = [to_rgb8(s.colors(ff.frame(t, Rect.of(ORIGIN[0] + 64, ORIGIN[1] + 64, 128, 128))))
                  for t in range(0, 32)]
    gap = np.full((128, 4, 3), 255, np.uint8)
    rows.append(np.concatenate([x for t in range(0, 32, 4) for x in (frames[t], gap)][:-1], 1))
out = np.concatenate([rows[0], np.full((4, rows[0].shape[1], 3), 255, np.uint8), rows[1]], 0)
write_png(os.path.join(ROOT, "docs", "motion.png"), out)
print("wrote docs/motion.png", out.shape[1], "x", out.shape[0])
