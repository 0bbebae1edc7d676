"""Where the test suite's time goes: a Markdown table from pytest's JUnit XML.

    bash scripts/test.sh --junitxml=out/full.xml
    bash scripts/test.sh --fast --junitxml=out/fast.xml
    .venv/bin/python scripts/test_durations.py out/full.xml [out/fast.xml] [--top 15]
    .venv/bin/python scripts/test_durations.py before=old.xml full=out/full.xml fast=out/fast.xml

Prints, per kind of test and per file, the seconds spent in its tests (setup,
call and teardown summed over every worker: in a parallel run the wall time is
about this sum over the number of workers) and the slowest tests, for
docs/testing.md.
"""
from __future__ import annotations

import argparse
import collections
import xml.etree.ElementTree as ET

# What the time of each file is mostly spent on.
KINDS = [
    ("tests/app/test_editor.py", "GUI drivers (the real editor under Xvfb)"),
    ("tests/export/", "exports (worker processes, Dask, subprocesses)"),
    ("tests/cli/", "command line (subprocesses, examples, a pip install)"),
    ("tests/reliability/test_fuzz.py", "fuzz examples"),
    ("tests/reliability/", "untrusted input (subprocesses, memory limits)"),
    ("tests/engine/test_import_limits.py", "untrusted input (subprocesses, memory limits)"),
    ("tests/engine/test_analysis.py", "analyses (CPU)"),
    ("tests/engine/test_large.py", "analyses (CPU)"),
    ("tests/engine/", "GL windows against the numpy oracle"),
    ("tests/app/", "the editor's session and canvas (GL, no window)"),
    ("tests/bench/", "benchmarks' measures"),
    ("tests/project/", "documents, projects, autosave (no GL)"),
    ("tests/", "layout rules"),
]


def kind(path: str) -> str:
    return next(k for prefix, k in KINDS if path.startswith(prefix))


def read(path: str) -> dict[str, float]:
    """Seconds per test id (file::name) of a JUnit XML report."""
    out: dict[str, float] = {}
    for tc in ET.parse(path).getroot().iter("testcase"):
        f = tc.get("classname", "").replace(".", "/") + ".py"
        out[f"{f}::{tc.get('name')}"] = float(tc.get("time", 0))
    return out


def table(runs: list[tuple[str, dict[str, float]]], top: int) -> str:
    names = [n for n, _ in runs]
    lines = ["| kind | " + " | ".join(f"{n} (s)" for n in names) + " |", "|---|" + "---|" * len(names)]
    per_kind = [collections.Counter() for _ in runs]
    per_file = [collections.Counter() for _ in runs]
    counts = [collections.Counter() for _ in runs]
    for i, (_, r) in enumerate(runs):
        for tid, s in r.items():
            f = tid.split("::")[0]
            per_kind[i][kind(f)] += s
            per_file[i][f] += s
            counts[i][f] += 1
    for k in sorted(per_kind[0], key=per_kind[0].get, reverse=True):
        lines.append(f"| {k} | " + " | ".join(f"{c[k]:.0f}" for c in per_kind) + " |")
    lines.append("| **all** | " + " | ".join(f"**{sum(c.values()):.0f}**" for c in per_kind) + " |")
    lines += ["", "| file | tests | " + " | ".join(f"{n} (s)" for n in names) + " |",
              "|---|---|" + "---|" * len(names)]
    for f in sorted(per_file[0], key=per_file[0].get, reverse=True):
        lines.append(f"| `{f}` | {counts[0][f]} | " + " | ".join(f"{c[f]:.1f}" if f in c else "-" for c in per_file)
                     + " |")
    lines += ["", f"The {top} slowest tests ({names[0]}):", "", "| s | test |", "|---|---|"]
    for tid, s in sorted(runs[0][1].items(), key=lambda kv: kv[1], reverse=True)[:top]:
        lines.append(f"| {s:.1f} | `{tid}` |")
    return "\n".join(lines)


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("reports", nargs="+", metavar="[NAME=]XML",
                   help="JUnit XML reports, each a column (default names: full, fast, ...)")
    p.add_argument("--top", type=int, default=15)
    a = p.parse_args(argv)
    defaults = ["full", "fast"] + [f"run {i}" for i in range(3, 10)]
    runs = []
    for i, spec in enumerate(a.reports):
        name, _, path = spec.rpartition("=") if "=" in spec else (defaults[i], "", spec)
        runs.append((name, read(path)))
    print(table(runs, a.top))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
