#!/usr/bin/env python3
"""Plots the speed-against-accuracy study (docs/speed-accuracy.md): error against cost for
every run of bench_accuracy's CSV, one PNG per scene, the Pareto front marked.

    .venv/bin/python scripts/plot_speed_accuracy.py [build/study/results.csv] [--out docs/images]

Cost (x, log): wall seconds per simulated second on one engine thread (left of 1 is faster
than real time). Error (y, log): the relative L2 error of all displacements over time
against the scene's converged reference (for the heart also the ejection-fraction error).
Runs are coloured by sweep; the Pareto front (no run both cheaper and more accurate) is the
black line; unstable runs are crosses at the top.
"""
import argparse
import csv
import math
import os
from collections import defaultdict

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

SWEEP_STYLE = {
    "base": ("black", "*"),
    "dt": ("tab:blue", "o"),
    "level": ("tab:green", "s"),
    "tolerance": ("tab:orange", "^"),
    "iteration cap": ("tab:red", "v"),
    "warm start": ("tab:purple", "D"),
    "solver": ("tab:brown", "P"),
    "rotation": ("tab:pink", "X"),
    "corotation": ("tab:red", "x"),
    "feature": ("tab:olive", "h"),
    "grid": ("tab:gray", "."),
    "reference-check": ("tab:cyan", "d"),
}


def num(v):
    try:
        x = float(v)
    except (TypeError, ValueError):
        return math.nan
    return x


def front(rows, err_key):
    pts = sorted(((r["cost"], r[err_key]) for r in rows if r["stable"] and r["sweep"] != "reference-check"
                  and math.isfinite(r[err_key]) and r[err_key] > 0))
    out, best = [], math.inf
    for c, e in pts:
        if e < best:
            out.append((c, e))
            best = e
    return out


def plot(scene, rows, err_key, label, path):
    fig, ax = plt.subplots(figsize=(7.5, 5))
    seen = set()
    for r in rows:
        e = r[err_key]
        if not math.isfinite(r["cost"]) or not math.isfinite(e) or e <= 0:
            continue
        color, marker = SWEEP_STYLE.get(r["sweep"], ("k", "o"))
        lab = r["sweep"] if r["sweep"] not in seen else None
        seen.add(r["sweep"])
        ax.scatter([r["cost"]], [e if r["stable"] else max(x[err_key] for x in rows if math.isfinite(x[err_key])) * 1.5],
                   c=color, marker=marker if r["stable"] else "x", s=50 if r["sweep"] == "base" else 28, label=lab,
                   zorder=3)
    f = front(rows, err_key)
    if f:
        ax.plot([c for c, _ in f], [e for _, e in f], "k-", lw=1.2, zorder=2, label="Pareto front")
    ax.axvline(1.0, color="0.6", lw=0.8, ls="--")
    for r in rows:  # name the presets
        if r["sweep"] == "preset" and r["stable"] and math.isfinite(r[err_key]) and r[err_key] > 0:
            ax.annotate(r["feature"].replace("fidelity: ", ""), (r["cost"], r[err_key]), textcoords="offset points",
                        xytext=(4, 6), fontsize=8)
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xlabel("cost: wall s per simulated s (1 engine thread; dashed = real time)")
    ax.set_ylabel(label)
    ax.set_title(f"{scene}: error against cost")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=7, loc="best")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    print(f"wrote {path}")


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("csv", nargs="?", default="build/study/results.csv")
    ap.add_argument("--out", default="docs/images")
    a = ap.parse_args()
    by_scene = defaultdict(list)
    with open(a.csv, newline="") as f:
        for r in csv.DictReader(f):
            by_scene[r["scene"]].append({
                "sweep": r["sweep"],
                "cost": num(r["wall_s_per_sim_s"]),
                "l2": num(r["l2_err_rel"]),
                "ef": abs(num(r["ef_err_pp"])),
                "stable": r["stable"] == "1",
                "feature": r["feature"],
            })
    os.makedirs(a.out, exist_ok=True)
    for scene, rows in by_scene.items():
        plot(scene, rows, "l2", "relative L2 error of displacements over time", os.path.join(a.out, f"speed-accuracy-{scene}.png"))
        if any(math.isfinite(r["ef"]) for r in rows):
            plot(scene, rows, "ef", "|ejection fraction error|, percentage points",
                 os.path.join(a.out, f"speed-accuracy-{scene}-ef.png"))


if __name__ == "__main__":
    main()
