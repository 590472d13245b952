#!/usr/bin/env python3
"""The scaling figures of docs/sweeps.md: the speed-against-accuracy study's wall time on 1,
2 and 4 local Dask workers (each sweep into a fresh directory, references included), the
engine's per-task overhead against a sequential loop, and a paper estimate of the study on
a 64-core cluster from the measured per-task costs.

    .venv/bin/python scripts/sweep_scaling.py [--workers 1 2 4] [--repeats 1] [--out build/scaling]

Prints Markdown tables. The overhead: sweeps of N one-step runs (N = 20 and 80), each
`--sequential` and on a local cluster of one worker; the difference of the slopes is the
cost per task, of the intercepts the cluster's start and stop."""

import argparse
import os
import shutil
import statistics
import subprocess
import sys
import time

import pandas as pd

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
BIN = os.path.join(ROOT, "build/release/service/fiberfem")
STUDY = ["cantilever", "cantilever-gravity", "land-beam", "land-ventricle", "heart"]
OVERHEAD_SWEEP = """sweep: overhead-{n}
scene: {scene}
set: {{solver.mode: dynamic, mesh.cells: [10, 1, 1], solver.threads: 1, solver.until: 0.0166666}}
groups:
  - name: one-step
    vary: {{regions[0].material.E_L: {{linear: [50000, 70000], num: {n}}}}}
"""


def timed(argv) -> float:
    t0 = time.monotonic()
    p = subprocess.run(argv, capture_output=True, text=True)
    if p.returncode != 0:
        sys.exit(f"{' '.join(argv)} failed: {p.stderr[-2000:]}")
    return time.monotonic() - t0


def study_times(workers, out) -> dict:
    times = {}
    for s in STUDY:
        d = os.path.join(out, f"w{workers}", s)
        shutil.rmtree(d, ignore_errors=True)
        times[s] = timed([BIN, "sweep", os.path.join(ROOT, f"configs/sweeps/speed-accuracy/{s}.yaml"),
                          "--workers", str(workers), "--out", d])
    return times


def overhead(out, repeats):
    scene = os.path.join(ROOT, "configs/scenes/cantilever-along.yaml")
    res = {}
    for n in (20, 80):
        path = os.path.join(out, f"overhead-{n}.yaml")
        with open(path, "w") as f:
            f.write(OVERHEAD_SWEEP.format(n=n, scene=scene).replace("regions[0].material.E_L",
                                                                    '"regions[0].material.E_L"'))
        for mode, extra in (("sequential", ["--sequential"]), ("dask", ["--workers", "1"])):
            ts = []
            for _ in range(repeats):
                d = os.path.join(out, f"overhead-{n}-{mode}")
                shutil.rmtree(d, ignore_errors=True)
                ts.append(timed([BIN, "sweep", path, "--out", d, *extra]))
            res[(mode, n)] = statistics.median(ts)
            # Outside the tasks: the wall time less the tasks' own (attempt_s, last repeat).
            tasks = pd.read_parquet(os.path.join(d, "results.parquet"))["attempt_s"].sum()
            res[(mode, n, "outside")] = ts[-1] - tasks
            res[(mode, n, "task")] = tasks / n
    slope = {m: (res[(m, 80)] - res[(m, 20)]) / 60 for m in ("sequential", "dask")}
    icept = {m: res[(m, 20)] - 20 * slope[m] for m in ("sequential", "dask")}
    return res, slope, icept


def estimate_64(out, per_task_s, startup_s, cores=64) -> list:
    """Per sweep, from the 1-worker run's per-task times (attempt_s): the reference first,
    then the rest spread over the cores (no sooner than the longest task)."""
    rows = []
    for s in STUDY:
        df = pd.read_parquet(os.path.join(out, "w1", s, "results.parquet"))
        ref = df[df["name"] == "reference"]["attempt_s"].sum()
        rest = df[df["name"] != "reference"]["attempt_s"]
        t = startup_s + ref + per_task_s + max(rest.max(), (rest.sum() + per_task_s * len(rest)) / cores)
        rows.append((s, len(df), ref, rest.sum(), rest.max(), t))
    return rows


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--workers", type=int, nargs="*", default=[1, 2, 4], help="worker counts of the study runs; none: the overhead only")
    ap.add_argument("--repeats", type=int, default=1, help="repeats of the overhead sweeps (median)")
    ap.add_argument("--out", default=os.path.join(ROOT, "build/scaling"))
    a = ap.parse_args()
    os.makedirs(a.out, exist_ok=True)
    res, slope, icept = overhead(a.out, a.repeats)
    print("| one-step runs | sequential, s | of which outside the tasks, s | task, ms | local cluster of 1 worker, s "
          "| of which outside the tasks, s | task, ms |\n|---:|---:|---:|---:|---:|---:|---:|")
    for n in (20, 80):
        print(f"| {n} | " + " | ".join(f"{res[(m, n)]:.2f} | {res[(m, n, 'outside')]:.2f} | "
                                       f"{res[(m, n, 'task')] * 1e3:.0f}" for m in ("sequential", "dask")) + " |")
    for m in ("sequential", "dask"):
        per = (res[(m, 80, "outside")] - res[(m, 20, "outside")]) / 60
        print(f"\n{m}: outside the tasks {per * 1e3:.0f} ms per task more, "
              f"{res[(m, 20, 'outside')] - 20 * per:.2f} s per sweep")
    per_task = slope["dask"] - slope["sequential"]
    startup = icept["dask"] - icept["sequential"]
    print(f"\nper task: sequential {slope['sequential'] * 1e3:.0f} ms, Dask {slope['dask'] * 1e3:.0f} ms: "
          f"overhead {per_task * 1e3:.0f} ms per task; cluster start and stop {startup:.1f} s\n")
    if not a.workers:
        return
    walls = {w: study_times(w, a.out) for w in a.workers}
    print("| sweep | " + " | ".join(f"{w} worker{'s' if w > 1 else ''}, s" for w in a.workers) + " |")
    print("|---|" + "---:|" * len(a.workers))
    for s in STUDY:
        print(f"| {s} | " + " | ".join(f"{walls[w][s]:.0f}" for w in a.workers) + " |")
    print("| **study** | " + " | ".join(f"**{sum(walls[w].values()):.0f}**" for w in a.workers) + " |\n")
    if 1 in a.workers:
        print("| sweep | rows | reference, s | other tasks summed, s | longest, s | 64 cores, s |")
        print("|---|---:|---:|---:|---:|---:|")
        total = 0
        for s, n, ref, rest, longest, t in estimate_64(a.out, max(per_task, 0), max(startup, 0)):
            total += t
            print(f"| {s} | {n} | {ref:.1f} | {rest:.1f} | {longest:.1f} | {t:.1f} |")
        print(f"| **study** | | | | | **{total:.0f}** |")


if __name__ == "__main__":
    main()
