#!/usr/bin/env python3
"""Commands per second the service takes while keeping its frame rate (docs/reliability.md).

For each number of client processes (and each engine thread count of --threads, each
other load of --beside), starts a fresh `fiberfem serve` (real time; one engine thread
unless --threads says otherwise), measures its steps per second before the flood, then
runs that many
`fiberfem ctl flood` clients at once (COUNT commands each, WINDOW in flight per client)
and reports the commands per second answered in all, the step rate during the flood
against the unloaded one, the acknowledgement latency, and whether every command was
acknowledged and applied exactly once (the accepted commands' parameter versions are
exactly v0+1 .. v0+N).

--beside spin keeps one core busy with another process (a shell loop at normal priority)
for the whole row, started before the service: how the service shares a machine with a
busy process. Threads 0 is the engine's automatic count.

    CYCLONEDDS_URI=file://$PWD/configs/dds/loopback.xml PYTHONPATH=clients/python \\
        .venv/bin/python scripts/flood_bench.py build/release/service/fiberfem [--clients 1 2 4 8] \\
        [--count 1000] [--window 8] [--scene cantilever] [--threads 1 2 0] [--beside none spin]
"""
import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
import time

from fiberfem_client import Client


def rates(c, run, n):
    out = []
    for _ in range(n):
        out.append(c.status(run, 5).frames_per_second)
    return out


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("binary")
    ap.add_argument("--clients", type=int, nargs="+", default=[1, 2, 4, 8])
    ap.add_argument("--count", type=int, default=1000, help="commands per client")
    ap.add_argument("--window", type=int, default=8, help="commands in flight per client")
    ap.add_argument("--scene", default="cantilever", help="built-in scene (heart, cantilever)")
    ap.add_argument("--threads", type=int, nargs="+", default=[1], help="engine threads per row (0: automatic)")
    ap.add_argument("--beside", choices=["none", "spin"], nargs="+", default=["none"],
                    help="other load during the row: none, or one core kept busy by a shell loop")
    a = ap.parse_args()
    print(f"| other load | threads | clients | commands | commands/s (all) | steps/s unloaded | steps/s during | ratio | "
          f"ack latency median / p99 (ms) | exactly once |")
    print("|---|---|---|---|---|---|---|---|---|---|")
    with tempfile.TemporaryDirectory() as work:
        for beside, threads, n in ((b, t, n) for b in a.beside for t in a.threads for n in a.clients):
            spin = subprocess.Popen(["sh", "-c", "while :; do :; done"]) if beside == "spin" else None
            try:
                row(a, work, n, threads, beside)
            finally:
                if spin:
                    spin.kill()
                    spin.wait()
    return 0


def row(a, work, n, threads, beside):
    run = f"floodbench-{os.getpid()}-{n}-{threads}-{beside}"
    log = open(os.path.join(work, f"serve-{n}-{threads}-{beside}.log"), "w")
    svc = subprocess.Popen([a.binary, "serve", "--builtin", a.scene, "--threads", str(threads), "--run-id", run, "--status-hz", "4"],
                           stdout=log, stderr=subprocess.STDOUT)
    c = Client(f"floodbench-{os.getpid()}")
    c.resolve_run(run, 30)
    v0 = c.send(run, "set_gravity", {"gravity": [0.0, 0.0, -9.81]}).parameter_version
    rates(c, run, 2)
    before = rates(c, run, 12)
    procs = [subprocess.Popen([a.binary, "ctl", "--run", run, "--timeout", "300", "flood", "set_gravity",
                               '{"gravity": [0, 0, -9.81]}', "--count", str(a.count), "--window", str(a.window)],
                              stdout=subprocess.PIPE, text=True) for _ in range(n)]
    during = []
    while any(p.poll() is None for p in procs):
        during.append(c.status(run, 5).frames_per_second)
    during = during[1:] if len(during) > 2 else during
    reports = [json.loads(p.stdout.read()) for p in procs]
    versions = sorted(v for r in reports for v in r["versions"])
    total = n * a.count
    once = versions == list(range(v0 + 1, v0 + total + 1)) and all(r["acked"] == a.count for r in reports)
    seconds = max(r["seconds"] for r in reports)
    lat_med = statistics.median(r["latency_ms_median"] for r in reports)
    lat_p99 = max(r["latency_ms_p99"] for r in reports)
    b, d = statistics.median(before), statistics.median(during) if during else float("nan")
    print(f"| {beside} | {threads if threads else 'automatic'} | {n} | {total} | {total / seconds:.0f} | {b:.1f} | {d:.1f} | {d / b:.2f} | {lat_med:.1f} / {lat_p99:.1f} | "
          f"{'yes' if once else 'NO'} |", flush=True)
    svc.terminate()
    svc.wait(30)
    log.close()


if __name__ == "__main__":
    sys.exit(main())
