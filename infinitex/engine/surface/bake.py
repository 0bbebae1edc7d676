"""Synthesis in a model's atlas and the images made from it.

:func:`atlas_coords` synthesizes the whole atlas (one window per level; the
passes read across chart seams through the atlas' indirection maps) and
returns exemplar coordinates with their sub-pixel remainders. :func:`atlas_image`
looks a map up through them (bilinear, like every directed synthesis), then
fills what lies off the charts so that the GPU's filtering and mipmaps do
not bleed background into the model: a linked gutter texel takes the colour
across the seam (the same surface point), every other texel its nearest chart
texel's.
"""
from __future__ import annotations

from dataclasses import replace

import numpy as np

from ..controls import NO_CONTROLS, Controls
from ..rect import Rect
from ..subpixel import sample, turn_normals
from .atlas import AtlasDomain, AtlasError


def check_sizes(atlas: AtlasDomain, exemplar_size: int) -> None:
    if atlas.size < exemplar_size:
        raise AtlasError(f"The atlas ({atlas.size} px) must be at least as large as the exemplar "
                         f"({exemplar_size} px).")


def with_comb(atlas: AtlasDomain, controls: Controls) -> AtlasDomain:
    """The atlas with the controls' direction field combed over it (AtlasDomain.combed); as it is without one."""
    return atlas if controls.direction is None else atlas.combed(controls.direction)


def atlas_coords(synth, atlas: AtlasDomain, controls: Controls = NO_CONTROLS) -> np.ndarray:
    """(N, N, 4) int32: the exemplar coordinate and remainder (1/256 px) of
    every atlas texel, synthesized with ``synth`` (an engine Synthesizer;
    its controls are replaced by ``controls`` with the atlas as surface; their
    direction field is combed over the model: AtlasDomain.combed)."""
    check_sizes(atlas, synth.analysis.size)
    saved = synth.controls
    synth.set_params(synth.params, replace(controls, surface=with_comb(atlas, controls), direction=None))
    try:
        return synth.window(Rect(0, 0, atlas.size, atlas.size), remainder=True)
    finally:
        synth.controls = saved


def fill_off_charts(image: np.ndarray, atlas: AtlasDomain, k: int = 0) -> np.ndarray:
    """Texels off the charts (of level k): linked ones take their target's value,
    the rest their nearest chart texel's (in place; returned)."""
    own = atlas.owner(k)
    chart, to = atlas.link_map(k)
    on = own >= 0
    linked = ~on & (chart >= 0)
    image[linked] = image[to[linked][:, 1], to[linked][:, 0]]
    known = on | linked
    if known.any() and not known.all():
        from scipy import ndimage  # imported when a model is baked, not by every command
        iy, ix = ndimage.distance_transform_edt(~known, return_distances=False, return_indices=True)
        image[~known] = image[iy[~known], ix[~known]]
    return image


def atlas_image(stack: np.ndarray, coords: np.ndarray, atlas: AtlasDomain, wrap: bool,
                normals: bool = False) -> np.ndarray:
    """A map (float32 (N, N, C)) through the atlas' coordinates: bilinear
    lookups of ``stack`` (the exemplar's finest level, or a material map aligned
    with it); ``normals``: a tangent-space normal map, turned with J."""
    img = sample(stack, coords, wrap)
    if normals:
        img = turn_normals(img, atlas.jacobians(0, 0, 0, atlas.size, atlas.size))
    return fill_off_charts(img, atlas)
