"""Drawing a textured model (the editor's 3D view, figures and benchmarks):
an orbit camera with Blender-like conventions and a lit, textured mesh on
any moderngl context (the editor's window, or a headless EGL one).

The camera orbits a target: yaw about the model's up, pitch, distance;
:meth:`OrbitCamera.ray` gives the world ray under a pixel, and
:meth:`ModelView.pick` the atlas texel it hits (a picking pass writes each
pixel's texture coordinates), so the tools paint on the model in the atlas.
"""
from __future__ import annotations

import math
import os
from dataclasses import dataclass, replace

import moderngl
import numpy as np

from infinitex.engine.gpu import build_program

SHADERS = os.path.join(os.path.dirname(__file__), "shaders")




def _normalize(v):
    v = np.asarray(v, np.float64)
    n = np.linalg.norm(v)
    return v / n if n > 0 else v


def look_at(eye, target, up) -> np.ndarray:
    f = _normalize(np.asarray(target) - eye)
    s = _normalize(np.cross(f, up))
    u = np.cross(s, f)
    m = np.eye(4)
    m[0, :3], m[1, :3], m[2, :3] = s, u, -f
    m[:3, 3] = -m[:3, :3] @ eye
    return m


def perspective(fovy_deg: float, aspect: float, near: float, far: float) -> np.ndarray:
    f = 1.0 / math.tan(math.radians(fovy_deg) / 2)
    m = np.zeros((4, 4))
    m[0, 0], m[1, 1] = f / aspect, f
    m[2, 2], m[2, 3] = (far + near) / (near - far), 2 * far * near / (near - far)
    m[3, 2] = -1.0
    return m


@dataclass(frozen=True)
class OrbitCamera:
    """Yaw and pitch (degrees) about ``target``, at ``distance``; +y is up."""

    target: tuple = (0.0, 0.0, 0.0)
    yaw: float = 30.0
    pitch: float = 20.0
    distance: float = 4.0
    fovy: float = 40.0

    @classmethod
    def framing(cls, positions: np.ndarray, **kw) -> "OrbitCamera":
        lo, hi = positions.min(axis=0), positions.max(axis=0)
        radius = float(np.linalg.norm(hi - lo)) / 2 or 1.0
        return cls(target=tuple((lo + hi) / 2), distance=radius / math.sin(math.radians(20.0)) * 0.8, **kw)

    @property
    def eye(self) -> np.ndarray:
        y, p = math.radians(self.yaw), math.radians(self.pitch)
        d = np.array([math.cos(p) * math.sin(y), math.sin(p), math.cos(p) * math.cos(y)])
        return np.asarray(self.target) + self.distance * d

    def matrices(self, aspect: float) -> tuple[np.ndarray, np.ndarray]:
        view = look_at(self.eye, np.asarray(self.target, np.float64), np.array([0.0, 1.0, 0.0]))
        proj = perspective(self.fovy, aspect, self.distance * 0.02, self.distance * 10)
        return view, proj

    def orbit(self, dyaw: float, dpitch: float) -> "OrbitCamera":
        return replace(self, yaw=(self.yaw + dyaw) % 360.0, pitch=max(-89.0, min(89.0, self.pitch + dpitch)))

    def zoom(self, factor: float) -> "OrbitCamera":
        return replace(self, distance=max(1e-6, self.distance * factor))

    def pan(self, dx: float, dy: float, aspect: float) -> "OrbitCamera":
        """Move the target by a fraction of the view (dx right, dy up)."""
        view, _ = self.matrices(aspect)
        h = 2 * self.distance * math.tan(math.radians(self.fovy) / 2)
        move = view[0, :3] * dx * h * aspect + view[1, :3] * dy * h
        return replace(self, target=tuple(np.asarray(self.target) - move))


class ModelView:
    """A model's mesh on a moderngl context, drawn lit with a texture."""

    def __init__(self, ctx: moderngl.Context, positions: np.ndarray, faces: np.ndarray, uvs: np.ndarray):
        self.ctx = ctx
        self.programs = [build_program(ctx, [os.path.join(SHADERS, "model.vert")],
                                       [os.path.join(SHADERS, "model.frag")], dict(MAGNIFY=magnify))
                         for magnify in (False, True)]
        self.prog = self.programs[0]
        P = np.asarray(positions, np.float64)[np.asarray(faces).reshape(-1)]
        tri = P.reshape(-1, 3, 3)
        n = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
        n /= np.maximum(np.linalg.norm(n, axis=-1, keepdims=True), 1e-30)
        normals = self._smooth_normals(positions, faces, n)
        uv = np.asarray(uvs, np.float64)[np.asarray(faces).reshape(-1)]
        data = np.concatenate([P, normals, uv], axis=1).astype("f4")
        self.vbo = ctx.buffer(data.tobytes())
        self.vaos = [ctx.vertex_array(p, [(self.vbo, "3f 3f 2f", "in_pos", "in_normal", "in_uv")])
                     for p in self.programs]
        self.positions = np.asarray(positions)
        self.texture = None
        self.seam_texture = None
        self.overlay_texture = None
        self._fbo = None
        self._synthesis = None  # set_synthesis: (coords, J, exemplar textures, m, toroidal)
        self.magnify = True     # draw by synthesis magnification once it is set

    @staticmethod
    def _smooth_normals(positions, faces, face_n) -> np.ndarray:
        """Per corner: the area-weighted mean of the face normals at the corner's
        position where they bend less than 40 degrees from its own face's (hard edges stay hard)."""
        _, pid = np.unique(np.asarray(positions), axis=0, return_inverse=True)
        pid = pid.reshape(-1)[np.asarray(faces).reshape(-1)]
        acc = np.zeros((pid.max() + 1, 3))
        np.add.at(acc, pid, np.repeat(face_n, 3, axis=0))
        smooth = acc[pid]
        smooth /= np.maximum(np.linalg.norm(smooth, axis=-1, keepdims=True), 1e-30)
        own = np.repeat(face_n, 3, axis=0)
        soft = (smooth * own).sum(-1) > math.cos(math.radians(40.0))
        return np.where(soft[:, None], smooth, own)

    def set_texture(self, rgb: np.ndarray) -> None:
        """The texture shown (uint8 (N, N, 1..4)), mipmapped."""
        a = np.asarray(rgb)
        if a.ndim == 2:
            a = a[..., None]
        if a.shape[2] == 1:
            a = np.repeat(a, 3, axis=2)
        elif a.shape[2] == 2:
            a = np.repeat(a[..., :1], 3, axis=2)
        a = np.ascontiguousarray(a[..., :3], np.uint8)
        if self.texture is None or self.texture.size != (a.shape[1], a.shape[0]):
            if self.texture is not None:
                self.texture.release()
            self.texture = self.ctx.texture((a.shape[1], a.shape[0]), 3, a.tobytes())
        else:
            self.texture.write(a.tobytes())
        self.texture.build_mipmaps()
        # Bilinear within the nearest mip level: trilinear costs llvmpipe 15% of its
        # frame rate and anisotropic filtering two thirds (bench/surface.py).
        self.texture.filter = (moderngl.LINEAR_MIPMAP_NEAREST, moderngl.LINEAR)

    def _set(self, name: str, value) -> None:
        if name in self.prog:  # the driver may drop unused uniforms
            self.prog[name].value = value

    def set_synthesis(self, coords: np.ndarray | None, jac: np.ndarray | None = None, exemplar=None,
                      m: int = 0, toroidal: bool = True) -> None:
        """Draw by synthesis magnification: the atlas's coordinates ((N, N, 4):
        texel, remainder in 1/256 px; off the charts, the texels across the
        seam), J per texel (Q12) and the exemplar (uint8 (H, H, C); its
        hi-res copy) whose m x m pixels the coordinates are in. None: the texture."""
        if self._synthesis is not None:
            for t in self._synthesis[:3]:
                t.release()
            self._synthesis = None
        if coords is None:
            return
        n = coords.shape[0]

        def itex(a):
            t = self.ctx.texture((n, n), 4, np.ascontiguousarray(a, np.int16).tobytes(), dtype="i2")
            t.filter = (moderngl.NEAREST, moderngl.NEAREST)
            return t
        e = np.asarray(exemplar)
        e = np.repeat(e, 3, axis=2) if e.shape[2] == 1 else (np.repeat(e[..., :1], 3, axis=2) if e.shape[2] == 2 else e[..., :3])
        ex = self.ctx.texture((e.shape[1], e.shape[0]), 3, np.ascontiguousarray(e, np.uint8).tobytes())
        ex.build_mipmaps()
        ex.filter = (moderngl.LINEAR_MIPMAP_LINEAR, moderngl.LINEAR)
        ex.repeat_x = ex.repeat_y = bool(toroidal)
        self._synthesis = (itex(coords), itex(jac), ex, m, toroidal)

    def set_seams(self, mask: np.ndarray | None) -> None:
        """Texels to mark (bool (N, N)), e.g. the charts' border texels; None: none."""
        if self.seam_texture is not None:
            self.seam_texture.release()
            self.seam_texture = None
        if mask is not None:
            m = np.ascontiguousarray(mask.astype(np.uint8) * 255)
            self.seam_texture = self.ctx.texture((m.shape[1], m.shape[0]), 1, m.tobytes())
            self.seam_texture.filter = (moderngl.NEAREST, moderngl.NEAREST)

    def set_overlay(self, rgba: np.ndarray | None) -> None:
        """A heat map over the atlas (uint8 (N, N, 4), alpha blended over the lit
        texture, e.g. the painted randomness); None: none."""
        if rgba is None:
            if self.overlay_texture is not None:
                self.overlay_texture.release()
                self.overlay_texture = None
            return
        a = np.ascontiguousarray(rgba, np.uint8)
        if self.overlay_texture is None or self.overlay_texture.size != (a.shape[1], a.shape[0]):
            if self.overlay_texture is not None:
                self.overlay_texture.release()
            self.overlay_texture = self.ctx.texture((a.shape[1], a.shape[0]), 4, a.tobytes())
            self.overlay_texture.filter = (moderngl.LINEAR, moderngl.LINEAR)
        else:
            self.overlay_texture.write(a.tobytes())

    def draw(self, camera: OrbitCamera, viewport: tuple[int, int, int, int], mode: int = 0) -> None:
        x, y, w, h = viewport
        view, proj = camera.matrices(w / max(1, h))
        mvp = (proj @ view).astype("f4")
        mag = self.magnify and self._synthesis is not None and mode != 1
        self.prog = self.programs[int(mag)]
        self.prog["mvp"].write(mvp.T.tobytes())
        eye = camera.eye
        self.prog["eye_dir"].value = tuple(_normalize(eye - np.asarray(camera.target)))
        light = view[:3, :3].T @ _normalize(np.array([0.5, 0.8, 0.6]))  # from above the camera's right
        self.prog["light"].value = tuple(light)
        self.prog["mode"].value = 1 if mode == 1 else 0
        self._set("marks", int(mode == 2 and self.seam_texture is not None))
        if self.texture is not None:
            self.texture.use(0)
            self._set("tex", 0)
        if self.seam_texture is not None:
            self.seam_texture.use(1)
            self._set("seams", 1)
        self._set("has_overlay", int(self.overlay_texture is not None and mode != 1))
        if self.overlay_texture is not None:
            self.overlay_texture.use(5)
            self._set("overlay", 5)
        if mag:
            coords, jac, ex, m, toroidal = self._synthesis
            for unit, t in ((2, coords), (3, jac), (4, ex)):
                t.use(unit)
            for name, v in (("coords", 2), ("jac", 3), ("exemplar", 4), ("n", coords.size[0]), ("m", float(m)),
                            ("toroidal", int(toroidal))):
                self._set(name, v)
        self.ctx.enable(moderngl.DEPTH_TEST)
        self.ctx.disable(moderngl.CULL_FACE)
        self.vaos[int(mag)].render(moderngl.TRIANGLES)
        self.ctx.disable(moderngl.DEPTH_TEST)

    def render(self, camera: OrbitCamera, size: tuple[int, int], mode: int = 0,
               background=(0.16, 0.17, 0.19)) -> np.ndarray:
        """An offscreen picture (uint8 (H, W, 3), top row first); mode 1: the
        texture coordinates under each pixel (float32 (H, W, 3): u, v, hit)."""
        w, h = size
        if self._fbo is None or self._fbo.size != (w, h):
            if self._fbo is not None:
                self._fbo.release()
            self._fbo = self.ctx.framebuffer(color_attachments=[self.ctx.texture((w, h), 4, dtype="f4")],
                                             depth_attachment=self.ctx.depth_renderbuffer((w, h)))
        self._fbo.use()
        self._fbo.clear(*background, 0.0, depth=1.0)
        self.draw(camera, (0, 0, w, h), mode)
        data = np.frombuffer(self._fbo.read(components=4, dtype="f4"), np.float32).reshape(h, w, 4)[::-1]
        if mode == 1:
            return data[..., :3].copy()
        return (np.clip(data[..., :3], 0, 1) * 255 + 0.5).astype(np.uint8)

    def pick(self, camera: OrbitCamera, size: tuple[int, int], x: int, y: int, atlas_size: int):
        """The atlas texel (x, y; top row 0) under pixel (x, y) of a view of ``size``, or None."""
        uvh = self.render(camera, size, mode=1, background=(0, 0, 0))
        if not (0 <= x < size[0] and 0 <= y < size[1]) or uvh[y, x, 2] < 0.5:
            return None
        u, v = float(uvh[y, x, 0]), float(uvh[y, x, 1])
        return (min(atlas_size - 1, max(0, int(u * atlas_size))), min(atlas_size - 1, max(0, int((1 - v) * atlas_size))))

    def release(self) -> None:
        self.set_synthesis(None)
        for o in (*self.vaos, self.vbo, *self.programs, self.texture, self.seam_texture, self.overlay_texture, self._fbo):
            if o is not None:
                o.release()


MAX_DAB_FRACTION = 0.25  # a dab on a model: at most this fraction of the atlas side in radius


def atlas_footprint(uvh: np.ndarray, x: float, y: float, n: int, owner: np.ndarray | None = None,
                    step: int = 2) -> tuple[tuple[float, float], float] | None:
    """Where the ray under view pixel (x, y) meets the model, from a picking
    render ``uvh`` ((h, w, 3): u, v, hit): the atlas position in finest texels
    (row 0 at the top) and the atlas texels one screen pixel spans there; None
    off the model.

    The span is the smallest of the four one-sided differences ``step`` pixels
    away (left, right, up, down) whose neighbour is on the model, on the same
    chart (``owner``: the atlas's chart per texel) and no farther than the
    step could reach: at a grazing angle the surface runs away along one axis
    only, and a neighbour across the silhouette or a seam lies anywhere in the
    atlas (which made a 47 px brush near a vase's outline a dab of thousands
    of texels). Without a usable neighbour the span is 1."""
    h, w = uvh.shape[:2]
    xi, yi = int(x), int(y)
    if not (0 <= xi < w and 0 <= yi < h) or uvh[yi, xi, 2] < 0.5:
        return None
    u, v = float(uvh[yi, xi, 0]), float(uvh[yi, xi, 1])
    pos = (u * n, (1.0 - v) * n)

    def chart(px: float, py: float) -> int:
        if owner is None:
            return 0
        return int(owner[min(n - 1, max(0, int(py))), min(n - 1, max(0, int(px)))])

    here = chart(*pos)
    spans = []
    for dx, dy in ((step, 0), (-step, 0), (0, step), (0, -step)):
        x2, y2 = xi + dx, yi + dy
        if not (0 <= x2 < w and 0 <= y2 < h) or uvh[y2, x2, 2] < 0.5:
            continue
        q = (float(uvh[y2, x2, 0]) * n, (1.0 - float(uvh[y2, x2, 1])) * n)
        if chart(*q) != here:
            continue
        spans.append(math.hypot(q[0] - pos[0], q[1] - pos[1]) / step)
    per_px = min(spans) if spans else 1.0
    return pos, per_px if per_px > 0 else 1.0


def dab_radius(radius: float, screen_units: bool, per_px: float, n: int) -> float:
    """A brush's radius in atlas texels: its screen radius times the texels a
    screen pixel spans there (or its radius as it is), at least 1 and at most
    MAX_DAB_FRACTION of the atlas side, however the surface is seen."""
    r = radius * per_px if screen_units else radius
    return float(min(max(1.0, r), max(1.0, MAX_DAB_FRACTION * n)))
