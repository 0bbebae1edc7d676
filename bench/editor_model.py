"""The editor's frame rate with a model open, while orbiting and at rest.

    xvfb-run -a -s "-screen 0 1280x800x24" python -m bench.editor_model [--json OUT.json]

The real editor (1280 x 800 window) driven by the imgui test engine: the
bundled brick at Variety on a 50,400-triangle vase (generated, unwrapped by
xatlas) at the default texture size; once its texture is done, 60 moves of the
middle button (orbiting), then 30 frames at rest (synthesis magnification).
Prints the frames per second, writes JSON.
"""
from __future__ import annotations

import argparse
import json
import os
import sys
import tempfile
import time

HERE = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, HERE)
sys.path.insert(0, os.path.join(HERE, "tests", "app"))


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--json", default=None)
    args = ap.parse_args()
    import trimesh
    from gui_harness import Harness

    from infinitex import ASSETS
    from infinitex.engine.surface.shapes import vase
    out = tempfile.mkdtemp(prefix="infinitex-bench-model-")
    os.environ.setdefault("INFINITEX_STATE", os.path.join(out, "state"))
    m = vase(segments=200, rings=125)
    path = os.path.join(out, "vase.glb")
    trimesh.Trimesh(m.positions, m.faces, visual=trimesh.visual.TextureVisuals(uv=m.uvs), process=False).export(path)
    h = Harness(out, os.path.join(ASSETS, "brick.png"), window_size=(1280, 800))
    ed = h.ed
    result = {}

    def test(ctx) -> None:
        h.settle(ctx)
        ctx.set_ref("//Infinitex")
        ctx.item_input_value("//**/Structure", 0)
        h.settle(ctx)
        ctx.menu_click("File/Open model...")
        ctx.yield_(2)
        ctx.item_input_value("//**/##path", path)
        ctx.yield_(3)
        t0 = time.perf_counter()
        h.settle(ctx, 900)
        result["texture_s"] = round(time.perf_counter() - t0, 1)
        r = ctx.item_info("//**/canvas").rect_full
        cx, cy = (r.min.x + r.max.x) / 2, (r.min.y + r.max.y) / 2
        ctx.mouse_move_to_pos((cx, cy))
        ctx.mouse_down(2)
        t0, f0 = time.perf_counter(), ed.frame_count
        for i in range(60):
            ctx.mouse_move_to_pos((cx + 3 * (i % 40), cy + (i % 7)))
        dt, frames = time.perf_counter() - t0, ed.frame_count - f0
        ctx.mouse_up(2)
        result["orbit_fps"] = round(frames / dt, 1)
        t0, f0 = time.perf_counter(), ed.frame_count
        ctx.yield_(30)
        result["rest_fps"] = round((ed.frame_count - f0) / (time.perf_counter() - t0), 1)
        result.update(triangles=len(m.faces), texture_size=ed.doc.surface.size, canvas=list(ed.canvas_size),
                      renderer=ed.renderer)
        h.check("measured", True)

    rc = h.run(test)
    print(f"model view, {result.get('triangles')} triangles, {result.get('texture_size')} px texture, canvas "
          f"{result.get('canvas')}: texture in {result.get('texture_s')} s; orbiting {result.get('orbit_fps')} fps, "
          f"at rest {result.get('rest_fps')} fps ({result.get('renderer')})")
    if args.json:
        with open(args.json, "w") as f:
            json.dump(result, f, indent=1)
    return rc


if __name__ == "__main__":
    sys.exit(main())
