"""The closed-loop circulation's error measures in a sweep (`errors: [pv_loop,
stroke_volume, peak_lv_pressure]`) on a small coupled ventricle: the real `fiberfem sweep`
and `fiberfem run` processes. Checked against the reports themselves: every error column
recomputed here from the run's and the reference's `circulation.beats` (last complete beat),
zero for the reference against itself, no archive written (the measures need none), and a
smaller step nearer the reference than a larger one (backward Euler converges)."""

import json
import math
import os
import sys

from sweep_support import HERE, Tally, cleanup, run_sweep, scratch, table

SWEEP = os.path.join(HERE, "circulation.yaml")


def last_beat_lv(row):
    with open(os.path.join(row["run_dir"], "report.json")) as f:
        beats = [b for b in json.load(f)["circulation"]["beats"] if b["complete"]]
    return beats[-1]["lv"]


def main():
    t = Tally()
    out = scratch("circulation")
    try:
        r = run_sweep(SWEEP, out, "--sequential")
        t.check(r.returncode == 0, f"sweep exit {r.returncode}: {r.stderr[-2000:]}")
        if r.returncode:
            return t.finish()
        df = table(out)
        by = {row["name"]: row for _, row in df.iterrows()}
        t.check(len(df) == 4 and (df["status"] == "completed").all(), f"4 completed rows: {list(df['status'])}")
        ref = last_beat_lv(by["reference"])
        for name, row in by.items():
            lv = last_beat_lv(row)
            rel = {k: abs(lv[k] - ref[k]) / abs(ref[k]) for k in
                   ("end_diastolic_volume_m3", "end_systolic_volume_m3", "stroke_volume_m3", "peak_pressure_pa")}
            expect = {"edv_err": rel["end_diastolic_volume_m3"], "esv_err": rel["end_systolic_volume_m3"],
                      "stroke_volume_err": rel["stroke_volume_m3"], "peak_lv_pressure_err": rel["peak_pressure_pa"],
                      "pv_loop_err": max(rel.values()),
                      "lv_ef_err_pp": 100 * (lv["ejection_fraction"] - ref["ejection_fraction"])}
            for col, value in expect.items():
                t.check(math.isclose(row[col], value, rel_tol=1e-12, abs_tol=1e-15),
                        f"{name}: {col} {row[col]} against the reports' {value}")
            t.check(not os.path.exists(os.path.join(row["run_dir"], "run.h5")), f"{name}: no archive written")
        t.check(by["reference"]["pv_loop_err"] == 0, "the reference against itself: zero error")
        t.check(by["dt/1"]["pv_loop_err"] < by["dt/0"]["pv_loop_err"],
                f"a smaller step is nearer: {by['dt/0']['pv_loop_err']} -> {by['dt/1']['pv_loop_err']}")
        level = next(row for name, row in by.items() if name.startswith("level"))
        t.check(by["dt/0"]["stroke_volume_err"] > 0 and level["pv_loop_err"] > 0, "coarser runs differ")
        print({name: round(row["pv_loop_err"], 5) for name, row in by.items()})
    finally:
        cleanup(out)
    return t.finish()


if __name__ == "__main__":
    sys.exit(main())
