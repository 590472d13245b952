#!/usr/bin/env python3
"""Regenerates the speed-against-accuracy pages from the study's sweeps
(configs/sweeps/speed-accuracy/, docs/speed-accuracy.md): the results page
docs/speed-accuracy-results.md (every row of every scene, the Pareto fronts, the cheapest
configuration per goal, the fidelity presets' rows) and the plots docs/images/
speed-accuracy-SCENE.png (L2 error against cost) and speed-accuracy-heart-ef.png.

    for s in cantilever cantilever-gravity land-beam land-ventricle heart; do
      build/release/service/fiberfem sweep configs/sweeps/speed-accuracy/$s.yaml --out build/study/$s
    done
    .venv/bin/python scripts/speed_accuracy_docs.py [--study build/study] [--docs docs]"""

import argparse
import os
import shutil

import pandas as pd

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
SCENES = ["cantilever", "cantilever-gravity", "land-beam", "land-ventricle", "heart"]


def preset_rows(scene, df) -> list:
    rows = []
    p = df[df["group"] == "preset"]
    bal = p[p["set:fidelity"] == '"balanced"']
    for _, r in p.iterrows():
        name = r["set:fidelity"].strip('"')
        cost = r["engine_s_per_sim_s"] / bal["engine_s_per_sim_s"].iloc[0] if len(bal) else float("nan")
        l2 = r["l2_err"] / bal["l2_err"].iloc[0] if len(bal) else float("nan")
        ef = f"{r['ef_err_pp']:.3g}" if pd.notna(r.get("ef_err_pp")) and scene == "heart" else ""
        rows.append(f"| {scene} | `{name}` | {int(r['elements'])} | {r['l2_err']:.3g} | {r['probe_err']:.3g} | {ef} | "
                    f"{r['engine_s_per_sim_s']:.3g} | {r['steps_per_s']:.4g} | {cost:.2g} | {l2:.2g} |")
    return rows


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--study", default=os.path.join(ROOT, "build/study"))
    ap.add_argument("--docs", default=os.path.join(ROOT, "docs"))
    a = ap.parse_args()
    out = ["# Speed against accuracy: the measured rows", "",
           "Made by the sweeps of `configs/sweeps/speed-accuracy/` and `scripts/speed_accuracy_docs.py`",
           "(docs/speed-accuracy.md says how, and what the columns mean). One row per configuration; `P`:",
           "on the Pareto front of L2 error against engine seconds per simulated second (one engine",
           "thread). Errors are deterministic; costs are single runs on a shared machine.", ""]
    presets = []
    for scene in SCENES:
        d = os.path.join(a.study, scene)
        df = pd.read_parquet(os.path.join(d, "results.parquet"))
        with open(os.path.join(d, "results.md")) as f:
            table = f.read()
        with open(os.path.join(d, "summary.txt")) as f:
            summary = [l for l in f.read().splitlines() if "<=" in l or l.startswith("Pareto front of l2")]
        out += [f"## {scene}", "", f"`configs/sweeps/speed-accuracy/{scene}.yaml`, {len(df)} runs.", "", table]
        out += ["Cheapest configuration per goal of the sweep file, and the L2 front:", ""]
        out += [f"- {l}" for l in summary] + [""]
        presets += preset_rows(scene, df)
        shutil.copy(os.path.join(d, "l2_err.png"), os.path.join(a.docs, "images", f"speed-accuracy-{scene}.png"))
        if scene == "heart" and os.path.exists(os.path.join(d, "ef_err_abs_pp.png")):
            shutil.copy(os.path.join(d, "ef_err_abs_pp.png"), os.path.join(a.docs, "images", "speed-accuracy-heart-ef.png"))
    out += ["## The fidelity presets", "",
            "| scene | preset | tets | L2 err | probe err | EF err pp | engine s / sim s | steps/s | cost / balanced's | L2 / balanced's |",
            "|---|---|---:|---:|---:|---:|---:|---:|---:|---:|", *presets, ""]
    with open(os.path.join(a.docs, "speed-accuracy-results.md"), "w") as f:
        f.write("\n".join(out))


if __name__ == "__main__":
    main()
