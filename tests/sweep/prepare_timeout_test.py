"""A run past the sweep's timeout_s is killed and becomes a `timeout` row (the sweep goes
on); prepare steps run once, in the sweep file's folder, and a failing one stops the
sweep with a message naming it."""

import os
import sys
import tempfile

from sweep_support import Tally, cleanup, recorded_rows, run_sweep, scratch, table

SCENE = os.path.join(os.path.dirname(os.path.abspath(__file__)), "../../configs/scenes/cantilever-along.yaml")
SWEEP = """sweep: timeouts
scene: {scene}
timeout_s: 1.0
set: {{solver.mode: dynamic, solver.threads: 1}}
prepare:
  - {{run: [python, -c, "import time, pathlib; pathlib.Path('made/count.txt').open('a').write('x')"],
     creates: made/count.txt}}
groups:
  - name: quick
    set: {{solver.until: 0.05}}
  - name: long
    set: {{solver.until: 500, mesh.cells: [60, 6, 6]}}
"""


def main():
    t = Tally()
    d = tempfile.mkdtemp(prefix="fiberfem-sweep-files-")
    out = scratch("timeout")
    try:
        path = os.path.join(d, "timeouts.yaml")
        with open(path, "w") as f:
            f.write(SWEEP.format(scene=os.path.abspath(SCENE)))
        p = run_sweep(path, out, "--workers", "1")
        t.check(p.returncode == 0, f"sweep exit {p.returncode}: {p.stderr[-2000:]}")
        if p.returncode == 0:
            df = table(out).set_index("name")
            t.check(df.loc["quick", "status"] == "completed", f"quick: {df.loc['quick', 'status']}")
            t.check(df.loc["long", "status"] == "timeout" and "timeout_s = 1 s" in df.loc["long", "reason"],
                    f"long: {df.loc['long', 'status']} {df.loc['long', 'reason']}")
            t.check(df.loc["long", "attempt_s"] < 30, f"killed at the timeout: {df.loc['long', 'attempt_s']} s")
        t.check(open(os.path.join(d, "made/count.txt")).read() == "x", "the prepare step ran once, in the file's folder")
        # Run again: the prepare step is skipped (its file exists), the timeout runs again.
        again = run_sweep(path, out, "--workers", "1")
        t.check(again.returncode == 0 and open(os.path.join(d, "made/count.txt")).read() == "x",
                "prepare skipped the second time")
        t.check([r["name"] for r in recorded_rows(out)].count("long") == 2, "the timed-out run ran again")
        t.check([r["name"] for r in recorded_rows(out)].count("quick") == 1, "the completed one did not")
        bad = os.path.join(d, "bad.yaml")
        with open(bad, "w") as f:
            f.write(SWEEP.format(scene=os.path.abspath(SCENE)).replace("sweep: timeouts", "sweep: bad").replace(
                "made/count.txt')", "nowhere/x.txt')").replace("creates: made/count.txt", "creates: made/other.txt"))
        out2 = os.path.join(d, "out2")
        p = run_sweep(bad, out2, "--sequential")
        t.check(p.returncode == 1 and "prepare[0]" in p.stderr and "made/other.txt" in p.stderr,
                f"a failing prepare step stops the sweep, named: {p.returncode} {p.stderr[-800:]}")
    finally:
        cleanup(d, out)
    return t.finish()


if __name__ == "__main__":
    sys.exit(main())
