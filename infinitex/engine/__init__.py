"""Infinitex engine: exemplar analysis (CPU) and deterministic synthesis (GLSL)."""
