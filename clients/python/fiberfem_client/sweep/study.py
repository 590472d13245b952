"""A sweep from file to table: the reference first (when the sweep has error measures),
then every configuration, each finished row recorded at once; then the table, the Pareto
fronts, the plots and the cheapest configuration per goal."""

from __future__ import annotations

import os
import subprocess
import sys

from .columns import ERROR_COLUMN
from .measures import ARCHIVE_ERRORS, error_measures
from .outdir import OutputDir
from .plots import plot_errors
from .runner import Progress
from .task import read_json as _read_json
from .table import build_table, recommendations, write_table


def _job(sweep, config, binary, od, done_keys, reference, archive, keep):
    return {"binary": binary, "scene": sweep.scene, "overrides": list(config.overrides), "name": config.name,
            "group": config.group, "values": config.values, "run_dir": od.runs, "archive": archive,
            "reference": reference, "errors": sweep.errors, "sample_s": sweep.sample_s,
            "timeout_s": sweep.timeout_s, "keep_archive": keep, "done_keys": done_keys}


class PrepareError(RuntimeError):
    """A `prepare` step of the sweep file failed."""


def prepare(sweep, stream):
    """Runs each `prepare` step whose file does not exist yet, in the sweep file's folder
    (`python` as the program is this interpreter)."""
    here = os.path.dirname(sweep.path)
    for i, (argv, creates) in enumerate(sweep.prepare):
        if os.path.exists(os.path.join(here, creates)):
            continue
        argv = [sys.executable if j == 0 and a == "python" else a for j, a in enumerate(argv)]
        os.makedirs(os.path.dirname(os.path.join(here, creates)), exist_ok=True)
        print(f"fiberfem sweep: prepare[{i}]: {' '.join(argv)}", file=stream, flush=True)
        p = subprocess.run(argv, cwd=here, capture_output=True, text=True)
        if p.returncode != 0 or not os.path.exists(os.path.join(here, creates)):
            raise PrepareError(f"{sweep.path}: prepare[{i}] ({' '.join(argv)}) failed with exit {p.returncode} "
                               f"or did not make {creates}: {(p.stderr or p.stdout).strip()[-600:]}")


class SweepRun:
    def __init__(self, sweep, out_dir, binary, runner, stream):
        self.sweep, self.binary, self.runner, self.stream = sweep, binary, runner, stream
        self.od = OutputDir(out_dir, sweep.name, sweep.path)
        self.done = self.od.done()
        self.rows = {}
        self.ran = self.skipped = 0

    def _record(self, row, config):
        if row.get("status") == "skipped":
            self.skipped += 1
            stored = dict(self.done[row["key"]])
            stored.update({k: row[k] for k in ("name", "group", "values", "overrides") if k in row})
            row = {**stored, **{k: v for k, v in row.items() if k.startswith("set:")}}
        else:
            self.ran += 1
            self.od.append(row)
        self.rows[config.name] = row
        return row

    def _run_all(self, jobs_configs, label):
        progress = Progress(len(jobs_configs), label, self.stream)
        by_name = {c.name: c for _, c in jobs_configs}

        def on_row(row):
            progress.row(self._record(row, by_name[row["name"]]))

        try:
            self.runner.run([j for j, _ in jobs_configs], on_row, progress.tick)
        finally:
            progress.close()

    def _reference(self):
        """Runs (or finds done, with its archive still there) the reference; returns the
        paths the other configurations' errors are measured against, or None."""
        sw = self.sweep
        archive = any(e in ARCHIVE_ERRORS for e in sw.errors)
        usable = {k for k, r in self.done.items()
                  if r.get("run_dir") and (not archive or os.path.exists(os.path.join(r["run_dir"], "run.h5")))}
        job = _job(sw, sw.reference, self.binary, self.od, usable, None, archive, True)
        self._run_all([(job, sw.reference)], "reference")
        row = self.rows[sw.reference.name]
        if row.get("status") != "completed":
            print(f"fiberfem sweep: the reference did not complete ({row.get('status')}: {row.get('reason')}); "
                  "no error measures", file=self.stream)
            return None
        ref = {"archive": os.path.join(row["run_dir"], "run.h5") if archive else None,
               "report": os.path.join(row["run_dir"], "report.json")}
        # The reference against itself: zero by construction, a check of the measures' plumbing.
        own = error_measures(ref["archive"], _read_json(ref["report"]), ref["archive"], _read_json(ref["report"]),
                             sw.sample_s, sw.errors)
        row.update({k: v for k, v in own.items() if k not in row})
        return ref

    def run(self):
        sw = self.sweep
        reference = self._reference() if sw.reference is not None else None
        archive = reference is not None and any(e in ARCHIVE_ERRORS for e in sw.errors)
        done_keys = set(self.done)
        configs = sw.configurations()
        jobs = [(_job(sw, c, self.binary, self.od, done_keys, reference, archive, sw.keep_archives), c)
                for c in configs]
        self._run_all(jobs, sw.name)
        order = ([sw.reference.name] if sw.reference is not None else []) + [c.name for c in configs]
        errors = sw.errors if reference is not None else []
        return build_table([self.rows[n] for n in order], errors, sw.cost)

    def finish(self, df):
        sw = self.sweep
        write_table(df, self.od.path)
        errors = sw.errors if any(ERROR_COLUMN[e] in df for e in sw.errors) else []
        plots = plot_errors(df, errors, sw.cost, sw.goals, self.od.path, sw.name)
        counts = df["status"].value_counts().to_dict()
        lines = [f"sweep {sw.name}: {len(df)} configurations ({', '.join(f'{v} {k}' for k, v in counts.items())}); "
                 f"ran {self.ran}, skipped {self.skipped} done before",
                 f"table: {os.path.join(self.od.path, 'results.parquet')} and results.csv"]
        lines += [f"plot: {p}" for p in plots]
        for e in errors:
            col = ERROR_COLUMN[e]
            if not df[col].notna().any():
                continue
            front = df[df[f"pareto_{col}"]]
            lines.append(f"Pareto front of {col} against {sw.cost}: " + ", ".join(front["name"]))
        lines += recommendations(df, sw.goals, sw.cost) if errors else []
        with open(os.path.join(self.od.path, "summary.txt"), "w", encoding="utf-8") as f:
            f.write("\n".join(lines) + "\n")
        return lines

    def close(self):
        self.od.close()
