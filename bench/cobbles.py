"""The generated cobblestone material (periodic Voronoi stones whose maps come
from the same shapes, so they tile and stay aligned): the shipped example
material (``scripts/make_material.py`` writes it), and a photo-like exemplar
of any size for the benchmarks and tests (the same stones at every size)."""
from __future__ import annotations

import numpy as np
from scipy.spatial import cKDTree


def _noise(m: int, rng: np.random.Generator, scale: float) -> np.ndarray:
    """Smooth periodic noise in [0, 1]."""
    f = np.fft.fft2(rng.standard_normal((m, m)))
    fy, fx = np.fft.fftfreq(m)[:, None], np.fft.fftfreq(m)[None, :]
    f *= np.exp(-(fx ** 2 + fy ** 2) * (m / scale) ** 2)
    n = np.real(np.fft.ifft2(f))
    return (n - n.min()) / (n.max() - n.min())


def cobbles(m: int = 512, seed: int = 7, stones: int | None = None) -> dict[str, np.ndarray]:
    """{role: float32 (m, m, C) in [0, 1]}: basecolor (3), height (1), normal (3), roughness (1)."""
    rng = np.random.default_rng(seed)
    n = stones or max(8, (m * m) // 2600)
    pts = rng.random((n, 2)) * m
    ys, xs = np.mgrid[0:m, 0:m]
    pix = np.stack([xs.ravel() + 0.5, ys.ravel() + 0.5], axis=1)
    d, idx = cKDTree(pts, boxsize=m).query(pix, k=2)
    d1, d2 = d[:, 0].reshape(m, m), d[:, 1].reshape(m, m)
    cell = idx[:, 0].reshape(m, m)
    gap = m / 90.0
    edge = np.clip((d2 - d1) / (2.0 * gap) - 0.5, 0.0, None)  # 0 in the joints, grows inside a stone
    dome = np.sqrt(np.clip(edge / 4.0, 0.0, 1.0))
    lift = rng.uniform(0.55, 1.0, n)[cell]
    fine = _noise(m, rng, 10.0)
    height = np.clip(0.08 + 0.72 * dome * lift + 0.12 * fine * (dome > 0), 0.0, 1.0)
    hue = rng.random(n)[cell]
    stone = np.stack([0.42 + 0.22 * hue, 0.38 + 0.14 * hue, 0.33 + 0.06 * hue], axis=-1)
    joint = np.array([0.20, 0.18, 0.16])
    shade = 0.75 + 0.35 * _noise(m, rng, 24.0)[..., None]
    t = np.clip(edge, 0.0, 1.0)[..., None]
    base = np.clip((joint + (stone - joint) * t) * shade, 0.0, 1.0)
    strength = m / 160.0  # height 1 = m/160 px of relief: the slopes of real cobbles
    gx = (np.roll(height, -1, axis=1) - np.roll(height, 1, axis=1)) * 0.5 * strength
    gy = (np.roll(height, -1, axis=0) - np.roll(height, 1, axis=0)) * 0.5 * strength
    nrm = np.stack([-gx, gy, np.ones_like(gx)], axis=-1)  # +Y up (OpenGL): image rows go down
    nrm /= np.linalg.norm(nrm, axis=-1, keepdims=True)
    rough = np.clip(0.9 - 0.35 * t[..., 0] + 0.1 * fine, 0.0, 1.0)
    return {"basecolor": base.astype(np.float32), "height": height[..., None].astype(np.float32),
            "normal": (nrm * 0.5 + 0.5).astype(np.float32), "roughness": rough[..., None].astype(np.float32)}
