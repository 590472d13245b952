#!/usr/bin/env python3
"""Regenerates the measured table of the circulation study
(configs/sweeps/speed-accuracy/heart-circulation.yaml, docs/speed-accuracy-circulation.md):
docs/speed-accuracy-circulation-results.md (every run: its settings, the LV's last beat,
the errors of its pressure-volume loop against the reference, the cost, the Pareto front)
and the plot docs/images/speed-accuracy-circulation.png (pv_loop_err against engine time).

    cp build/release/service/fiberfem /tmp/fiberfem-study
    /tmp/fiberfem-study sweep configs/sweeps/speed-accuracy/heart-circulation.yaml \\
        --out build/study/heart-circulation --binary /tmp/fiberfem-study --workers 2
    .venv/bin/python scripts/speed_accuracy_circulation_docs.py [--study build/study/heart-circulation] [--docs docs]"""

import argparse
import json
import math
import os
import shutil

import pandas as pd

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
ML, MMHG = 1e-6, 133.322387415


def settings_text(row) -> str:
    """The group's own --set values (the sweep's common ones left out), short."""
    parts = []
    for o in json.loads(row["overrides"]):
        key, value = o.split("=", 1)
        if key in ("solver.until", "solver.threads") or (key == "solver.dt" and value == "0.016666666666666666"):
            continue
        if key == "mesh.file":
            value = os.path.basename(value).replace("biventricle-0.00", "").replace(".msh", " mm")
        elif key == "solver.dt":
            value = f"1/{round(1 / float(value))} s"
        parts.append(f"{key.split('.')[-1]} {value}")
    return ", ".join(parts) or "shipped (4 mm, 1/60 s, PCG 1e-6)"


def last_beat(run_dir):
    try:
        with open(os.path.join(run_dir, "report.json")) as f:
            beats = [b for b in json.load(f)["circulation"]["beats"] if b["complete"]]
        return beats[-1]["lv"]
    except (OSError, ValueError, KeyError, IndexError, TypeError):
        return None


def pct(v) -> str:
    return f"{100 * v:.3g}%" if isinstance(v, float) and math.isfinite(v) else ""


def rows(df) -> list:
    out = ["| run | settings | status | EDV mL | ESV mL | SV mL | EF | peak mmHg | EDV err | ESV err | SV err | peak err "
           "| pv_loop_err | engine s / sim s | front |",
           "|---|---|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---|"]
    for _, r in df.sort_values(["group", "name"]).iterrows():
        lv = last_beat(r.get("run_dir")) if r["status"] == "completed" else None
        beat = (f"{lv['end_diastolic_volume_m3'] / ML:.3f} | {lv['end_systolic_volume_m3'] / ML:.3f} | "
                f"{lv['stroke_volume_m3'] / ML:.3f} | {lv['ejection_fraction']:.4f} | {lv['peak_pressure_pa'] / MMHG:.2f}"
                if lv else " | | | | ")
        status = r["status"] if r["status"] == "completed" else f"{r['status']}: {str(r.get('reason', ''))[:100]}"
        out.append(f"| {r['name']} | {settings_text(r)} | {status.replace('|', '/')} | {beat} | {pct(r.get('edv_err'))} | "
                   f"{pct(r.get('esv_err'))} | {pct(r.get('stroke_volume_err'))} | {pct(r.get('peak_lv_pressure_err'))} | "
                   f"{pct(r.get('pv_loop_err'))} | {r['engine_s_per_sim_s']:.3g} | {'P' if r.get('pareto_pv_loop_err') else ''} |")
    return out


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--study", default=os.path.join(ROOT, "build/study/heart-circulation"))
    ap.add_argument("--docs", default=os.path.join(ROOT, "docs"))
    a = ap.parse_args()
    df = pd.read_parquet(os.path.join(a.study, "results.parquet"))
    out = ["# Speed against accuracy of the closed-loop circulation: the measured rows", "",
           "Made by `configs/sweeps/speed-accuracy/heart-circulation.yaml` and",
           "`scripts/speed_accuracy_circulation_docs.py` ([speed-accuracy-circulation.md](speed-accuracy-circulation.md)",
           "says how and what they show). One row per run, one engine thread each: the LV's last beat",
           "(the fourth) in the scene's units, its errors against the reference's (distance over the",
           "reference's value), `pv_loop_err` the largest of the four; `P`: on the Pareto front of",
           "`pv_loop_err` against engine seconds per simulated second. Errors are deterministic; the",
           "times are single runs on a shared machine.", ""]
    out += rows(df)
    with open(os.path.join(a.study, "summary.txt")) as f:
        out += ["", "Cheapest run per goal of the sweep file:", ""]
        out += [f"- {line}" for line in f.read().splitlines() if "<=" in line] + [""]
    with open(os.path.join(a.docs, "speed-accuracy-circulation-results.md"), "w", encoding="utf-8") as f:
        f.write("\n".join(out) + "\n")
    shutil.copy(os.path.join(a.study, "pv_loop_err.png"), os.path.join(a.docs, "images", "speed-accuracy-circulation.png"))
    print(f"wrote {os.path.join(a.docs, 'speed-accuracy-circulation-results.md')}")


if __name__ == "__main__":
    main()
