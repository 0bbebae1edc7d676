"""Real near-regular images for the lattice tests and benchmark.

27 textures with a lattice (grids, rows, weaves, bricks, stripes; periods 4 px
to half the image) and 8 stochastic ones, from Debian's
``openarena-081-textures`` package (GPL-2+, so they are fetched, never
committed). ``data/near_regular.json`` names each file inside the package's
texture archive, its SHA-256 and its true lattice, checked by hand once
(overlaid on the image) and stored: ``grid`` gives two vectors spanning the
lattice, ``rows`` the vector across the rows (its length is the period), ``none``
means no lattice.

The package (94 MB) is downloaded once from deb.debian.org (or by
``apt-get download``) and the 35 images are cached under
``$INFINITEX_CACHE/near-regular`` (default ``~/.cache/infinitex``).
"""
from __future__ import annotations

import hashlib
import io
import json
import math
import os
import shutil
import subprocess
import tarfile
import tempfile
import urllib.request
import zipfile

import numpy as np

from lattice_gen import lattice_error

DATA = os.path.join(os.path.dirname(os.path.abspath(__file__)), "data")
MANIFEST = os.path.join(DATA, "near_regular.json")
# A second set from another source (the Cube 2 game's textures, CC-BY-3.0; the
# files lie in the package directly): 13 lattices (grids, hexagons, diamond
# plate, courses and shingles) and 19 stochastic images, split by their place in
# the list (even: tuned on, odd: only reported; bench.lattice).
CUBE2 = os.path.join(DATA, "lattice_cube2.json")
TOLERANCE = 0.03  # the target: within 3% of the true vectors


class Unavailable(RuntimeError):
    """The image set could not be fetched (no network, package gone)."""


def manifest(path: str = MANIFEST) -> dict:
    with open(path, encoding="utf-8") as f:
        return json.load(f)


def cache_dir() -> str:
    base = os.environ.get("INFINITEX_CACHE") or os.path.join(
        os.environ.get("XDG_CACHE_HOME") or os.path.join(os.path.expanduser("~"), ".cache"), "infinitex")
    return os.path.join(base, "near-regular")


def _cached_name(entry: dict) -> str:
    return entry["sha256"][:16] + os.path.splitext(entry["path"])[1]


def _download(pkg: dict, into: str) -> str:
    """The package's .deb in ``into``, checked against its SHA-256."""
    deb = os.path.join(into, os.path.basename(pkg["url"]))
    errors = []
    try:
        with urllib.request.urlopen(pkg["url"], timeout=60) as r, open(deb, "wb") as f:
            shutil.copyfileobj(r, f)
    except OSError as e:
        errors.append(f"{pkg['url']}: {e}")
        if shutil.which("apt-get"):  # a mirror configured on this machine
            done = subprocess.run(["apt-get", "download", f"{pkg['name']}={pkg['version']}"], cwd=into,
                                  capture_output=True, text=True, timeout=600)
            if done.returncode != 0:
                errors.append("apt-get download: " + done.stderr.strip().splitlines()[-1:][0]
                              if done.stderr.strip() else "apt-get download failed")
    if not os.path.exists(deb):
        raise Unavailable("could not fetch " + pkg["name"] + ": " + "; ".join(errors))
    h = hashlib.sha256()
    with open(deb, "rb") as f:
        for chunk in iter(lambda: f.read(1 << 20), b""):
            h.update(chunk)
    if h.hexdigest() != pkg["sha256"]:
        raise Unavailable(f"{os.path.basename(deb)} does not match its recorded SHA-256")
    return deb


def _members_from_deb(deb: str, members: list[str]) -> dict[str, bytes]:
    """Files of a .deb's data archive (through dpkg-deb, which knows every
    compression a .deb may use)."""
    if not shutil.which("dpkg-deb"):
        raise Unavailable("dpkg-deb is needed to unpack the image set's package")
    tar_bytes = subprocess.run(["dpkg-deb", "--fsys-tarfile", deb], capture_output=True, check=True).stdout
    out = {}
    with tarfile.open(fileobj=io.BytesIO(tar_bytes)) as tar:
        for m in members:
            for name in (m, "./" + m):
                try:
                    out[m] = tar.extractfile(name).read()
                    break
                except KeyError:
                    continue
            else:
                raise Unavailable(f"{m} is not in {os.path.basename(deb)}")
    return out


def fetch(path: str = MANIFEST) -> list[tuple[dict, str]]:
    """(entry, path of the cached image) for every image of the set, fetching
    the package first if any image is missing. Raises Unavailable."""
    m = manifest(path)
    root = cache_dir()
    os.makedirs(root, exist_ok=True)
    out = [(e, os.path.join(root, _cached_name(e))) for e in m["images"]]
    missing = [(e, p) for e, p in out if not os.path.exists(p)]
    if missing:
        with tempfile.TemporaryDirectory(dir=root) as tmp:
            deb = _download(m["package"], tmp)
            if "archive" in m["package"]:  # the images lie in a zip inside the package
                with zipfile.ZipFile(io.BytesIO(_members_from_deb(deb, [m["package"]["archive"]])[m["package"]["archive"]])) as pk3:
                    read = {e["path"]: pk3.read(e["path"]) for e, _ in missing}
            else:
                read = _members_from_deb(deb, [e["path"] for e, _ in missing])
            for e, p in missing:
                data = read[e["path"]]
                if hashlib.sha256(data).hexdigest() != e["sha256"]:
                    raise Unavailable(f"{e['path']} does not match its recorded SHA-256")
                part = p + ".part"
                with open(part, "wb") as f:
                    f.write(data)
                os.replace(part, p)
    return out


def load(path: str) -> np.ndarray:
    from PIL import Image
    with Image.open(path) as im:
        return np.asarray(im.convert("RGB"), np.float32) / 255.0


def rows_error(t1, t2, across) -> float:
    """How far a found basis is from the rows whose period vector is ``across``:
    each found vector must cross a whole number of rows (the relative error of
    its projection, in periods), and together they must step one row."""
    a = np.asarray(across, float)
    p = float(np.hypot(*a))
    n = a / p
    ks = [float(np.asarray(v, float) @ n) / p for v in (t1, t2)]
    ints = [round(k) for k in ks]
    if math.gcd(abs(ints[0]), abs(ints[1])) != 1:
        return math.inf
    return max(abs(k - i) / max(1, abs(i)) for k, i in zip(ks, ints))


def correct(entry: dict, detection) -> bool:
    """Whether a Detection matches the stored truth (within 3%)."""
    if entry["kind"] == "none":
        return detection.lattice is None
    if detection.lattice is None:
        return False
    if entry["kind"] == "rows":
        return rows_error(detection.t1, detection.t2, entry["vectors"][0]) <= TOLERANCE
    t1, t2 = entry["vectors"]
    return lattice_error(detection.t1, detection.t2, t1, t2) <= TOLERANCE
