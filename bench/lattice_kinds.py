"""Lattice detection on a generated set that cannot be overfit (issue 66).

    python -m bench.lattice_kinds [--n 50] [--stochastic 64] [--few 100]
                                  [--contents shapes,tiles,photo,noise]
                                  [--jobs N] [--json OUT.json] [--dump DIR]

Images from tests/lattice_kinds.py: N per lattice kind and cell content
(square, rectangular, hexagonal, oblique, staggered x shapes, tiles, photo,
noise; any angle, degraded by colour variation, jitter, lighting, blur and
noise), STOCHASTIC per stochastic kind (must get no lattice) and FEW lattices
that repeat 1.5 to 2.6 times along a vector: under 2 they must get no
lattice; from 2 to 3 repeats a lattice is taken only with a confidence of 0.5
(lattice.SURE_REPEATS, FEW_CONFIDENCE), and the table says how many were
given one and how many of those were right. Each image is rebuilt from its kind and
index alone, so the set is fixed by the counts.

A found lattice is right when both vectors and the cell's area are within 2%
of the true lattice (tests/lattice_gen.lattice_error; a supercell is wrong).
Prints right / wrong / none per kind and content, the false lattices per
stochastic kind, writes JSON (default bench/results/lattice-kinds.json: the
summary and every miss) and,
with --dump, each miss's image as a PNG named by its case and what became of
it (the vectors found are in the JSON).
"""
from __future__ import annotations

import argparse
import json
import os
import sys
import time
from concurrent.futures import ProcessPoolExecutor

import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, ROOT)
sys.path.insert(0, os.path.join(ROOT, "tests"))

import lattice_kinds as K  # noqa: E402
from lattice_gen import lattice_error  # noqa: E402

from infinitex.engine.controls.lattice_detect import detect  # noqa: E402
from infinitex.engine.safeio import atomic_write  # noqa: E402

RIGHT = 0.02


def _case(job):
    group, kind, content, index = job
    if group == "lattice" or group == "few":
        img, t1, t2 = K.lattice_case(kind, content, index, few=group == "few")
    else:
        img, t1, t2 = K.stochastic_case(kind, index), None, None
    t0 = time.perf_counter()
    d = detect(img)
    seconds = time.perf_counter() - t0
    found = d.lattice is not None
    err = lattice_error(d.t1, d.t2, t1, t2) if (found and t1 is not None) else None
    if group == "lattice":
        status = "none" if not found else ("right" if err <= RIGHT else "wrong")
    else:
        status = "false" if found else "none"
    repeats = None
    if t1 is not None:
        a, b = K.reduce(t1, t2)
        repeats = round(K.SIDE / max(np.hypot(*a), np.hypot(*b)), 3)
    return {"group": group, "kind": kind, "content": content, "index": index, "status": status, "repeats": repeats,
            "error": None if err is None or not np.isfinite(err) else round(float(err), 4),
            "confidence": round(float(d.confidence), 3), "seconds": round(seconds, 4),
            "found": [list(map(float, d.t1)), list(map(float, d.t2))] if found else None,
            "truth": [list(map(float, t1)), list(map(float, t2))] if t1 is not None else None}


def jobs(n: int, n_stochastic: int, n_few: int, contents=K.CONTENTS) -> list[tuple]:
    out = [("lattice", k, c, i) for k in K.LATTICE_KINDS for c in contents for i in range(n)]
    out += [("stochastic", k, "", i) for k in K.STOCHASTIC_KINDS for i in range(n_stochastic)]
    out += [("few", K.LATTICE_KINDS[i % len(K.LATTICE_KINDS)], K.CONTENTS[(i // 5) % len(K.CONTENTS)], i)
            for i in range(n_few)]
    return out


def run(n: int, n_stochastic: int, n_few: int, workers: int, contents=K.CONTENTS) -> list[dict]:
    todo = jobs(n, n_stochastic, n_few, contents)
    if workers <= 1:
        return [_case(j) for j in todo]
    with ProcessPoolExecutor(workers) as pool:
        return list(pool.map(_case, todo, chunksize=8))


def summarize(results: list[dict]) -> dict:
    lat = [r for r in results if r["group"] == "lattice"]
    table = {}
    for kind in K.LATTICE_KINDS + ("all",):
        row = {}
        for content in K.CONTENTS + ("all",):
            sel = [r for r in lat if kind in (r["kind"], "all") and content in (r["content"], "all")]
            if sel:
                row[content] = {s: sum(r["status"] == s for r in sel) for s in ("right", "wrong", "none")}
                row[content]["of"] = len(sel)
        table[kind] = row
    sto = {}
    for kind in K.STOCHASTIC_KINDS:
        sel = [r for r in results if r["group"] == "stochastic" and r["kind"] == kind]
        sto[kind] = {"false": sum(r["status"] == "false" for r in sel), "of": len(sel)}
    few = [r for r in results if r["group"] == "few"]
    under2 = [r for r in few if r["repeats"] < 2.0]
    two = [r for r in few if r["repeats"] >= 2.0]
    secs = sorted(r["seconds"] for r in results)
    return {"lattices": table, "stochastic": sto,
            "stochastic_false": sum(v["false"] for v in sto.values()),
            "stochastic_of": sum(v["of"] for v in sto.values()),
            "few_false": sum(r["status"] == "false" for r in few), "few_of": len(few),
            "under_two_false": sum(r["status"] == "false" for r in under2), "under_two_of": len(under2),
            "two_to_three": {"right": sum(r["status"] == "false" and r["error"] is not None and r["error"] <= RIGHT
                                          for r in two),
                             "given": sum(r["status"] == "false" for r in two), "of": len(two)},
            "median_seconds": secs[len(secs) // 2] if secs else None}


def print_table(s: dict) -> None:
    print("lattices right (wrong, none) per kind x content:")
    print(f"  {'kind':12s}" + "".join(f"{c:>18s}" for c in K.CONTENTS + ("all",)))
    for kind, row in s["lattices"].items():
        cells = []
        for c in K.CONTENTS + ("all",):
            v = row.get(c)
            cells.append(f"{100 * v['right'] / v['of']:5.1f}% ({v['wrong']:2d},{v['none']:3d})" if v else "")
        print(f"  {kind:12s}" + "".join(f"{x:>18s}" for x in cells))
    print("stochastic given a lattice: " + ", ".join(f"{k} {v['false']}/{v['of']}" for k, v in s["stochastic"].items()))
    print(f"  all: {s['stochastic_false']}/{s['stochastic_of']} "
          f"({100 * s['stochastic_false'] / max(1, s['stochastic_of']):.1f}%)")
    t = s["two_to_three"]
    print(f"too few repeats: under 2 given a lattice {s['under_two_false']}/{s['under_two_of']}; "
          f"2 to 2.6 given one {t['given']}/{t['of']} (right {t['right']})")
    print(f"median detection time: {1000 * s['median_seconds']:.0f} ms (256^2)")


def dump(results: list[dict], folder: str) -> None:
    from PIL import Image
    os.makedirs(folder, exist_ok=True)
    for r in results:
        if r["status"] in ("right",) or (r["group"] != "lattice" and r["status"] == "none"):
            continue
        if r["group"] == "stochastic":
            img = K.stochastic_case(r["kind"], r["index"])
        else:
            img = K.lattice_case(r["kind"], r["content"], r["index"], few=r["group"] == "few")[0]
        name = f"{r['group']}-{r['kind']}-{r['content'] or 'x'}-{r['index']:03d}-{r['status']}.png"
        Image.fromarray((np.clip(img, 0, 1) * 255).astype(np.uint8)).save(os.path.join(folder, name))


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--n", type=int, default=50, help="images per lattice kind and content (default 50: 1,000)")
    ap.add_argument("--stochastic", type=int, default=64, help="images per stochastic kind (default 64: 512)")
    ap.add_argument("--few", type=int, default=100, help="lattices with too few repeats (default 100)")
    ap.add_argument("--contents", default=",".join(K.CONTENTS), help="only these cell contents (comma-separated)")
    ap.add_argument("--jobs", type=int, default=os.cpu_count() or 1)
    ap.add_argument("--json", default=os.path.join(ROOT, "bench", "results", "lattice-kinds.json"))
    ap.add_argument("--dump", help="write each miss as a PNG into this folder")
    a = ap.parse_args(argv)
    t0 = time.perf_counter()
    results = run(a.n, a.stochastic, a.few, a.jobs, tuple(a.contents.split(",")))
    s = summarize(results)
    print_table(s)
    print(f"({len(results)} images in {time.perf_counter() - t0:.0f} s)")
    misses = [r for r in results if (r["group"] == "lattice" and r["status"] != "right") or r["status"] == "false"]
    atomic_write(a.json, json.dumps({"summary": s, "misses": misses}, indent=1).encode())
    if a.dump:
        dump(results, a.dump)
    return 0


if __name__ == "__main__":
    sys.exit(main())
