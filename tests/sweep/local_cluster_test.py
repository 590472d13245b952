"""A local Dask cluster of 2 worker processes runs the tiny sweep; its table equals the same
configurations run one after another (--sequential) in every field but the timings. The
measures are checked against independent sources: the reports' own probe positions
(double precision, written by the engine) for the final probe error, zero error of the
reference against itself, and a refused configuration as a row naming the bad key."""

import json
import math
import os
import sys

import numpy as np

from sweep_support import TINY, Tally, cleanup, result_columns, run_sweep, scratch, table


def report(row):
    with open(os.path.join(row["run_dir"], "report.json")) as f:
        return json.load(f)


def main():
    t = Tally()
    seq, par = scratch("seq"), scratch("par")
    try:
        a = run_sweep(TINY, seq, "--sequential")
        b = run_sweep(TINY, par, "--workers", "2")
        t.check(a.returncode == 0, f"sequential sweep exit {a.returncode}: {a.stderr[-2000:]}")
        t.check(b.returncode == 0, f"local-cluster sweep exit {b.returncode}: {b.stderr[-2000:]}")
        if a.returncode or b.returncode:
            return t.finish()
        t.check("local Dask cluster, 2 worker processes" in b.stderr, "the local cluster has 2 worker processes")
        da, db = table(seq), table(par)
        t.check(len(da) == 8 and list(da["name"]) == list(db["name"]), f"8 rows in both, same order: {list(db['name'])}")
        workers = set(db["worker"].dropna())
        t.check(len(workers) == 2, f"both workers ran configurations: {workers}")
        cols = result_columns(da)
        t.check(set(cols) <= set(db.columns), "same columns")
        for c in cols:
            same = all(_same(x, y) for x, y in zip(da[c], db[c]))
            t.check(same, f"column {c} differs: {list(da[c])} vs {list(db[c])}")
        by = {r["name"]: r for _, r in db.iterrows()}
        t.check((db["status"] == "completed").sum() == 7, f"7 completed: {list(db['status'])}")
        ref = by["reference"]
        t.check(ref["l2_err"] == 0 and ref["probe_err"] == 0, "the reference against itself: zero error")
        bad = by["refused"]
        t.check(bad["status"] == "refused" and "solver.dt" in bad["reason"], f"refused row names solver.dt: {bad['reason']}")
        # final_err from the archives (float32 positions interpolated in time) against the
        # reports' double-precision probe positions at the end.
        rr = report(ref)
        for name in ("step/0", "level/0", "tolerance/0"):
            r = by[name]
            rep = report(r)
            u = np.subtract(rep["probes"][0]["final_m"], rep["probes"][0]["rest_m"])
            ur = np.subtract(rr["probes"][0]["final_m"], rr["probes"][0]["rest_m"])
            expected = np.linalg.norm(u - ur) / np.linalg.norm(ur)
            t.check(math.isclose(r["final_err"], expected, rel_tol=1e-3, abs_tol=1e-6),
                    f"{name}: final_err {r['final_err']} against the reports' {expected}")
        # Same scene as the reference but the tolerance: a tiny error; the coarse level: large.
        t.check(by["level/1"]["l2_err"] < 1e-3, f"level/1 (the reference's mesh) l2 {by['level/1']['l2_err']}")
        t.check(by["level/0"]["l2_err"] > 10 * by["level/1"]["l2_err"], "the coarse mesh errs more")
        front = list(db[db["pareto_l2_err"]]["name"])
        t.check("reference" in front or len(front) > 0, f"a Pareto front is marked: {front}")
        t.check(os.path.exists(os.path.join(par, "l2_err.png")), "the L2 plot is written")
        t.check(os.path.exists(os.path.join(par, "results.csv")), "the CSV table is written")
        t.check("l2_err <= 0.3:" in b.stdout and "probe_err <= 0.05:" in b.stdout, f"a line per goal: {b.stdout}")
    finally:
        cleanup(seq, par)
    return t.finish()


def _same(x, y) -> bool:
    if isinstance(x, float) and isinstance(y, float) and math.isnan(x) and math.isnan(y):
        return True
    try:
        return bool(x == y) or (x is None and y is None)
    except Exception:
        return False


if __name__ == "__main__":
    sys.exit(main())
