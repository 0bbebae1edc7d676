"""Models generated here (CC0, no files): for tests, benchmarks and figures.

- :func:`cube`: six faces, each its own chart, packed 3 x 2 in the atlas
  with a margin, some turned or mirrored in UV so seams join charts at
  different angles.
- :func:`cylinder`: a tube unwrapped in one chart with one seam (u = 0 and
  u = 1 meet), plus the two caps as charts.
- :func:`vase`: a surface of revolution with a wavy profile, unwrapped by
  xatlas into many charts: a model to bake for the README figure and the
  benchmark (any triangle count).
"""
from __future__ import annotations

import numpy as np

from .mesh import Model


def _grid(n: int):
    """(n+1)^2 grid points in [0, 1]^2 and its 2 n^2 triangles (counter-clockwise)."""
    s = np.linspace(0.0, 1.0, n + 1)
    u, v = np.meshgrid(s, s)
    pts = np.stack([u.ravel(), v.ravel()], axis=-1)
    i = np.arange(n)
    a = (i[None, :] + (n + 1) * i[:, None]).ravel()
    faces = np.concatenate([np.stack([a, a + 1, a + n + 2], -1), np.stack([a, a + n + 2, a + n + 1], -1)])
    return pts, faces


# (origin, axis s, axis t) of each face, seen from outside: s x t = the outward normal.
_FACES = (
    ((-1, -1, 1), (2, 0, 0), (0, 2, 0)),    # +z
    ((1, -1, 1), (0, 0, -2), (0, 2, 0)),    # +x
    ((1, -1, -1), (-2, 0, 0), (0, 2, 0)),   # -z
    ((-1, -1, -1), (0, 0, 2), (0, 2, 0)),   # -x
    ((-1, 1, 1), (2, 0, 0), (0, 0, -2)),    # +y
    ((-1, -1, -1), (2, 0, 0), (0, 0, 2)),   # -y
)
# How each face's square sits in its atlas cell: 0 as is, 1 turned 90 degrees, 2 mirrored.
_UV_TURN = (0, 1, 0, 2, 1, 0)


def cube(n: int = 4, margin: float = 0.04, turns: bool = True) -> Model:
    """A cube of side 2 centred at 0, each face an n x n grid and its own chart."""
    pts, tri = _grid(n)
    P, F, UV = [], [], []
    cell = 1.0 / 3.0
    for i, (o, s, t) in enumerate(_FACES):
        o, s, t = (np.asarray(x, np.float64) for x in (o, s, t))
        P.append(o + pts[:, :1] * s + pts[:, 1:] * t)
        a, b = pts[:, 0], pts[:, 1]
        kind = _UV_TURN[i] if turns else 0
        if kind == 1:
            a, b = 1.0 - b, a
        elif kind == 2:
            a = 1.0 - a
        cx, cy = (i % 3) * cell, (i // 3) * 0.5
        side = min(cell, 0.5) - 2 * margin
        UV.append(np.stack([cx + margin + a * side, cy + margin + b * side], -1))
        F.append(tri + i * len(pts))
    return Model(np.concatenate(P), np.concatenate(F), np.concatenate(UV), name="cube")


def cylinder(segments: int = 48, rings: int = 8, radius: float = 1.0, height: float = 2.0,
             caps: bool = True) -> Model:
    """An open or capped tube around +y: the side one chart in u in [0.02, 0.98]
    x v in [0.35, 0.98], with a seam where u wraps; each cap a disc chart below."""
    u = np.linspace(0.0, 1.0, segments + 1)
    v = np.linspace(0.0, 1.0, rings + 1)
    U, V = np.meshgrid(u, v)
    ang = 2 * np.pi * U
    P = [np.stack([radius * np.sin(ang), height * (V - 0.5), radius * np.cos(ang)], -1).reshape(-1, 3)]
    UV = [np.stack([0.02 + 0.96 * U, 0.35 + 0.63 * V], -1).reshape(-1, 2)]
    i = np.arange(segments)
    j = np.arange(rings)
    a = (i[None, :] + (segments + 1) * j[:, None]).ravel()
    F = [np.concatenate([np.stack([a, a + 1, a + segments + 2], -1), np.stack([a, a + segments + 2, a + segments + 1], -1)])]
    if caps:
        base = len(P[0])
        for k, (y, cx) in enumerate(((height / 2, 0.25), (-height / 2, 0.75))):
            c = np.linspace(0, 2 * np.pi, segments + 1)[:-1]
            ring = np.stack([radius * np.sin(c), np.full_like(c, y), radius * np.cos(c)], -1)
            P.append(np.concatenate([[[0.0, y, 0.0]], ring]))
            uvr = 0.15
            UV.append(np.concatenate([[[cx, 0.17]], np.stack([cx + uvr * np.sin(c), 0.17 + uvr * np.cos(c) * (1 if y > 0 else -1)], -1)]))
            centre = base
            rim = base + 1 + np.arange(segments)
            nxt = base + 1 + (np.arange(segments) + 1) % segments
            tris = np.stack([centre + 0 * rim, rim, nxt], -1) if y > 0 else np.stack([centre + 0 * rim, nxt, rim], -1)
            F.append(tris)
            base += 1 + segments
    return Model(np.concatenate(P), np.concatenate(F), np.concatenate(UV), name="cylinder")


def vase(segments: int = 96, rings: int = 64) -> Model:
    """A closed vase (surface of revolution, wavy profile, a foot and a lip),
    about 2 segments x rings triangles, unwrapped by xatlas."""
    from .mesh import unwrap
    t = np.linspace(0.0, 1.0, rings + 1)
    r = 0.55 + 0.35 * np.sin(np.pi * t * 1.6 + 0.3) + 0.06 * np.sin(9 * np.pi * t)
    y = 2.4 * t - 1.2
    ang = np.linspace(0, 2 * np.pi, segments, endpoint=False)
    P = np.stack([r[:, None] * np.sin(ang)[None], np.broadcast_to(y[:, None], (rings + 1, segments)),
                  r[:, None] * np.cos(ang)[None]], -1).reshape(-1, 3)
    i = np.arange(segments)
    j = np.arange(rings)
    a = (i[None, :] + segments * j[:, None]).ravel()
    b = ((i[None, :] + 1) % segments + segments * j[:, None]).ravel()
    F = np.concatenate([np.stack([a, b, b + segments], -1), np.stack([a, b + segments, a + segments], -1)])
    bottom, top = len(P), len(P) + 1
    P = np.concatenate([P, [[0.0, y[0], 0.0], [0.0, y[-1], 0.0]]])
    F = np.concatenate([F, np.stack([np.full(segments, bottom), (i + 1) % segments, i], -1),
                        np.stack([np.full(segments, top), rings * segments + i, rings * segments + (i + 1) % segments], -1)])
    return unwrap(P, F, name="vase", isolated=False)  # (our own shape: no child process)
