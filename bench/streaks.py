"""Regular streaks on the first screen: autocorrelation peaks of a large window.

    python -m bench.streaks [--exemplar PNG] [--size 2048] [--structures 0,2]
                            [--no-peer] [--json OUT.json] [--figure OUT.png]

The editor opens on gravel, and zoomed out (25-50%) a texture that places one
feature at regular spacing reads as streaks. This measures it the way the
structure issue states the target: the highest normalized autocorrelation of
a SIZE^2 window's luminance at shifts of 32 px or more (up to a quarter of the
window), against the exemplar's own at the same shifts (circular when the
exemplar tiles, as the synthesis reads it); both on the raw luminance and
blurred by a 6 px Gaussian (what still shows at 25%). A peak above the
exemplar's own is a repetition the synthesis made. Ours at each Structure
preset asked for (window at (10007, -20011)), and G'MIC's
``syntexturize_matchpatch`` of the same size when the ``gmic`` module is there.
Prints a table, writes JSON and a figure (each output's top-left 1024^2 at 50%).
"""
from __future__ import annotations

import argparse
import json
import os
import sys
import tempfile
import time

import numpy as np
from PIL import Image
from scipy import ndimage

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, ROOT)

from bench.measures import autocorrelation  # noqa: E402
from infinitex.engine.analysis import analyze  # noqa: E402
from infinitex.engine.exemplar import load_exemplar  # noqa: E402
from infinitex.engine.imagefile import to_u8, write_png  # noqa: E402
from infinitex.engine.material import luma  # noqa: E402
from infinitex.engine.params import STRUCTURE_NAMES, SynthParams, structure_index, structure_params  # noqa: E402
from infinitex.engine.pyramid import Rect  # noqa: E402
from infinitex.engine.synth import Synthesizer  # noqa: E402

GRAVEL = os.path.join(ROOT, "infinitex", "assets", "gravel.png")
ORIGIN = (10007, -20011)
MIN_SHIFT = 32
BLUR = 6.0


def luminance(img: np.ndarray) -> np.ndarray:
    """An image's luminance as a 2-D float64 array (Rec. 709, as the material's luma)."""
    return luma(np.asarray(img))[..., 0].astype(np.float64)


def peak(y: np.ndarray, periodic: bool, blur: float = 0.0, lim: int | None = None) -> tuple[float, tuple[int, int]]:
    """Highest normalized autocorrelation of ``y`` at shifts (dx, dy) with
    max(|dx|, |dy|) >= MIN_SHIFT, up to ``lim`` (default: half the image when
    periodic, a quarter otherwise); overlap-normalized when not periodic."""
    if blur:
        y = ndimage.gaussian_filter(y, blur, mode="wrap" if periodic else "reflect")
    ac, dy, dx = autocorrelation(y, periodic)
    lim = lim or min(y.shape) // (2 if periodic else 4)
    ady, adx = np.abs(dy), np.abs(dx)
    ok = (np.maximum(adx, ady) >= MIN_SHIFT) & (adx <= lim) & (ady <= lim)
    iy, ix = np.unravel_index(int(np.argmax(np.where(ok, ac, -np.inf))), ac.shape)
    return float(ac[iy, ix]), (int(dx[0, ix]), int(dy[iy, 0]))


def measure(y: np.ndarray, periodic: bool) -> dict:
    raw, raw_at = peak(y, periodic)
    blurred, blurred_at = peak(y, periodic, BLUR)
    return {"peak": raw, "peak_at": raw_at, "peak_blurred": blurred, "peak_blurred_at": blurred_at}


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--exemplar", default=GRAVEL)
    ap.add_argument("--size", type=int, default=2048)
    ap.add_argument("--structures", default="0,2", help="Structure presets, by number or name (default 0,2)")
    ap.add_argument("--no-peer", action="store_true")
    ap.add_argument("--json", metavar="OUT.json")
    ap.add_argument("--figure", metavar="OUT.png")
    a = ap.parse_args(argv)
    n = a.size
    if n < 8 * MIN_SHIFT:
        ap.error(f"--size must be at least {8 * MIN_SHIFT}.")
    structures = [structure_index(s) for s in a.structures.split(",")]
    ex = load_exemplar(a.exemplar)
    an = analyze(ex)
    rows = {"exemplar": {**measure(luminance(ex.pixels), ex.toroidal), "toroidal": ex.toroidal}}
    shots = []
    for st in structures:
        with Synthesizer(an, structure_params(SynthParams.default(an.L), st)) as s:
            t = time.perf_counter()
            out = s.colors(s.window(Rect.of(ORIGIN[0], ORIGIN[1], n, n)))
            rows[STRUCTURE_NAMES[st]] = {**measure(luminance(out), False), "time_s": time.perf_counter() - t}
        shots.append((STRUCTURE_NAMES[st], out))
    if not a.no_peer:
        try:
            import gmic
        except ImportError:
            print("peer skipped: the gmic module is not installed (requirements-bench.txt)")
        else:
            with tempfile.TemporaryDirectory() as tmp:
                src, dst = os.path.join(tmp, "ex.png"), os.path.join(tmp, "peer.png")
                write_png(src, to_u8(ex.pixels))
                t = time.perf_counter()
                gmic.run(f"{src} syntexturize_matchpatch {n},{n} cut 0,255 output {dst}")
                el = time.perf_counter() - t
                peer = np.asarray(Image.open(dst).convert("RGB"), np.float32) / 255.0
            rows["peer (G'MIC)"] = {**measure(luminance(peer), False), "time_s": el}
            shots.append(("peer", peer))
    own, own_b = rows["exemplar"]["peak"], rows["exemplar"]["peak_blurred"]
    print(f"{os.path.basename(a.exemplar)}, {n}^2 window; highest autocorrelation at shifts of "
          f"{MIN_SHIFT} px or more (raw / blurred {BLUR:g} px); above the exemplar's own = a repetition made")
    print(f"{'':16s} {'raw':>7s} {'at':>12s} {'blurred':>8s} {'at':>12s}  above own")
    for name, r in rows.items():
        above = "" if name == "exemplar" else ("yes" if r["peak"] > own or r["peak_blurred"] > own_b else "no")
        print(f"{name:16s} {r['peak']:7.3f} {str(r['peak_at']):>12s} {r['peak_blurred']:8.3f} "
              f"{str(r['peak_blurred_at']):>12s}  {above}")
    if a.json:
        os.makedirs(os.path.dirname(os.path.abspath(a.json)), exist_ok=True)
        with open(a.json, "w") as f:
            json.dump({"exemplar": os.path.basename(a.exemplar), "size": n, "min_shift": MIN_SHIFT,
                       "blur": BLUR, "origin": ORIGIN, "rows": rows}, f, indent=1)
    if a.figure and shots:
        k = min(n, 1024)
        tiles = []
        for _, img in shots:
            y = np.clip(luminance(img[:k, :k]), 0.0, 1.0)
            y = y[: k // 2 * 2, : k // 2 * 2].reshape(k // 2, 2, k // 2, 2).mean(axis=(1, 3))
            tiles.append(np.pad(to_u8(y)[..., None], ((0, 0), (0, 8), (0, 0)), constant_values=255))
        write_png(a.figure, np.concatenate(tiles, axis=1)[:, :-8])
        print("figure (" + " | ".join(name for name, _ in shots) + f", top-left {k}^2 at 50%): {a.figure}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
