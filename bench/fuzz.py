"""Long fuzz runs of every untrusted input, with figures.

    .venv/bin/python -m bench.fuzz [--cases 10000] [--targets import,project,cli,parts,model] [--seed S] [--json OUT]

Runs the targets of tests/fuzzing.py and tests/fuzz_models.py (the same generators and checks as the
test suite's fuzz tests), each in its own process, and counts per target:
inputs accepted, refused with the program's own error, crashes (any broken
promise: a foreign exception, a subprocess, a read outside what the user
chose, a damaged or replaced file, a multi-line error), hangs (over the time
limit per case), the slowest and median case, and the process's peak memory.
Prints a table and writes JSON (default bench/results/fuzz.json).
"""
from __future__ import annotations

import argparse
import json
import os
import resource
import shutil
import statistics
import subprocess
import sys
import tempfile
import time

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(HERE)
TARGETS = ("import", "project", "cli", "parts", "model")


def run_target(target: str, cases: int, seed: int, timeout: float) -> dict:
    sys.path.insert(0, os.path.join(ROOT, "tests"))
    sys.path.insert(0, ROOT)
    import warnings
    warnings.filterwarnings("ignore", module=r"PIL(\.|$)")
    from hypothesis import HealthCheck, Phase, given, settings
    from hypothesis import seed as hseed

    import fuzz_models as FM
    import fuzzing as F

    root = {"project": F.project_sandbox, "cli": F.cli_sandbox, "parts": F.parts_sandbox,
            "model": FM.model_sandbox}.get(target, lambda: None)()
    strategy = {"import": F.image_files(), "project": F.project_files(), "cli": F.command_lines(),
                "parts": F.parts_folders(), "model": FM.model_cases()}[target]
    counts = {"accepted": 0, "refused": 0, "crash": 0, "hang": 0}
    times: list[float] = []
    failures: list[dict] = []

    def one(x):
        t0 = time.perf_counter()
        try:
            if target == "import":
                out = F.run_import(x, timeout)
            elif target == "project":
                out = F.run_project(x, root, timeout)
            elif target == "parts":
                out = F.run_parts(x, root, timeout)
            elif target == "model":
                out = FM.run_model(x, root, timeout)
            else:
                out = F.run_cli(x, root, timeout)
            counts[out] += 1
        except F.Crash as exc:
            counts["crash"] += 1
            failures.append({"kind": "crash", "why": str(exc)[:300], "input": repr(x)[:300]})
        except F.Hang:
            counts["hang"] += 1
            failures.append({"kind": "hang", "input": repr(x)[:300]})
        except BaseException as exc:  # anything else is a crash too; Hypothesis must not see it
            if isinstance(exc, KeyboardInterrupt):
                raise
            counts["crash"] += 1
            failures.append({"kind": "crash", "why": f"{type(exc).__name__}: {exc}"[:300], "input": repr(x)[:300]})
        times.append(time.perf_counter() - t0)

    test = given(strategy)(settings(max_examples=cases, phases=[Phase.generate], deadline=None, database=None,
                                    suppress_health_check=list(HealthCheck))(one))
    t0 = time.perf_counter()
    hseed(seed)(test)()
    wall = time.perf_counter() - t0
    if root:
        shutil.rmtree(os.path.dirname(root) if target == "project" else root, ignore_errors=True)
    return dict(target=target, cases=len(times), **counts, seconds=round(wall, 1),
                median_ms=round(statistics.median(times) * 1000, 2), max_ms=round(max(times) * 1000, 1),
                peak_mb=round(resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024, 0),
                timeout_s=timeout, seed=seed, failures=failures[:20])


def main(argv: list[str]) -> int:
    p = argparse.ArgumentParser(prog="python -m bench.fuzz", description=__doc__.split("\n")[0])
    p.add_argument("--cases", type=int, default=10_000, help="cases per target")
    p.add_argument("--targets", default=",".join(TARGETS))
    p.add_argument("--seed", type=int, default=20261122)
    p.add_argument("--timeout", type=float, default=30.0, help="seconds a case may take before it counts as a hang")
    p.add_argument("--json", default=os.path.join(HERE, "results", "fuzz.json"))
    p.add_argument("--one", help=argparse.SUPPRESS)
    args = p.parse_args(argv)
    if args.one:
        print(json.dumps(run_target(args.one, args.cases, args.seed, args.timeout)))
        return 0
    results = []
    env = dict(os.environ, INFINITEX_CACHE=tempfile.mkdtemp(prefix="infinitex-fuzz-cache-"))
    for target in args.targets.split(","):
        sys.stderr.write(f"fuzzing {target}: {args.cases} cases...\n")
        r = subprocess.run([sys.executable, "-m", "bench.fuzz", "--one", target, "--cases", str(args.cases),
                            "--seed", str(args.seed), "--timeout", str(args.timeout)],
                           cwd=ROOT, env=env, capture_output=True, text=True)
        if r.returncode != 0:
            sys.stderr.write(r.stderr[-3000:])
            results.append(dict(target=target, error=r.stderr[-500:]))
            continue
        results.append(json.loads(r.stdout.strip().splitlines()[-1]))
    shutil.rmtree(env["INFINITEX_CACHE"], ignore_errors=True)
    print("| target | cases | accepted | refused | crashes | hangs | median ms | max ms | peak MB | wall s |")
    print("|---|---|---|---|---|---|---|---|---|---|")
    for r in results:
        if "error" in r:
            print(f"| {r['target']} | runner failed | | | | | | | | |")
            continue
        print(f"| {r['target']} | {r['cases']} | {r['accepted']} | {r['refused']} | {r['crash']} | {r['hang']} | "
              f"{r['median_ms']} | {r['max_ms']} | {r['peak_mb']:.0f} | {r['seconds']} |")
    os.makedirs(os.path.dirname(os.path.abspath(args.json)), exist_ok=True)
    from infinitex.engine.safeio import atomic_write
    atomic_write(args.json, json.dumps(dict(cases_per_target=args.cases, seed=args.seed, results=results),
                                       indent=1).encode())
    bad = sum(r.get("crash", 0) + r.get("hang", 0) for r in results) + sum("error" in r for r in results)
    return 1 if bad else 0


if __name__ == "__main__":
    sys.path.insert(0, ROOT)
    sys.exit(main(sys.argv[1:]))
