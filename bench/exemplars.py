"""Structured benchmark exemplars of our own making (CC0), so that tuning the
synthesis does not overfit the nine shared ones: spots, cells, cracks, a weave
and text, 128 x 128, each with whole elements a synthesis must keep whole.

    python -m bench.exemplars [OUT_DIR]     # default bench/exemplars/

Deterministic (fixed seeds). The text uses Pillow's built-in font (Aileron
Regular, CC0, embedded in Pillow).
"""
from __future__ import annotations

import os
import sys

import numpy as np
from PIL import Image, ImageDraw, ImageFont
from scipy import ndimage
from scipy.spatial import cKDTree

HERE = os.path.dirname(os.path.abspath(__file__))
M = 128


def _noise(rng, m: int, scale: float) -> np.ndarray:
    f = np.fft.fft2(rng.standard_normal((m, m)))
    fy, fx = np.fft.fftfreq(m)[:, None], np.fft.fftfreq(m)[None, :]
    f *= np.exp(-(fx ** 2 + fy ** 2) * (m / scale) ** 2)
    n = np.real(np.fft.ifft2(f))
    return (n - n.min()) / (n.max() - n.min())


def spots(m: int = M, seed: int = 1) -> np.ndarray:
    """Dark round spots of a few sizes on a mottled ground; periodic."""
    rng = np.random.default_rng(seed)
    img = 0.78 + 0.1 * _noise(rng, m, 12.0)
    ys, xs = np.mgrid[0:m, 0:m]
    for _ in range(22):
        cx, cy, r = rng.uniform(0, m), rng.uniform(0, m), rng.uniform(4.0, 10.0)
        dx = np.minimum(np.abs(xs - cx), m - np.abs(xs - cx))
        dy = np.minimum(np.abs(ys - cy), m - np.abs(ys - cy))
        d = np.sqrt(dx * dx + dy * dy)
        img = np.minimum(img, np.clip(0.12 + (d - r) * 0.35, 0.12, 1.0))
    rgb = np.stack([img * 0.95, img * 0.85, img * 0.6], axis=-1)
    return np.clip(rgb, 0, 1)


def cells(m: int = M, seed: int = 2) -> np.ndarray:
    """Voronoi cells with thin dark walls and a shade per cell; periodic."""
    rng = np.random.default_rng(seed)
    pts = rng.random((40, 2)) * m
    ys, xs = np.mgrid[0:m, 0:m]
    d, idx = cKDTree(pts, boxsize=m).query(np.stack([xs.ravel() + 0.5, ys.ravel() + 0.5], 1), k=2)
    wall = np.clip(((d[:, 1] - d[:, 0]) - 1.2) / 1.5, 0.0, 1.0).reshape(m, m)
    shade = (0.45 + 0.4 * rng.random(len(pts)))[idx[:, 0]].reshape(m, m)
    g = 0.1 + (shade - 0.1) * wall
    return np.stack([g * 0.7, g * 0.95, g * 0.6], axis=-1)


def cracks(m: int = M, seed: int = 3) -> np.ndarray:
    """Thin branching dark cracks over a light, slightly mottled surface."""
    rng = np.random.default_rng(seed)
    mask = np.zeros((m, m), dtype=bool)
    for _ in range(9):
        x, y = rng.uniform(0, m, 2)
        ang = rng.uniform(0, 2 * np.pi)
        for _ in range(int(rng.uniform(60, 160))):
            ang += rng.normal(0, 0.35)
            x, y = (x + np.cos(ang)) % m, (y + np.sin(ang)) % m
            mask[int(y), int(x)] = True
            if rng.random() < 0.02:  # a branch
                bx, by, ba = x, y, ang + rng.choice([-1, 1]) * rng.uniform(0.6, 1.2)
                for _ in range(int(rng.uniform(10, 40))):
                    ba += rng.normal(0, 0.3)
                    bx, by = (bx + np.cos(ba)) % m, (by + np.sin(ba)) % m
                    mask[int(by), int(bx)] = True
    dist = ndimage.distance_transform_edt(~np.tile(mask, (3, 3)))[m:2 * m, m:2 * m]
    base = 0.72 + 0.15 * _noise(rng, m, 10.0)
    g = base * np.clip(dist / 1.6, 0.25, 1.0)
    return np.stack([g, g * 0.96, g * 0.9], axis=-1)


def weave(m: int = M, seed: int = 4) -> np.ndarray:
    """A basket weave: blocks of three strands, alternately horizontal and vertical."""
    rng = np.random.default_rng(seed)
    ys, xs = np.mgrid[0:m, 0:m].astype(np.float64)
    block = 16
    bx, by = (xs // block).astype(int), (ys // block).astype(int)
    horiz = (bx + by) % 2 == 0
    u = np.where(horiz, ys, xs) % block            # across the strands
    strand = (u % (block / 3)) / (block / 3)       # 0..1 across one strand
    along = np.where(horiz, xs, ys) % block / block
    profile = np.sin(np.pi * strand) ** 0.6
    sag = 0.85 + 0.15 * np.sin(np.pi * along)
    g = (0.15 + 0.75 * profile * sag) * (0.92 + 0.08 * _noise(rng, m, 20.0))
    return np.stack([g * 0.95, g * 0.8, g * 0.55], axis=-1)


def text(m: int = M, seed: int = 5) -> np.ndarray:
    """Lines of words, black on off-white (glyphs must stay whole to stay legible)."""
    rng = np.random.default_rng(seed)
    words = ("texture synthesis keeps every glyph whole and the lines straight so that "
             "a page of words still reads like text at any size or place").split()
    img = Image.new("L", (m, m), 236)
    draw = ImageDraw.Draw(img)
    font = ImageFont.load_default(size=11)
    y = 1
    while y < m - 10:
        x = 1
        while True:
            w = words[int(rng.integers(len(words)))]
            width = draw.textlength(w + " ", font=font)
            if x + width > m + 20:
                break
            draw.text((x, y), w, fill=20, font=font)
            x += width
        y += 13
    g = np.asarray(img, dtype=np.float64) / 255.0
    return np.repeat(g[..., None], 3, axis=2)


MAKERS = {"spots": spots, "cells": cells, "cracks": cracks, "weave": weave, "text": text}


def main(argv: list[str]) -> int:
    out = argv[0] if argv else os.path.join(HERE, "exemplars")
    os.makedirs(out, exist_ok=True)
    for name, make in MAKERS.items():
        px = np.clip(np.rint(make() * 255.0), 0, 255).astype(np.uint8)
        Image.fromarray(px).save(os.path.join(out, f"{name}.png"))
        print(f"wrote {name}.png {px.shape[1]}x{px.shape[0]}")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
