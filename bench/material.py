"""What a material costs over a single map (issue 11).

    python -m bench.material [--size 2048] [--frames 30] [--json OUT.json]

On the shipped cobblestone material (infinitex/assets/cobbles: 512^2 base
color, 16-bit normal and height, roughness), in one process and one GL
context, after the analysis is cached:

- **Export throughput** of a SIZE x SIZE rectangle (``ExportJob``, the code
  behind File > Export and ``infinitex export``): 1 map (the base color) and
  all 4 maps, each at its own depth; Mpixel/s of the output rectangle, with
  the synthesis and the per-map lookup + encode + write split out.
- **Lit preview frame time** on a 904 x 726 canvas (the editor's canvas at
  its default window size), at 25%, 100% and 400% zoom, against the plain
  color display: the median of ``--frames`` draws, each waited for (glFinish).
"""
from __future__ import annotations

import argparse
import json
import os
import statistics
import sys
import tempfile
import time

HERE = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, HERE)

from infinitex.project import Display, Document, ExemplarSource, View  # noqa: E402
from infinitex.app.render.canvas import Canvas  # noqa: E402
from infinitex.app.session import Session, frame_for  # noqa: E402
from infinitex.export.window import ExportJob  # noqa: E402
from infinitex.engine.gpu import Gpu  # noqa: E402
from infinitex.engine.material import assign_roles  # noqa: E402
from infinitex.engine.pyramid import Rect  # noqa: E402

COBBLES = os.path.join(HERE, "infinitex", "assets", "cobbles")
CANVAS = (904, 726)


def export_rates(session: Session, n: int, folder: str) -> list[dict]:
    rows = []
    rect = Rect.of(-n // 2, 1000, n, n)
    for label, maps in (("1 map (base color)", ["basecolor"]), ("4 maps", None)):
        job = ExportJob(session, rect, os.path.join(folder, "bench.png"), maps=maps, tile=512)
        t0 = time.perf_counter()
        while job.index < len(job.tiles):  # the synthesis, tile by tile, as step() does
            t = job.tiles[job.index]
            job.pyramid.request(job.L, t)
            c = job.pyramid.read(job.L, t)
            job.coords[t.y0 - job.rect.y0:t.y1 - job.rect.y0, t.x0 - job.rect.x0:t.x1 - job.rect.x0] = c
            job.index += 1
        t1 = time.perf_counter()
        job._write()
        t2 = time.perf_counter()
        job._close()
        files = sum(os.path.getsize(p) for _, p, _ in job.outputs)
        rows.append(dict(maps=label, count=len(job.outputs), seconds=t2 - t0, synthesis_s=t1 - t0,
                         maps_s=t2 - t1, mpx_per_s=n * n / (t2 - t0) / 1e6, bytes=files))
    return rows


def frame_times(session: Session, gpu: Gpu, frames: int) -> list[dict]:
    canvas = Canvas(gpu)
    canvas.ensure_size(*CANVAS)
    kind, role = session.shape_map()
    canvas.set_shape(session.shape_stack(role), kind, session.analysis.toroidal, (session.generation, role))
    ex = session.material.maps["basecolor"].exemplar
    canvas.set_exemplar(session.display_stack("basecolor"), session.analysis.toroidal, ex.hires, session.generation)
    rows = []
    for zoom in (0.25, 1.0, 4.0):
        view = View(300.0, -200.0, zoom)
        frame = frame_for(view, *CANVAS, session.L)
        while not session.refine(frame, 0.5):
            pass
        row = {"zoom": zoom}
        for mode in ("color", "lit"):
            d = Display(mode=mode)
            canvas.render(session.pyramid, frame, view, d)
            gpu.ctx.finish()
            times = []
            for _ in range(frames):
                t0 = time.perf_counter()
                canvas.render(session.pyramid, frame, view, d)
                gpu.ctx.finish()
                times.append(time.perf_counter() - t0)
            row[f"{mode}_ms"] = 1000 * statistics.median(times)
        rows.append(row)
    canvas.release()
    return rows


def main(argv: list[str]) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--size", type=int, default=2048)
    p.add_argument("--frames", type=int, default=30)
    p.add_argument("--json", default=os.path.join(HERE, "bench", "results", "material-llvmpipe.json"))
    a = p.parse_args(argv)
    found = assign_roles([COBBLES])
    maps = [(r, ExemplarSource.from_file(path)) for r, path in found.items()]
    doc = Document(maps[0][1]).with_maps(maps)
    gpu = Gpu()
    session = Session(gpu)
    t0 = time.perf_counter()
    session.load_now(doc)
    load_s = time.perf_counter() - t0
    with tempfile.TemporaryDirectory() as folder:
        exports = export_rates(session, a.size, folder)
    frames = frame_times(session, gpu, a.frames)
    print(f"cobbles material ({', '.join(session.material.roles)}), {gpu.renderer}; opened in {load_s:.1f} s")
    print(f"\nexport of {a.size}x{a.size}")
    print(f"{'maps':<22}{'total s':>9}{'synth s':>9}{'maps s':>9}{'Mpx/s':>8}{'MB':>8}")
    for r in exports:
        print(f"{r['maps']:<22}{r['seconds']:>9.2f}{r['synthesis_s']:>9.2f}{r['maps_s']:>9.2f}"
              f"{r['mpx_per_s']:>8.2f}{r['bytes'] / 1e6:>8.1f}")
    print(f"\nframe time on a {CANVAS[0]}x{CANVAS[1]} canvas (median of {a.frames})")
    print(f"{'zoom':<8}{'color ms':>10}{'lit ms':>10}")
    for r in frames:
        print(f"{r['zoom'] * 100:>5.0f}%  {r['color_ms']:>10.1f}{r['lit_ms']:>10.1f}")
    result = dict(renderer=gpu.renderer, size=a.size, open_s=load_s, exports=exports, frames=frames,
                  canvas=list(CANVAS), date=time.strftime("%Y-%m-%d"))
    os.makedirs(os.path.dirname(a.json), exist_ok=True)
    with open(a.json, "w") as f:
        json.dump(result, f, indent=1)
    session.release()
    gpu.release()
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
