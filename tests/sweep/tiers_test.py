"""A sweep across model tiers with errors from the reports alone (`errors: [settled]`,
`cost: wall_s`): the accurate tier at both element orders (static Newton) and the real-time
tier settling in time, on a small neo-Hookean beam. Checked against independent sources:
the settled error recomputed from the reports' double-precision probe positions, zero for
the reference against itself, no archive written (no error measure needs one), and the
real-time tier (corotated linear tetrahedra, the law's small-strain limit, settled in
time) against the accurate tier's static Newton on the same linear tetrahedra: two
independent solvers of one small-strain problem."""

import json
import math
import os
import sys

import numpy as np

from sweep_support import HERE, Tally, cleanup, run_sweep, scratch, table

TIERS = os.path.join(HERE, "tiers.yaml")


def settled_displacement(row):
    with open(os.path.join(row["run_dir"], "report.json")) as f:
        p = json.load(f)["probes"][0]
    return np.subtract(p["final_m"], p["rest_m"])


def main():
    t = Tally()
    out = scratch("tiers")
    try:
        r = run_sweep(TIERS, out, "--sequential")
        t.check(r.returncode == 0, f"sweep exit {r.returncode}: {r.stderr[-2000:]}")
        if r.returncode:
            return t.finish()
        df = table(out)
        by = {row["name"]: row for _, row in df.iterrows()}
        t.check(len(df) == 6 and (df["status"] == "completed").all(), f"6 completed rows: {list(df['status'])}")
        t.check(by["reference"]["settled_err"] == 0, "the reference against itself: zero error")
        u_ref = settled_displacement(by["reference"])
        for name, row in by.items():
            expected = np.linalg.norm(settled_displacement(row) - u_ref) / np.linalg.norm(u_ref)
            t.check(math.isclose(row["settled_err"], expected, rel_tol=1e-9, abs_tol=1e-15),
                    f"{name}: settled_err {row['settled_err']} against the reports' {expected}")
            t.check(not os.path.exists(os.path.join(row["run_dir"], "run.h5")), f"{name}: no archive written")
        # Refinement helps each accurate order; quadratic beats linear on the same cells.
        t.check(by["quadratic/1"]["settled_err"] < by["quadratic/0"]["settled_err"],
                f"quadratic refines: {by['quadratic/0']['settled_err']} -> {by['quadratic/1']['settled_err']}")
        t.check(by["linear/1"]["settled_err"] < by["linear/0"]["settled_err"],
                f"linear refines: {by['linear/0']['settled_err']} -> {by['linear/1']['settled_err']}")
        t.check(by["quadratic/1"]["settled_err"] < by["linear/0"]["settled_err"], "order 2 beats order 1 on 10 x 2 x 2")
        # The two tiers on the same linear tetrahedra (20 x 4 x 4): the same small-strain answer.
        rt, lin = settled_displacement(by["real-time"]), settled_displacement(by["linear/1"])
        t.check(np.linalg.norm(rt - lin) < 0.02 * np.linalg.norm(lin),
                f"real-time tier settled {rt} against the accurate tier's order 1 {lin}")
        t.check(df["wall_s"].notna().all() and (df["wall_s"] > 0).all(), "every row has its wall time")
        t.check("pareto_settled_err" in df and df["pareto_settled_err"].any(), "a Pareto front of settled_err against wall_s")
    finally:
        cleanup(out)
    return t.finish()


if __name__ == "__main__":
    sys.exit(main())
