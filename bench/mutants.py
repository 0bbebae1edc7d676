"""Deliberate bugs the test suite must catch (mutation checks).

    .venv/bin/python -m bench.mutants [--fast] [--tests-from REV] [--only NAME,...] [--json OUT]

Each of the mutants (15) is one small, plausible bug in the engine, the exports or the
project format (a comparison off by one, a margin too small, a setting left out
of a cache key...). For each, the checkout is copied to a temporary folder, the
bug is written into the copy, and the tests that should notice it run there
(pytest -x, in parallel processes); the mutant is *killed* when they fail, and
*survives* when they pass. ``--tests-from REV`` takes the copy's tests/ from a
git revision instead (to compare the suite before and after it was shrunk: the
same mutants must be killed). ``--fast`` runs the whole fast set
(``scripts/test.sh --fast``: every test not marked gui or slow) against each
mutant instead of its own tests: what the edit-test loop catches. Prints a
table and writes JSON (default bench/results/mutants.json, with --fast
mutants-fast.json). A few minutes on 2 cores with llvmpipe (--fast: about
half an hour).
"""
from __future__ import annotations

import argparse
import json
import os
import shutil
import subprocess
import sys
import tempfile
import time

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(HERE)

ENGINE = "tests/engine/test_synthesis.py tests/engine/test_features.py tests/engine/test_fidelity.py"
LOCAL = "tests/engine/test_fidelity.py tests/engine/test_randomness_fields.py tests/app/test_painting.py"

# (name, file, text, replacement, tests)
MUTANTS = [
    ("child offset at the finest level", "infinitex/engine/shaders/upsample.frag",
     "- ((h + 1) >> 1);", "- (h >> 1);", "tests/engine/test_synthesis.py"),
    ("correction keeps the last of equal costs", "infinitex/engine/shaders/correct.frag",
     "            if (cost < best) {", "            if (cost <= best) {", "tests/engine/test_synthesis.py"),
    ("fidelity search keeps the last of equal costs", "infinitex/engine/shaders/fidelity.frag",
     "    if (c < best) {", "    if (c <= best) {", "tests/engine/test_fidelity.py"),
    ("feature bound one pixel short", "infinitex/engine/shaders/common.glsl",
     "int lim = (a.w >> 4) + 2;", "int lim = (a.w >> 4);", ENGINE),
    ("feature disc boundary excluded", "infinitex/engine/shaders/common.glsl",
     "d16.x * d16.x + d16.y * d16.y <= a.w * a.w", "d16.x * d16.x + d16.y * d16.y < a.w * a.w", ENGINE),
    ("window margins without the fidelity stage", "infinitex/engine/params.py",
     "for n, r in ((passes, radius),) + tuple(stages):", "for n, r in ((passes, radius),):",
     "tests/engine/test_fidelity.py"),
    ("local update reach one pixel short", "infinitex/engine/local_update.py",
     "reach = max(self.pyr.margins[l])", "reach = max(self.pyr.margins[l]) - 1", LOCAL),
    ("analysis cache key without the settings", "infinitex/engine/analysis.py",
     "h.update(json.dumps(asdict(settings), sort_keys=True).encode())", "pass",
     "tests/engine/test_analysis.py tests/engine/test_synthesis.py tests/engine/test_fidelity.py"),
    ("appearance features in float32", "infinitex/engine/neighborhoods.py",
     "quantized, np.float64).reshape(m, m, NDIM)", "quantized, np.float32).reshape(m, m, NDIM)",
     "tests/engine/test_analysis.py"),
    ("export tiles one pixel short", "infinitex/export/streamed.py",
     "Rect(x0, y0, min(x0 + self.tile, lr.x1), min(y0 + self.tile, lr.y1))",
     "Rect(x0, y0, min(x0 + self.tile - 1, lr.x1), min(y0 + self.tile, lr.y1))",
     "tests/export/test_tiled_export.py tests/app/test_session.py"),
    ("project files forget the seed", "infinitex/project/format.py",
     '"jitter": list(doc.jitter), "seed": doc.seed,', '"jitter": list(doc.jitter), "seed": 0,',
     "tests/project/test_document.py tests/app/test_session.py"),
    ("subpass rectangles one texel short", "infinitex/engine/params.py",
     "reads[a + 2] = (hi[a] + max(ds) - q[a]) // s + 1", "reads[a + 2] = (hi[a] + max(ds) - q[a]) // s",
     "tests/engine/test_synthesis.py tests/engine/test_fidelity.py"),
    ("row taps clamped on a toroidal exemplar", "infinitex/engine/gpu.py",
     "xs = xs & (m - 1) if toroidal else np.clip(xs, 0, m - 1)", "xs = np.clip(xs, 0, m - 1)",
     "tests/engine/test_fidelity.py"),
    ("a dab's region says less than it changed (tools/paint.py)", "infinitex/app/ui/tools/paint.py",
     "            field, rect = field.painted(cx, cy, r, b.value_u16, b.strength, b.hardness)\n"
     "            rects.append(rect)",
     "            field, rect = field.painted(cx, cy, r, b.value_u16, b.strength, b.hardness)\n"
     "            rects.append((rect[0] + 4, rect[1], rect[2], rect[3]))",
     "tests/app/test_painting.py"),
    ("an undo says none of its step's region (project/history.py)", "infinitex/project/history.py",
     "        self._move(step.doc, step.region)\n        self._group = None\n        return True\n\n    def redo",
     "        self._move(step.doc, ())\n        self._group = None\n        return True\n\n    def redo",
     "tests/project/test_document.py"),
]


def _copy(dst: str, tests_from: str | None) -> None:
    ignore = shutil.ignore_patterns(".git", ".venv", "out", "__pycache__", "*.pyc", "results")
    for name in ("infinitex", "tests", "bench", "examples", "scripts"):
        shutil.copytree(os.path.join(ROOT, name), os.path.join(dst, name), ignore=ignore)
    shutil.copytree(os.path.join(ROOT, "docs"), os.path.join(dst, "docs"), ignore=ignore)  # (the guide's own tests)
    for name in ("main.py", "pytest.ini", "pyproject.toml", "README.md"):
        shutil.copy2(os.path.join(ROOT, name), dst)
    if tests_from:
        shutil.rmtree(os.path.join(dst, "tests"))
        tar = subprocess.run(["git", "archive", tests_from, "tests"], cwd=ROOT, check=True, capture_output=True).stdout
        subprocess.run(["tar", "-x", "-C", dst], input=tar, check=True)


def run_mutant(mutant, tests_from: str | None, workers: str, fast: bool = False) -> dict:
    name, path, text, repl, tests = mutant
    select = ["-m", "not gui and not slow", "tests"] if fast else ["-m", "not gui", *tests.split()]
    with tempfile.TemporaryDirectory(prefix="infinitex-mutant-") as tmp:
        _copy(tmp, tests_from)
        target = os.path.join(tmp, path)
        with open(target) as f:
            src = f.read()
        if src.count(text) < 1:
            return dict(name=name, outcome="stale", seconds=0.0, detail=f"{text!r} not found in {path}")
        with open(target, "w") as f:
            f.write(src.replace(text, repl, 1))
        env = dict(os.environ, PYTHONDONTWRITEBYTECODE="1")
        env.pop("INFINITEX_CACHE", None)  # tests/conftest.py makes a fresh one per run
        t0 = time.perf_counter()
        r = subprocess.run([sys.executable, "-m", "pytest", "-q", "-x", "-p", "no:cacheprovider", "-n", workers,
                            *select], cwd=tmp, env=env, capture_output=True, text=True)
        seconds = time.perf_counter() - t0
    failed = [ln for ln in r.stdout.splitlines() if ln.startswith("FAILED")]
    # pytest -x in parallel processes ends "interrupted" (rc 2) at the first failure.
    outcome = ("killed" if failed or r.returncode == 1 else "survived" if r.returncode == 0
               else f"error (rc {r.returncode})")
    return dict(name=name, outcome=outcome, seconds=round(seconds, 1),
                detail=failed[0][7:] if failed else r.stdout.strip().splitlines()[-1] if r.stdout.strip() else "")


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--tests-from", help="take tests/ from this git revision")
    p.add_argument("--only", help="comma-separated mutant names (substrings)")
    p.add_argument("--workers", default="2")
    p.add_argument("--fast", action="store_true", help="run the fast set (scripts/test.sh --fast) against each")
    p.add_argument("--json")
    a = p.parse_args(argv)
    a.json = a.json or os.path.join(HERE, "results", "mutants-fast.json" if a.fast else "mutants.json")
    chosen = [m for m in MUTANTS if not a.only or any(s in m[0] for s in a.only.split(","))]
    results = []
    for m in chosen:
        res = run_mutant(m, a.tests_from, a.workers, a.fast)
        results.append(res)
        print(f"{res['outcome']:>9}  {res['seconds']:6.1f} s  {res['name']}  ({res['detail']})", flush=True)
    killed = sum(r["outcome"] == "killed" for r in results)
    print(f"{killed} of {len(results)} killed (tests from {a.tests_from or 'the working tree'}"
          f"{', the fast set' if a.fast else ''})")
    os.makedirs(os.path.dirname(a.json), exist_ok=True)
    with open(a.json, "w") as f:
        json.dump(dict(tests_from=a.tests_from or "working tree", fast_set=a.fast, mutants=results), f, indent=1)
    return 0 if killed == len(results) else 1


if __name__ == "__main__":
    sys.exit(main())
