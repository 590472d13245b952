#!/usr/bin/env python3
"""The real-time tier's speed through the service's engine seam, old build against new.

    scripts/measure_engine_seam.py OLD_BUILD NEW_BUILD [--rounds N] [--seconds S]

OLD_BUILD and NEW_BUILD are build directories (e.g. build/release of two checkouts). Each
round runs, for the old then the new build (the order swapped every other round, so both
see the same machine load on average):

  bench_step --sizes small           the step itself (every row of the small beam)
  bench_service frames --seconds S   the served heart and 100k-node box: steps/s while
                                     publishing every step, states/s received
  bench_service latency --commands C command acknowledgement and effect latency

and prints, per row, the median over the rounds of each build and the ratio new / old.
The service rows run under CYCLONEDDS_URI=configs/dds/loopback-large.xml (as
docs/service-performance.md). Used for docs/service-performance.md ("The engine seam").
"""
import argparse
import os
import re
import statistics
import subprocess
import sys

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def table_rows(text):
    """Markdown table rows of a benchmark's output as lists of cells (header rows skipped)."""
    rows = []
    for line in text.splitlines():
        if not line.startswith("|") or line.startswith("|---") or "steps/s" in line or "| path |" in line:
            continue
        rows.append([c.strip() for c in line.strip().strip("|").split("|")])
    return rows


def number(cell):
    m = re.match(r"[-+0-9.eE]+", cell)
    return float(m.group(0)) if m else None


def bench_step(build):
    out = subprocess.run([os.path.join(build, "tests/bench/bench_step"), "--sizes", "small"], capture_output=True, text=True,
                         check=True).stdout
    figures = {}
    for cells in table_rows(out):
        if len(cells) < 8 or cells[0] != "small":
            continue
        name = "bench_step " + " / ".join(cells[2:5])
        figures[name + ": steps/s (mean)"] = number(cells[5])
        figures[name + ": ms/step median"] = number(cells[6])
    return figures


def bench_service(build, what, extra):
    env = dict(os.environ, CYCLONEDDS_URI="file://" + os.path.join(ROOT, "configs/dds/loopback-large.xml"))
    out = subprocess.run([os.path.join(build, "tests/bench/bench_service"), what, *extra], capture_output=True, text=True,
                         check=True, env=env).stdout
    figures = {}
    if what == "frames":
        for cells in table_rows(out):
            if len(cells) >= 5:
                figures[f"bench_service frames {cells[0]}: steps/s publishing every step"] = number(cells[3])
                figures[f"bench_service frames {cells[0]}: states/s received"] = number(cells[4])
    else:
        for line in out.splitlines():
            m = re.search(r"(command-to-effect latency|command round trip).*median ([0-9.]+) ms", line)
            if m:
                figures[f"bench_service latency: {m.group(1)}, median ms"] = float(m.group(2))
        if not figures:
            figures["bench_service latency (raw)"] = None
            print(out, file=sys.stderr)
    return figures


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("old")
    ap.add_argument("new")
    ap.add_argument("--rounds", type=int, default=3)
    ap.add_argument("--seconds", type=float, default=5)
    ap.add_argument("--commands", type=int, default=100)
    ap.add_argument("--skip-step", action="store_true", help="leave out bench_step (when its two binaries are the same code)")
    ap.add_argument("--skip-frames", action="store_true", help="leave out bench_service frames (minutes: the 100k-node box)")
    a = ap.parse_args()
    builds = {"old": a.old, "new": a.new}
    samples = {"old": {}, "new": {}}
    for r in range(a.rounds):
        for which in (("old", "new") if r % 2 == 0 else ("new", "old")):
            b = builds[which]
            figures = {}
            if not a.skip_step:
                figures.update(bench_step(b))
            try:  # a benchmark that fails on a loaded machine loses its round, not the others
                if not a.skip_frames:
                    figures.update(bench_service(b, "frames", ["--seconds", str(a.seconds)]))
                figures.update(bench_service(b, "latency", ["--commands", str(a.commands)]))
            except subprocess.CalledProcessError as e:
                print(f"round {r + 1} {which}: {e}", file=sys.stderr)
            for k, v in figures.items():
                samples[which].setdefault(k, []).append(v)
            print(f"round {r + 1}/{a.rounds} {which}: {figures}", file=sys.stderr, flush=True)
    print(f"| figure (median of {a.rounds} rounds, alternated) | old | new | new / old |\n|---|---:|---:|---:|")
    for k in samples["old"]:
        o = [v for v in samples["old"][k] if v is not None]
        n = [v for v in samples["new"].get(k, []) if v is not None]
        if not o or not n:
            continue
        mo, mn = statistics.median(o), statistics.median(n)
        print(f"| {k} | {mo:.3g} | {mn:.3g} | {mn / mo if mo else float('nan'):.3f} |")


if __name__ == "__main__":
    main()
