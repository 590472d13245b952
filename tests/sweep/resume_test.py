"""An interrupted sweep resumes without re-running its finished rows; two sweeps never write
into one output directory (another sweep's directory is refused, and so is a directory a
running sweep holds).

The sweep (one worker) is killed whole (SIGKILL to its process group: no clean-up at all)
after its first rows are recorded; the second call must record only the others, keyed by
scene hash and binary version, and end with every configuration in its table."""

import os
import signal
import sys

from sweep_support import (HERE, TINY, Tally, cleanup, kill_group, recorded_rows, run_sweep, scratch, start_sweep,
                           table, wait_for)

SLOW = os.path.join(HERE, "slow.yaml")


def main():
    t = Tally()
    out, other = scratch("resume"), scratch("other")
    try:
        p = start_sweep(SLOW, out, "--workers", "1")
        t.check(bool(wait_for(lambda: len(recorded_rows(out)) >= 2, 180)), "two rows recorded before the kill")
        # Stopped (SIGSTOP), the sweep still holds its directory but finishes no more rows:
        # on a busy machine the second sweep below takes longer to start than the rest of
        # the first one takes to run.
        os.killpg(p.pid, signal.SIGSTOP)
        busy = run_sweep(SLOW, out, "--workers", "1")
        t.check(busy.returncode == 3 and "in use by another sweep" in busy.stderr,
                f"a second sweep into a directory in use is refused: {busy.returncode} {busy.stderr[-500:]}")
        kill_group(p)
        before = recorded_rows(out)
        t.check(2 <= len(before) < 7, f"the sweep was interrupted part way ({len(before)} of 7 rows)")
        again = run_sweep(SLOW, out, "--workers", "1")
        t.check(again.returncode == 0, f"resumed sweep exit {again.returncode}: {again.stderr[-2000:]}")
        after = recorded_rows(out)
        first_keys = [r["key"] for r in before]
        new_keys = [r["key"] for r in after[len(before):]]
        t.check(not set(first_keys) & set(new_keys), f"no finished row ran again: {set(first_keys) & set(new_keys)}")
        t.check(len(before) + len(new_keys) == 7, f"the rest ran once each: {len(before)} + {len(new_keys)}")
        t.check(f"skipped {len(before)} done before" in again.stdout, f"the summary says so: {again.stdout}")
        df = table(out)
        t.check(len(df) == 7 and (df["status"] == "completed").all(), f"every row in the table: {list(df['status'])}")
        t.check(set(df["key"]) == set(first_keys) | set(new_keys), "the table holds the rows of both calls")
        # A third call runs nothing.
        third = run_sweep(SLOW, out, "--workers", "1")
        t.check(third.returncode == 0 and "ran 0, skipped 7" in third.stdout, f"nothing left to run: {third.stdout}")
        t.check(len(recorded_rows(out)) == 7, "and records nothing")
        # Another sweep into this directory is refused, and leaves it as it was.
        mtime = os.path.getmtime(os.path.join(out, "results.parquet"))
        refused = run_sweep(TINY, out, "--workers", "1")
        t.check(refused.returncode == 3 and "holds the results of sweep 'slow'" in refused.stderr,
                f"another sweep is refused: {refused.returncode} {refused.stderr[-500:]}")
        t.check(os.path.getmtime(os.path.join(out, "results.parquet")) == mtime and len(recorded_rows(out)) == 7,
                "the refused sweep wrote nothing")
        # A directory with other files is not taken either.
        with open(os.path.join(other, "notes.txt"), "w") as f:
            f.write("mine\n")
        t.check(run_sweep(TINY, other, "--sequential").returncode == 3, "a non-empty directory is refused")
    finally:
        cleanup(out, other)
    return t.finish()


if __name__ == "__main__":
    sys.exit(main())
