#!/usr/bin/env python3
"""Records a synthetic history of N commits from real results files, for checking
`shadowbench history` (CI, tests, demonstrations).

Commit k (1..N) gets the runs of one of the given results files, drawn at random (seeded), so
measured times vary as much as the real runs did; with a single file, --noise multiplies every
measured time (`*_ms` but `model_ms`, run and phases) by a normal factor 1 + noise * N(0, 1).
--step CASE:FIGURE multiplies one figure of the one run whose case id contains CASE by --factor
from commit --step-at on (FIGURE: a top-level field such as model_ms, or counters.NAME,
error.NAME).

    scripts/synthetic-history.py --db h.sqlite --commits 30 --step-at 20 \\
        --step pcss_cpu-model_t1964:model_ms --factor 1.05 out/ci-*/results.json

Prints the commit ids, one a line, first to last.
"""
import argparse
import copy
import hashlib
import json
import os
import random
import subprocess
import sys
import tempfile


def measured(name):
    return name.endswith("_ms") and name != "model_ms"


def jitter(run, rng, noise):
    for k in list(run):
        if measured(k) and isinstance(run[k], (int, float)):
            run[k] *= 1 + noise * rng.gauss(0, 1)
    for p in run.get("phases", []):
        jitter(p, rng, noise)


def step(run, figure, factor):
    head, _, rest = figure.partition(".")
    target = run.get(head) if rest else run
    key = rest if rest else head
    if not isinstance(target, dict) or not isinstance(target.get(key), (int, float)):
        sys.exit(f"--step: run {run.get('algorithm')}/{run.get('backend')} has no figure {figure}")
    target[key] *= factor


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("results", nargs="+")
    ap.add_argument("--db", required=True)
    ap.add_argument("--commits", type=int, default=30)
    ap.add_argument("--step", help="CASE:FIGURE to step")
    ap.add_argument("--step-at", type=int, default=20, help="first commit (1-based) stepped")
    ap.add_argument("--factor", type=float, default=1.05)
    ap.add_argument("--noise", type=float, default=0.0)
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--bin", default="target/release/shadowbench")
    ap.add_argument("--prefix", default="synthetic", help="distinguishes the commit ids")
    a = ap.parse_args()
    pool = [json.load(open(p)) for p in a.results]
    rng = random.Random(a.seed)
    case, _, figure = (a.step or "").partition(":")
    if a.step and not figure:
        sys.exit("--step: expected CASE:FIGURE")
    with tempfile.TemporaryDirectory() as tmp:
        for k in range(1, a.commits + 1):
            data = copy.deepcopy(pool[rng.randrange(len(pool))])
            hit = 0
            for run in data["runs"]:
                if run.get("failure"):
                    continue
                if a.noise > 0:
                    jitter(run, rng, a.noise)
                p = run["params"]
                cid = (f"{run['scene']}_{run['algorithm']}_{run['backend']}_t{p['triangles']}"
                       f"_l{p['light_size']}_m{p['map_resolution']}_b{p['tile_size']}"
                       f"_{p['image'][0]}x{p['image'][1]}")
                if a.step and k >= a.step_at and case in cid:
                    step(run, figure, a.factor)
                    hit += 1
            if a.step and k >= a.step_at and hit != 1:
                sys.exit(f"--step: '{case}' matches {hit} runs; it must match one")
            path = os.path.join(tmp, f"results-{k}.json")
            json.dump(data, open(path, "w"))
            sha = hashlib.sha1(f"{a.prefix}-{k}".encode()).hexdigest()
            subprocess.run(
                [a.bin, "history", "record", path, "--db", a.db, "--commit", sha,
                 "--branch", "main", "--date", f"2026-01-01T00:{k // 60:02d}:{k % 60:02d}Z",
                 "--subject", f"{a.prefix} commit {k}", "--machine", a.prefix],
                check=True, stdout=subprocess.DEVNULL)
            print(sha)


if __name__ == "__main__":
    main()
