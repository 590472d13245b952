#!/usr/bin/env python3
"""Commands per second the service takes while keeping its frame rate (docs/reliability.md).

For each number of client processes, starts a fresh `fiberfem serve` (real time, one
engine thread), measures its steps per second unloaded, then runs that many
`fiberfem ctl flood` clients at once (COUNT commands each, WINDOW in flight per client)
and reports the commands per second answered in all, the step rate during the flood
against the unloaded one, the acknowledgement latency, and whether every command was
acknowledged and applied exactly once (the accepted commands' parameter versions are
exactly v0+1 .. v0+N).

    CYCLONEDDS_URI=file://$PWD/configs/dds/loopback.xml PYTHONPATH=clients/python \\
        .venv/bin/python scripts/flood_bench.py build/release/service/fiberfem [--clients 1 2 4 8] \\
        [--count 1000] [--window 8] [--scene cantilever]
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
    a = ap.parse_args()
    print(f"| clients | commands | commands/s (all) | steps/s unloaded | steps/s during | ratio | ack latency median / p99 (ms) | exactly once |")
    print("|---|---|---|---|---|---|---|---|")
    with tempfile.TemporaryDirectory() as work:
        for n in a.clients:
            run = f"floodbench-{os.getpid()}-{n}"
            log = open(os.path.join(work, f"serve-{n}.log"), "w")
            svc = subprocess.Popen([a.binary, "serve", "--builtin", a.scene, "--threads", "1", "--run-id", run, "--status-hz", "4"],
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
            print(f"| {n} | {total} | {total / seconds:.0f} | {b:.1f} | {d:.1f} | {d / b:.2f} | {lat_med:.1f} / {lat_p99:.1f} | "
                  f"{'yes' if once else 'NO'} |", flush=True)
            svc.terminate()
            svc.wait(30)
            log.close()
    return 0


if __name__ == "__main__":
    sys.exit(main())
