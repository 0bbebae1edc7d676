"""User controls of the synthesis: the one engine input built from a document.

Everything an artist paints, places or marks reaches the synthesis passes
through a :class:`Controls` value (immutable): today the two randomness fields
of LH05 section 4.2 (ALGORITHM.md section 5), placed features (4.3) and the
lattice of a near-regular texture (4.5, :mod:`engine.controls.lattice`). The pyramid asks it, per strip and level, for what the passes read.

**Randomness fields** modulate the jitter: ``J_l(p) = floor(h H(p) r_l M_l(p) + 1/2)``
with the effective ``r_l M_l(p)`` clamped to [0, 1]. Field values are uint16 in
1/32768ths: 0 = calm (no jitter), 32768 = neutral, 65535 = almost 2 (rough).

- :class:`ExemplarField` (over the exemplar, m x m): ``M_l(p) = R_E,l[S_l(p)]``
  where ``S_l(p)`` is the upsampled coordinate before jitter and ``R_E,l`` the
  min-mipmap (a level-l texel covers h_l x h_l exemplar pixels and takes their
  minimum, so a protected feature stays protected at every scale).
- :class:`CanvasField` (over the infinite canvas, finest-level pixels, sparse
  64 x 64 tiles; unpainted = neutral): ``M_l(p) = R_S,l[p]``, mipmapped toward
  neutral: a level-l pixel (covering h_l x h_l canvas pixels) takes the value
  closest to neutral that its whole footprint agrees on (the largest of an
  all-calm footprint, the smallest of an all-rough one, else neutral). Paint
  thus acts on the features that fit inside the painted area: a small dab
  changes fine detail, a large area calms or roughens large features too, and
  no dab re-rolls the big features around it (LH05's mean mipmap would). With
  a toroidal period n, the field is read at ``p mod n_l``.

Both multiply: ``t = (E * C + 2^14) >> 15``, ``r'_q = min(1024, (r_q t + 2^14) >> 15)``,
so a neutral field gives exactly the unmodulated jitter.

**Avoided exemplar regions** (:class:`ExemplarMask`, m x m, 1 = avoid): a
blemish, a logo, or one distinctive element that would recur once per
exemplar area. Correction never picks a candidate inside the mask while any
candidate outside it is left (its cost is above every real cost), and the
search adds TBN10's random walk so that a pixel deep inside the region still
finds a way out; coordinates the jitter puts there are corrected away on the
corrected levels.
"""
from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

import numpy as np

from .avoid import ExemplarMask
from .features import (
    FEATURE_CELL,
    MAX_FEATURE_RADIUS,
    MAX_FEATURES,
    Feature,
    features_from_json,
    features_to_json,
    fit_features,
)
from .fields import (
    NEUTRAL,
    TILE,
    CanvasField,
    ExemplarArray,
    ExemplarField,
    apply_dab,
    dab_rect,
    dab_weights,
    modulated_rq,
    reduce_toward_neutral,
)
from .lattice import Lattice

__all__ = [
    "Controls", "NO_CONTROLS", "NEUTRAL", "TILE", "CanvasField", "ExemplarArray", "ExemplarField", "ExemplarMask",
    "Feature", "FEATURE_CELL", "MAX_FEATURE_RADIUS", "MAX_FEATURES", "Lattice", "apply_dab", "dab_rect",
    "dab_weights", "features_from_json", "features_to_json", "fit_features", "modulated_rq",
    "reduce_toward_neutral",
]


@dataclass(frozen=True)
class Controls:
    """Everything painted or placed by the user that the passes read."""

    randomness_exemplar: ExemplarField | None = None
    randomness_canvas: CanvasField | None = None
    features: tuple[Feature, ...] = ()
    lattice: Lattice | None = None  # near-regular mode: the exemplar is this lattice's rectified block
    avoid: ExemplarMask | None = None  # exemplar regions the correction does not copy

    def normalized(self) -> Controls:
        """Neutral fields and empty masks dropped (they change nothing), so equal effects compare equal."""
        e = self.randomness_exemplar
        c = self.randomness_canvas
        a = self.avoid
        return Controls(None if e is None or e.neutral else e, None if c is None or c.neutral else c,
                        tuple(self.features), self.lattice, None if a is None or a.empty else a)

    def exemplar_inputs(self) -> tuple:
        """What is painted over the exemplar (randomness field, avoid mask): a
        change of either reaches the whole canvas."""
        return (self.randomness_exemplar, self.avoid)

    def lattice_shift(self, m: int, level: int) -> tuple[int, int] | None:
        """(log2 cx, log2 cy) when ``level`` is a lattice level: jitter is
        quantized to whole cells and the lattice similarity sets are used."""
        return None if self.lattice is None else self.lattice.quant_shift(m, level)

    def validate(self, m: int, lattice_grid: tuple[int, int] | None = None) -> None:
        """Raise ValueError if these controls cannot drive an m x m exemplar
        analyzed with ``lattice_grid`` (the analysis' (nx, ny); None: unchecked)."""
        if self.lattice is not None and lattice_grid is not None \
                and (self.lattice.nx, self.lattice.ny) != tuple(lattice_grid):
            raise ValueError(f"The lattice has {self.lattice.nx}x{self.lattice.ny} cells but the exemplar was "
                             f"analyzed for {lattice_grid[0]}x{lattice_grid[1]}.")
        e = self.randomness_exemplar
        if e is not None and e.size != m:
            raise ValueError(f"The exemplar randomness field is {e.size}x{e.size}; the exemplar is {m}x{m}.")
        a = self.avoid
        if a is not None and a.size != m:
            raise ValueError(f"The avoid mask is {a.size}x{a.size}; the exemplar is {m}x{m}.")
        if a is not None and a.full:
            raise ValueError("The avoid mask covers the whole exemplar: leave some of it usable.")
        L = m.bit_length() - 1
        for f in self.features:
            f.validate(m, L)

    @cached_property
    def features_key(self) -> str:
        import hashlib
        return hashlib.sha256(repr(self.features).encode()).hexdigest()

    def level_signature(self, level: int, m: int = 0) -> tuple:
        """What level ``level`` reads of the controls (fields change all levels)."""
        e, c = self.randomness_exemplar, self.randomness_canvas
        return (None if e is None else e.key, None if c is None else c.key,
                self.features_key if self.features else None,
                None if self.lattice is None else (self.lattice.nx, self.lattice.ny, self.lattice_shift(m, level)),
                None if self.avoid is None else self.avoid.key)

    @cached_property
    def _feature_index(self) -> dict:
        """Spatial index: FEATURE_CELL-sized canvas cells -> feature indices."""
        index: dict = {}
        for i, f in enumerate(self.features):
            x0, y0, x1, y1 = f.bbox()
            for cy in range(y0 // FEATURE_CELL, (y1 - 1) // FEATURE_CELL + 1):
                for cx in range(x0 // FEATURE_CELL, (x1 - 1) // FEATURE_CELL + 1):
                    index.setdefault((cx, cy), []).append(i)
        return index

    def features_in(self, x0: int, y0: int, x1: int, y1: int) -> list[int]:
        """Indices (in order) of the features whose reach meets a finest-level rectangle."""
        if not self.features:
            return []
        index = self._feature_index
        cells = ((x1 - 1) // FEATURE_CELL - x0 // FEATURE_CELL + 1) * ((y1 - 1) // FEATURE_CELL - y0 // FEATURE_CELL + 1)
        if cells > len(index):
            found = {i for lst in index.values() for i in lst}
        else:
            found = set()
            for cy in range(y0 // FEATURE_CELL, (y1 - 1) // FEATURE_CELL + 1):
                for cx in range(x0 // FEATURE_CELL, (x1 - 1) // FEATURE_CELL + 1):
                    found.update(index.get((cx, cy), ()))
        out = []
        for i in sorted(found):
            fx0, fy0, fx1, fy1 = self.features[i].bbox()
            if fx0 < x1 and x0 < fx1 and fy0 < y1 and y0 < fy1:
                out.append(i)
        return out

    def feature_table(self, level: int, L: int, m: int, toroidal: bool, x0: int, y0: int, x1: int, y1: int,
                      period: int = 0) -> np.ndarray | None:
        """The features active at ``level`` over a level-pixel rectangle, as the
        int32 (N, 2, 4) table the passes read: (p_F,l x, y, frac x + 16 frac y,
        radius in 1/16 level pixels), (u_F x, y, 0, 0); None when there are none.
        With a period (a toroidal tile) every feature applies, modulo the tile."""
        k = L - level
        rows = []
        found = range(len(self.features)) if period else self.features_in(x0 << k, y0 << k, x1 << k, y1 << k)
        for i in found:
            f = self.features[i]
            a, b = f.level_range(L)
            if not a <= level <= b:
                continue
            f = f.clamped(m, toroidal)
            r16 = (f.radius_at(level, L) << 4) >> k
            px, py = f.canvas
            fx, fy = ((px << 4) >> k) & 15, ((py << 4) >> k) & 15
            rows.append([[px >> k, py >> k, fx + 16 * fy, r16], [f.exemplar[0], f.exemplar[1], 0, 0]])
        return np.asarray(rows, dtype=np.int32) if rows else None

    def changed_rects(self, other: Controls) -> list | None:
        """Finest-level rectangles outside which ``other`` reads the same as this
        one; None when the change reaches everywhere (the exemplar field, the avoid mask)."""
        if self.exemplar_inputs() != other.exemplar_inputs() or self.lattice != other.lattice:
            return None
        before = self.randomness_canvas or CanvasField()
        after = other.randomness_canvas or CanvasField()
        out = before.changed_rects(after)
        if self.features != other.features:
            old, new = set(self.features), set(other.features)
            out += [f.bbox() for f in old ^ new]  # added, removed, moved or resized
            # Which feature wins an overlap follows the list order: features whose
            # relative order changed are changes too.
            ka = [f for f in self.features if f in new]
            kb = [f for f in other.features if f in old]
            out += [f.bbox() for x, y in zip(ka, kb) if x != y for f in (x, y)]
        return out


NO_CONTROLS = Controls()
