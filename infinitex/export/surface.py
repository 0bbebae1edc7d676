"""Texture a model: synthesize in its atlas (engine/surface) and write every
map of the document's material at the atlas' size, plus a GLB of the model with
the maps attached (PBR: base color, normal, metallic-roughness, occlusion),
which opens as is in Blender and any glTF viewer.

Synthesis runs at up to 4096 texels; larger outputs (to 8192) are synthesis
magnification of it (LH05 5 / LH06 6): each output texel blends its 4 nearest
synthesized texels' coordinates, extrapolated through their J. Off the charts,
a texel takes the colour across its seam (a linked gutter texel) or its
nearest chart texel's, so filtering and mipmaps do not bleed background in.
"""
from __future__ import annotations

import os
from dataclasses import dataclass, replace

import numpy as np

from infinitex.engine.controls import Controls
from infinitex.engine.imagefile import encode_image, to_u8
from infinitex.engine.material import IMAGE, Material
from infinitex.engine.pyramid import Pyramid, Rect, SynthesisError
from infinitex.engine.safeio import atomic_write
from infinitex.engine.subpixel import turn_normals
from infinitex.engine.surface.atlas import MAX_SIZE, AtlasDomain
from infinitex.engine.surface.bake import atlas_coords, fill_off_charts, with_comb
from infinitex.engine.surface.mesh import Model, texel_density

MAX_OUTPUT = 8192
MAG_BAND = 128  # synthesized rows magnified at once


@dataclass(frozen=True)
class SurfacePlan:
    """What a surface bake makes: the output size, the synthesized size, and the texture's scale."""

    size: int  # output texels a side
    synth_size: int  # synthesized texels a side (size, or 4096 magnified)
    sigma: float  # exemplar px per world unit

    @property
    def magnify(self) -> int:
        return self.size // self.synth_size


def plan(model: Model, size: int, exemplar_size: int, repeats: float | None = None,
         texel_ratio: float | None = None, synth_size: int | None = None) -> SurfacePlan:
    """Sizes and scale: ``repeats``: the exemplar's width fits this many times
    across the model's largest side; else ``texel_ratio`` (default 1) exemplar
    px per synthesized texel, typically. ``synth_size``: synthesize at this
    size (a project's own, which its painted maps are in) and magnify to ``size``."""
    if size & (size - 1) or not exemplar_size <= size <= MAX_OUTPUT or size < 64:
        raise ValueError(f"The texture size must be a power of two from {max(64, exemplar_size)} "
                         f"(the exemplar's size) to {MAX_OUTPUT}.")
    synth = min(size, MAX_SIZE) if synth_size is None else synth_size
    if synth > size or size // synth > 8:
        raise ValueError(f"A texture of {size} px is made from a synthesized one of {size // 8} to {size} px.")
    if repeats is not None:
        if not (np.isfinite(repeats) and 0.01 <= repeats <= 10000):
            raise ValueError("--repeats must be from 0.01 to 10000.")
        sigma = exemplar_size * repeats / model.extent
    else:
        t = 1.0 if texel_ratio is None else texel_ratio
        if not (np.isfinite(t) and 0.25 <= t <= 4.0):
            raise ValueError("--texel-ratio must be from 0.25 to 4.")
        sigma = t * texel_density(model, synth)
    return SurfacePlan(size, synth, sigma)


def surface_controls(controls: Controls, painted_on_model: bool = True) -> tuple[Controls, list[str]]:
    """The document's controls that make sense on a model (what is painted or
    set on the exemplar, and the canvas randomness, features and direction
    field when they were placed on the model: a document with a model paints
    in its atlas; the direction field is then combed over the model, see
    AtlasDomain.combed), and the names of those left out (placed on the plane)."""
    plane = [("canvas labels", controls.labels_canvas), ("lattice", controls.lattice)]
    if not painted_on_model:
        plane[:0] = [("canvas randomness", controls.randomness_canvas), ("features", controls.features),
                     ("direction field", controls.direction)]
    dropped = [name for name, v in plane if v]
    kept = replace(controls, labels_canvas=None, lattice=None,
                   randomness_canvas=controls.randomness_canvas if painted_on_model else None,
                   features=controls.features if painted_on_model else (),
                   direction=controls.direction if painted_on_model else None)
    return kept, dropped


def bake_maps(synth, atlas: AtlasDomain, material: Material, roles: list[str], plan_: SurfacePlan,
              controls: Controls, progress=None) -> tuple[dict[str, np.ndarray], np.ndarray]:
    """{role: float32 (size, size, C)} and the synthesized coordinates."""
    atlas = with_comb(atlas, controls)  # (normal maps turn with the combed J too)
    coords = atlas_coords(synth, atlas, controls)
    if progress:
        progress("synthesized")
    return maps_from_coords(coords, atlas, material, roles, plan_, progress), coords


def maps_from_coords(coords: np.ndarray, atlas: AtlasDomain, material: Material, roles: list[str],
                     plan_: SurfacePlan, progress=None) -> dict[str, np.ndarray]:
    """Every map through the atlas' coordinates (magnified past the synthesized size)."""
    out = {}
    if plan_.magnify == 1:
        jac = None
        for role in roles:
            img = material.lookup(role, coords)
            if role == "normal":
                jac = atlas.jacobians(0, 0, 0, atlas.size, atlas.size) if jac is None else jac
                img = turn_normals(img, jac)
            out[role] = fill_off_charts(img, atlas)
            if progress:
                progress(role)
        return out
    filled = fill_off_charts(coords.copy(), atlas)
    n, s = atlas.size, plan_.magnify
    jac = atlas.jacobians(0, -1, -1, n + 2, n + 2)
    padded = np.pad(filled, ((1, 1), (1, 1), (0, 0)), mode="edge")
    for role in roles:
        bands = []
        for y0 in range(0, n, MAG_BAND):
            y1 = min(n, y0 + MAG_BAND)
            band = material.magnified(role, padded[y0:y1 + 2], s, jac[y0:y1 + 2])
            if role == "normal":  # turned with the texture, each output texel by its synthesized texel's J
                inner = jac[y0 + 1:y1 + 1, 1:n + 1]
                band = turn_normals(band, np.repeat(np.repeat(inner, s, axis=0), s, axis=1))
            bands.append(band)
        out[role] = np.concatenate(bands, axis=0)
        if progress:
            progress(role)
    return out


def glb_bytes(model: Model, maps: dict[str, np.ndarray]) -> bytes:
    """The model with a PBR material made of ``maps`` (8-bit PNG textures), as GLB."""
    import trimesh
    from PIL import Image

    def img(a, mode=None):
        u8 = to_u8(a)
        if u8.shape[2] == 1:
            u8 = u8[..., 0]
        elif u8.shape[2] == 2:
            u8 = u8[..., :1].repeat(3, axis=2)
        return Image.fromarray(np.ascontiguousarray(u8)).convert(mode) if mode else Image.fromarray(np.ascontiguousarray(u8))

    kw = {}
    base = maps.get("basecolor", maps.get(IMAGE))
    if base is not None:
        kw["baseColorTexture"] = img(base, "RGBA" if base.shape[2] in (2, 4) else "RGB")
    if "normal" in maps:
        kw["normalTexture"] = img(maps["normal"][..., :3], "RGB")
    rough, metal = maps.get("roughness"), maps.get("metallic")
    if rough is not None or metal is not None:
        shape = (rough if rough is not None else metal).shape[:2]
        mr = np.zeros(shape + (3,), np.float32)
        mr[..., 1] = rough[..., 0] if rough is not None else 1.0
        mr[..., 2] = metal[..., 0] if metal is not None else 0.0
        kw["metallicRoughnessTexture"] = img(mr, "RGB")
        kw["roughnessFactor"] = 1.0
        kw["metallicFactor"] = 1.0 if metal is not None else 0.0
    elif base is not None:
        kw["roughnessFactor"], kw["metallicFactor"] = 0.8, 0.0
    if "ao" in maps:
        kw["occlusionTexture"] = img(maps["ao"][..., :1], "RGB")
    material = trimesh.visual.material.PBRMaterial(name="infinitex", **kw)
    visual = trimesh.visual.TextureVisuals(uv=np.asarray(model.uvs), material=material)
    mesh = trimesh.Trimesh(vertices=np.asarray(model.positions), faces=np.asarray(model.faces), visual=visual,
                           process=False)
    return mesh.export(file_type="glb")


def map_files(out: str, roles: list[str], depths: dict[str, int], single: bool) -> list[tuple[str, str, int]]:
    """[(role, path, depth)] of the maps written beside ``out`` (OUT_basecolor.png, OUT_height.tif...)."""
    from infinitex.engine.imagefile import depth_extension
    base = os.path.splitext(out)[0]
    return [(r, f"{base}{'' if single else '_' + ('basecolor' if r == IMAGE else r)}{depth_extension(depths[r])}",
             depths[r]) for r in roles]


def write_outputs(out: str, model: Model, maps: dict[str, np.ndarray], files, material: Material) -> list[str]:
    """Write each map (atomically, at its depth) and, for a .glb ``out``, the model with them."""
    written = []
    for role, path, depth in files:
        vr = material.maps[role].exemplar.value_range if role in material.maps else (0.0, 1.0)
        atomic_write(path, encode_image(maps[role], depth, vr))
        written.append(path)
    if out.lower().endswith(".glb"):
        atomic_write(out, glb_bytes(model, maps))
        written.append(out)
    return written


class AtlasRun:
    """A model's atlas synthesized a budget at a time on one GL context (the
    editor's model view, model exports): the same request as
    :func:`~infinitex.engine.surface.bake.atlas_coords`, spread over frames."""

    def __init__(self, gpu, gan, params, controls: Controls, atlas: AtlasDomain):
        self.atlas = atlas = with_comb(atlas, controls)  # a direction field combed over the model
        self.L = gan.analysis.L
        self.pyramid = Pyramid(gpu, gan, params, scrolling=False,
                               controls=replace(controls, surface=atlas, direction=None))
        self.pyramid.requests.start(self.L, Rect(0, 0, atlas.size, atlas.size))
        self.done = False
        self._areas = [float(4 ** l) for l in range(self.L + 1)]

    def level_done(self, l: int) -> bool:
        buf = self.pyramid.buffers[l]
        n = max(1, self.atlas.size >> (self.L - l))
        return buf is not None and buf.valid is not None and buf.valid.contains(Rect(0, 0, n, n))

    @property
    def finest_done(self) -> int:
        """The finest level complete (-1: none yet)."""
        return max((l for l in range(self.L + 1) if self.level_done(l)), default=-1)

    @property
    def progress(self) -> float:
        done = sum(a for l, a in enumerate(self._areas) if self.level_done(l))
        return 1.0 if self.done else min(0.99, done / sum(self._areas))

    def step(self, budget_s: float) -> bool:
        import time
        if not self.done:
            self.done = self.pyramid.requests.advance(time.perf_counter() + budget_s)
        return self.done

    def coords(self, level: int | None = None) -> np.ndarray:
        """(n, n, 4) of a complete level (default: the finest)."""
        level = self.L if level is None else level
        n = max(1, self.atlas.size >> (self.L - level))
        return self.pyramid.read(level, Rect(0, 0, n, n), remainder=True)

    def release(self) -> None:
        if self.pyramid is not None:
            self.pyramid.release()
            self.pyramid = None


class ModelExportJob:
    """File > Export model in the editor: the atlas at the export's size,
    synthesized a budget at a time (the editor stays live), then every map and
    the GLB written. The same interface as export.window.ExportJob."""

    def __init__(self, session, settings, out_path: str, size: int, depth: int | None = None):
        import time

        from infinitex.engine.material import export_depths
        if session.synth is None:
            raise SynthesisError("Nothing to export yet: the exemplar is still being analyzed.")
        mat = session.material
        self.material = mat
        self.roles = mat.roles
        m = session.analysis.size
        try:
            self.plan = plan(settings.model, size, m, repeats=float(settings.repeats), synth_size=settings.size)
            depths = export_depths(mat, self.roles, depth, os.path.splitext(out_path)[0] + ".png")
        except ValueError as exc:
            raise SynthesisError(str(exc)) from None
        self.model = settings.model
        self.out_path = out_path
        self.out_rect = Rect(0, 0, size, size)
        self.coords_path = None
        self.files = map_files(out_path, self.roles, depths, False)
        self.outputs = self.files + [("model", out_path, 8)]
        self.atlas = AtlasDomain(settings.model, self.plan.synth_size, self.plan.sigma, frame=settings.frame,
                                 up=settings.up)
        controls, _ = surface_controls(session.controls)
        self.run_ = AtlasRun(session.gpu, session.synth.gan, session.params, controls, self.atlas)
        self.done = self.cancelled = False
        self.error: str | None = None
        self.started = time.monotonic()

    @property
    def progress(self) -> float:
        return 0.95 * self.run_.progress if self.run_ is not None else 1.0

    def cancel(self) -> None:
        self.cancelled = True
        self._close()

    def step(self, budget_s: float = 0.03) -> bool:
        if self.done or self.cancelled:
            return True
        try:
            if not self.run_.step(budget_s):
                return False
            coords = self.run_.coords()
            maps = maps_from_coords(coords, self.run_.atlas, self.material, self.roles, self.plan)
            write_outputs(self.out_path, self.model, maps, self.files, self.material)
        except (OSError, ValueError) as exc:
            self.error = str(exc)
        self.done = True
        self._close()
        return True

    def _close(self) -> None:
        if self.run_ is not None:
            self.run_.release()
            self.run_ = None
