"""Synthesis parameters and the geometry that follows from them (LH05 3.3-3.4)."""
from __future__ import annotations

from dataclasses import dataclass, replace
from functools import lru_cache

import numpy as np

from . import fixed

DEFAULT_JITTER = 0.6
# TBN10 random-walk steps when the analysis has no similarity sets (k = 0).
DEFAULT_WALK = 6
FIRST_CORRECTED_LEVEL = 3  # LH05: correction is skipped on levels 0-2
# The fidelity stage (discrete patch optimization, shaders/fidelity.frag): patches
# of (2 R + 1)^2 level pixels (R = SynthParams.fidelity_radius, default
# FIDELITY_RADIUS), FIDELITY_SEARCH random candidates around the best (radius
# m/4, halved each step) after the 8 neighbors' predictions; with
# SynthParams.fidelity_vote each iteration's search is followed by a vote (a
# plurality over the predictions of the patches around each pixel: Kwatra et
# al. 2005's voting step, on coordinates).
FIDELITY_RADIUS = 3
FIDELITY_RADII = (2, 3, 4, 5)
FIDELITY_SEARCH = 4
MAX_FIDELITY = 6


@dataclass(frozen=True)
class SynthParams:
    """Everything besides the analysis that decides the synthesized texture.

    ``jitter`` holds r_l per level (coarse to fine, L+1 values in [0, 1]);
    ``corrected`` lists the levels that get correction, None meaning LH05's
    default (levels >= 3), each getting ``passes`` passes, unless
    ``level_passes`` gives the count per level; ``period`` is 0 for the infinite canvas or n (a
    power of two) for an n x n toroidal texture.
    """

    jitter: tuple[float, ...]
    seed: int = 0
    passes: int = 2            # c
    subgrid: int = 2           # s: s^2 subpasses per pass
    kappa: float = 0.5
    corrected: tuple[int, ...] | None = None
    period: int = 0
    walk: int | None = None    # TBN10 random-walk steps added to each correction (0: off; radius m/2 halved);
                               # None: DEFAULT_WALK without similarity sets (k = 0), else off
    level_passes: tuple[int, ...] | None = None  # correction passes per level, coarse to fine (0: not corrected);
                                                 # overrides `passes` and `corrected`; None: `passes` on `corrected`
    fidelity: tuple[int, ...] | None = None  # fidelity-stage iterations per level, coarse to fine (None: none)
    fidelity_radius: int = FIDELITY_RADIUS   # its patches: (2 R + 1)^2 level pixels
    fidelity_vote: bool = False              # each iteration: a search pass, then a vote pass

    @classmethod
    def default(cls, levels: int, **kw) -> "SynthParams":
        """Defaults for an exemplar with finest level L = ``levels``."""
        return cls(jitter=(DEFAULT_JITTER,) * (levels + 1), **kw)

    def with_jitter(self, r: float) -> "SynthParams":
        return replace(self, jitter=(float(r),) * len(self.jitter))

    @property
    def L(self) -> int:
        return len(self.jitter) - 1

    def passes_at(self, level: int) -> int:
        """Correction passes of level ``level``: ``level_passes[level]`` when given
        (which then decides alone which levels are corrected), else ``passes`` on
        the corrected levels and 0 elsewhere."""
        if self.level_passes is not None:
            return int(self.level_passes[level]) if 0 <= level < len(self.level_passes) else 0
        return int(self.passes) if level in self.corrected_levels() else 0

    def fidelity_at(self, level: int) -> int:
        """Iterations of the fidelity stage on ``level`` (0: none)."""
        if self.fidelity is None or not 0 <= level < len(self.fidelity):
            return 0
        return int(self.fidelity[level])

    def fidelity_passes(self, level: int) -> int:
        """Passes of the fidelity stage on ``level``, in subpass_order: one per
        iteration, or with the vote two (the search on even passes, the vote on odd)."""
        return self.fidelity_at(level) * (2 if self.fidelity_vote else 1)

    def corrected_levels(self) -> frozenset[int]:
        """The levels chosen for correction (whatever their pass counts)."""
        if self.corrected is None:
            return frozenset(range(FIRST_CORRECTED_LEVEL, self.L + 1))
        return frozenset(self.corrected)

    def correcting_levels(self) -> frozenset[int]:
        """The levels that actually get correction subpasses."""
        return frozenset(l for l in range(self.L + 1) if self.passes_at(l) > 0)

    def validate(self, levels: int) -> None:
        """Raise ValueError with a user-readable sentence if unusable."""
        if len(self.jitter) != levels + 1:
            raise ValueError(f"Expected {levels + 1} randomness values (one per level), got {len(self.jitter)}.")
        for r in self.jitter:
            fixed.jitter_q(r)
        fixed.psi_q(self.kappa)
        if not 0 <= self.passes <= 8:
            raise ValueError("Correction passes must be between 0 and 8.")
        if self.level_passes is not None:
            if len(self.level_passes) != levels + 1:
                raise ValueError(f"Expected {levels + 1} correction pass counts (one per level), "
                                 f"got {len(self.level_passes)}.")
            if not all(0 <= int(c) <= 8 for c in self.level_passes):
                raise ValueError("Correction passes must be between 0 and 8 on every level.")
        if self.fidelity is not None:
            if len(self.fidelity) != levels + 1:
                raise ValueError(f"Expected {levels + 1} fidelity iteration counts (one per level), "
                                 f"got {len(self.fidelity)}.")
            if not all(0 <= int(c) <= MAX_FIDELITY for c in self.fidelity):
                raise ValueError(f"Fidelity iterations must be between 0 and {MAX_FIDELITY} on every level.")
        if self.fidelity_radius not in FIDELITY_RADII:
            raise ValueError(f"The fidelity patch radius must be one of {', '.join(map(str, FIDELITY_RADII))}.")
        if self.walk is not None and not 0 <= self.walk <= 12:
            raise ValueError("Random-walk steps must be between 0 and 12.")
        if not 1 <= self.subgrid <= 4:
            raise ValueError("The subpass grid size s must be between 1 and 4.")
        bad = [l for l in self.corrected_levels() if not 0 <= l <= levels]
        if bad:
            raise ValueError(f"Corrected levels {bad} do not exist (levels are 0..{levels}).")
        if self.period and (self.period & (self.period - 1) or not 32 <= self.period <= 4096):
            raise ValueError("A toroidal texture size must be a power of two from 32 to 4096.")
        if not 0 <= self.seed < 2 ** 32:
            raise ValueError("The seed must be an integer in [0, 2^32).")

    def level_period(self, level: int) -> int:
        """n_l: the period at level l (0 = none); 1 means the level is constant."""
        if not self.period:
            return 0
        return max(1, self.period >> (self.L - level))

    def walk_steps(self, k: int, avoiding: bool = False) -> int:
        """Random-walk steps of a correction with similarity sets of size k (by
        default on without sets, or with exemplar regions to avoid: the walk
        finds a way out of them)."""
        if self.walk is not None:
            return int(self.walk)
        return DEFAULT_WALK if k == 0 or avoiding else 0

    def level_signature(self, level: int) -> tuple:
        """What level ``level`` itself depends on (beyond coarser levels)."""
        corr = level in self.correcting_levels()
        fid = self.fidelity_at(level)
        return (self.jitter[level], self.seed, self.level_period(level), corr,
                (self.passes_at(level), self.subgrid, self.kappa, self.walk) if corr else None,
                (fid, self.subgrid, self.fidelity_radius, self.fidelity_vote) if fid else None)


# "Structure / Variety" (a document setting): 0 is the per-pixel synthesis alone
# (most variety); each step up runs the fidelity stage more, for textures whose
# elements must come out whole (weaves, cells, text, bricks). Per preset: the
# stage's iterations per level from the finest (the last count repeats down to
# FIRST_CORRECTED_LEVEL), the patch radius and whether each iteration ends with
# the vote. The iterations go where they pay: on the coarser scales, which lay
# out the elements, and which are small (a second iteration there, none on the
# finest scale, is closer to the exemplar than one everywhere, in less time).
# (Less randomness on the fine levels was measured too and did not help; the
# measurements: docs/benchmarks.md.)
STRUCTURE_NAMES = ("Variety", "Light", "Balanced", "Strong", "Maximum")
STRUCTURE_LEVELS = len(STRUCTURE_NAMES)
STRUCTURE_PRESETS = (
    ((), FIDELITY_RADIUS, False),
    ((0, 1, 1, 2), 2, True),
    ((0, 1, 1, 2), 3, True),
    ((1, 2), 3, True),
    ((3,), 5, True),
)
DEFAULT_STRUCTURE = 2


def structure_index(value: int | str) -> int:
    """A Structure preset from its number (0 to 4) or its name (any case)."""
    names = [n.lower() for n in STRUCTURE_NAMES]
    if isinstance(value, str):
        t = value.strip().lower()
        if t in names:
            return names.index(t)
        if t.isdigit() and int(t) < len(names):
            return int(t)
    elif isinstance(value, (int, np.integer)) and not isinstance(value, bool) and 0 <= value < len(names):
        return int(value)
    raise ValueError(f"{str(value)[:40]!r} is not a Structure preset: use 0 to {len(names) - 1} "
                     f"or {', '.join(names)}.")


def structure_params(params: SynthParams, structure: int) -> SynthParams:
    """``params`` with the fidelity stage of a Structure preset (0: ``params`` unchanged)."""
    if not 0 <= int(structure) < STRUCTURE_LEVELS:
        raise ValueError(f"Structure must be from 0 ({STRUCTURE_NAMES[0]}) to {STRUCTURE_LEVELS - 1} "
                         f"({STRUCTURE_NAMES[-1]}).")
    counts, radius, vote = STRUCTURE_PRESETS[int(structure)]
    if not counts:
        return params
    L = params.L
    fid = tuple(counts[min(L - l, len(counts) - 1)] if l >= min(FIRST_CORRECTED_LEVEL, L) else 0
                for l in range(L + 1))
    return replace(params, fidelity=fid, fidelity_radius=radius, fidelity_vote=vote)


def subpass_order(s: int, passes: int) -> list[list[tuple[int, int]]]:
    """The phases (i, j) rewritten by each subpass of each pass.

    For s = 2 this is LH05's order (chosen to reduce padding); otherwise a fixed
    shuffle (a scanline order is worse, LH05 3.3)."""
    if s == 2:
        lh05 = [[(0, 0), (1, 1), (0, 1), (1, 0)], [(0, 1), (0, 0), (1, 1), (1, 0)]]
        return [lh05[c % 2] for c in range(passes)]
    phases = [(i, j) for j in range(s) for i in range(s)]
    out = []
    for c in range(passes):
        keyed = sorted(phases, key=lambda ph: int(fixed.lowbias32(
            (ph[0] * 73856093) ^ (ph[1] * 19349663) ^ (c * 83492791) ^ 0x5BD1E995)))
        out.append(keyed)
    return out


@lru_cache(maxsize=256)
def correction_margins(s: int, passes: int, radius: int,
                       stages: tuple[tuple[int, int], ...] = ()) -> tuple[int, int, int, int]:
    """Exact padding (left, right, top, bottom) a region needs so that after all
    subpasses its interior is independent of what lies outside (LH05 3.4):
    ``passes`` correction passes reading ``radius`` around each pixel, then each
    further stage of ``stages`` as (passes, radius) (the fidelity stage).

    Tracks, per phase, how far from each side of the (s-aligned) buffer its
    pixels are exact; a rewritten pixel is exact once everything it reads is.
    """
    phases = [(i, j) for j in range(s) for i in range(s)]
    margin = {ph: [0, 0, 0, 0] for ph in phases}
    for n, r in ((passes, radius),) + tuple(stages):
        foot = [(dx, dy) for dy in range(-r, r + 1) for dx in range(-r, r + 1)]
        for order in subpass_order(s, n):
            for ph in order:
                new = [0, 0, 0, 0]
                for dx, dy in foot:
                    other = margin[((ph[0] + dx) % s, (ph[1] + dy) % s)]
                    new = [max(new[0], other[0] - dx), max(new[1], other[1] + dx),
                           max(new[2], other[2] - dy), max(new[3], other[3] + dy)]
                margin[ph] = new
    return tuple(max(margin[ph][i] for ph in phases) for i in range(4))


def subpass_rects(s: int, stages: tuple[tuple[int, int], ...], dims: tuple[int, int],
                  interior: tuple[int, int, int, int]) -> tuple | None:
    """What each subpass must compute (see _needs), or None."""
    needs = _needs(s, stages, dims, interior)
    return None if needs is None else needs[0]


def first_rects(s: int, stages: tuple[tuple[int, int], ...], dims: tuple[int, int],
                interior: tuple[int, int, int, int]) -> dict | None:
    """What the first subpass reads of each phase, so what the upsampling must
    compute: phase -> block texels (x0, y0, x1, y1) (see _needs), or None."""
    needs = _needs(s, stages, dims, interior)
    return None if needs is None else needs[1]


@lru_cache(maxsize=1024)
def _needs(s: int, stages: tuple[tuple[int, int], ...], dims: tuple[int, int],
           interior: tuple[int, int, int, int]) -> tuple | None:
    """What each subpass must compute so that the ``interior`` (x0, y0, x1, y1,
    local pixels of a region of ``dims``) comes out exactly as if every subpass
    computed its whole block: per subpass of ``stages`` ((passes, read radius)
    each, in subpass_order, as correction_margins), its rectangle in block
    texels (x0, y0, x1, y1), possibly empty; and per phase what the first
    subpass reads of it. None when a read would leave the region (then compute
    whole blocks).

    Walked backwards: a subpass matters only at the pixels of its phase that
    later subpasses (or the interior) read, and those read their neighbors
    within the radius, which is what matters of each phase before it. A
    pixel computed with the same inputs gets the same value, and the pixels
    left as they were are never read by one that matters. A small window on
    the coarse scales, whose margins are most of their regions, costs a
    fraction of what it did."""
    phases = [(i, j) for j in range(s) for i in range(s)]
    seq = [(ph, r) for n, r in stages for order in subpass_order(s, n) for ph in order]
    # Per phase, the block texels that matter (x0, y0, x1, y1; empty when x0 >= x1).
    need = {}
    for q in phases:
        need[q] = tuple(-(-(interior[a] - q[a % 2]) // s) for a in (0, 1)) + \
            tuple((interior[a] - 1 - q[a % 2]) // s + 1 for a in (2, 3))
    out = []
    for ph, r in reversed(seq):
        b = need[ph]
        out.append(b)
        if b[0] >= b[2] or b[1] >= b[3]:
            continue
        # The pixels of phase ph it computes span [lo, hi] per axis; a read at
        # offset d lands on phase (ph + d) mod s, block texel floor((x + d) / s).
        lo = (s * b[0] + ph[0], s * b[1] + ph[1])
        hi = (s * (b[2] - 1) + ph[0], s * (b[3] - 1) + ph[1])
        if lo[0] - r < 0 or lo[1] - r < 0 or hi[0] + r >= dims[0] or hi[1] + r >= dims[1]:
            return None
        for q in phases:
            reads = [0, 0, 0, 0]
            for a in (0, 1):
                ds = [d for d in range(-r, r + 1) if (ph[a] + d - q[a]) % s == 0]
                if not ds:
                    reads = None
                    break
                reads[a] = (lo[a] + min(ds) - q[a]) // s
                reads[a + 2] = (hi[a] + max(ds) - q[a]) // s + 1
            if reads is None:
                continue
            old = need[q]
            if q != ph and old[0] < old[2] and old[1] < old[3]:
                reads = [min(old[0], reads[0]), min(old[1], reads[1]), max(old[2], reads[2]), max(old[3], reads[3])]
            need[q] = tuple(reads)
    return tuple(out[::-1]), dict(need)
