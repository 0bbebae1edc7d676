"""A palette of exemplars (texture by numbers across several images): each
exemplar, or material with the same maps, becomes one label of a single
combined exemplar the engine synthesizes from.

Packing: the entries, each fitted by the document's fit rule, are brought to
one cell size ``c`` (the smallest entry's side, halved until the grid fits the
fit rule's largest exemplar; larger entries are resized to it, or center
cropped under a "crop" rule) and laid out row by row on a ``g x g`` grid, g
the smallest power of two with g*g >= the number of entries. Cells beyond the
last entry repeat the entries from the first (cell j holds entry j mod n), so
no cell is empty. The combined exemplar is toroidal: every cell borders others
on all four sides, and the neighborhoods that straddle two cells are the
transitions synthesis may use between labels. Its label map gives cell j the
label j mod n.

The coordinate map stays meaningful: exemplar pixel (x, y) lies in cell
(x // c, y // c), whose entry and pixel within the entry (as fitted) are
:meth:`PaletteLayout.locate`.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from PIL import Image

from .exemplar import MIN_SIZE, Exemplar, ExemplarError, fit_rule
from .material import MATERIAL_BUDGET, Material, MaterialError, MaterialMap, map_costs, renormalize

MAX_ENTRIES = 16  # one label each


HEAD_BYTES = 1 << 20  # what is read of a palette file not yet read to size its decode from its header


def check_palette_budget(entries: list[list[tuple[str, bytes]]], fit: str,
                         sizes: dict[str, int] | None = None) -> None:
    """Refuse a palette whose import would need more than MATERIAL_BUDGET at its
    peak, like one material's: every entry's files (held throughout), the
    largest single decode and every fitted map, from the headers, before any
    entry is decoded. ``entries``: per entry, its maps' (name, file bytes).
    ``sizes``: {name: file size} of files given by their first bytes only
    (:func:`file_heads`): their size counts, and a header those bytes do not
    hold is left to the check of the whole file."""
    peaks, kept, files = [0], 0, 0
    for entry in entries:
        for name, data in entry:
            head_only = sizes is not None and name in sizes and sizes[name] > len(data)
            try:
                peak, k = map_costs(data, name, fit)
            except ExemplarError as exc:
                if head_only:  # (a TIFF whose directory lies past the first bytes, say)
                    peak, k = 0, 0
                else:
                    raise MaterialError(f"The palette's {name}: {exc}") from None
            peaks.append(peak)
            kept += k
            files += sizes[name] if sizes is not None and name in sizes else len(data)
    total = files + max(peaks) + kept
    if total > MATERIAL_BUDGET:
        raise MaterialError(f"The palette's {len(entries)} exemplars would need about {total // 2**20} MB to import "
                            f"together, more than the {MATERIAL_BUDGET // 2**20} MB allowed; use fewer or smaller ones.")


def file_heads(paths: list[str]) -> tuple[list[tuple[str, bytes]], dict[str, int]]:
    """([(name, first HEAD_BYTES)], {name: size}) of regular files not yet
    read (safeio.read_head: never blocks; anything else is left to the full
    read, which refuses it)."""
    import os

    from .safeio import read_head
    heads, sizes = [], {}
    for path in paths:
        head = read_head(path, HEAD_BYTES)
        if head:
            name = os.path.basename(path)
            heads.append((name, head))
            sizes[name] = os.path.getsize(path)
    return heads, sizes


def grid_side(n: int) -> int:
    """g: the smallest power of two with g * g >= n (the grid of n entries)."""
    g = 1
    while g * g < n:
        g *= 2
    return g


def cell_labels(n: int) -> np.ndarray:
    """The label of each cell of the grid of n entries: uint8 (g, g), cell j -> j mod n."""
    g = grid_side(n)
    return (np.arange(g * g) % n).astype(np.uint8).reshape(g, g)


@dataclass(frozen=True)
class PaletteLayout:
    """Where each entry of a palette lies in the combined exemplar."""

    names: tuple[str, ...]   # the entries' file names, in label order
    grid: int                # g: the exemplar is g x g cells
    cell: int                # c: a cell's side in exemplar pixels
    sizes: tuple[int, ...]   # each entry's side as fitted, before it was brought to the cell
    crop: bool = False       # entries larger than the cell were center-cropped (else resized)

    @property
    def size(self) -> int:
        return self.grid * self.cell

    @property
    def count(self) -> int:
        return len(self.names)

    def labels(self) -> np.ndarray:
        """The combined exemplar's label map: uint8 (m, m), cell j -> label j mod n."""
        c = self.cell
        return np.ascontiguousarray(np.kron(cell_labels(self.count), np.ones((c, c), np.uint8)))

    def locate(self, coords: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(entry, x, y) of exemplar coordinates ``coords`` (..., 2): which
        entry each pixel was copied from and where in that entry (its pixels as
        fitted by the document's rule)."""
        coords = np.asarray(coords, np.int64)
        c = self.cell
        x, y = coords[..., 0], coords[..., 1]
        entry = ((y // c) * self.grid + x // c) % self.count
        sizes = np.asarray(self.sizes, np.int64)[entry]
        lx, ly = x % c, y % c
        if self.crop:
            off = (sizes - c) // 2
            return entry, lx + off, ly + off
        return entry, (lx * sizes) // c, (ly * sizes) // c


def _channels(px: np.ndarray, want: int) -> np.ndarray:
    """Pixels brought to ``want`` channels: gray replicated to RGB, an opaque alpha added."""
    c = px.shape[2]
    if c == want:
        return px
    gray = c <= 2
    color = np.repeat(px[..., :1], 3, axis=2) if gray and want >= 3 else px[..., :min(c, 3) if not gray else 1]
    alpha = px[..., c - 1:] if c in (2, 4) else np.ones(px.shape[:2] + (1,), np.float32)
    parts = [color] + ([alpha] if want in (2, 4) else [])
    return np.ascontiguousarray(np.concatenate(parts, axis=2), dtype=np.float32)


def resized(px: np.ndarray, size: int) -> np.ndarray:
    """Square float32 pixels (n, n, C) in [0, 1] resized to size x size (Lanczos, per channel)."""
    planes = [np.asarray(Image.fromarray(np.ascontiguousarray(px[..., k], dtype=np.float32), mode="F")
                         .resize((size, size), Image.LANCZOS)) for k in range(px.shape[2])]
    return np.ascontiguousarray(np.clip(np.stack(planes, axis=2), 0.0, 1.0), dtype=np.float32)


def _to_cell(px: np.ndarray, c: int, crop: bool, role: str) -> np.ndarray:
    m = px.shape[0]
    if m == c:
        return px
    if crop:
        o = (m - c) // 2
        return px[o:o + c, o:o + c]
    out = resized(px, c)
    return renormalize(out) if role == "normal" else out


def layout_for(names: list[str], sizes: list[int], fit: str) -> PaletteLayout:
    """The packing of entries of fitted sides ``sizes`` under ``fit``; ExemplarError if impossible."""
    n = len(sizes)
    if not 2 <= n <= MAX_ENTRIES:
        raise ExemplarError(f"A palette has 2 to {MAX_ENTRIES} exemplars, not {n}.")
    rule, limit = fit_rule(fit)
    g = grid_side(n)
    c = min(sizes)
    while g * c > limit:
        c //= 2
    if c < MIN_SIZE:
        raise ExemplarError(f"{n} exemplars need cells of at least {MIN_SIZE} px; the smallest is {min(sizes)} px.")
    return PaletteLayout(tuple(names), g, c, tuple(int(s) for s in sizes), crop=rule == "crop")


def pack_palette(entries: list[Material], names: list[str], fit: str) -> tuple[Material, PaletteLayout]:
    """One material holding every entry's maps on the palette's grid (the
    entries have the same roles), and its layout."""
    roles = entries[0].roles
    for i, mat in enumerate(entries[1:], start=1):
        if mat.roles != roles:
            raise ExemplarError(f"{names[i]} has the maps {', '.join(mat.roles)} but {names[0]} has "
                                f"{', '.join(roles)}; the exemplars of a palette have the same maps.")
    layout = layout_for(names, [mat.size for mat in entries], fit)
    g, c, n = layout.grid, layout.cell, layout.count
    maps = {}
    for role in roles:
        exs = [mat.maps[role].exemplar for mat in entries]
        if len({ex.value_range for ex in exs}) > 1:
            raise ExemplarError(f"The {role} maps of the palette have different value ranges "
                                "(float images scaled differently); they cannot share one exemplar.")
        want = max(ex.channels for ex in exs)
        cells = [_to_cell(_channels(ex.pixels, want), c, layout.crop, role) for ex in exs]
        out = np.empty((g * c, g * c, want), np.float32)
        for j in range(g * g):
            y, x = divmod(j, g)
            out[y * c:(y + 1) * c, x * c:(x + 1) * c] = cells[j % n]
        first = exs[0]
        ex = Exemplar(pixels=out, toroidal=True, toroidal_guess=True, source="palette: " + ", ".join(names),
                      fit=first.fit, original_size=(g * c, g * c), hires=None,
                      depth=max(e.depth for e in exs), value_range=first.value_range)
        maps[role] = MaterialMap(role, ex)
    return Material(maps, True), layout
