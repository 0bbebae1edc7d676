"""Animations of a flowing texture (engine/advect.py) as files: an image
sequence, a flipbook atlas with its description, an animated WebP or PNG, an
MP4 video. Everything is written at the end, atomically: a cancelled or failed
run leaves the files that were there before, and no partial one.

**The flipbook atlas** (``OUT.png``) holds the frames in rows of ``columns``,
left to right and top to bottom from frame 0; ``OUT.json`` beside it gives
what game engines ask for: Unity's Texture Sheet Animation (tiles X = columns,
Y = rows, frame count, cycles from the frame rate), Unreal's SubUV (sub images
horizontal and vertical), Godot's animated sprite frames (hframes, vframes)::

    {"image": "lava.png", "frame_width": 256, "frame_height": 256, "frames": 32,
     "columns": 8, "rows": 4, "fps": 24, "loop": true, "order": "row-major, top-left first",
     "sha256": "..."}

``sha256`` is the atlas file's: a description that does not match its atlas
(a copy of one without the other) shows.

Video (MP4, H.264 through PyAV's FFmpeg, yuv420p at CRF 16): sizes are padded to
even numbers by repeating the last column or row, as the codec needs.
"""
from __future__ import annotations

import hashlib
import io
import json
import math
import os
import secrets
import shutil

import numpy as np

from infinitex.engine.safeio import WriteError, atomic_write, printable

FORMATS = {".png": "atlas", ".webp": "webp", ".apng": "apng", ".mp4": "mp4"}
FRAME_NAME = "frame_{:04d}.png"
MAX_ATLAS_SIDE = 16384
MAX_WEBP_SIDE = 16383  # the WebP format's limit
MAX_FRAMES = 4096


def animation_format(out: str) -> str:
    """'folder' (an image sequence: a name without extension, or an existing
    folder), 'atlas', 'webp', 'apng' or 'mp4', from the output's name."""
    ext = os.path.splitext(out)[1].lower()
    if os.path.isdir(out) or out.endswith(os.sep) or not ext:
        return "folder"
    if ext not in FORMATS:
        raise WriteError(f"{printable(out)}: an animation is a folder, or a .png flipbook atlas, a .webp, an "
                         f".apng or an .mp4, not {printable(ext)}.")
    return FORMATS[ext]


def atlas_grid(frames: int, w: int, h: int) -> tuple[int, int]:
    """(columns, rows) of a flipbook atlas of ``frames`` frames of w x h: the
    fewest empty cells, then the squarest sheet, within MAX_ATLAS_SIDE (32
    frames: 8 x 4); WriteError when they cannot fit."""
    fits = [(c, -(-frames // c)) for c in range(1, frames + 1)
            if c * w <= MAX_ATLAS_SIDE and -(-frames // c) * h <= MAX_ATLAS_SIDE]
    if not fits:
        raise WriteError(f"{frames} frames of {w}x{h} do not fit an atlas of {MAX_ATLAS_SIDE} px a side; "
                         "write a folder or a video, or fewer or smaller frames.")
    return min(fits, key=lambda cr: (cr[0] * cr[1] - frames, abs(math.log(cr[0] * w / (cr[1] * h))), -cr[0]))


def check_folder_output(out: str, roles: tuple[str, ...] = ()) -> None:
    """An image sequence replaces a folder only if it holds an earlier sequence
    (frame_NNNN.png) and nothing else; a material's (``roles``) only if it holds
    such sequences in folders named by its roles."""
    if os.path.lexists(out) and not os.path.isdir(out):
        raise WriteError(f"{printable(out)} exists and is not a folder; it is not replaced.")
    if not os.path.isdir(out):
        return
    for name in os.listdir(out):
        sub = os.path.join(out, name)
        if roles and name in roles and os.path.isdir(sub) and not os.path.islink(sub):
            check_folder_output(sub)
        elif roles or not _is_frame_name(name):
            raise WriteError(f"{printable(out)} holds other files ({printable(name)}...); an image sequence "
                             "replaces only a folder of frames.")


def check_animation_output(out: str, fmt: str, outputs: list[tuple[str, str]], frames: int, w: int, h: int,
                           roles: tuple[str, ...] = ()) -> None:
    """Everything about writing ``frames`` frames of w x h to ``out`` that can be
    checked before any work (WriteError): the folder a sequence replaces (a
    material's: ``roles``), each file's name, the atlas' grid, WebP's size."""
    from infinitex.engine.safeio import check_output
    if fmt == "folder":
        check_folder_output(out, roles)
    else:
        for _, path in outputs:
            check_output(path, (os.path.splitext(out)[1].lower(),), "animation")
    if fmt == "atlas":
        atlas_grid(frames, w, h)
    if fmt == "webp" and max(w, h) > MAX_WEBP_SIDE:
        raise WriteError(f"A WebP is at most {MAX_WEBP_SIDE} px a side, not {max(w, h)}; write a folder, "
                         "an APNG or a video.")


def _is_frame_name(name: str) -> bool:
    return name.startswith("frame_") and name.endswith(".png") and name[6:-4].isdigit()


class AnimationWriter:
    """Collects frames (uint8 (H, W, C)) and writes them all in :meth:`close`."""

    def __init__(self, out: str, fmt: str, fps: float, loop: bool, make_parent: bool = False):
        self.out, self.fmt, self.fps, self.loop = out, fmt, float(fps), bool(loop)
        self.make_parent = make_parent  # a material's sequence: OUT/ROLE, OUT made if missing
        self.frames: list[np.ndarray] = []

    def add(self, frame: np.ndarray) -> None:
        if frame.ndim == 2:
            frame = frame[..., None]
        self.frames.append(np.ascontiguousarray(frame))

    def close(self) -> list[str]:
        """Write the files; returns their paths."""
        if not self.frames:
            raise WriteError("No frame to write.")
        return getattr(self, "_" + self.fmt)()

    def _folder(self) -> list[str]:
        from infinitex.engine.safeio import TMP_SUFFIX
        from infinitex.export.formats import png_bytes
        out = os.path.abspath(self.out.rstrip(os.sep) or self.out)
        parent = os.path.dirname(out)
        if self.make_parent:
            try:
                os.makedirs(parent, exist_ok=True)  # a material's OUT, holding one folder per map
            except OSError as exc:
                raise WriteError(f"Cannot make the folder of {printable(self.out)}: {exc.strerror or exc}.") from None
        check_folder_output(out)
        tmp = os.path.join(parent, f".{os.path.basename(out)[:64]}.{os.getpid()}.{secrets.token_hex(6)}{TMP_SUFFIX}")
        old = None
        try:
            os.mkdir(tmp)
            for i, f in enumerate(self.frames):
                with open(os.path.join(tmp, FRAME_NAME.format(i)), "wb") as fh:
                    fh.write(png_bytes(f))
            if os.path.isdir(out):
                old = tmp + ".old" + TMP_SUFFIX
                os.rename(out, old)
            os.rename(tmp, out)
        except BaseException as exc:
            if old is not None and not os.path.exists(out):
                os.rename(old, out)  # the earlier sequence back in place
                old = None
            shutil.rmtree(tmp, ignore_errors=True)
            if isinstance(exc, OSError):
                raise WriteError(f"Writing {printable(self.out)} failed: {exc.strerror or exc}.") from None
            raise
        if old is not None:
            shutil.rmtree(old, ignore_errors=True)
        return [out]

    def _atlas(self) -> list[str]:
        from infinitex.export.formats import png_bytes
        h, w = self.frames[0].shape[:2]
        cols, rows = atlas_grid(len(self.frames), w, h)
        sheet = np.zeros((rows * h, cols * w) + self.frames[0].shape[2:], np.uint8)
        for i, f in enumerate(self.frames):
            r, c = divmod(i, cols)
            sheet[r * h:(r + 1) * h, c * w:(c + 1) * w] = f
        data = png_bytes(sheet)
        desc = dict(image=os.path.basename(self.out), frame_width=w, frame_height=h, frames=len(self.frames),
                    columns=cols, rows=rows, fps=self.fps, loop=self.loop, order="row-major, top-left first",
                    sha256=hashlib.sha256(data).hexdigest())
        meta = os.path.splitext(self.out)[0] + ".json"
        # The description first: a run stopped between the two leaves the old atlas
        # beside a description whose sha256 names the new one, which shows.
        atomic_write(meta, (json.dumps(desc, indent=1) + "\n").encode())
        atomic_write(self.out, data)
        return [self.out, meta]

    def _animated(self, fmt: str) -> list[str]:
        from PIL import Image
        imgs = [Image.fromarray(f[..., 0] if f.shape[2] == 1 else f[..., :4]) for f in self.frames]
        buf = io.BytesIO()
        ms = max(1, int(round(1000.0 / self.fps)))
        extra = dict(lossless=True, quality=90, method=4) if fmt == "WEBP" else {}
        try:
            imgs[0].save(buf, format=fmt, save_all=True, append_images=imgs[1:], duration=ms,
                         loop=0 if self.loop else 1, **extra)
        except (RuntimeError, ValueError, OSError) as exc:
            raise WriteError(f"Encoding {printable(self.out)} failed: {exc}.") from None
        atomic_write(self.out, buf.getvalue())
        return [self.out]

    def _webp(self) -> list[str]:
        return self._animated("WEBP")

    def _apng(self) -> list[str]:
        return self._animated("PNG")

    def _mp4(self) -> list[str]:
        import av
        from fractions import Fraction
        h, w = self.frames[0].shape[:2]

        def write(f) -> None:
            with av.open(f, "w", format="mp4") as box:
                stream = box.add_stream("libx264", rate=Fraction(self.fps).limit_denominator(1000))
                stream.width, stream.height = w + (w & 1), h + (h & 1)
                stream.pix_fmt = "yuv420p"
                stream.options = {"crf": "16"}
                for fr in self.frames:
                    rgb = np.repeat(fr[..., :1], 3, axis=2) if fr.shape[2] < 3 else fr[..., :3]
                    rgb = np.pad(rgb, ((0, h & 1), (0, w & 1), (0, 0)), mode="edge")
                    for packet in stream.encode(av.VideoFrame.from_ndarray(np.ascontiguousarray(rgb), format="rgb24")):
                        box.mux(packet)
                for packet in stream.encode():
                    box.mux(packet)
        atomic_write(self.out, writer=write)
        return [self.out]


def animation_outputs(out: str, fmt: str, roles: list[str]) -> list[tuple[str, str]]:
    """[(role, path)]: one output per map of a material (OUT_basecolor.png, OUT/basecolor/ for a sequence)."""
    from infinitex.engine.material import IMAGE, map_path
    if list(roles) == [IMAGE]:
        return [(IMAGE, out)]
    if fmt == "folder":
        return [(r, os.path.join(out, r)) for r in roles]
    return [(r, map_path(out, r)) for r in roles]


def render_animation(frames, material, rect, start: int, n: int, writers: dict, progress=None,
                     cancelled=None) -> list[str] | None:
    """Frames ``start`` .. ``start + n - 1`` of ``frames`` (engine/advect.py
    FlowFrames) over ``rect``, each map of ``material`` to its writer (a
    normal map turned with the texture), written at the end; returns the
    files written, or None when ``cancelled()`` stopped it (nothing written).
    ``progress(fraction, t)`` after each frame."""
    from infinitex.engine.imagefile import to_u8
    from infinitex.engine.subpixel import turn_normals
    for i in range(n):
        if cancelled is not None and cancelled():
            return None
        t = start + i
        if "normal" in writers:
            coords, jac = frames.frame_with_jacobians(t, rect)
        else:
            coords, jac = frames.frame(t, rect), None
        for role, writer in writers.items():
            px = material.lookup(role, coords)
            if role == "normal" and jac is not None:
                px = turn_normals(px, jac)
            writer.add(to_u8(px))
        if progress is not None:
            progress((i + 1) / (n + 1), t)
    if cancelled is not None and cancelled():
        return None
    written = []
    for writer in writers.values():
        written += writer.close()
    return written
