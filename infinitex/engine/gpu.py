"""OpenGL 3.3 core plumbing: context, shader programs, exemplar textures.

Every GL program of the product is built by :func:`build_program` from GLSL
files: the synthesis passes' in ``engine/shaders/*.glsl`` / ``*.frag`` /
``*.vert``, the editor's canvas and model view's in ``app/render/shaders``;
one header (the version and a few ``#define`` lines: subpass grid size, model,
drawing mode) before the files. :class:`Gpu` caches the engine's per context.
"""
from __future__ import annotations

import os
import sys
from functools import cached_property

import moderngl
import numpy as np

from . import fixed
from .analysis import Analysis

SHADER_DIR = os.path.join(os.path.dirname(__file__), "shaders")
GLSL_VERSION = "#version 330 core"
# The most memory the correction's per-texel projection tables may take (LevelTextures.table).
TABLE_MAX_BYTES = 256 << 20


class GLUnavailable(RuntimeError):
    """No usable OpenGL 3.3 context; the message says what was tried."""


def create_context() -> moderngl.Context:
    """A headless OpenGL 3.3+ core context (EGL on Linux, native elsewhere)."""
    attempts = [dict(backend="egl"), {}] if sys.platform.startswith("linux") else [{}]
    errors = []
    for kwargs in attempts:
        try:
            return moderngl.create_standalone_context(require=330, **kwargs)
        except Exception as exc:  # moderngl raises plain Exception subclasses
            errors.append(f"{kwargs.get('backend', 'default')}: {exc}")
    raise GLUnavailable("No usable OpenGL 3.3 context could be created ("
                        + "; ".join(errors) + "). On Debian install libegl1 and libgl1.")


def set_uniforms(prog: moderngl.Program, **values) -> None:
    """Set uniforms by name, skipping those the compiler optimized out (bytes: written raw)."""
    for name, value in values.items():
        try:
            member = prog[name]
        except KeyError:
            continue
        if isinstance(value, bytes):
            member.write(value)
        else:
            member.value = value


def read_shader(name: str) -> str:
    """A shader file's text: a name in engine/shaders, or a path."""
    with open(os.path.join(SHADER_DIR, name), encoding="utf-8") as f:
        return f.read()


def shader_header(defines: dict) -> str:
    """The version line and one ``#define`` per entry (True: defined, no value), sorted."""
    return GLSL_VERSION + "\n" + "".join(
        f"#define {k} {'' if v is True else v}\n" for k, v in sorted(defines.items()) if v is not False)


def build_program(ctx: moderngl.Context, vertex: list[str], fragment: list[str],
                  defines: dict | None = None) -> moderngl.Program:
    """A program from shader files (names in engine/shaders, or paths), each
    stage the header then its files in order. Macros written over several
    lines are joined: GLSL has line continuations only from 4.20, and some 3.30
    compilers reject them. A driver's refusal is a :class:`GLUnavailable`
    naming the file."""
    head = shader_header(defines or {})
    vert = head + "".join(read_shader(n) for n in vertex)
    frag = (head + "".join(read_shader(n) for n in fragment)).replace("\\\n", " ")
    try:
        return ctx.program(vertex_shader=vert, fragment_shader=frag)
    except moderngl.Error as exc:
        raise GLUnavailable(f"The GPU driver rejected shader {os.path.basename(fragment[-1])}: {exc}") from None


class Gpu:
    """A moderngl context with the synthesis programs and a full-screen quad."""

    def __init__(self, ctx: moderngl.Context | None = None):
        self.owns_context = ctx is None
        self.ctx = ctx or create_context()
        self._programs: dict[tuple, moderngl.Program] = {}
        self._sources: dict[int, tuple] = {}  # a program's glo -> (shader file, defines)
        self._vaos: dict[tuple, moderngl.VertexArray] = {}
        quad = np.array([-1, -1, 1, -1, -1, 1, -1, 1, 1, -1, 1, 1], dtype="f4")
        self.quad = self.ctx.buffer(quad.tobytes())

    def activate(self) -> None:
        """Make this Gpu's own (standalone) context current. Several headless
        contexts may live in one process (tests, a pipeline); GL calls go to
        whichever was made current last, so every engine entry point calls this.
        A context given to Gpu (the editor's window) is left to its owner."""
        if self.owns_context:
            self.ctx.__enter__()

    def release(self) -> None:
        """Free the programs and buffers, and the context if this Gpu made it."""
        self.activate()
        for obj in [*self._vaos.values(), *self._programs.values(), self.quad]:
            obj.release()
        self._vaos.clear()
        self._programs.clear()
        self._sources.clear()
        if self.owns_context:
            self.ctx.release()

    @cached_property
    def renderer(self) -> str:
        info = self.ctx.info
        return f"{info.get('GL_RENDERER', '?')} / {info.get('GL_VERSION', '?')}"

    def program(self, frag: str, **defines) -> tuple[moderngl.Program, moderngl.VertexArray]:
        key = (frag, tuple(sorted(defines.items())))
        if key not in self._programs:
            prog = build_program(self.ctx, ["fullscreen.vert"], ["common.glsl", frag], defines)
            self._programs[key] = prog
            self._sources[prog.glo] = key
            self._vaos[key] = self.ctx.vertex_array(prog, [(self.quad, "2f", "in_pos")])
        return self._programs[key], self._vaos[key]

    def program_source(self, prog) -> tuple[str, dict] | None:
        """The shader file and defines a program of :meth:`program` was made from."""
        key = self._sources.get(prog.glo)
        return None if key is None else (key[0], dict(key[1]))

    def texture(self, size: tuple[int, int], components: int, data: np.ndarray | None, dtype: str):
        """A 2D integer texture of ``size`` (w, h), texel-fetched only, holding
        ``data`` (h, w, components) if given.

        Its storage is never a power of two wide or high (one texel more where
        ``size`` is): llvmpipe compiles a shader variant per combination of its
        textures' power-of-two sides, so strips of changing sizes would compile
        new ones (about a second each, cold) in the middle of a stroke. The
        texels beyond ``size`` are never read."""
        w, h = (int(size[0]), int(size[1]))
        tex = self.ctx.texture((_npot(w), _npot(h)), components, dtype=dtype)
        if data is not None:
            tex.write(np.ascontiguousarray(data).tobytes(), viewport=(0, 0, w, h), alignment=1)
        tex.filter = (moderngl.NEAREST, moderngl.NEAREST)
        tex.repeat_x = tex.repeat_y = False
        return tex

    def uint_texture(self, size: tuple[int, int], data: np.ndarray):
        return self.texture(size, 4, np.asarray(data, dtype=np.uint32), "u4")

    def u32_texture(self, data: np.ndarray):
        """A single-channel uint32 (R32UI) texture of a (h, w) array."""
        return self.texture((data.shape[1], data.shape[0]), 1, np.asarray(data, dtype=np.uint32), "u4")

    def u16_texture(self, data: np.ndarray):
        """A single-channel uint16 (R16UI) texture of a (h, w) array."""
        return self.texture((data.shape[1], data.shape[0]), 1, np.asarray(data, dtype=np.uint16), "u2")

    def int_texture(self, size: tuple[int, int], components: int, data: np.ndarray | None = None):
        return self.texture(size, components, None if data is None else np.asarray(data, dtype=np.int16), "i2")


def _npot(n: int) -> int:
    """n, or n + 1 where n is a power of two of at least 2 (see Gpu.texture)."""
    return n + 1 if n >= 2 and n & (n - 1) == 0 else n


def _rgba(arr: np.ndarray) -> np.ndarray:
    """(m, m, n<=4) int array to (m, m, 4) int16, zero-padded."""
    out = np.zeros(arr.shape[:2] + (4,), dtype=np.int16)
    out[:, :, :arr.shape[2]] = arr
    return out


def pack8(arr: np.ndarray) -> np.ndarray:
    """(m, m, 8) values in int16 range to (m, m, 4) uint32: texel component c
    holds dim c in its low 16 bits and dim c + 4 in its high 16 bits, each
    offset by 32768 (unpacked in correct.frag without signed shifts)."""
    a = arr.astype(np.int64) + 32768
    return (a[:, :, :4] | (a[:, :, 4:] << 16)).astype(np.uint32)


class LevelTextures:
    """The per-level analysis data the correction pass reads, as GL textures."""

    def __init__(self, gpu: Gpu, an: Analysis, level: int):
        lv = an.levels[level]
        m = an.size
        if an.model == "appearance":
            self.feat = gpu.uint_texture((m, m), pack8(lv.feat))
        else:
            self.feat = gpu.int_texture((m, m), 4, _rgba(lv.feat))
        self.nbhd = gpu.uint_texture((m, m), pack8(lv.nbhd))
        self.sim = [] if lv.simset is None else _sim_textures(gpu, lv.simset)
        self.lattice_sim = None if lv.lattice_simset is None else _sim_textures(gpu, lv.lattice_simset)
        # Row r of the projection -> uniform P[2r] (dims 0-3), P[2r+1] (dims 4-7);
        # as floats where that is exact (correct.frag PROJ_FLOAT).
        vmax = int(np.abs(lv.feat).max()) * (fixed.APPEARANCE_PREDICTIONS if an.model == "appearance" else 1)
        self.proj_float = fixed.exact_in_float(lv.proj, vmax)
        self.proj = np.ascontiguousarray(lv.proj, dtype=np.float32 if self.proj_float else np.int32).tobytes()
        self.shift = lv.shift
        self._gpu, self._lv = gpu, lv
        self._colors = None
        self._table = None
        self._row_taps: dict = {}

    @property
    def colors(self):
        """E_l as the fidelity stage reads it (fixed.quantized_colors, one 8-bit
        unsigned integer channel per channel of E), uploaded on first use."""
        if self._colors is None:
            q = self._quantized
            self._colors = self._gpu.ctx.texture((q.shape[1], q.shape[0]), q.shape[2], q.tobytes(), dtype="u1")
            self._colors.filter = (moderngl.NEAREST, moderngl.NEAREST)
        return self._colors

    @cached_property
    def _quantized(self) -> np.ndarray:
        """fixed.quantized_colors of E_l (uint8 (m, m, C)), for colors and row_taps."""
        return np.ascontiguousarray(fixed.quantized_colors(self._lv.stack), dtype=np.uint8)

    def row_taps(self, h: int, radius: int, toroidal: bool):
        """fidelity.frag ROW_TAPS' texture (RGBA32UI array, row_taps_layers(C, R)
        layers): at (x, y), the taps q[y, tap(x + h (i - R))], i = 0..2R, of the
        quantized colors, packed C bytes each (4 for 3 channels), as many to a
        uint as fit; tap wraps on a toroidal exemplar, else clamps to [0, m-1]."""
        key = (h, radius, toroidal)
        if key not in self._row_taps:
            q = self._quantized
            m, C = q.shape[0], q.shape[2]
            tap_bytes = 4 if C >= 3 else C
            per_uint = 4 // tap_bytes
            packed = np.zeros((m, m), np.uint32)
            for c in range(C):
                packed |= q[:, :, c].astype(np.uint32) << np.uint32(8 * c)
            layers = row_taps_layers(C, radius)
            rows = np.zeros((m, m, layers * 4), np.uint32)
            x = np.arange(m)
            for i in range(2 * radius + 1):
                xs = x + h * (i - radius)
                xs = xs & (m - 1) if toroidal else np.clip(xs, 0, m - 1)
                rows[:, :, i // per_uint] |= packed[:, xs] << np.uint32(8 * tap_bytes * (i % per_uint))
            data = np.ascontiguousarray(rows.reshape(m, m, layers, 4).transpose(2, 0, 1, 3))
            tex = self._gpu.ctx.texture_array((m, m, layers), 4, data.tobytes(), dtype="u4")
            tex.filter = (moderngl.NEAREST, moderngl.NEAREST)
            self._row_taps[key] = tex
        return self._row_taps[key]

    @property
    def table(self):
        """The appearance model's projection per exemplar texel (correct.frag
        PROJ_TABLE), uploaded on first use: layer 2 t (dims 0-3) and 2 t + 1
        (dims 4-7) of an RGBA32I array hold P_t A_l[u], diagonal t's rows of the
        projection applied to A_l[u], before the shift. N_S(p) is then a sum of
        12 of them: the same integers as projecting the sums (it is linear), at
        a fraction of the cost."""
        if self._table is None:
            lv = self._lv
            m = lv.feat.shape[0]
            feat = lv.feat.astype(np.int64)
            proj = lv.proj.astype(np.int64)
            layers = np.empty((2 * len(fixed.DIAGONALS), m, m, 4), np.int32)
            for t in range(len(fixed.DIAGONALS)):
                q = feat @ proj[t * fixed.NDIM:(t + 1) * fixed.NDIM]  # (m, m, 8)
                layers[2 * t], layers[2 * t + 1] = q[..., :4], q[..., 4:]
            self._table = self._gpu.ctx.texture_array((m, m, len(layers)), 4, layers.tobytes(), dtype="i4")
            self._table.filter = (moderngl.NEAREST, moderngl.NEAREST)
        return self._table

    def release(self) -> None:
        for t in [self.feat, self.nbhd] + self.sim + (self.lattice_sim or []) + [self._colors, self._table,
                                                                                 *self._row_taps.values()]:
            if t is not None:
                t.release()


def row_taps_layers(channels: int, radius: int) -> int:
    """Layers of LevelTextures.row_taps (fidelity.frag ROW_TEXELS)."""
    per_uint = 4 // (4 if channels >= 3 else channels)
    uints = -(-(2 * radius + 1) // per_uint)
    return -(-uints // 4)


def _sim_textures(gpu: Gpu, simset: np.ndarray) -> list:
    """Similarity sets (m, m, k, 2) as the two RGBA32I textures sim01, sim23."""
    m = simset.shape[0]
    sims = simset.reshape(m, m, -1)
    return [gpu.int_texture((m, m), 4, _rgba(sims[:, :, 0:4]) if sims.shape[2] >= 4
                            else _rgba(np.concatenate([sims[:, :, 0:2]] * 2, axis=2))),
            gpu.int_texture((m, m), 4, _rgba(sims[:, :, 4:8]))]


class GpuAnalysis:
    """An analysis uploaded to one context; level textures are uploaded on first use."""

    def __init__(self, gpu: Gpu, an: Analysis):
        self.gpu = gpu
        self.analysis = an
        self._levels: dict[int, LevelTextures] = {}

    def level(self, level: int) -> LevelTextures:
        if level not in self._levels:
            self._levels[level] = LevelTextures(self.gpu, self.analysis, level)
        return self._levels[level]

    @property
    def projection_tables(self) -> bool:
        """Whether the correction reads the projection per texel (LevelTextures.table):
        for the appearance model, while the tables of every level stay within
        TABLE_MAX_BYTES (128 bytes a texel a level)."""
        an = self.analysis
        return an.model == "appearance" and 128 * an.size ** 2 * (an.L + 1) <= TABLE_MAX_BYTES

    def correction_defines(self, level: int, avoid: bool = False, direction: bool = False) -> dict:
        """correct.frag's defines on ``level`` (``avoid``: with an avoided region;
        ``direction``: with a direction field, which reads A_l itself)."""
        an = self.analysis
        d = dict(DIST_CLAMP=fixed.DIST_CLAMP, PSI_ONE=fixed.PSI_ONE, K=an.k)
        if self.projection_tables and not direction:
            d["PROJ_TABLE"] = True
        elif self.level(level).proj_float:
            d["PROJ_FLOAT"] = True
        if avoid:
            d["AVOID"] = True
        if an.model == "appearance":
            d.update(MODEL_APPEARANCE=True, PROJ_ROWS=4 * fixed.NDIM)
        else:
            d.update(MODEL_COLOR=True, NCH=an.channels, PROJ_ROWS=25 * an.channels)
        return d

    def release(self) -> None:
        for lt in self._levels.values():
            lt.release()
        self._levels.clear()
