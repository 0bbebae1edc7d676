"""Quality and speed side by side: this project, the exemplar tiled, and G'MIC.

    python -m bench.quality [--json OUT.json] [--sheet OUT.png] [--sizes 256 512] [--exemplars DIR ...]

For every exemplar (default ``../shared/exemplars`` and our own structured ones,
``bench/exemplars``: spots, cells, cracks, weave, text) and output size it
measures (bench/measures.py):

- ``energy`` / ``completeness``: multi-scale 5x5 neighborhood matching, output
  to exemplar and back (mean squared difference per value; lower is better);
- ``coverage`` (0..1, 1 = every exemplar pixel used equally often) and ``used``
  (fraction of exemplar pixels used), from the coordinate map (ours, tiled);
- ``verbatim_mean_px`` (area-weighted mean size of regions copied verbatim)
  and ``verbatim_max_px``, from the coordinate map;
- ``copied``: the fraction of the output's 5x5 windows found in the exemplar
  (every value within 2/255), from the pixels alone, so for the peer too (how
  much is copied);
- ``repetition``: highest autocorrelation peak away from the origin (1 = tiled);
- ``histogram``: mean 1-D Wasserstein distance of the value histograms;
- ``sheared`` (fraction of neighbor pairs one exemplar pixel off: zipper lines
  when magnified), ``usage_peak`` (the most used 16 px block of the
  exemplar over the mean) and ``straight_runs`` (seams running straight for
  12 px or more, per 1000 neighbor pairs; see bench.straight_seams), from the
  coordinate map;
- ``ps``: Portilla-Simoncelli texture-statistics distance (plenoptic on CPU
  torch, luminance, 4 scales x 4 orientations; relative difference per group
  of statistics, averaged; 0 = the exemplar's statistics).

and, over all exemplars, the medians of each measure per method and size, with
ours / peer ratios and how many exemplars each method wins.

for ``ours`` (default settings, a window at canvas position (10007, -20011)),
``tiled`` (the exemplar repeated) and ``peer`` (G'MIC ``syntexturize_matchpatch``,
``pip install gmic``: a benchmark-only dependency, see requirements-bench.txt).
Times: ``warm_s`` (ours: a window call with the analysis cached and shaders
compiled; peer: a second in-process ``gmic.run``) and ``cold_s`` (each as a
whole command in a fresh process with a cold analysis cache), with
``peer / ours`` ratios. Writes a contact sheet (exemplar | ours | tiled | peer |
ours in lattice mode).

``default`` is what the default path makes: ours in lattice mode where the
lattice is detected with confidence (an image opened or synthesized without
``--lattice``), else ours; the summary gives its medians and ratios too.

Near-regular exemplars (a lattice detected, or the best guess for the shared
brick and reptile skin) are also synthesized in lattice mode (engine/controls/lattice.py,
in the input's geometry, brought to the exemplar's scale) and every method gets
a ``lattice_regularity``: the autocorrelation at the two lattice vectors, output
over exemplar (1 = as regular as the exemplar).
"""
from __future__ import annotations

import argparse
import glob
import json
import os
import subprocess
import sys
import tempfile
import time

import numpy as np
from PIL import Image

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, ROOT)

from bench.measures import all_measures  # noqa: E402
from infinitex.engine.analysis import (
    AnalysisSettings,  # noqa: E402
    analyze,  # noqa: E402
)
from infinitex.engine.controls import Controls  # noqa: E402
from infinitex.engine.controls.lattice import (  # noqa: E402
    autocorrelation_at,
    original_geometry_box,
    rectified_exemplar,
    render_original,
)
from infinitex.engine.controls.lattice_block import choose_block  # noqa: E402
from infinitex.engine.controls.lattice_detect import detect  # noqa: E402
from infinitex.engine.exemplar import load_exemplar, load_full  # noqa: E402
from infinitex.engine.imagefile import PIL_MODES, to_rgb8, to_u8, write_png  # noqa: E402
from infinitex.engine.params import DEFAULT_STRUCTURE, SynthParams, structure_params  # noqa: E402
from infinitex.engine.pyramid import Rect  # noqa: E402
from infinitex.engine.synth import Synthesizer  # noqa: E402

ORIGIN = (10007, -20011)
NEAR_REGULAR = ("brick", "reptile_skin")  # below the detector's threshold: the best guess is used


def lattice_case(path: str, name: str, fitted_size: int):
    """(lattice, image, scale, found) for a near-regular exemplar, else None.
    ``scale`` is fitted-exemplar pixels per input pixel (the resize fit rule);
    ``found``: the default path uses it (detected with confidence), else it is
    the detector's best guess."""
    img = load_full(path)
    d = detect(img)
    lat = d.lattice
    if lat is None and name in NEAR_REGULAR and d.t1 is not None:
        lat = choose_block(d.t1, d.t2, img.shape[1], img.shape[0])
    if lat is None:
        return None
    return lat, img, fitted_size / min(img.shape[:2]), d.lattice is not None


def lattice_output(lat, img, n: int, scale: float, structure: int) -> np.ndarray:
    """n x n of lattice mode in the input's geometry, at the fitted exemplar's scale."""
    ex = rectified_exemplar(img, lat)
    an = analyze(ex, AnalysisSettings(lattice=(lat.nx, lat.ny)))
    synth = Synthesizer(an, structure_params(SynthParams.default(an.L), structure), controls=Controls(lattice=lat))
    w = int(round(n / scale))
    x0, y0 = ORIGIN[0] // 4, ORIGIN[1] // 4
    box = original_geometry_box(lat, an.size, x0, y0, w, w)
    try:
        coords = synth.window(Rect(*box))
    finally:
        synth.release()
    src = ex.hires if ex.hires is not None else ex.pixels
    out = render_original(coords, box, lat, an.size, src, x0, y0, w, w)
    planes = [np.asarray(Image.fromarray(out[:, :, c], mode="F").resize((n, n), Image.LANCZOS))
              for c in range(out.shape[2])]
    return np.clip(np.stack(planes, axis=2), 0.0, 1.0)


def regularity(exemplar: np.ndarray, out: np.ndarray, vectors) -> list[float]:
    return [round(autocorrelation_at(out, v) / max(1e-9, autocorrelation_at(exemplar, v)), 3) for v in vectors]


def _save(path: str, a: np.ndarray) -> None:
    a = to_u8(a)
    Image.fromarray(a[..., 0] if a.shape[2] == 1 else a).save(path)


def _load_as(path: str, channels: int) -> np.ndarray:
    img = Image.open(path)
    img = img.convert(PIL_MODES[channels])
    a = np.asarray(img, dtype=np.float32) / 255.0
    return a[..., None] if a.ndim == 2 else a


def _timed(cmd: list[str], env: dict) -> float:
    t = time.perf_counter()
    r = subprocess.run(cmd, env=env, capture_output=True, text=True, cwd=ROOT)
    if r.returncode != 0:
        raise RuntimeError(f"{' '.join(cmd)} failed: {r.stderr[-500:]}")
    return time.perf_counter() - t


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--json", metavar="OUT.json")
    ap.add_argument("--sheet", metavar="OUT.png", default=os.path.join(ROOT, "out", "contact-sheet.png"))
    ap.add_argument("--sizes", nargs="+", type=int, default=[256, 512])
    ap.add_argument("--fidelity", type=int, default=DEFAULT_STRUCTURE, metavar="PRESET",
                    help=f"Structure preset of ours (default {DEFAULT_STRUCTURE}, the documents' default)")
    ap.add_argument("--exemplars", nargs="+", default=[os.path.join(os.path.dirname(ROOT), "shared", "exemplars"),
                                                       os.path.join(ROOT, "bench", "exemplars")])
    ap.add_argument("--no-ps", action="store_true",
                    help="skip the Portilla-Simoncelli distance (where plenoptic and torch cannot be installed)")
    args = ap.parse_args(argv)
    ps = not args.no_ps
    try:
        import gmic
        if ps:
            import plenoptic  # noqa: F401  (the Portilla-Simoncelli statistics)
    except ImportError:
        sys.stderr.write("bench.quality needs the peer: run `bash scripts/setup.sh --bench` "
                         "(or .venv/bin/pip install -r requirements-bench.txt)\n")
        return 2
    paths = [p for folder in args.exemplars for p in sorted(glob.glob(os.path.join(folder, "*")))
             if p.lower().endswith((".png", ".jpg", ".jpeg", ".bmp", ".tif", ".tiff", ".webp"))]
    if not paths:
        sys.stderr.write(f"no exemplars in {args.exemplars}\n")
        return 2
    tmp = tempfile.mkdtemp(prefix="infinitex-quality-")
    results: dict = {"sizes": args.sizes, "origin": list(ORIGIN), "structure": args.fidelity, "exemplars": {}}
    sheet_rows = []
    renderer = None
    for path in paths:
        name = os.path.splitext(os.path.basename(path))[0]
        ex = load_exemplar(path)
        an = analyze(ex)
        synth = Synthesizer(an, structure_params(SynthParams.default(an.L), args.fidelity))
        renderer = synth.gpu.renderer
        m = ex.size
        ex_png = os.path.join(tmp, f"{name}.png")
        _save(ex_png, ex.pixels)  # the peer gets exactly the exemplar we use
        entry = {"size": m, "channels": ex.channels}
        case = lattice_case(path, name, m)
        if case is not None:
            lat, full, scale, found = case
            entry["lattice_found"] = found
            vectors = [(lat.t1[0] * scale, lat.t1[1] * scale), (lat.t2[0] * scale, lat.t2[1] * scale)]
            entry["lattice"] = lat.to_text()
        for n in args.sizes:
            rect = Rect.of(ORIGIN[0], ORIGIN[1], n, n)
            synth.window(Rect.of(0, 0, 32, 32))  # shaders compiled, textures uploaded
            t = time.perf_counter()
            coords = synth.window(rect)
            ours = synth.colors(coords)
            ours_warm = time.perf_counter() - t
            yy, xx = np.mgrid[0:n, 0:n]
            tiled_coords = np.stack([xx % m, yy % m], axis=-1)
            tiled = ex.pixels[tiled_coords[..., 1], tiled_coords[..., 0]]
            peer_png = os.path.join(tmp, f"{name}-peer-{n}.png")
            cmd = f"{ex_png} syntexturize_matchpatch {n},{n} cut 0,255 output {peer_png}"
            gmic.run(cmd)
            t = time.perf_counter()
            gmic.run(cmd)
            peer_warm = time.perf_counter() - t
            peer = _load_as(peer_png, ex.channels)
            env = dict(os.environ, INFINITEX_CACHE=tempfile.mkdtemp(prefix="cold-cache-"))
            ours_cold = _timed([sys.executable, "main.py", "synth", path, "-o", os.path.join(tmp, "o.png"),
                                "--size", str(n), str(n), "--origin", *map(str, ORIGIN), "--fidelity", str(args.fidelity), "-q"], env)
            peer_cold = _timed([sys.executable, "-c", f"import gmic; gmic.run({cmd!r})"], env)
            row = {
                "ours": all_measures(ex.pixels, ours, coords, m, an.toroidal, ps=ps),
                "tiled": all_measures(ex.pixels, tiled, tiled_coords, m, an.toroidal, ps=ps),
                "peer": all_measures(ex.pixels, peer, toroidal=an.toroidal, ps=ps),
                "time": {"ours_warm_s": ours_warm, "peer_warm_s": peer_warm, "ours_cold_s": ours_cold,
                         "peer_cold_s": peer_cold, "warm_ratio_peer_over_ours": peer_warm / ours_warm,
                         "cold_ratio_peer_over_ours": peer_cold / ours_cold},
            }
            lat_out = None
            if case is not None:
                lat_out = lattice_output(lat, full, n, scale, args.fidelity)
                row["lattice"] = all_measures(ex.pixels, lat_out, ps=ps)
                for method, img in (("ours", ours), ("tiled", tiled), ("peer", peer), ("lattice", lat_out)):
                    row[method]["lattice_regularity"] = regularity(ex.pixels, img, vectors)
            # What the default path makes: the lattice where it is found with confidence.
            row["default"] = row["lattice"] if case is not None and found else row["ours"]
            entry[str(n)] = row
            print(f"{name:<13}{n:>5}  ours {ours_warm * 1000:7.0f} ms  peer {peer_warm * 1000:7.0f} ms  "
                  f"(cold {ours_cold:5.1f} s / {peer_cold:5.1f} s)", flush=True)
            if n == args.sizes[0]:
                ex_big = np.asarray(Image.fromarray(to_rgb8(ex.pixels)).resize((n, n), Image.NEAREST))
                blank = np.full((n, n, 3), 40, dtype=np.uint8)
                cells = [ex_big, to_rgb8(ours), to_rgb8(tiled), to_rgb8(peer), blank if lat_out is None else to_rgb8(lat_out)]
                sheet_rows.append(np.concatenate(cells, axis=1))
        results["exemplars"][name] = entry
        synth.release()
    results["renderer"] = renderer
    results["summary"] = summarize(results)
    _print_table(results)
    _print_summary(results["summary"])
    os.makedirs(os.path.dirname(os.path.abspath(args.sheet)), exist_ok=True)
    gap = 4
    rows = [np.pad(r, ((0, gap), (0, 0), (0, 0)), constant_values=255) for r in sheet_rows]
    write_png(args.sheet, np.concatenate(rows, axis=0))
    print(f"contact sheet (exemplar | ours | tiled | peer | ours, lattice mode): {args.sheet}")
    if args.json:
        from infinitex.engine.safeio import atomic_write
        atomic_write(args.json, json.dumps(results, indent=1).encode())
    return 0


SUMMARY_MEASURES = ("energy", "ps", "repetition", "copied", "verbatim_mean_px", "histogram", "sheared", "usage_peak",
                    "straight_runs")


def summarize(results: dict) -> dict:
    """Per size: the median of each measure per method over all exemplars, ours / peer,
    and how many exemplars ours beats the peer on (lower is better for each)."""
    out = {}
    for n in results["sizes"]:
        rows = [e[str(n)] for e in results["exemplars"].values()]
        s: dict = {"exemplars": len(rows)}
        for meas in SUMMARY_MEASURES:
            per = {}
            for method in ("ours", "default", "peer", "tiled"):
                vals = [r[method][meas] for r in rows if method in r and meas in r[method]]
                if vals:
                    per[method] = float(np.median(vals))
            for method in ("ours", "default"):
                if method in per and "peer" in per:
                    per[f"{method}_over_peer"] = per[method] / per["peer"] if per["peer"] else float("inf")
                    per[f"{method}_wins"] = int(sum(r[method][meas] < r["peer"][meas] for r in rows
                                                    if method in r and meas in r[method] and meas in r["peer"]))
            s[meas] = per
        out[str(n)] = s
    return out


def _print_summary(summary: dict) -> None:
    print("\nmedians over all exemplars (lower is better); ours/peer; exemplars where ours beats the peer")
    for n, s in summary.items():
        for meas in SUMMARY_MEASURES:
            d = s.get(meas, {})
            if "ours" not in d:
                continue
            peer = f"peer {d['peer']:.5f}  ours/peer {d['ours_over_peer']:.2f}  ours wins {d['ours_wins']}/{s['exemplars']}" \
                if "peer" in d else ""
            print(f"{n:>5} {meas:<17} ours {d['ours']:.5f}  {peer}")
            if "default_over_peer" in d:
                print(f"{'':>5} {'':<17} default (the lattice where found) {d['default']:.5f}  "
                      f"default/peer {d['default_over_peer']:.2f}  wins {d['default_wins']}/{s['exemplars']}")


def _print_table(results: dict) -> None:
    print(f"\nrenderer: {results['renderer']}")
    hdr = (f"{'exemplar':<13}{'size':>5} {'method':<6}{'energy':>9}{'complete':>9}{'cover':>7}{'used':>6}"
           f"{'verb.mean':>10}{'verb.max':>9}{'repeat':>7}{'copied':>7}{'hist':>7}{'PS':>7}")
    print(hdr)
    for name, entry in results["exemplars"].items():
        for n in results["sizes"]:
            row = entry[str(n)]
            for method in ("ours", "tiled", "peer", "lattice"):
                if method not in row:
                    continue
                d = row[method]
                cov = f"{d['coverage']:7.3f}{d['used']:6.2f}" if "coverage" in d else f"{'-':>7}{'-':>6}"
                verb = f"{d['verbatim_mean_px']:10.0f}{d['verbatim_max_px']:9d}" if "verbatim_max_px" in d \
                    else f"{'-':>10}{'-':>9}"
                reg = d.get("lattice_regularity")
                reg = f"  lattice regularity {reg[0]:.2f} / {reg[1]:.2f}" if reg else ""
                ps = f"{d['ps']:7.3f}" if "ps" in d else f"{'-':>7}"
                print(f"{name:<13}{n:>5} {method:<6}{d['energy']:9.5f}{d['completeness']:9.5f}{cov}{verb}"
                      f"{d['repetition']:7.2f}{d['copied']:7.2f}{d['histogram']:7.3f}{ps}{reg}")
            t = row["time"]
            print(f"{'':<19}time: ours {t['ours_warm_s'] * 1000:.0f} ms warm, {t['ours_cold_s']:.1f} s cold; "
                  f"peer {t['peer_warm_s'] * 1000:.0f} ms warm, {t['peer_cold_s']:.1f} s cold; "
                  f"peer/ours {t['warm_ratio_peer_over_ours']:.1f}x warm, {t['cold_ratio_peer_over_ours']:.1f}x cold")


if __name__ == "__main__":
    sys.exit(main())
