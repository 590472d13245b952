#!/usr/bin/env python3
"""Regenerates the measured rows of the study across model tiers
(configs/sweeps/tiers/, docs/speed-accuracy-tiers.md): docs/speed-accuracy-tiers-results.md
(every run: tier, element order, mesh, bulk modulus, the benchmark probes, the error
against the reference and the cost) and the plots docs/images/speed-accuracy-tiers-SCENE.png
(settled error against wall time, the Pareto front drawn).

    for s in land-beam land-ventricle land-ventricle-p3; do
      build/release/service/fiberfem sweep configs/sweeps/tiers/$s.yaml --out build/study/tiers-$s
    done
    .venv/bin/python scripts/speed_accuracy_tiers_docs.py [--study build/study] [--docs docs]

A scene whose sweep is not in --study keeps its section (and plot) of the existing results
page, so one sweep can be re-run alone."""

import argparse
import json
import math
import os
import shutil

import pandas as pd
import yaml

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
# Sweep, what its probes are, and the published converged values of the probes' deformed z, mm.
SCENES = {"land-beam": ("problem 1, swept from 20 x 2 x 2 cells", [4.17]),
          "land-ventricle": ("problem 2, lv_ellipsoid 24 / 10 / 2 with rings graded towards the apex (shipped)",
                             [-26.6, -28.3]),
          "land-ventricle-p3": ("problem 3, lv_ellipsoid 24 / 10 / 6 with rings graded towards the apex (shipped), "
                                "14 quadrature points", [-12.35, -15.45])}
TIER = {"quadratic-mixed": ("accurate", 2, "mixed"), "quadratic-penalty": ("accurate", 2, "penalty"),
        "bulk-modulus": ("accurate", 2, "penalty"), "preset": ("accurate", 2, "mixed"),
        "preset-real-time": ("real-time", 1, "linearised"),
        "linear-penalty": ("accurate", 1, "penalty"), "real-time": ("real-time", 1, "linearised"),
        "reference": ("accurate", 2, "mixed"), "quadrature-4": ("accurate", 2, "mixed")}


def mesh_text(values: dict) -> str:
    if "fidelity" in values:
        return f"`fidelity: {values['fidelity']}`"
    for key in ("mesh.cells", "mesh.resolution"):
        if key in values:
            v = values[key]
            return " x ".join(map(str, v)) if isinstance(v, list) else " / ".join(str(x) for x in v.values())
    return "shipped"


def probes_z_mm(run_dir) -> list:
    try:
        with open(os.path.join(run_dir, "report.json")) as f:
            return [1e3 * p["final_m"][2] for p in json.load(f).get("probes", [])]
    except (OSError, ValueError, TypeError, KeyError):
        return []


def settings(row) -> dict:
    """The run's --set values (the sweep's and its group's), parsed as the scene reads them."""
    return {k: yaml.safe_load(v) for k, v in (o.split("=", 1) for o in json.loads(row["overrides"]))}


def rows(df) -> list:
    out = ["| run | tier | order | volume | mesh | tets | bulk modulus, Pa | status | probe z, mm | settled err | wall s | front |",
           "|---|---|---|---|---|---:|---:|---|---|---:|---:|---|"]
    for _, r in df.iterrows():
        tier, order, volume = TIER.get(r["group"], ("?", "?", "?"))
        values = settings(r)
        bulk = values.get("regions[0].material.bulk_modulus", "")
        z = " / ".join(f"{v:.3f}" for v in probes_z_mm(r.get("run_dir"))) if r["status"] == "completed" else ""
        err = f"{100 * r['settled_err']:.3g}%" if r["status"] == "completed" and math.isfinite(r["settled_err"]) else ""
        status = r["status"] if r["status"] == "completed" else f"{r['status']}: {str(r.get('reason', ''))[:120]}"
        out.append(f"| {r['name']} | {tier} | {order} | {volume} | {mesh_text(values)} | {r['elements']:.0f} | {bulk if bulk == '' else f'{bulk:.0e}'} | "
                   f"{status.replace('|', '/')} | {z} | {err} | {r['wall_s']:.3g} | {'P' if r.get('pareto_settled_err') else ''} |")
    return out


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--study", default=os.path.join(ROOT, "build/study"))
    ap.add_argument("--docs", default=os.path.join(ROOT, "docs"))
    a = ap.parse_args()
    out = ["# Speed against accuracy across model tiers: the measured rows", "",
           "Made by the sweeps of `configs/sweeps/tiers/` and `scripts/speed_accuracy_tiers_docs.py`",
           "([speed-accuracy-tiers.md](speed-accuracy-tiers.md) says how and what they show). One row",
           "per run, one engine thread each; `settled err`: the distance of the first probe's final",
           "displacement from the reference's, over the reference's; `P`: on the Pareto front of that",
           "error against wall time. Errors are deterministic; wall times are single runs on a shared",
           "machine.", ""]
    results = os.path.join(a.docs, "speed-accuracy-tiers-results.md")
    kept = earlier_sections(results)
    for scene, (what, published) in SCENES.items():
        d = os.path.join(a.study, f"tiers-{scene}")
        if not os.path.exists(os.path.join(d, "results.parquet")):
            # Not swept this time: its section and plot stay those of the run that made them.
            if scene not in kept:
                raise SystemExit(f"speed_accuracy_tiers_docs.py: no {d}/results.parquet and no earlier section for {scene}")
            print(f"kept the earlier rows of {scene} (no {d})")
            out += kept[scene]
            continue
        df = pd.read_parquet(os.path.join(d, "results.parquet"))
        out += [f"## {scene}: Land et al. 2015 {what}", "",
                f"`configs/sweeps/tiers/{scene}.yaml`, {len(df)} runs; published probe z: "
                + " / ".join(f"{p} mm" for p in published) + ".", ""]
        out += rows(df)
        with open(os.path.join(d, "summary.txt")) as f:
            out += ["", "Cheapest run per goal of the sweep file:", ""]
            out += [f"- {l}" for l in f.read().splitlines() if "<=" in l] + [""]
        shutil.copy(os.path.join(d, "settled_err.png"), os.path.join(a.docs, "images", f"speed-accuracy-tiers-{scene}.png"))
    with open(results, "w", encoding="utf-8") as f:
        f.write("\n".join(out) + "\n")
    print(f"wrote {results}")


def earlier_sections(path) -> dict:
    """The lines of each scene's section ("## SCENE: ...") of an existing results page."""
    sections, scene = {}, None
    try:
        with open(path, encoding="utf-8") as f:
            lines = f.read().splitlines()
    except OSError:
        return sections
    for line in lines:
        if line.startswith("## "):
            scene = line[3:].split(":", 1)[0]
            sections[scene] = []
        if scene is not None:
            sections[scene].append(line)
    return sections


if __name__ == "__main__":
    main()
