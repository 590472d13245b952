#!/usr/bin/env python3
"""Rest -> exercise -> rest on a served heart with the closed-loop circulation
(docs/circulation.md, section Steering).

Starts `fiberfem serve configs/scenes/heart-circulation-realtime.yaml` (paused, recorded into
an archive), drives it with the Python client: a few beats at rest, then exercise (heart rate
up, systemic arterial resistance down, peak tension up, the atrial kick moved to the end of the
shorter beat), then rest again. Every change is sent half-way through a beat, when the atria
rest, so that the beat under way goes on (set_circulation keeps its phase).

The figures of each phase come from the service's archive: `fiberfem run --resume` from the
recorded checkpoint some beats before the phase ends continues the served run bit for bit and
writes its report (pressures, volumes and flows each step); over the last whole beats of the
phase it prints the heart rate (from the spacing of the LV volume's minima), LV stroke volume
and ejection fraction, mean aortic pressure and cardiac output (mean aortic valve flow), in
the scene's units and at human scale (pressures / 0.15, volumes / 0.2: the scene's scale).

Usage: CYCLONEDDS_URI=file://$PWD/configs/dds/loopback.xml \\
       .venv/bin/python scripts/circulation_exercise.py [--out DIR] [--binary build/release/service/fiberfem]
"""

import argparse
import json
import math
import os
import subprocess
import sys
import time

import numpy as np

from fiberfem_client import Client, FiberfemError

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
SCENE = os.path.join(ROOT, "configs", "scenes", "heart-circulation-realtime.yaml")
DT = 0.0166667                            # the scene's step, s
SCALE_P, SCALE_V = 0.15, 0.2              # the scene's circulation.scale
LEAD_S = 60.0 / 72 - 0.8                  # the atria contract this long before the ventricles' beat

# Each phase: beats, heart rate (1/min), systemic arterial resistance (mmHg s/mL, the scene's
# units before scale), peak tension (Pa).
PHASES = [
    ("rest", 5, 72, 0.8, 22.0e3),
    ("exercise", 10, 100, 0.5, 30.0e3),
    ("rest again", 8, 72, 0.8, 22.0e3),
]
MEASURED_BEATS = 2  # the last whole beats of each phase


def phase_commands(rate, resistance, tension):
    onset = 60.0 / rate - LEAD_S  # the atrial kick just before the ventricles' beat, as at rest
    atrium = {"onset": onset}
    return [("set_circulation", {"heart_rate": rate, "systemic": {"arteries": {"resistance": resistance}},
                                 "chambers": {"left_atrium": atrium, "right_atrium": atrium}}),
            ("set_contraction", {"peak_tension": tension})]


def wait_frame(client, run, frame, timeout_s=600):
    end = time.monotonic() + timeout_s
    while time.monotonic() < end:
        try:
            s = client.status(run, wait_s=10)
        except FiberfemError:  # a busy machine can hold a status back; the run is still there
            continue
        if s.frame >= frame:
            return s
        time.sleep(0.05)
    raise RuntimeError(f"run {run} did not reach frame {frame}")


def serve_and_drive(binary, archive, run_id):
    """Serves the scene, plays the phases; returns each phase's (start, end) step and the
    heart rate the service's status reported in it."""
    log = open(archive + ".serve.log", "w")
    service = subprocess.Popen([binary, "serve", SCENE, "--run-id", run_id, "--fast", "--paused", "--threads", "1",
                                "--set", "archive.path=" + archive, "--set", "archive.checkpoint_every=1"],
                               stdout=log, stderr=subprocess.STDOUT)
    client = Client()
    spans, step, beat_start = [], 0, 0.0
    try:
        client.resolve_run(run_id, wait_s=30)
        for i, (name, beats, rate, resistance, tension) in enumerate(PHASES):
            period = 60.0 / rate
            if i > 0:
                for kind, args in phase_commands(rate, resistance, tension):
                    ack = client.send(run_id, kind, args)
                    if not ack.accepted:
                        raise RuntimeError(f"{kind} {args}: rejected: {ack.reason}")
                    print(f"t = {step * DT:.3f} s (step {step}): {kind} {json.dumps(args)}: {ack.reason}", flush=True)
            # Half-way through the phase's last beat: the beats count from the one under way.
            end_time = beat_start + (beats - 0.5) * period if i < len(PHASES) - 1 else beat_start + beats * period
            end = int(round(end_time / DT))
            client.send(run_id, "step", {"count": end - step})
            status = wait_frame(client, run_id, end)
            spans.append((name, step, end, status.heart_rate_bpm, period))
            step, beat_start = end, beat_start + (beats - 1) * period
        client.send(run_id, "shutdown", {})
        service.wait(timeout=60)
    finally:
        if service.poll() is None:
            service.terminate()
            service.wait(timeout=30)
        log.close()
    return spans


def phase_report(binary, archive, out_dir, name, end_step, period):
    """Resumes the archive a few beats before `end_step` and runs to it with a report."""
    start_s = end_step * DT - (MEASURED_BEATS + 1) * period
    report = os.path.join(out_dir, "phase-" + name.replace(" ", "-") + ".json")
    r = subprocess.run([binary, "run", "--resume", f"{archive}@{start_s:.6f}", "--steps", str(end_step),
                        "--report", report], capture_output=True, text=True)
    if r.returncode != 0:
        raise RuntimeError(f"resume for {name}: {r.stdout}{r.stderr}")
    with open(report) as f:
        return json.load(f)["circulation"]["steps"]


def figures(steps, period):
    """Per-phase figures over the last MEASURED_BEATS whole periods of `steps`."""
    t = np.asarray(steps["time_s"])
    keep = t > t[-1] - MEASURED_BEATS * period + 1e-9
    t, v = t[keep], np.asarray(steps["lv_volume_m3"])[keep] * 1e6
    p_ao = np.asarray(steps["systemic_arterial_pressure_pa"])[keep] / 133.322387415
    q_ao = np.asarray(steps["aortic_flow_m3_s"])[keep] * 1e6
    per_beat = np.array_split(np.arange(len(t)), MEASURED_BEATS)
    sv = np.mean([v[b].max() - v[b].min() for b in per_beat])
    ef = np.mean([(v[b].max() - v[b].min()) / v[b].max() for b in per_beat])
    minima = [t[b][np.argmin(v[b])] for b in per_beat]
    rate = 60.0 / float(np.mean(np.diff(minima))) if len(minima) > 1 else math.nan
    return {"heart_rate_bpm": rate, "stroke_volume_ml": sv, "ejection_fraction": ef,
            "mean_aortic_mmhg": float(p_ao.mean()), "aortic_max_mmhg": float(p_ao.max()),
            "aortic_min_mmhg": float(p_ao.min()), "cardiac_output_ml_min": 60.0 * float(q_ao.mean()),
            "sv_times_rate_ml_min": sv * rate}


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--out", default=os.path.join(ROOT, "build", "exercise"))
    ap.add_argument("--binary", default=os.path.join(ROOT, "build", "release", "service", "fiberfem"))
    a = ap.parse_args()
    if not os.environ.get("CYCLONEDDS_URI"):
        os.environ["CYCLONEDDS_URI"] = "file://" + os.path.join(ROOT, "configs", "dds", "loopback.xml")
    os.makedirs(a.out, exist_ok=True)
    archive = os.path.join(a.out, "exercise.h5")
    if os.path.exists(archive):
        os.remove(archive)
    spans = serve_and_drive(a.binary, archive, f"exercise-{os.getpid()}")
    rows = []
    print(f"\n{'phase':<11} {'status HR':>9} {'HR':>6} {'SV mL':>7} {'EF':>6} {'MAP mmHg':>9} {'aortic':>8} "
          f"{'CO mL/min':>9} | human scale: {'SV mL':>6} {'MAP':>5} {'CO L/min':>8}")
    for name, _, end, status_rate, period in spans:
        f = figures(phase_report(a.binary, archive, a.out, name, end, period), period)
        f["phase"], f["status_heart_rate_bpm"] = name, status_rate
        rows.append(f)
        print(f"{name:<11} {status_rate:9.0f} {f['heart_rate_bpm']:6.1f} {f['stroke_volume_ml']:7.2f} "
              f"{f['ejection_fraction']:6.3f} {f['mean_aortic_mmhg']:9.2f} "
              f"{f['aortic_max_mmhg']:4.0f}/{f['aortic_min_mmhg']:<3.0f} {f['cardiac_output_ml_min']:9.0f} | "
              f"{'':13} {f['stroke_volume_ml'] / SCALE_V:6.1f} {f['mean_aortic_mmhg'] / SCALE_P:5.0f} "
              f"{f['cardiac_output_ml_min'] / SCALE_V / 1000:8.2f}")
    with open(os.path.join(a.out, "figures.json"), "w") as fjson:
        json.dump(rows, fjson, indent=1)
    return 0


if __name__ == "__main__":
    sys.exit(main())
