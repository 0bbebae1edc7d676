"""Materials: a set of aligned maps that one synthesis drives.

The synthesis produces exemplar *coordinates* ``S`` (docs/algorithm.md
sections 1 and 4), so every map aligned with the exemplar (base color, normal,
height, roughness...) is looked up through the same ``S``: ``map_l[S]``. Only the
maps chosen for the analysis (with weights; default base color plus height)
shape the appearance vectors; the others just follow.

Roles and the naming rule
    A map's role comes from the last word of its file name (after ``_``,
    ``-``, ``.`` or a space, case-insensitive, a trailing resolution such as
    ``_2k`` ignored): see :data:`ROLE_NAMES`. ``wood_basecolor.png``,
    ``Wood_Normal.png`` and ``wood-height-2k.tif`` are the base color, normal
    and height of the material ``wood``. Given one map, its *siblings* are the
    image files in the same folder with the same material name.

Sizes
    All maps must have the same pixel size; each goes through the same fit
    rule (``exemplar.py``), so they stay aligned. Anything else is refused
    with one sentence, and nothing is half-loaded.

Channels
    Base color keeps its 1 to 4 channels; a normal map is RGB (alpha
    dropped); height, roughness, ao, metallic and opacity are one channel (a
    color image gives its luminance, Rec. 709).

Precision
    Every map keeps its source's precision (``Exemplar.depth``: 8, 16 or 32
    bits) as float32 in [0, 1]; float maps remember their range
    (``value_range``) so 32-bit exports are in the source's units.

Normal maps
    Stored encoded (``n * 0.5 + 0.5``, OpenGL convention, +Y up). The finest
    level is the map itself; every filtered version (the Gaussian stack's
    coarser levels, synthesis magnification) is renormalized to unit length.
"""
from __future__ import annotations

import os
import re
import stat
from dataclasses import dataclass, field

import numpy as np
from PIL import Image

from .exemplar import HIRES_MAX, IMPORT_BUDGET, Exemplar, ExemplarError, crop_box, decoding, fit_rule
from .exemplar import import_cost, load_exemplar_bytes, open_image
from .safeio import ReadError, printable, read_limited
from .subpixel import bilinear, sample, shear_pull
from .tiffinfo import is_tiff, loses_precision, page_tags

IMAGE = "image"  # the one map of a single-image exemplar
ROLES = ("basecolor", "normal", "height", "roughness", "ao", "metallic", "opacity")
ROLE_NAMES = {
    "basecolor": ("basecolor", "albedo", "diffuse", "color", "colour", "col", "diff"),
    "normal": ("normal", "nrm", "normalgl", "nor", "norm"),
    "height": ("height", "disp", "displacement", "bump"),
    "roughness": ("roughness", "rough", "rgh"),
    "ao": ("ao", "ambientocclusion", "occlusion"),
    "metallic": ("metallic", "metalness", "metal"),
    "opacity": ("opacity", "alpha", "mask"),
}
ROLE_LABELS = {"basecolor": "Base color", "normal": "Normal", "height": "Height", "roughness": "Roughness",
               "ao": "Ambient occlusion", "metallic": "Metallic", "opacity": "Opacity", IMAGE: "Image"}
_SUFFIX = {name: role for role, names in ROLE_NAMES.items() for name in names}
IMAGE_EXTENSIONS = (".png", ".jpg", ".jpeg", ".bmp", ".tif", ".tiff", ".webp", ".tga", ".qoi")
MAX_MAPS = len(ROLES)
MAX_FOLDER_ENTRIES = 10000  # a folder with more files than this is not scanned for maps
MATERIAL_BUDGET = 2 * IMPORT_BUDGET  # bytes a whole material's import may use (its files, one decode, the fitted maps)
_NAME = re.compile(r"^(?P<base>.+?)[_\-. ](?P<word>[A-Za-z]+)(?:[_\-. ]\d{1,2}k)?$", re.IGNORECASE)


class MaterialError(ExemplarError):
    """A set of maps could not be used as a material; the message is one sentence."""


def role_of(path: str) -> tuple[str, str] | None:
    """(material name lowercased, role) from a file name, or None when the name says no role."""
    stem, ext = os.path.splitext(os.path.basename(path))
    if ext.lower() not in IMAGE_EXTENSIONS:
        return None
    m = _NAME.match(stem)
    if not m:
        return None
    role = _SUFFIX.get(m.group("word").lower())
    return (m.group("base").lower(), role) if role else None


def _listdir(folder: str) -> list[str]:
    try:
        with os.scandir(folder) as it:
            names = []
            for e in it:
                names.append(e.name)
                if len(names) > MAX_FOLDER_ENTRIES:
                    raise MaterialError(f"The folder {printable(folder)} holds more than {MAX_FOLDER_ENTRIES} "
                                        "files; choose the maps themselves.")
    except OSError as exc:
        raise MaterialError(f"The folder {printable(folder)} cannot be read: {exc.strerror or exc}.") from None
    return sorted(names)


def _claim(found: dict[str, str], role: str, path: str) -> None:
    if role in found:
        raise MaterialError(f"Two files claim the {ROLE_LABELS[role].lower()} role: "
                            f"{printable(os.path.basename(found[role]))} and {printable(os.path.basename(path))}; "
                            "choose the files yourself.")
    found[role] = path


def check_found(full: str, folder: str, chosen: bool = False) -> None:
    """A map found by its name in ``folder`` is read only if it is a regular
    file (a FIFO, device, folder or broken link is an error, not skipped), and,
    unless the user ``chosen`` it, not a link to a file outside that folder
    (as a project's references: nothing outside is read without a word)."""
    shown = printable(os.path.basename(full))
    try:
        st = os.stat(full)
    except OSError:
        raise MaterialError(f"The map {shown} cannot be read (a broken link, or no permission).") from None
    if stat.S_ISDIR(st.st_mode):
        raise MaterialError(f"The map {shown} is a folder, not an image file.")
    if not stat.S_ISREG(st.st_mode):
        raise MaterialError(f"The map {shown} is not a regular file (a FIFO, device or socket); it is not read.")
    if not chosen and os.path.islink(full):
        real, home = os.path.realpath(full), os.path.realpath(folder)
        if os.path.commonpath([real, home]) != home:
            raise MaterialError(f"The map {shown} is a link to {printable(real)}, outside the material's folder; "
                                "it is not read (choose that file itself to use it).")


def siblings(path: str) -> dict[str, str]:
    """The maps of the material ``path`` belongs to, by the naming rule
    ({role: path}, ``path`` included); {} when its name says no role."""
    named = role_of(path)
    if named is None:
        return {}
    base, _ = named
    folder = os.path.dirname(os.path.abspath(path))
    own = os.path.basename(os.path.abspath(path))
    found: dict[str, str] = {}
    for name in _listdir(folder):
        r = role_of(name)
        if r is not None and r[0] == base:
            full = os.path.join(folder, name)
            check_found(full, folder, chosen=name == own)
            _claim(found, r[1], full)
    return found


def folder_maps(folder: str) -> dict[str, str]:
    """The maps in a folder ({role: path}): one material's files, named by the rule."""
    found: dict[str, str] = {}
    bases = set()
    for name in _listdir(folder):
        r = role_of(name)
        if r is None:
            continue
        full = os.path.join(folder, name)
        check_found(full, folder)
        bases.add(r[0])
        _claim(found, r[1], full)
    if not found:
        raise MaterialError(f"The folder {printable(folder)} holds no maps named by the rule "
                            "(NAME_basecolor.png, NAME_normal.png, NAME_height.png...).")
    if len(bases) > 1:
        raise MaterialError(f"The folder {printable(folder)} holds maps of several materials "
                            f"({', '.join(sorted(bases)[:4])}); choose one material's files.")
    return found


def assign_roles(paths: list[str]) -> dict[str, str]:
    """Roles of several chosen files, by the naming rule ({role: path}); the
    files' sizes together are checked against MATERIAL_BUDGET (nothing read yet)."""
    if len(paths) == 1:
        p = paths[0]
        found = folder_maps(p) if os.path.isdir(p) else siblings(p) or {IMAGE: p}
        check_total_size(found)
        return found
    found = {}
    for p in paths:
        r = role_of(p)
        if r is None:
            raise MaterialError(f"The name {printable(os.path.basename(p))} says no role; end it in _basecolor, "
                                "_normal, _height, _roughness, _ao, _metallic or _opacity.")
        _claim(found, r[1], p)
    check_total_size(found)
    return found


def _over_budget(total: int, n: int) -> MaterialError:
    return MaterialError(f"The {n} maps of this material would need about {total // 2**20} MB to import together, "
                         f"more than the {MATERIAL_BUDGET // 2**20} MB a material may use; reduce them first.")


def check_total_size(found: dict[str, str]) -> None:
    """Refuse maps whose files together are larger than MATERIAL_BUDGET (they are
    all held while the material is imported), before any is read."""
    total = sum(os.stat(p).st_size for p in found.values() if os.path.isfile(p))
    if total > MATERIAL_BUDGET:
        raise _over_budget(total, len(found))


def map_costs(data: bytes, name: str, fit: str) -> tuple[int, int]:
    """(peak bytes besides the file, bytes kept afterwards) of importing one
    map by the fit rule, from its header (nothing decoded)."""
    with decoding(name):
        try:
            img = open_image(data, name)
        except Exception as exc:
            if isinstance(exc, ExemplarError) or not is_tiff(data):
                raise
            tags = page_tags(data)  # a TIFF Pillow cannot read: through tifffile
            w, h = (max(1, int(tags.get(t, 1) or 1)) for t in (256, 257))
            c = min(4, max(1, int(tags.get(277, 1) or 1)))
            peak = w * h * c * (8 + 8 + 4) + (16 << 20)
        else:
            with img:
                w, h = img.size
                c = 4 if img.mode == "P" else min(4, len(img.getbands()))
                peak = import_cost(w, h, img.mode, 0, fit, img.format or "")
                deep = (img.format == "PNG" and data[24:25] == b"\x10") or \
                    (img.format == "TIFF" and loses_precision(img.tag_v2))
                if deep:  # decoded at 16 bits by imagecodecs or tifffile
                    peak = max(peak, w * h * 4 * (2 + 4 + 4 + 4) + (16 << 20))
    _x, _y, side = crop_box(w, h, fit)
    limit = fit_rule(fit)[1]
    target = min(limit, 1 << max(0, side - 1).bit_length())
    hires = min(side, HIRES_MAX) ** 2 if side != target else 0
    return peak, c * 4 * (target * target + hires)


def check_budget(files: list[tuple[str, str, bytes]], fit: str) -> None:
    """Refuse a material whose import would need more than MATERIAL_BUDGET at its
    peak: every file (held throughout), the largest single decode and every
    fitted map, estimated from the headers before any map is decoded."""
    peaks, kept = [0], 0
    for role, name, data in files:
        try:
            p, k = map_costs(data, printable(os.path.basename(name)), fit)
        except ExemplarError as exc:
            raise MaterialError(f"The {ROLE_LABELS[role].lower()} map: {exc}") from None
        peaks.append(p)
        kept += k
    total = sum(len(d) for _, _, d in files) + max(peaks) + kept
    if total > MATERIAL_BUDGET:
        raise _over_budget(total, len(files))


def ordered(roles) -> list[str]:
    """Roles in the canonical order (image, then ROLES)."""
    return sorted(roles, key=lambda r: -1 if r == IMAGE else ROLES.index(r))


def _check_regular(path: str) -> None:
    try:
        st = os.stat(path)
    except OSError:
        raise MaterialError(f"The map {printable(os.path.basename(path))} is missing.") from None
    if not stat.S_ISREG(st.st_mode):
        raise MaterialError(f"The map {printable(os.path.basename(path))} is not a regular file.")


def read_maps(found: dict[str, str], limit: int) -> list[tuple[str, str, bytes]]:
    """[(role, path, bytes)] of the files, in canonical order; one sentence on failure."""
    out = []
    for role in ordered(found):
        path = found[role]
        _check_regular(path)
        try:
            out.append((role, path, read_limited(path, limit, "image")))
        except ReadError as exc:
            raise MaterialError(f"The {ROLE_LABELS[role].lower()} map: {exc}") from None
    return out


# -- the material ----------------------------------------------------------------


def luma(px: np.ndarray) -> np.ndarray:
    c = px.shape[2]
    if c == 1:
        return px
    rgb = px[..., :3] if c >= 3 else np.repeat(px[..., :1], 3, axis=2)
    if np.array_equal(rgb[..., 0], rgb[..., 1]) and np.array_equal(rgb[..., 0], rgb[..., 2]):
        return np.ascontiguousarray(rgb[..., :1])
    y = rgb.astype(np.float64) @ np.array([0.2126, 0.7152, 0.0722])
    return np.ascontiguousarray(np.clip(y, 0.0, 1.0)[..., None], dtype=np.float32)


def _shape_for_role(role: str, px: np.ndarray, name: str) -> np.ndarray:
    if role in ("basecolor", IMAGE):
        return px
    if role == "normal":
        if px.shape[2] < 3:
            raise MaterialError(f"The normal map {printable(name)} has {px.shape[2]} channel(s); a normal map is RGB.")
        return np.ascontiguousarray(px[..., :3])
    return luma(px)


def renormalize(encoded: np.ndarray) -> np.ndarray:
    """Encoded normals (..., 3) in [0, 1] brought back to unit length (a zero
    vector becomes +Z)."""
    n = encoded.astype(np.float64) * 2.0 - 1.0
    length = np.sqrt((n * n).sum(axis=-1, keepdims=True))
    n = np.where(length > 1e-8, n / np.maximum(length, 1e-8), np.array([0.0, 0.0, 1.0]))
    return np.clip(n * 0.5 + 0.5, 0.0, 1.0).astype(np.float32)


@dataclass
class MaterialMap:
    role: str
    exemplar: Exemplar  # this map fitted like every other: pixels (m, m, C), hires, depth, value_range

    @property
    def pixels(self) -> np.ndarray:
        return self.exemplar.pixels

    @property
    def channels(self) -> int:
        return self.exemplar.channels

    @property
    def depth(self) -> int:
        return self.exemplar.depth


@dataclass
class Material:
    """Aligned maps of one size, in canonical role order."""

    maps: dict[str, MaterialMap]
    toroidal: bool
    _stacks: dict = field(default_factory=dict, repr=False)

    @property
    def roles(self) -> list[str]:
        return list(self.maps)

    @property
    def single(self) -> bool:
        return list(self.maps) == [IMAGE]

    @property
    def primary(self) -> str:
        return next(iter(self.maps))

    @property
    def size(self) -> int:
        return self.maps[self.primary].exemplar.size

    def default_weights(self) -> dict[str, float]:
        """Base color (or the image) plus height when present; else the first map."""
        w = {r: 1.0 for r in (IMAGE, "basecolor", "height") if r in self.maps}
        return w or {self.primary: 1.0}

    def guide(self, weights: dict[str, float] | None = None) -> Exemplar:
        """The exemplar the analysis sees: the chosen maps, each scaled by its
        weight, side by side as channels (a single image: the image itself)."""
        weights = self.default_weights() if weights is None else weights
        parts = [(r, float(weights.get(r, 0.0))) for r in self.maps if weights.get(r, 0.0) > 0.0]
        if not parts:
            raise MaterialError("No map feeds the analysis; give at least one map a weight above 0.")
        first = self.maps[parts[0][0]].exemplar
        if len(parts) == 1 and parts[0][1] == 1.0:
            px = first.pixels
        else:
            px = np.ascontiguousarray(np.concatenate([self.maps[r].pixels * np.float32(w) for r, w in parts], axis=2),
                                      dtype=np.float32)
        return Exemplar(pixels=px, toroidal=self.toroidal, toroidal_guess=first.toroidal_guess,
                        source=first.source, fit=first.fit, original_size=first.original_size,
                        hires=first.hires if px is first.pixels else None, depth=first.depth,
                        value_range=first.value_range)

    def stack(self, role: str) -> list[np.ndarray]:
        """The map's Gaussian stack E_0..E_L (float32 (m, m, C)); normals renormalized
        on every filtered level (the finest level is the map itself)."""
        cached = self._stacks.get(role)
        if cached is None:
            from .neighborhoods import gaussian_stack
            cached = gaussian_stack(self.maps[role].pixels, self.toroidal)
            if role == "normal":
                cached = [lv if i == len(cached) - 1 else renormalize(lv) for i, lv in enumerate(cached)]
            self._stacks[role] = cached
        return cached

    def lookup(self, role: str, coords: np.ndarray, level: int | None = None) -> np.ndarray:
        """map_l[S]: float32 (H, W, C) of coordinates (H, W, 2) at ``level`` (default: finest);
        (H, W, 4) with sub-pixel remainders: bilinear (engine/subpixel.py)."""
        st = self.stack(role)
        return sample(st[len(st) - 1 if level is None else level], coords, self.toroidal)

    def magnified(self, role: str, coords: np.ndarray, scale: int, jac: np.ndarray | None = None) -> np.ndarray:
        """Synthesis magnification (LH05 section 5) of finest-level coordinates:
        ``coords`` covers the output's texels plus one on every side ((H+2, W+2, 2));
        the result is (H*scale, W*scale, C). Each output pixel blends, bilinearly,
        the map sampled at its 4 nearest texels' coordinates extrapolated to it
        (from the full-resolution map when the import kept one). Normals are
        renormalized after the blend. With a direction field, ``coords`` carry
        sub-pixel remainders ((H+2, W+2, 4)) and ``jac`` (H+2, W+2, 4) is J per
        texel (Q12): each texel's coordinate is extrapolated through its J."""
        mp = self.maps[role]
        m = mp.exemplar.size
        src = mp.exemplar.hires if mp.exemplar.hires is not None else mp.pixels
        if role == "normal" and src.shape[2] > 3:
            src = src[..., :3]
        if role not in ("basecolor", "normal", IMAGE) and src.shape[2] != 1:
            src = luma(src)
        if src.shape[0] > m * scale:  # pre-filter the hi-res copy to the output's resolution
            n = m * scale
            src = np.stack([np.asarray(Image.fromarray(np.ascontiguousarray(src[..., c]), mode="F")
                                       .resize((n, n), Image.LANCZOS)) for c in range(src.shape[2])], axis=2)
            if role == "normal":
                src = renormalize(np.clip(src, 0.0, 1.0))
        ratio = src.shape[0] / m
        H, W = coords.shape[0] - 2, coords.shape[1] - 2
        X = (np.arange(W * scale) + 0.5) / scale - 0.5   # texel-space position minus half a texel
        Y = (np.arange(H * scale) + 0.5) / scale - 0.5
        bx, by = np.floor(X).astype(np.int64), np.floor(Y).astype(np.int64)
        tx, ty = (X - bx)[None, :], (Y - by)[:, None]
        out = np.zeros((H * scale, W * scale, src.shape[2]), dtype=np.float64)
        corners = [(i, j) for j in (0, 1) for i in (0, 1)]
        pred, wgt = [], []
        for i, j in corners:
            rows, cols = (by + j + 1)[:, None], (bx + i + 1)[None, :]
            u = coords[rows, cols].astype(np.float64)  # (h, w, 2 or 4)
            ox, oy = np.broadcast_to(tx - i, u.shape[:2]), np.broadcast_to(ty - j, u.shape[:2])
            if u.shape[-1] == 4:  # a direction field: the remainder, and the offset through J
                u = u[..., :2] + u[..., 2:] / 256.0
            if jac is not None:
                J = jac[rows, cols].astype(np.float64) / 4096.0
                ox, oy = J[..., 0] * ox + J[..., 1] * oy, J[..., 2] * ox + J[..., 3] * oy
            pred.append(np.stack([u[..., 0] + 0.5 + ox, u[..., 1] + 0.5 + oy], axis=-1))
            wgt.append((tx if i else 1.0 - tx) * (ty if j else 1.0 - ty))
        for c in range(4):
            P = pred[c] + shear_pull(pred, wgt, c, m, self.toroidal, 1)
            out += wgt[c][..., None] * bilinear(src, P[..., 0] * ratio - 0.5, P[..., 1] * ratio - 0.5, self.toroidal)
        out = np.clip(out, 0.0, 1.0).astype(np.float32)
        return renormalize(out) if role == "normal" else out


def load_material(files: list[tuple[str, str, bytes]], fit: str = "resize", toroidal: bool | None = None) -> Material:
    """A material from [(role, name, bytes)]: every map decoded and fitted by the
    same rule, sizes checked, roles unique. All or nothing (MaterialError)."""
    if not files:
        raise MaterialError("A material needs at least one map.")
    if len(files) > MAX_MAPS + 1:
        raise MaterialError(f"A material has at most {MAX_MAPS} maps, not {len(files)}.")
    roles = [r for r, _, _ in files]
    for r in roles:
        if r != IMAGE and r not in ROLES:
            raise MaterialError(f"Unknown map role {printable(r)!r}; use one of {', '.join(ROLES)}.")
        if roles.count(r) > 1:
            raise MaterialError(f"Two maps have the {ROLE_LABELS[r].lower()} role; each role is used once.")
    if IMAGE in roles and len(roles) > 1:
        raise MaterialError("A single image cannot be combined with other maps; give it a role.")
    files = sorted(files, key=lambda f: -1 if f[0] == IMAGE else ROLES.index(f[0]))
    check_budget(files, fit)
    maps: dict[str, MaterialMap] = {}
    first_name, first_size = "", None
    for role, name, data in files:
        try:
            ex = load_exemplar_bytes(data, name=os.path.basename(name), fit=fit, toroidal=toroidal)
        except MaterialError:
            raise
        except ExemplarError as exc:
            raise MaterialError(f"The {ROLE_LABELS[role].lower()} map: {exc}") from None
        if first_size is None:
            first_name, first_size = os.path.basename(name), ex.original_size
        elif ex.original_size != first_size:
            w, h = ex.original_size
            raise MaterialError(f"{printable(os.path.basename(name))} is {w}x{h} px but {printable(first_name)} is "
                                f"{first_size[0]}x{first_size[1]} px; the maps of a material must have the same size.")
        px = _shape_for_role(role, ex.pixels, name)
        if px is not ex.pixels:
            hires = None if ex.hires is None else _shape_for_role(role, ex.hires, name)
            ex = Exemplar(pixels=px, toroidal=ex.toroidal, toroidal_guess=ex.toroidal_guess, source=ex.source,
                          fit=ex.fit, original_size=ex.original_size, hires=hires, depth=ex.depth,
                          value_range=ex.value_range)
        maps[role] = MaterialMap(role, ex)
    primary = next(iter(maps.values())).exemplar
    tor = primary.toroidal_guess if toroidal is None else bool(toroidal)
    for mp in maps.values():
        mp.exemplar.toroidal = tor
    return Material(maps, tor)


def single(ex: Exemplar, stack: list[np.ndarray] | None = None) -> Material:
    """The material of a single-image exemplar: its one map (``stack``: its
    Gaussian stack when already computed, e.g. by the analysis)."""
    mat = Material({IMAGE: MaterialMap(IMAGE, ex)}, ex.toroidal)
    if stack is not None:
        mat._stacks[IMAGE] = list(stack)
    return mat


def export_depths(material: Material, roles: list[str], depth: int | None, out: str) -> dict[str, int]:
    """The bit depth each exported map is written at: ``depth`` when given,
    else the map's own (8, 16 or 32). A single image's depth follows the
    output's extension: ``.png`` (8 or 16 bits) or ``.tif`` (32-bit float)."""
    from .imagefile import DEPTHS
    if depth is not None and depth not in DEPTHS:
        raise MaterialError(f"The bit depth is 8, 16 or 32, not {depth}.")
    if material.single:
        tif = os.path.splitext(out)[1].lower() in (".tif", ".tiff")
        own = material.maps[IMAGE].depth
        d = depth or (32 if tif else min(own, 16))
        if (d == 32) != tif:
            raise MaterialError("A 32-bit export is a float TIFF (name it .tif); 8 and 16 bits are PNG (.png).")
        return {IMAGE: d}
    return {r: depth or material.maps[r].depth for r in roles}


def map_path(out: str, role: str, ext: str | None = None) -> str:
    """A material map's file beside ``out``: NAME.png -> NAME_ROLE.png (or NAME_ROLE + ``ext``)."""
    base, own = os.path.splitext(out)
    return f"{base}_{role}{own if ext is None else ext}"


def output_paths(out: str, roles: list[str], depths: dict[str, int]) -> list[tuple[str, str, int]]:
    """[(role, path, depth)]: ``OUT.png`` for a single image, else one file per
    map, ``OUT_basecolor.png``, ``OUT_height.tif`` (32-bit maps are TIFF)..."""
    from .imagefile import depth_extension
    if roles == [IMAGE]:
        return [(IMAGE, out, depths[IMAGE])]
    return [(r, map_path(out, r, depth_extension(depths[r])), depths[r]) for r in roles]


def check_maps_spec(spec: str | None) -> None:
    """``--maps`` names only known roles (checked before any work)."""
    if spec is None or spec.strip().lower() == "all":
        return
    alias = {**_SUFFIX, IMAGE: IMAGE}
    words = [w.strip().lower() for w in spec.split(",") if w.strip()]
    if not words:
        raise MaterialError("--maps names no map.")
    for w in words:
        if w not in alias:
            raise MaterialError(f"--maps: {printable(w, 40)!r} is not a map role; use all or some of "
                                f"{', '.join(ROLES)}.")


def parse_maps(spec: str | None, material: Material) -> list[str]:
    """``--maps all|basecolor,height,...`` as roles of the material (canonical order)."""
    if spec is None or spec.strip().lower() == "all":
        return material.roles
    wanted = [w.strip().lower() for w in spec.split(",") if w.strip()]
    alias = {**_SUFFIX, IMAGE: IMAGE}
    roles = []
    for w in wanted:
        r = alias.get(w)
        if r is None:
            raise MaterialError(f"--maps: {printable(w, 40)!r} is not a map role; use all or some of "
                                f"{', '.join(ROLES)}.")
        if r not in material.maps:
            have = ", ".join(material.roles)
            raise MaterialError(f"--maps: this material has no {r} map (it has {have}).")
        if r not in roles:
            roles.append(r)
    if not roles:
        raise MaterialError("--maps names no map.")
    return ordered(roles)


def open_material(paths, fit: str = "resize", toroidal: bool | None = None) -> Material:
    """A material from files: one map (its siblings come along), a folder, or
    several maps (roles from their names); a plain image is a one-map material."""
    from .exemplar import MAX_FILE_BYTES
    paths = [os.fspath(paths)] if isinstance(paths, (str, os.PathLike)) else [os.fspath(p) for p in paths]
    found = assign_roles(paths)
    return load_material([(r, p, data) for r, p, data in read_maps(found, MAX_FILE_BYTES)], fit, toroidal)
