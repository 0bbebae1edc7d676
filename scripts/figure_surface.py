"""Make docs/surface.png: texture on models, continuous across UV seams.

    .venv/bin/python scripts/figure_surface.py [OUT.png]

Three models of our own (generated, CC0: engine/surface/shapes.py): a vase
unwrapped by xatlas into 20-odd charts (the bundled brick; whole, and close to
a seam), a cube whose six faces are separate charts, turned and mirrored in
the atlas (the bundled gravel; a corner), a capped cylinder whose side wraps
around one seam (the bench's weave; that seam). Top row: synthesis in the atlas (ours: neighborhoods read across the
seams); bottom row: the same passes on each chart on its own. The charts'
borders are marked in red on the right quarter of each picture only, so the seams
themselves show on the left.
"""
import os
import sys

import numpy as np
from PIL import Image, ImageDraw

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, ROOT)

from infinitex import ASSETS  # noqa: E402
from infinitex.app.render.model_view import ModelView, OrbitCamera  # noqa: E402
from infinitex.engine.analysis import analyze  # noqa: E402
from infinitex.engine.exemplar import load_exemplar  # noqa: E402
from infinitex.engine.gpu import Gpu  # noqa: E402
from infinitex.engine.imagefile import to_rgb8  # noqa: E402
from infinitex.engine.params import SynthParams, structure_params  # noqa: E402
from infinitex.engine.surface import AtlasDomain  # noqa: E402
from infinitex.engine.surface.bake import atlas_coords, atlas_image  # noqa: E402
from infinitex.engine.surface.shapes import cube, cylinder, vase  # noqa: E402
from infinitex.engine.synth import Synthesizer  # noqa: E402
from infinitex.export.surface import plan  # noqa: E402

CELL = 400


def seam_close_up(model, size: int) -> OrbitCamera:
    """A camera close to a seam at mid height of the model, looking at it along its normal."""
    atlas = AtlasDomain(model, size, 1.0)
    P = model.positions
    keep = atlas.b_other >= 0
    mid = 0.5 * (P[atlas.b_a[keep]] + P[atlas.b_b[keep]])
    y = P[:, 1]
    target_y = y.min() + 0.45 * (y.max() - y.min())
    i = int(np.argmin(np.abs(mid[:, 1] - target_y) + 0.01 * np.arange(len(mid)) / len(mid)))
    c = mid[i]
    yaw = float(np.degrees(np.arctan2(c[0], c[2])))
    return OrbitCamera(target=tuple(c), yaw=yaw, pitch=8.0, distance=0.28 * float(np.ptp(y)))


def main(out: str) -> int:
    v = vase()
    cases = [("vase", v, os.path.join(ASSETS, "brick.png"), 1024, 5.0,
              [OrbitCamera.framing(v.positions, yaw=20.0, pitch=15.0).zoom(1.3), seam_close_up(v, 1024)]),
             ("cube", cube(), os.path.join(ASSETS, "gravel.png"), 512, 2.0,
              [OrbitCamera(target=(0.7, 0.7, 0.7), yaw=45.0, pitch=30.0, distance=2.4)]),
             ("cylinder", cylinder(), os.path.join(ROOT, "bench", "exemplars", "weave.png"), 512, 3.0,
              [OrbitCamera(target=(0.0, 0.2, 1.0), yaw=0.0, pitch=10.0, distance=1.6)])]
    gpu = Gpu()
    rows = [[], []]
    try:
        for name, model, path, size, repeats, cams in cases:
            an = analyze(load_exemplar(path))
            pl = plan(model, size, an.size, repeats=repeats)
            params = structure_params(SynthParams.default(an.L, seed=5), 2)
            with Synthesizer(an, params, gpu=gpu) as synth:
                for r, seams in enumerate((True, False)):
                    atlas = AtlasDomain(model, size, pl.sigma, seams=seams)
                    img = to_rgb8(atlas_image(an.levels[an.L].stack, atlas_coords(synth, atlas), atlas,
                                              an.toroidal))
                    own = atlas.owner(0)
                    border = np.zeros_like(own, bool)
                    border[:, 1:] |= own[:, 1:] != own[:, :-1]
                    border[1:] |= own[1:] != own[:-1]
                    border &= own >= 0
                    gpu.activate()
                    view = ModelView(gpu.ctx, model.positions, model.faces, model.uvs)
                    view.set_texture(img)
                    view.set_seams(border)
                    for cam in cams:
                        plain = view.render(cam, (CELL, CELL))
                        marked = view.render(cam, (CELL, CELL), mode=2)
                        pic = plain.copy()
                        pic[:, 3 * CELL // 4:] = marked[:, 3 * CELL // 4:]
                        rows[r].append(pic)
                    view.release()
            print(name, "done", flush=True)
    finally:
        gpu.release()
    top, bottom = np.concatenate(rows[0], axis=1), np.concatenate(rows[1], axis=1)
    pad = 22
    canvas = Image.new("RGB", (top.shape[1], 2 * CELL + 2 * pad), (24, 25, 28))
    canvas.paste(Image.fromarray(top), (0, pad))
    canvas.paste(Image.fromarray(bottom), (0, 2 * pad + CELL))
    d = ImageDraw.Draw(canvas)
    d.text((8, 5), "synthesis in the atlas, across the seams (ours)  -  right quarters: chart borders in red",
           fill=(230, 230, 230))
    d.text((8, pad + CELL + 5), "the same passes on each chart on its own", fill=(230, 230, 230))
    canvas.save(out)
    print(out)
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1] if len(sys.argv) > 1 else os.path.join(ROOT, "docs", "surface.png")))
