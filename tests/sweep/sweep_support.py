"""What the sweep tests share: the real `fiberfem sweep` command (the C++ handover to the
Python package), a scratch directory, reading a sweep's table back, and a tally printed as
'N passed, N failed'. Usage of every test: test.py FIBERFEM_BIN."""

import json
import os
import shutil
import signal
import subprocess
import sys
import tempfile
import time

import pandas as pd

HERE = os.path.dirname(os.path.abspath(__file__))
TINY = os.path.join(HERE, "tiny.yaml")
BIN = os.path.abspath(sys.argv[1]) if len(sys.argv) > 1 else os.environ.get("FIBERFEM_BIN", "")
# Columns that are times or places, not results (the same configuration run twice differs
# only there), the run directory (under each sweep's own output directory), and the Pareto
# marks (they rank by a cost, which is a time).
NOT_RESULTS = {"wall_s", "engine_s", "steps_per_s", "median_step_s", "wall_s_per_sim_s", "engine_s_per_sim_s",
               "peak_rss_mb", "started_utc", "worker", "attempt_s", "run_dir"}


def result_columns(df) -> list:
    return sorted(c for c in df.columns if c not in NOT_RESULTS and not c.startswith("pareto_"))


class Tally:
    def __init__(self):
        self.passed, self.failed = 0, 0

    def check(self, ok: bool, what: str):
        if ok:
            self.passed += 1
        else:
            self.failed += 1
            print(f"FAILED: {what}", flush=True)

    def finish(self) -> int:
        print(f"{self.passed} passed, {self.failed} failed", flush=True)
        return 1 if self.failed else 0


def scratch(name: str) -> str:
    d = tempfile.mkdtemp(prefix=f"fiberfem-sweep-{name}-")
    return d


def sweep_argv(sweep_file, out, *extra):
    return [BIN, "sweep", sweep_file, "--out", out, *extra]


def run_sweep(sweep_file, out, *extra, timeout=300):
    """Runs `fiberfem sweep` to its end; returns the CompletedProcess."""
    return subprocess.run(sweep_argv(sweep_file, out, *extra), capture_output=True, text=True, timeout=timeout)


def start_sweep(sweep_file, out, *extra):
    """Starts `fiberfem sweep` in its own process group (to kill it whole)."""
    return subprocess.Popen(sweep_argv(sweep_file, out, *extra), stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            text=True, start_new_session=True)


def kill_group(p):
    try:
        os.killpg(p.pid, signal.SIGKILL)
    except ProcessLookupError:
        pass
    p.wait(timeout=30)


def table(out) -> pd.DataFrame:
    return pd.read_parquet(os.path.join(out, "results.parquet"))


def recorded_rows(out) -> list:
    path = os.path.join(out, "rows.jsonl")
    if not os.path.exists(path):
        return []
    with open(path) as f:
        lines = f.read().splitlines()
    # A row killed half-written has no closing brace: not a row.
    return [json.loads(l) for l in lines if l.endswith("}")]


def fiberfem_runs_under(out) -> list:
    """(pid, parent pid) of every live `fiberfem run` process writing under `out`."""
    found = []
    for pid in os.listdir("/proc"):
        if not pid.isdigit():
            continue
        try:
            with open(f"/proc/{pid}/cmdline", "rb") as f:
                argv = f.read().split(b"\0")
            with open(f"/proc/{pid}/stat") as f:
                ppid = int(f.read().rsplit(")", 1)[1].split()[1])
        except OSError:
            continue
        if len(argv) > 2 and argv[1] == b"run" and any(out.encode() in a for a in argv) and b"--report" in argv:
            found.append((int(pid), ppid))
    return found


def wait_for(pred, timeout_s, step=0.05):
    end = time.monotonic() + timeout_s
    while time.monotonic() < end:
        v = pred()
        if v:
            return v
        time.sleep(step)
    return pred()


def cleanup(*dirs):
    for d in dirs:
        shutil.rmtree(d, ignore_errors=True)
