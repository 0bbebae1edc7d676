"""User controls of the synthesis: the one engine input built from a document.

Everything an artist paints, places or marks reaches the synthesis passes
through a :class:`Controls` value (immutable): today the two randomness fields
of LH05 section 4.2 (docs/algorithm.md section 5), placed features (4.4) and the
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
    feature_arrays,
    feature_bins,
    features_from_json,
    features_to_json,
    fit_features,
    level_values,
    reach_bins,
    rescaled_features,
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
from .direction import DirectionField
from .labels import MAX_LABELS, CanvasLabels, ExemplarLabels
from .lattice import Lattice

# Lattice mode: the randomness of the levels finer than the lattice levels, as a
# fraction of the document's (0.6 -> 0.3 by default). Over 48 near-regular
# images, half the randomness there gave lower neighborhood energy on 47 and
# straighter grid lines (docs/benchmarks.md, "Lattice mode's finer scales").
LATTICE_FINE_JITTER = 0.5

__all__ = [
    "Controls", "NO_CONTROLS", "NEUTRAL", "TILE", "CanvasField", "CanvasLabels", "DirectionField", "ExemplarArray",
    "ExemplarField",
    "ExemplarLabels", "ExemplarMask", "MAX_LABELS",
    "Feature", "FEATURE_CELL", "MAX_FEATURE_RADIUS", "MAX_FEATURES", "Lattice", "apply_dab", "dab_rect",
    "dab_weights", "feature_arrays", "feature_bins", "features_from_json", "features_to_json", "fit_features",
    "modulated_rq", "reduce_toward_neutral", "rescaled_features",
]


@dataclass(frozen=True)
class Controls:
    """Everything painted or placed by the user that the passes read."""

    randomness_exemplar: ExemplarField | None = None
    randomness_canvas: CanvasField | None = None
    features: tuple[Feature, ...] = ()
    lattice: Lattice | None = None  # near-regular mode: the exemplar is this lattice's rectified block
    avoid: ExemplarMask | None = None  # exemplar regions the correction does not copy
    # Texture by numbers (engine/controls/labels.py): the exemplar's label map,
    # the labels painted over the canvas, and how strongly they are followed.
    labels_exemplar: ExemplarLabels | None = None
    labels_canvas: CanvasLabels | None = None
    label_strength: float = 1.0
    # Direction and scale over the canvas (engine/controls/direction.py, LH06 5).
    direction: DirectionField | None = None
    # Synthesis in a mesh's texture atlas (engine/surface/atlas.py, LH06 6): the
    # atlas domain gives J per texel and the indirection maps across chart seams.
    surface: object | None = None

    def normalized(self) -> Controls:
        """Neutral fields, empty masks and labels that constrain nothing dropped
        (they change nothing), so equal effects compare equal."""
        e = self.randomness_exemplar
        c = self.randomness_canvas
        a = self.avoid
        lc = self.labels_canvas
        d = self.direction
        out = (None if e is None or e.neutral else e, None if c is None or c.neutral else c,
               tuple(self.features), self.lattice, None if a is None or a.empty else a,
               self.labels_exemplar, None if lc is None or lc.empty else lc, float(self.label_strength),
               None if d is None or d.identity else d, self.surface)
        before = (e, c, self.features, self.lattice, a, self.labels_exemplar, lc, self.label_strength, d,
                  self.surface)
        if all(x is y for i, (x, y) in enumerate(zip(out, before)) if i != 7) and out[7] == before[7]:
            return self  # already normalized: keep what is cached (the features' arrays)
        return Controls(*out)

    @property
    def labels_active(self) -> bool:
        """Canvas labels are painted and the exemplar has a label map: synthesis follows them."""
        return self.labels_exemplar is not None and self.labels_canvas is not None and not self.labels_canvas.empty

    def exemplar_inputs(self) -> tuple:
        """What is painted over the exemplar (randomness field, avoid mask, label
        map) and the label strength: a change of any reaches the whole canvas."""
        return (self.randomness_exemplar, self.avoid, self.labels_exemplar,
                float(self.label_strength) if self.labels_exemplar is not None else None)

    def jitter_at(self, params, m: int, level: int) -> float:
        """r_l as the passes use it: the document's randomness on ``level``,
        times LATTICE_FINE_JITTER on the levels finer than a lattice's lattice
        levels (their jitter is not whole cells, and at full strength it moves
        parts of a cell out of step with its neighbors: grid lines kink)."""
        r = float(params.jitter[level])
        if self.lattice is not None and self.lattice.quant_shift(m, level) is None:
            r *= LATTICE_FINE_JITTER
        return r

    @property
    def dithered_upsampling(self) -> bool:
        """Whether each pixel is upsampled from a parent chosen at random per axis
        (common.glsl parent_step), so that seams do not run straight along a
        coarse level's texel borders; not on a lattice, whose seams belong on
        the borders of its cells."""
        return self.lattice is None

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
        le = self.labels_exemplar
        if le is not None and le.size != m:
            raise ValueError(f"The exemplar label map is {le.size}x{le.size}; the exemplar is {m}x{m}.")
        if not 0.0 <= float(self.label_strength) <= 8.0:
            raise ValueError("The label strength must be from 0 to 8.")
        if self.labels_active and self.lattice is not None:
            raise ValueError("Texture by numbers does not work on a lattice; turn one of them off.")
        if self.direction is not None and not self.direction.identity and self.lattice is not None:
            raise ValueError("A direction field does not work on a lattice; turn one of them off.")
        if self.surface is not None and (self.lattice is not None or self.directed_field):
            raise ValueError("Synthesis on a model takes its directions from the model; it does not work with "
                             "a lattice or a painted direction field.")
        if self.labels_active:
            missing = sorted(set(self.labels_canvas.used) - set(le.present))
            if missing:
                raise ValueError(f"The canvas labels use label {missing[0] + 1}, which the exemplar's label map "
                                 f"does not have (it has {', '.join(str(i + 1) for i in le.present)}).")
        L = m.bit_length() - 1
        if self.features:
            f = self._features
            levels = (f[:, 8] == 1) & ((f[:, 4] < 0) | (f[:, 4] > f[:, 5]) | (f[:, 5] > L))
            bad = ((f[:, 6:8] < 0) | (f[:, 6:8] >= m)).any(axis=1) | (f[:, 2] < 0) | (f[:, 2] > f[:, 3]) \
                | (f[:, 3] > MAX_FEATURE_RADIUS) | levels
            for i in np.flatnonzero(bad)[:1]:
                self.features[i].validate(m, L)  # its sentence

    @cached_property
    def _features(self) -> np.ndarray:
        """The features as int64 arrays (feature_arrays), computed once."""
        return feature_arrays(self.features)

    @cached_property
    def features_key(self) -> str:
        import hashlib
        return hashlib.sha256(self._features.tobytes() + repr(self._features.shape).encode()).hexdigest()

    def level_signature(self, level: int, m: int = 0) -> tuple:
        """What level ``level`` reads of the controls (fields change all levels)."""
        e, c = self.randomness_exemplar, self.randomness_canvas
        labels = (self.labels_exemplar.key, self.labels_canvas.key, float(self.label_strength)) \
            if self.labels_active else None
        return (None if e is None else e.key, None if c is None else c.key,
                self.features_key if self.features else None,
                None if self.lattice is None else (self.lattice.nx, self.lattice.ny, self.lattice_shift(m, level)),
                None if self.avoid is None else self.avoid.key, labels,
                None if self.direction is None else self.direction.key,
                None if self.surface is None else self.surface.key)

    @property
    def directed_field(self) -> bool:
        """A direction field other than the identity is painted."""
        return self.direction is not None and not self.direction.identity

    @property
    def directed(self) -> bool:
        """Coordinates carry sub-pixel parts: a direction field is painted, or
        synthesis runs in a mesh's atlas (J per texel)."""
        return self.directed_field or self.surface is not None

    def _meeting(self, x0: int, y0: int, x1: int, y1: int) -> np.ndarray:
        """Indices (ascending) of the features whose reach (Feature.bbox) meets a finest-level rectangle."""
        f = self._features
        r = f[:, 3] + 2
        return np.flatnonzero((f[:, 0] - r < x1) & (x0 < f[:, 0] + r + 1) & (f[:, 1] - r < y1) & (y0 < f[:, 1] + r + 1))

    def features_in(self, x0: int, y0: int, x1: int, y1: int) -> list[int]:
        """Indices (in order) of the features whose reach meets a finest-level rectangle."""
        return self._meeting(x0, y0, x1, y1).tolist() if self.features else []

    def feature_table(self, level: int, L: int, m: int, toroidal: bool, x0: int, y0: int, x1: int, y1: int,
                      period: int = 0) -> np.ndarray | None:
        """The features active at ``level`` over a level-pixel rectangle, as the
        int32 (N, 2, 4) table the passes read: (p_F,l x, y, frac x + 16 frac y,
        radius in 1/16 level pixels), (u_F x, y, 0, 0); None when there are none.
        With a period (a toroidal tile) every feature applies, modulo the tile.
        Computed on arrays (Feature.level_range, radius_at and clamped, for all at once)."""
        if not self.features:
            return None
        if self.surface is not None:  # placed on a model: per-chart copies (engine/surface/features.py)
            return self.surface.feature_table(self.features_key, self._features, level, L, m, toroidal,
                                              x0, y0, x1, y1)
        k = L - level
        f = self._features if period else self._features[self._meeting(x0 << k, y0 << k, x1 << k, y1 << k)]
        active, radius, u = level_values(f, level, L, m, toroidal)
        f, radius, u = f[active], radius[active], u[active]
        if not len(f):
            return None
        px, py = f[:, 0], f[:, 1]
        table = np.zeros((len(f), 2, 4), dtype=np.int32)
        table[:, 0] = np.stack([px >> k, py >> k, (((px << 4) >> k) & 15) + 16 * (((py << 4) >> k) & 15),
                                (radius << 4) >> k], axis=-1)
        table[:, 1, :2] = u
        return table

    def feature_lookup(self, level: int, L: int, m: int, toroidal: bool, x0: int, y0: int, x1: int, y1: int,
                       period: int = 0):
        """What the shader reads of the features over a strip: (feature_table,
        then feature_bins' cells, entries, origin and shift), or None when none
        is active there. A pixel then tests only the features whose reach meets
        its cell: the cost follows the features a strip touches."""
        table = self.feature_table(level, L, m, toroidal, x0, y0, x1, y1, period)
        if table is None:
            return None
        if self.surface is not None:
            return (table, *reach_bins(*self.surface.table_reach(table, level, L), len(table), x0, y0,
                                       x1 - x0, y1 - y0))
        return (table, *feature_bins(table, x0, y0, x1 - x0, y1 - y0, period))

    def reaches_everywhere(self, other: Controls) -> bool:
        """Whether going from these controls to ``other`` may change the texture
        anywhere, whatever was edited where: the exemplar's inputs (randomness
        field, avoid mask, labels), the lattice, the model, what unpainted
        labels mean, the first or last direction field (the state gains or drops
        its sub-pixel parts), or the features on a model (one reaches other
        charts of the atlas)."""
        if self.exemplar_inputs() != other.exemplar_inputs() or self.lattice != other.lattice \
                or self.surface is not other.surface:
            return True
        la, lb = self.labels_canvas or CanvasLabels(), other.labels_canvas or CanvasLabels()
        if la.background != lb.background:
            return True
        if self.directed and not other.directed:
            return True
        return self.surface is not None and self.features != other.features

    def changed_rects(self, other: Controls) -> list | None:
        """Finest-level rectangles outside which ``other`` reads the same as this
        one, found by comparing the two (an edit made by a tool says where it
        reached instead: :meth:`Pyramid.update_controls`'s ``changed``); None when
        the change reaches everywhere (:meth:`reaches_everywhere`)."""
        if self.reaches_everywhere(other):
            return None
        before = self.randomness_canvas or CanvasField()
        after = other.randomness_canvas or CanvasField()
        out = before.changed_rects(after)
        la, lb = self.labels_canvas or CanvasLabels(), other.labels_canvas or CanvasLabels()
        out += la.changed_rects(lb)
        out += (self.direction or DirectionField()).changed_rects(other.direction or DirectionField())
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
