"""Error against cost plots (PNG, one per error measure): every completed configuration,
coloured by group, the Pareto front as a black line, each goal as a dashed line."""

from __future__ import annotations

import os

import numpy as np

from .columns import ERROR_COLUMN

MARKERS = ("o", "s", "^", "D", "v", "P", "X")
COST_LABEL = {"engine_s_per_sim_s": "engine s per simulated s", "wall_s_per_sim_s": "wall s per simulated s",
              "wall_s": "wall time of the run, s", "peak_rss_mb": "peak memory, MB"}


def plot_errors(df, errors: list, cost: str, goals: list, out_dir: str, title: str) -> list:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    written = []
    done = df[df["status"] == "completed"]
    for e in errors:
        col = ERROR_COLUMN[e]
        if col not in done or cost not in done:
            continue
        d = done[np.isfinite(done[col].astype(float)) & (done[col].astype(float) > 0)]
        if d.empty:
            continue
        fig, ax = plt.subplots(figsize=(9, 4.8), dpi=110)
        colours = plt.get_cmap("tab20").colors
        for i, (g, part) in enumerate(d.groupby("group", sort=False)):
            ax.scatter(part[cost], part[col], s=24, label=g, color=colours[i % len(colours)],
                       marker=MARKERS[(i // len(colours) + i) % len(MARKERS)])
        front = d[d[f"pareto_{col}"]].sort_values(cost)
        ax.step(front[cost], front[col], where="post", color="black", lw=1.2, label="Pareto front")
        ax.set_xscale("log"), ax.set_yscale("log")
        for ge, limit in goals:
            if ge == e:
                ax.axhline(limit, color="gray", ls="--", lw=1, label=f"goal {limit:g}")
        if cost.endswith("per_sim_s"):
            ax.axvline(1.0, color="tab:red", ls=":", lw=1, label="real time")
        ax.set_xlabel(COST_LABEL.get(cost, cost)), ax.set_ylabel(col)
        ax.set_title(f"{title}: {col} against cost")
        ax.legend(fontsize=7, loc="upper left", bbox_to_anchor=(1.01, 1.0), borderaxespad=0)
        ax.grid(True, which="both", alpha=0.25)
        fig.tight_layout()
        path = os.path.join(out_dir, f"{col}.png")
        fig.savefig(path)
        plt.close(fig)
        written.append(path)
    return written
