"""The sweep's table: one row per configuration (pandas), the Pareto front of each error
measure against the cost, the cheapest configuration meeting each goal, and the files
(results.parquet, results.csv)."""

from __future__ import annotations

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
    import json

    sets = json.loads(row["overrides"]) if isinstance(row.get("overrides"), str) else []
    return " ".join(f"--set {s}" for s in sets) or "the scene as it is"
