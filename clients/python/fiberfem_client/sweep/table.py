"""The sweep's table: one row per configuration (pandas), the Pareto front of each error
measure against the cost, the cheapest configuration meeting each goal, and the files
(results.parquet, results.csv)."""

from __future__ import annotations

import json
import math
import os

import numpy as np
import pandas as pd

from .columns import ERROR_COLUMN

FIRST_COLUMNS = ["name", "group", "status", "reason", "key", "scene_sha256", "binary_sha256"]


def build_table(rows: list, errors: list, cost: str) -> pd.DataFrame:
    df = pd.DataFrame(rows)
    for c in FIRST_COLUMNS:
        if c not in df:
            df[c] = ""
    df = df[FIRST_COLUMNS + [c for c in df.columns if c not in FIRST_COLUMNS]]
    for e in errors:
        col = ERROR_COLUMN[e]
        df[f"pareto_{col}"] = pareto_front(df, col, cost) if col in df and cost in df else False
    return df


def pareto_front(df: pd.DataFrame, error: str, cost: str) -> np.ndarray:
    """True for completed rows no other completed row beats in both cost and error (one
    of them strictly)."""
    ok = (df["status"] == "completed") & np.isfinite(df[error].astype(float)) & np.isfinite(df[cost].astype(float))
    mark = np.zeros(len(df), dtype=bool)
    idx = df.index[ok]
    order = sorted(idx, key=lambda i: (df.at[i, cost], df.at[i, error]))
    best = math.inf
    for i in order:
        if df.at[i, error] < best:
            mark[df.index.get_loc(i)] = True
            best = df.at[i, error]
    return mark


def cheapest(df: pd.DataFrame, error_column: str, limit: float, cost: str):
    """The completed row of least cost whose error is at most `limit`, or None."""
    if error_column not in df or cost not in df:
        return None
    ok = df[(df["status"] == "completed") & (df[error_column].astype(float) <= limit)]
    ok = ok[np.isfinite(ok[cost].astype(float))]
    return None if ok.empty else ok.loc[ok[cost].astype(float).idxmin()]


def write_table(df: pd.DataFrame, out_dir: str):
    df.to_parquet(os.path.join(out_dir, "results.parquet"), index=False)
    df.to_csv(os.path.join(out_dir, "results.csv"), index=False)
    with open(os.path.join(out_dir, "results.md"), "w", encoding="utf-8") as f:
        f.write(markdown(df))


# The results page's columns: (table column, heading, significant digits or None for text).
MARKDOWN_COLUMNS = [("elements", "tets", None), ("l2_err", "L2 err", 3), ("probe_err", "probe err", 3),
                    ("probe_err_m", "probe err mm", 3), ("final_err", "final err", 3),
                    ("volume_err", "volume err", 3), ("ef_err_pp", "EF err pp", 3), ("phase_err_ms", "phase ms", 3),
                    ("settled_err", "settled err", 3), ("settled_err_m", "settled err mm", 3),
                    ("engine_s_per_sim_s", "engine s / sim s", 3), ("wall_s", "wall s", 3), ("wall_s_per_sim_s", "wall s / sim s", 3),
                    ("steps_per_s", "steps/s", 4), ("recovered_steps", "recovered", None),
                    ("peak_rss_mb", "peak MB", 3)]


def markdown(df: pd.DataFrame) -> str:
    """The table as Markdown: name, group, the swept settings, status, the measures present,
    P for a row on the L2 front (else the first front marked)."""
    sets = [c for c in df.columns if c.startswith("set:")]
    cols = [c for c in MARKDOWN_COLUMNS if c[0] in df and df[c[0]].notna().any()]
    fronts = [c for c in df.columns if c.startswith("pareto_") and df[c].any()]
    front = "pareto_l2_err" if "pareto_l2_err" in fronts else (fronts[0] if fronts else None)
    head = ["configuration", "group", *[c[4:] for c in sets], "status", *[h for _, h, _ in cols], "front"]
    lines = ["| " + " | ".join(head) + " |", "|" + "---|" * 2 + "---|" * len(sets) + "---|" + "---:|" * len(cols) + "---|"]
    for _, r in df.iterrows():
        cells = [str(r["name"]), str(r["group"]), *[_text(r.get(c)) for c in sets],
                 str(r["status"]) + (f": {r['reason']}" if r["status"] not in ("completed",) and r.get("reason") else "")]
        for c, _, digits in cols:
            v = r.get(c)
            if c in ("probe_err_m", "settled_err_m") and _finite(v):
                v = v * 1e3
            cells.append(_number(v, digits))
        cells.append("P" if front and bool(r.get(front)) else "")
        lines.append("| " + " | ".join(x.replace("|", "/") for x in cells) + " |")
    return "\n".join(lines) + "\n"


def _finite(v) -> bool:
    try:
        return v is not None and math.isfinite(float(v))
    except (TypeError, ValueError):
        return False


def _number(v, digits) -> str:
    if not _finite(v):
        return ""
    if digits is None:
        return str(int(v)) if float(v).is_integer() else str(v)
    return f"{float(v):.{digits}g}"


def _text(v) -> str:
    if v is None or (isinstance(v, float) and math.isnan(v)):
        return ""
    return str(v).replace('"', "")


def recommendations(df: pd.DataFrame, goals: list, cost: str) -> list:
    """One line per goal: the cheapest configuration meeting it, its settings, error and
    cost, or that none does."""
    lines = []
    for error, limit in goals:
        col = ERROR_COLUMN[error]
        row = cheapest(df, col, limit, cost)
        if row is None:
            lines.append(f"{col} <= {limit:g}: no configuration meets it")
            continue
        lines.append(f"{col} <= {limit:g}: {row['name']} ({describe(row)}): {col} {row[col]:.4g}, "
                     f"{cost} {row[cost]:.4g}, {row.get('steps_per_s', math.nan):.4g} steps/s")
    return lines


def describe(row) -> str:
    sets = json.loads(row["overrides"]) if isinstance(row.get("overrides"), str) else []
    return " ".join(f"--set {s}" for s in sets) or "the scene as it is"
