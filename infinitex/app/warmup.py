"""Shader warm-up: the first dab of a new kind of edit must not freeze the editor.

Each kind of edit (painted randomness, labels, a direction field, an avoided
region, a feature, randomness painted on the exemplar) switches the synthesis
to shader variants of its own. A CPU driver (llvmpipe) compiles a variant when
it first draws with it, about a second each on this 2-core machine, and that
second falls in the frame of the first dab. Mesa keeps what it compiled in its
on-disk shader cache, so once per machine is enough.

So when a document's full analysis is installed, :class:`ShaderWarmup` starts a
low-priority process (``python -m infinitex.app.warmup``, the project as JSON
on its standard input) that synthesizes a small view of the same document in
its own headless context and applies one edit of each kind the document does
not have yet, the way the editor does (a local update and a quick look). The
variants it compiles land in the disk cache, where the editor finds them. A
marker in the state folder (one line per document kind and shader version)
keeps it from running again for what was warmed already.
"""
from __future__ import annotations

import hashlib
import json
import os
import subprocess
import sys

from infinitex.engine.gpu import read_shader

MARKER = "shader-warmup.txt"
MARKER_LINES = 256


def warm_key(doc_json: str, renderer: str) -> str:
    """What decides the variants: the renderer, the shaders, the exemplar and
    the document's analysis and synthesis settings (not its paint)."""
    doc = json.loads(doc_json)
    shaders = os.path.join(os.path.dirname(os.path.dirname(__file__)), "engine", "shaders")
    h = hashlib.sha256(renderer.encode())
    for name in sorted(os.listdir(shaders)):
        h.update(name.encode() + read_shader(name).encode())
    keep = [doc.get("exemplar", {}).get("sha256"), doc.get("analysis"), doc.get("synthesis")]
    h.update(json.dumps(keep, sort_keys=True, default=str).encode())
    return h.hexdigest()[:32]


class ShaderWarmup:
    """Runs the warm-up process once per document kind (see the module)."""

    def __init__(self, state_dir: str):
        self.state_dir = state_dir
        self.proc: subprocess.Popen | None = None
        self._key: str | None = None

    def _done_keys(self) -> list[str]:
        try:
            with open(os.path.join(self.state_dir, MARKER), encoding="ascii", errors="replace") as f:
                return [line.strip() for line in f.read(64 * MARKER_LINES).splitlines()[:MARKER_LINES]]
        except OSError:
            return []

    def start(self, project_json: str, renderer: str) -> bool:
        """Warm the variants of this document's edits in the background, unless
        done already; True when a process started."""
        if os.environ.get("INFINITEX_NO_WARMUP") or \
                os.environ.get("MESA_SHADER_CACHE_DISABLE", "").lower() in ("1", "true", "yes"):
            return False  # (benchmarks and tests; no disk cache to fill)
        self.poll()
        key = warm_key(project_json, renderer)
        if self.proc is not None or key in self._done_keys():
            return False
        try:
            self.proc = subprocess.Popen([sys.executable, "-m", "infinitex.app.warmup"], stdin=subprocess.PIPE,
                                         stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
            self.proc.stdin.write(project_json.encode("utf-8"))
            self.proc.stdin.close()
        except OSError:
            self.stop()
            return False
        self._key = key
        return True

    def poll(self) -> None:
        """Record a finished warm-up (so it does not run again)."""
        if self.proc is None or self.proc.poll() is None:
            return
        ok = self.proc.returncode == 0
        self.proc = None
        if ok and self._key is not None:
            from infinitex.engine.safeio import atomic_write
            keys = [self._key] + [k for k in self._done_keys() if k != self._key]
            try:
                os.makedirs(self.state_dir, exist_ok=True)
                atomic_write(os.path.join(self.state_dir, MARKER), ("\n".join(keys[:MARKER_LINES]) + "\n").encode())
            except OSError:
                pass
        self._key = None

    def stop(self) -> None:
        """Stop a warm-up still running (the editor closes)."""
        if self.proc is not None:
            if self.proc.poll() is None:
                self.proc.kill()
            self.proc.wait()
        self.proc, self._key = None, None


def edits(base, an) -> list[tuple[str, object]]:
    """One small edit of each kind ``base`` (Controls) does not have yet, as the
    Controls after it."""
    from dataclasses import replace

    import numpy as np

    from infinitex.engine.controls import (CanvasField, CanvasLabels, DirectionField, ExemplarField, ExemplarLabels,
                                           ExemplarMask, Feature)
    from infinitex.engine.controls.direction import jacobian
    m = an.size
    out = []
    if base.randomness_canvas is None:
        out.append(("randomness", replace(base, randomness_canvas=CanvasField().painted(40.0, 40.0, 16.0, 0)[0])))
    if base.labels_exemplar is None:
        v = np.zeros((m, m), np.uint8)
        v[:, m // 2:] = 1
        out.append(("labels", replace(base, labels_exemplar=ExemplarLabels(v),
                                      labels_canvas=CanvasLabels().painted(40.0, 40.0, 16.0, 2)[0])))
    if base.direction is None and base.lattice is None:
        out.append(("direction", replace(base, direction=DirectionField().painted(
            40.0, 40.0, 16.0, jacobian(45.0, 1.0), 1.0)[0])))
    if base.avoid is None:
        out.append(("avoid", replace(base, avoid=ExemplarMask.blank(m).painted(m / 2, m / 2, m / 8))))
    if not base.features:
        out.append(("features", replace(base, features=(Feature((m // 2, m // 2), (40, 40), 6, 14, None),))))
    if base.randomness_exemplar is None:
        out.append(("exemplar", replace(base, randomness_exemplar=ExemplarField.blank(m).painted(m / 2, m / 2, m / 8, 0))))
    return out


def main() -> int:
    """The warm-up process: the project as JSON on standard input, at the
    lowest priority (set here, for every thread, not by a ``preexec_fn``:
    Python code run between fork and exec in the editor, whose GL and UI
    threads hold locks, is documented as unsafe)."""
    from infinitex.engine.priority import lower_priority
    lower_priority(19)  # every thread (numpy's BLAS threads exist already)
    from infinitex.engine.pyramid import Rect
    from infinitex.export.workers import ProjectSynthesizer
    raw = sys.stdin.buffer.read(1 << 30).decode("utf-8")
    synth = ProjectSynthesizer(raw)()
    base = synth.controls
    if getattr(base, "surface", None) is not None:
        return 0
    an, L = synth.analysis, synth.L
    view = Rect(0, 0, 96, 96)
    failed = 0
    for _, controls in edits(base, an):
        try:
            synth.set_params(synth.params, base)
            vp = synth.viewport()
            vp.show(view)
            vp.pyramid.update_controls(controls, defer=True)
            vp.pyramid.looks.look(L, view)
            vp.pyramid.settle()
            vp.show(view)  # (an edit of the exemplar's inputs re-synthesizes the whole view)
            vp.release()
        except Exception:  # the others still count; not marked done, so tried again next time
            failed += 1
    synth.release()
    return 1 if failed else 0

if __name__ == "__main__":
    sys.exit(main())
