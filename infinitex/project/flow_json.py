"""Texture in motion in project files (format version 12): the flow
(engine/controls/flow.py) and how it plays. The velocity in 1/256 px per
frame, the renewal period, a loop's length, the frames an export makes and
their rate, and a velocity map as little-endian int16 (H, W, 2) bytes,
zlib-compressed and base64-encoded, with its canvas position. Untrusted data:
every number range-checked, the map size-limited and decompressed with a
bound; a damaged entry is one sentence."""
from __future__ import annotations

import base64
import zlib
from dataclasses import dataclass

import numpy as np

from infinitex.engine.controls.flow import MAX_LOOP, MAX_SPEED, Q, Flow, FlowError, VelocityMap

from .document import ProjectError

MAX_STORED_MAP_SIDE = 2048  # a velocity map kept in a project (8 MB of int16 pairs at most)
MAX_FPS = 240.0


@dataclass(frozen=True)
class Motion:
    """A document's texture in motion: the flow, the frames an animation has
    (a loop's length when it loops) and how fast they play."""

    flow: Flow
    frames: int = 48
    fps: float = 24.0

    def validate(self) -> None:
        try:
            self.flow.validate()
        except FlowError as exc:
            raise ProjectError(f"The project's flow: {exc}") from None
        if not 1 <= self.frames <= MAX_LOOP or (self.flow.loop and self.flow.loop != self.frames):
            raise ProjectError(f"The project's animation has 1 to {MAX_LOOP} frames (a loop's own length).")
        if not 0 < self.fps <= MAX_FPS:
            raise ProjectError(f"The project's frame rate is more than 0 and at most {MAX_FPS:g}.")


def motion_to_json(m: Motion) -> dict:
    f = m.flow
    out = {"velocity": list(f.velocity), "period": f.period, "loop": f.loop, "distortion": f.distortion,
           "frames": m.frames, "fps": m.fps}
    if f.map is not None:
        v = f.map.values
        if max(v.shape[:2]) > MAX_STORED_MAP_SIDE:
            raise ProjectError(f"A velocity map over {MAX_STORED_MAP_SIDE} px a side is not kept in a project.")
        out["map"] = {"x": f.map.x, "y": f.map.y, "w": int(v.shape[1]), "h": int(v.shape[0]), "v16": _encoded(f.map)}
    return out


_ENCODED: dict = {}  # the last map's encoding: an autosave of an unchanged map encodes nothing


def _encoded(vmap: VelocityMap) -> str:
    text = _ENCODED.get(vmap.key)
    if text is None:
        raw = np.ascontiguousarray(vmap.values, "<i2").tobytes()
        text = base64.b64encode(zlib.compress(raw, 1)).decode()
        _ENCODED.clear()
        _ENCODED[vmap.key] = text
    return text


def _int(d: dict, key: str, lo: int, hi: int) -> int:
    v = d.get(key)
    if not isinstance(v, int) or isinstance(v, bool) or not lo <= v <= hi:
        raise ProjectError(f"The project's flow is damaged ({key}).")
    return v


def _number(d: dict, key: str, lo: float, hi: float) -> float:
    v = d.get(key)
    if not isinstance(v, (int, float)) or isinstance(v, bool) or not np.isfinite(v) or not lo <= v <= hi:
        raise ProjectError(f"The project's flow is damaged ({key}).")
    return float(v)


def motion_from_json(d: object) -> Motion | None:
    """The project's motion, or None; all or nothing."""
    if d is None:
        return None
    if not isinstance(d, dict) or not isinstance(d.get("velocity"), list) or len(d["velocity"]) != 2:
        raise ProjectError("The project's flow is damaged.")
    vel = {"vx": d["velocity"][0], "vy": d["velocity"][1]}
    lim = MAX_SPEED * Q
    velocity = (_int(vel, "vx", -lim, lim), _int(vel, "vy", -lim, lim))
    vmap = None
    if d.get("map") is not None:
        m = d["map"]
        if not isinstance(m, dict):
            raise ProjectError("The project's velocity map is damaged.")
        w, h = _int(m, "w", 1, MAX_STORED_MAP_SIDE), _int(m, "h", 1, MAX_STORED_MAP_SIDE)
        x, y = _int(m, "x", -(2 ** 31), 2 ** 31 - 1), _int(m, "y", -(2 ** 31), 2 ** 31 - 1)
        size = w * h * 4
        text = m.get("v16")
        if not isinstance(text, str) or len(text) > 2 * size + 1024:
            raise ProjectError("The project's velocity map is damaged.")
        try:
            z = zlib.decompressobj()
            raw = z.decompress(base64.b64decode(text, validate=True), size + 1)
        except Exception:
            raise ProjectError("The project's velocity map is damaged.") from None
        if len(raw) != size or z.unconsumed_tail:
            raise ProjectError("The project's velocity map is damaged.")
        try:
            vmap = VelocityMap(np.frombuffer(raw, "<i2").astype(np.int32).reshape(h, w, 2), x, y)
        except FlowError as exc:
            raise ProjectError(f"The project's velocity map: {exc}") from None
    flow = Flow(velocity=velocity, map=vmap, period=_int(d, "period", 2, 128), loop=_int(d, "loop", 0, MAX_LOOP),
                distortion=_number(d, "distortion", 0.05, 4.0))
    motion = Motion(flow, _int(d, "frames", 1, MAX_LOOP), _number(d, "fps", 1e-3, MAX_FPS))
    motion.validate()
    return motion
