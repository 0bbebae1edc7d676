"""The document's model, textured live (the editor's model view): its atlas
synthesized a budget at a time (:class:`~infinitex.export.surface.AtlasRun`),
each complete pyramid level shown as soon as it is done (a coarse texture
first, sharper as the finer levels arrive), started again whenever what
decides the texture changes. No imgui here; the session's GL context.
"""
from __future__ import annotations

import numpy as np

from infinitex.engine.imagefile import to_u8
from infinitex.engine.material import IMAGE
from infinitex.engine.surface import AtlasDomain
from infinitex.engine.surface.bake import fill_off_charts, with_comb
from infinitex.export.surface import AtlasRun, surface_controls

MIN_SHOWN = 32  # levels smaller than this are not worth uploading


class ModelPreview:
    """The atlas of ``doc.surface`` for the session's analysis, parameters and controls."""

    def __init__(self):
        self.key: tuple | None = None
        self.run: AtlasRun | None = None
        self.atlas: AtlasDomain | None = None
        self._atlases: dict = {}
        self.image: np.ndarray | None = None  # uint8 (n, n, C) of the level shown
        self.image_level = -1
        self.version = 0  # bumps when ``image`` changes
        self.left_out: list[str] = []  # the document's plane controls the model does not use
        self.key_model: tuple | None = None
        self.error: str | None = None  # why the model cannot be textured now
        self._floor = -1  # a new run shows its levels from this one (the old texture's) on
        self._run_shown = -1

    @property
    def done(self) -> bool:
        return self.run is not None and self.run.done and self._run_shown == self.run.L

    @property
    def progress(self) -> float:
        return 0.0 if self.run is None else self.run.progress

    def atlas_for(self, settings, m: int) -> AtlasDomain:
        """The model's atlas: its geometry (coverage, charts, indirection maps)
        built once per model and size; a new scale or frame only reframes it."""
        key = (settings.model.key, settings.size)
        base = self._atlases.get(key)
        if base is None:
            self._atlases.clear()  # one model's geometry at a time (hundreds of MB at 4096)
            base = self._atlases[key] = settings.atlas(m)
        sigma = settings.sigma(m)
        if base.sigma == sigma and base.frame == settings.frame and tuple(base.up) == tuple(
                np.asarray(settings.up, np.float64) / np.linalg.norm(settings.up)):
            return base
        return base.reframed(sigma, settings.frame, settings.up)

    def sync(self, session, doc) -> None:
        """Start again when the model, the analysis, the parameters or the controls changed."""
        settings = doc.surface if doc is not None else None
        if settings is None or not session.ready:
            self.release()
            return
        if settings.size < session.analysis.size:
            self.release()
            self.error = (f"The model's texture ({settings.size} px) must be at least as large as the exemplar "
                          f"({session.analysis.size} px): choose a larger texture size.")
            return
        self.error = None
        controls, self.left_out = surface_controls(session.controls)
        key = (settings, session.generation, session.params, controls)
        if key == self.key:
            return
        self.key = key
        if self.run is not None:
            self.run.release()
        same_model = self.atlas is not None and self.key_model == (settings, session.generation)
        self.key_model = (settings, session.generation)
        # A new run of the same model keeps showing the old texture until it is as sharp.
        self._floor = self.image_level if same_model else -1
        self._run_shown = -1
        self.atlas = with_comb(self.atlas_for(settings, session.analysis.size), controls)
        self.run = AtlasRun(session.gpu, session.synth.gan, session.params, controls, self.atlas)
        self._session = session

    def step(self, budget_s: float, role: str | None = None) -> bool:
        """Synthesize for about ``budget_s``; show the finest complete level. True when all is shown."""
        run = self.run
        if run is None:
            return True
        if not run.done:
            run.step(budget_s)
        level = run.finest_done
        n = self.atlas.size >> (run.L - level) if level >= 0 else 0
        if level > self._run_shown and level >= self._floor and (n >= MIN_SHOWN or level == run.L):
            self._show(level, role)
            self._run_shown = level
        return self.done

    def _show(self, level: int, role: str | None) -> None:
        s = self._session
        mat = s.material
        role = role if role in mat.maps else next((r for r in ("basecolor", IMAGE) if r in mat.maps), mat.primary)
        coords = self.run.coords(level)
        img = mat.lookup(role, coords, level)
        self.image = to_u8(fill_off_charts(img, self.atlas, self.run.L - level))
        self.image_level = level
        self.version += 1

    def magnification(self, role: str | None = None):
        """What the model view magnifies once the finest level is shown: the
        coordinates (off the charts: the texels across the seam, else the
        nearest chart texel's), J per texel, the shown map's exemplar (its
        hi-res copy when there is one, uint8), m and whether it wraps; or None."""
        if self.image is None or self.run is None or self._run_shown != self.run.L:
            return None
        mat = self._session.material
        role = role if role in mat.maps else next((r for r in ("basecolor", IMAGE) if r in mat.maps), mat.primary)
        ex = mat.maps[role].exemplar
        n = self.atlas.size
        coords = fill_off_charts(self.run.coords().copy(), self.atlas)
        return (coords, self.atlas.jacobians(0, 0, 0, n, n), to_u8(ex.hires if ex.hires is not None else ex.pixels),
                ex.size, mat.toroidal)

    def coords(self) -> np.ndarray | None:
        """The finished atlas's coordinates (tests), or None while it runs."""
        return self.run.coords() if self.run is not None and self.run.done else None

    def release(self) -> None:
        if self.run is not None:
            self.run.release()
        self.run = None
        self.key = self.key_model = self.atlas = None
        self.image = None
        self.image_level = self._floor = self._run_shown = -1
