"""Texture on a model (LH06 section 6): meshes with texture coordinates
(:mod:`.mesh`) and synthesis directly in their atlas, continuous across UV
seams (:mod:`.atlas`, :mod:`.bake`)."""
from .atlas import GUTTER, AtlasDomain, AtlasError
from .mesh import Model, ModelError, load_model, unwrap

__all__ = ["AtlasDomain", "AtlasError", "GUTTER", "Model", "ModelError", "load_model", "unwrap"]
