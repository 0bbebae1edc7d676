"""Whether an exemplar tiles: how often the guess takes a photo cut from a
larger one for a tiling texture, and what that does to a synthesis.

    python -m bench.tiling_guess [--json OUT.json] [--figure docs/straight-seams.png]

A photo cut from a larger one does not wrap; taken for tiling (toroidal), its
synthesis copies the jump across its borders as long straight horizontal and
vertical lines. The guess compares the wrap-around seams with the interior
(engine/wrap.py guess_toroidal): once at the pixel scale only, now at
blocks of 1, 2, 4 and 8 px as well.

1. On the game textures of tests/near_regular.py (OpenArena, Cube 2; tiling
   textures, deduplicated): each whole (its largest square, 256^2), 8 cuts of
   it (half its side at seeded places, 4 at 128^2 and 4 at 256^2; these do
   not tile) and one cut made tileable (engine/tileable.py make_tileable,
   which tiles by construction). Counted: how many each test takes for tiling.
2. A synthesis (Balanced, 512^2 window) of a cut of Cube 2's dirt taken for
   tiling, against the guess: the pixels on a wrap-around seam (neighbors
   whose exemplar coordinates are adjacent only across the exemplar's border).
3. The figure: a crop of both at 200% (taken for tiling | its wrap-around
   seams in red | the guess).
Prints a table, writes JSON.
"""
from __future__ import annotations

import argparse
import hashlib
import json
import os
import sys

import numpy as np
from PIL import Image

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, ROOT)
sys.path.insert(0, os.path.join(ROOT, "tests"))

import near_regular  # noqa: E402

from infinitex.engine.analysis import analyze  # noqa: E402
from infinitex.engine.exemplar import from_array  # noqa: E402
from infinitex.engine.imagefile import to_u8  # noqa: E402
from infinitex.engine.params import SynthParams, structure_params  # noqa: E402
from infinitex.engine.pyramid import Rect  # noqa: E402
from infinitex.engine.synth import Synthesizer  # noqa: E402
from infinitex.engine.tileable import make_tileable  # noqa: E402
from infinitex.engine.wrap import guess_toroidal, seams_match_at_pixel_scale  # noqa: E402

DIRT = "generic_dirt1_col.jpg"


def square(img: np.ndarray, size: int, cut: tuple[float, float] | None = None) -> np.ndarray:
    """The largest square of ``img`` (or, with ``cut``, a square of half its
    side at that fraction of the room), resized to ``size``."""
    h, w = img.shape[:2]
    im = Image.fromarray((img * 255).round().astype(np.uint8))
    if cut is None:
        s = min(w, h)
        im = im.crop((0, 0, s, s))
    else:
        s = min(w, h) // 2
        x0, y0 = int(cut[0] * (w - s)), int(cut[1] * (h - s))
        im = im.crop((x0, y0, x0 + s, y0 + s))
    return np.asarray(im.resize((size, size), Image.LANCZOS), np.float32) / 255.0


def guesses(images: list[np.ndarray]) -> dict:
    rng = np.random.default_rng(11)
    kinds = {k: {"n": 0, "pixel_scale": 0, "guess": 0} for k in ("whole", "cut", "made tileable")}

    def count(kind, a):
        kinds[kind]["n"] += 1
        kinds[kind]["pixel_scale"] += seams_match_at_pixel_scale(a)
        kinds[kind]["guess"] += guess_toroidal(a)

    for img in images:
        count("whole", square(img, 256))
        for _ in range(4):
            for size in (128, 256):
                count("cut", square(img, size, tuple(rng.uniform(0.05, 0.95, 2))))
        cut = square(img, 128, tuple(rng.uniform(0.05, 0.95, 2)))
        count("made tileable", make_tileable(cut, band=16))
    return kinds


def wrap_seams(S: np.ndarray, m: int) -> np.ndarray:
    """Pixels whose right or lower neighbor continues their exemplar
    coordinates only across the exemplar's border."""
    out = np.zeros(S.shape[:2], bool)
    for axis, step in ((1, (1, 0)), (0, (0, 1))):
        d = np.diff(S, axis=axis) - np.array(step)
        wrapped = (d != 0).any(-1) & ~(((d + m // 2) % m - m // 2) != 0).any(-1)
        if axis == 1:
            out[:, :-1] |= wrapped
        else:
            out[:-1] |= wrapped
    return out


def synthesis(pixels: np.ndarray, toroidal: bool | None, n: int = 512):
    ex = from_array(pixels, toroidal=toroidal)
    an = analyze(ex)
    with Synthesizer(an, structure_params(SynthParams.default(an.L), 2)) as s:
        S = s.window(Rect.of(1000, -2000, n, n)).astype(np.int64)
        img = to_u8(s.colors(S)).reshape(n, n, -1)[..., :3]
    return ex, img, wrap_seams(S, an.size)


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--json", default=os.path.join(ROOT, "bench", "results", "tiling_guess.json"))
    ap.add_argument("--figure", default=None)
    args = ap.parse_args(argv)

    seen, images, dirt = set(), [], None
    for path in (near_regular.MANIFEST, near_regular.CUBE2):
        for entry, file in near_regular.fetch(path):
            img = near_regular.load(file)
            key = hashlib.sha256(img.tobytes()).hexdigest()
            if key not in seen:
                seen.add(key)
                images.append(img)
            if entry["path"].endswith(DIRT):
                dirt = img
    kinds = guesses(images)
    print(f"{len(images)} game textures (tiling), their cuts (not tiling) and cuts made tileable")
    print(f"{'':16s}{'n':>6s}{'taken for tiling: pixel scale':>32s}{'the guess':>12s}")
    for k, v in kinds.items():
        print(f"{k:16s}{v['n']:6d}{v['pixel_scale']:32d}{v['guess']:12d}")

    cut = square(dirt, 256, (102 / 256, 73 / 256))  # a 256 px cut at (102, 73)
    before = synthesis(cut, True)
    after = synthesis(cut, None)
    seams = {"taken for tiling": int(before[2].sum()), "guess": int(after[2].sum()),
             "guess_tiles": bool(after[0].toroidal)}
    print(f"dirt cut (512^2 window, Balanced): wrap-around seam pixels taken for tiling "
          f"{seams['taken for tiling']}, with the guess ({'tiles' if seams['guess_tiles'] else 'does not tile'}) "
          f"{seams['guess']}")
    if args.figure:
        marked = before[1].copy()
        marked[before[2]] = (255, 40, 40)
        x0, y0, x1, y1 = 60, 20, 252, 212
        panels = [Image.fromarray(a[y0:y1, x0:x1]).resize((2 * (x1 - x0), 2 * (y1 - y0)), Image.NEAREST)
                  for a in (before[1], marked, after[1])]
        w, h = panels[0].size
        fig = Image.new("RGB", (3 * w + 16, h), (255, 255, 255))
        for i, p in enumerate(panels):
            fig.paste(p, (i * (w + 8), 0))
        fig.save(args.figure)
        print("figure:", args.figure)
    os.makedirs(os.path.dirname(args.json), exist_ok=True)
    with open(args.json, "w") as f:
        json.dump({"guesses": kinds, "dirt_synthesis": seams}, f, indent=1)


if __name__ == "__main__":
    main()
