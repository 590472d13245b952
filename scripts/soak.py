#!/usr/bin/env python3
"""Soak run of the service (docs/reliability.md): the default heart served as fast as it
goes for a stretch of simulated time (default 1800 s = 30 min) while commands arrive
every few wall seconds. Samples the service's resident memory (/proc/PID/status VmRSS),
its steps per second and energies (from its status on DDS) and reports:

  RSS at the start (after warm-up), end, max, and its slope (least squares, MB/hour);
  steps/s: median of the first 10 % of samples against the last 10 % (drift, %), and the
  same for the service's CPU time per step (independent of the machine's other load);
  kinetic + elastic energy: min and max; commands sent, accepted, unanswered.

    CYCLONEDDS_URI=file://$PWD/configs/dds/loopback.xml PYTHONPATH=clients/python \\
        .venv/bin/python scripts/soak.py build/release/service/fiberfem [--sim-seconds 1800] [--json out/soak.json]

Speed and memory are reported, never asserted; the exit status is non-zero only when the
service died, a command went unanswered or energy became non-finite.
"""
import argparse
import json
import math
import os
import statistics
import subprocess
import sys
import tempfile
import time

from fiberfem_client import Client, FiberfemError

# The commands that arrive, in turn (docs/commands.md): heart rate changes, a transient
# push on the apex, peak tension changes, damping.
COMMANDS = [
    ("set_contraction", {"heart_rate": 90}),
    ("apply_force", {"name": "soak-push", "target": {"point": [0.0, 0.0, -0.045]}, "force": [0.0, 0.0, 0.02], "duration": 0.3}),
    ("set_contraction", {"heart_rate": 72, "peak_tension": 9.0e3}),
    ("set_damping", {"mass": 2.0}),
    ("set_contraction", {"peak_tension": 11.0e3}),
    ("clear_force", {}),
]


def rss_kb(pid):
    with open(f"/proc/{pid}/status") as f:
        for line in f:
            if line.startswith("VmRSS:"):
                return int(line.split()[1])
    return 0


def cpu_s(pid):
    """User + system CPU time of the process, s (/proc/PID/stat fields 14 and 15)."""
    with open(f"/proc/{pid}/stat") as f:
        fields = f.read().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")


def slope(xs, ys):
    n = len(xs)
    if n < 2:
        return 0.0
    mx, my = sum(xs) / n, sum(ys) / n
    sxx = sum((x - mx) ** 2 for x in xs)
    return sum((x - mx) * (y - my) for x, y in zip(xs, ys)) / sxx if sxx > 0 else 0.0


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("binary")
    ap.add_argument("--sim-seconds", type=float, default=1800.0, help="simulated time to run, s")
    ap.add_argument("--command-every", type=float, default=2.0, help="wall seconds between commands")
    ap.add_argument("--sample-every", type=float, default=5.0, help="wall seconds between samples")
    ap.add_argument("--threads", type=int, default=1)
    ap.add_argument("--warmup", type=float, default=0.05, help="fraction of the samples left out of the RSS start")
    ap.add_argument("--json", help="write the samples and the summary here")
    a = ap.parse_args()

    run = f"soak-{os.getpid()}"
    with tempfile.TemporaryDirectory() as work:
        log = open(os.path.join(work, "serve.log"), "w")
        svc = subprocess.Popen([a.binary, "serve", "--fast", "--threads", str(a.threads), "--run-id", run, "--status-hz", "1",
                                "--until", str(a.sim_seconds)], stdout=log, stderr=subprocess.STDOUT)
        c = Client(f"soak-{os.getpid()}")
        c.resolve_run(run, 30)
        t0 = time.monotonic()
        samples, sent, accepted, unanswered, rejections = [], 0, 0, 0, {}
        next_cmd = next_sample = t0
        k = 0
        last_status = None
        while svc.poll() is None:
            now = time.monotonic()
            if now >= next_cmd:
                kind, args = COMMANDS[k % len(COMMANDS)]
                k += 1
                sent += 1
                try:
                    ack = c.send(run, kind, args, wait_s=30)
                    accepted += ack.accepted
                    if not ack.accepted:
                        rejections[f"{kind}: {ack.reason}"] = rejections.get(f"{kind}: {ack.reason}", 0) + 1
                except FiberfemError:
                    if svc.poll() is None:
                        unanswered += 1
                next_cmd += a.command_every
            if now >= next_sample:
                try:
                    st = c.status(run, 5)
                    last_status = st
                    if st.state == "stopped":
                        break
                    samples.append({"wall_s": now - t0, "sim_s": st.time_s, "rss_kb": rss_kb(svc.pid), "cpu_s": cpu_s(svc.pid),
                                    "load1": os.getloadavg()[0],
                                    "steps_per_s": st.frames_per_second, "kinetic_j": st.kinetic_energy_j,
                                    "elastic_j": st.elastic_energy_j, "frame": st.frame})
                    s = samples[-1]
                    print(f"{s['wall_s']:8.0f} s wall  t={s['sim_s']:8.1f} s  {s['steps_per_s']:6.1f} steps/s  "
                          f"RSS {s['rss_kb'] / 1024:7.1f} MB  E {s['kinetic_j'] + s['elastic_j']:.3e} J", flush=True)
                except (FiberfemError, FileNotFoundError, ProcessLookupError):
                    pass
                next_sample += a.sample_every
            time.sleep(0.05)
        code = svc.wait(timeout=60)
        log.close()
        tail = open(os.path.join(work, "serve.log")).read()[-2000:]

    if len(samples) < 4:
        print("too few samples:\n" + tail, file=sys.stderr)
        return 1
    w = max(1, int(len(samples) * a.warmup))
    kept = samples[w:]
    tenth = max(1, len(samples) // 10)
    first = statistics.median(s["steps_per_s"] for s in samples[:tenth])
    last = statistics.median(s["steps_per_s"] for s in samples[-tenth:])
    energy = [s["kinetic_j"] + s["elastic_j"] for s in samples]
    # CPU time per step between samples: the work a step costs, whatever else the machine runs.
    for a_, b_ in zip(samples, samples[1:]):
        b_["cpu_ms_per_step"] = 1e3 * (b_["cpu_s"] - a_["cpu_s"]) / max(1, b_["frame"] - a_["frame"])
    cps = [s["cpu_ms_per_step"] for s in samples[1:]]
    half = kept[len(kept) // 2:]
    rss_mb = [s["rss_kb"] / 1024 for s in kept]
    summary = {
        "sim_seconds": samples[-1]["sim_s"], "wall_seconds": samples[-1]["wall_s"], "samples": len(samples),
        "exit_code": code,
        "rss_start_mb": rss_mb[0], "rss_end_mb": rss_mb[-1], "rss_max_mb": max(rss_mb),
        "rss_slope_mb_per_hour": slope([s["wall_s"] / 3600 for s in kept], rss_mb),
        "rss_slope_mb_per_sim_hour": slope([s["sim_s"] / 3600 for s in kept], rss_mb),
        "steps_per_s_first_10pct": first, "steps_per_s_last_10pct": last,
        "steps_per_s_drift_pct": 100 * (last - first) / first if first > 0 else float("nan"),
        "rss_slope_second_half_mb_per_hour": slope([s["wall_s"] / 3600 for s in half], [s["rss_kb"] / 1024 for s in half]),
        "cpu_ms_per_step_first_10pct": statistics.median(cps[:tenth]),
        "cpu_ms_per_step_last_10pct": statistics.median(cps[-tenth:]),
        "load1_first_10pct": statistics.median(s["load1"] for s in samples[:tenth]),
        "load1_last_10pct": statistics.median(s["load1"] for s in samples[-tenth:]),
        "rejections": rejections,
        "energy_min_j": min(energy), "energy_max_j": max(energy),
        "commands_sent": sent, "commands_accepted": accepted, "commands_unanswered": unanswered,
        "final_frame": last_status.frame if last_status else None,
    }
    print(json.dumps(summary, indent=1))
    if a.json:
        os.makedirs(os.path.dirname(os.path.abspath(a.json)), exist_ok=True)
        with open(a.json, "w") as f:
            json.dump({"summary": summary, "samples": samples}, f, indent=1)
    ok = code == 0 and unanswered == 0 and all(math.isfinite(e) for e in energy)
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
