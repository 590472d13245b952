"""A worker killed with SIGKILL in the middle of a configuration: the sweep still completes
with every row. The test finds a running `fiberfem run` of the sweep, kills the Dask
worker process that started it (its parent), and checks that Dask ran that configuration
again on a worker (the row is completed, with another worker than the killed one) and
that no run of the killed worker is left behind."""

import os
import signal
import sys

from sweep_support import (HERE, Tally, cleanup, fiberfem_runs_under, kill_group, recorded_rows, scratch, start_sweep,
                           table, wait_for)

SLOW = os.path.join(HERE, "slow.yaml")


def main():
    t = Tally()
    out = scratch("kill")
    p = start_sweep(SLOW, out, "--workers", "2")
    try:
        runs = wait_for(lambda: fiberfem_runs_under(out), 120)
        t.check(bool(runs), "a fiberfem run of the sweep appeared")
        if not runs:
            return t.finish()
        run_pid, worker_pid = runs[0]
        with open(f"/proc/{run_pid}/cmdline", "rb") as f:
            argv = f.read().split(b"\0")
        done_before = {r["key"] for r in recorded_rows(out)}  # the killed worker may have finished some already
        os.kill(worker_pid, signal.SIGKILL)
        gone = wait_for(lambda: not os.path.exists(f"/proc/{run_pid}") or _zombie(run_pid), 10)
        t.check(gone, "the killed worker's run died with it")
        stdout, stderr = p.communicate(timeout=300)
        t.check(p.returncode == 0, f"sweep exit {p.returncode}: {stderr[-3000:]}")
        df = table(out)
        t.check(len(df) == 7, f"every configuration has a row: {list(df['name'])}")
        t.check((df["status"] == "completed").all(), f"every row completed: {list(df['status'])} {list(df['reason'])}")
        report = argv[argv.index(b"--report") + 1].decode()
        key = os.path.basename(os.path.dirname(report))
        again = df[df["key"] == key]
        t.check(len(again) == 1 and again.iloc[0]["status"] == "completed",
                f"the killed configuration ({key}) was run again to completion")
        later = df[~df["key"].isin(done_before)]
        pids = {w.rsplit(":", 1)[1] for w in later["worker"]}
        t.check(str(worker_pid) not in pids, f"no row finished after the kill is from the killed worker {worker_pid}: {pids}")
    finally:
        if p.poll() is None:
            kill_group(p)
        cleanup(out)
    return t.finish()


def _zombie(pid) -> bool:
    try:
        with open(f"/proc/{pid}/stat") as f:
            return f.read().rsplit(")", 1)[1].split()[0] == "Z"
    except OSError:
        return True


if __name__ == "__main__":
    sys.exit(main())
