"""The circulation on the bus and in replay, against the run report and the archive read
with h5py (independent sources). A batch run of the circulation heart writes the report
and an archive; then, on the DDS loopback profile, with real processes:

1. `fiberfem serve` of the same scene: the Python client's circulation samples equal the
   report's per-step values at the same step (pressures, volumes, flows, iterations; the
   same engine on one thread rounds the same), and once a beat is complete the sample's
   beat figures equal the report's for that beat;
2. `fiberfem ctl echo --circulation` prints those numbers in mmHg and mL;
3. `fiberfem replay` of the archive republishes, frame for frame, what h5py reads in its
   /frames/circulation.

Usage: circulation_outputs_test.py PATH/TO/fiberfem SOURCE_DIR   (CYCLONEDDS_URI set)
"""
import json
import os
import re
import subprocess
import sys
import tempfile

import h5py
import numpy as np
from fiberfem_client import Client

MMHG, ML = 133.322387415, 1e-6
UNTIL = "2.0"  # 120 steps: beat 0 (0.833 s) and beat 1 complete


def report_steps(report):
    steps = report["circulation"]["steps"]
    return {name: np.asarray(v) for name, v in steps.items()}


def close(a, b, rel=1e-12):
    return abs(a - b) <= rel * max(abs(a), abs(b), 1e-30)


def check_sample_against_report(c, steps, beats):
    k = c.frame - 1  # the report's rows are steps 1, 2, ...
    assert k >= 0 and abs(steps["time_s"][k] - c.time_s) < 1e-12, (c.frame, c.time_s)
    for name in ("lv_pressure_pa", "lv_volume_m3", "rv_pressure_pa", "rv_volume_m3", "systemic_arterial_pressure_pa",
                 "aortic_flow_m3_s", "pulmonary_venous_flow_m3_s", "la_volume_m3"):
        assert close(getattr(c, name), steps[name][k]), (c.frame, name, getattr(c, name), steps[name][k])
    assert c.pressure_iterations == steps["pressure_iterations"][k], (c.frame, c.pressure_iterations)
    if c.beat >= 0:
        b = beats[c.beat]
        assert b["complete"], b
        assert close(c.lv_end_diastolic_volume_m3, b["lv"]["end_diastolic_volume_m3"]), (c.beat, b)
        assert close(c.lv_stroke_volume_m3, b["lv"]["stroke_volume_m3"]), (c.beat, b)
        assert close(c.rv_peak_pressure_pa, b["rv"]["peak_pressure_pa"]), (c.beat, b)
        assert close(c.systemic_arterial_max_pa, b["systemic_arterial_max_pa"]), (c.beat, b)


def serve_and_echo(fiberfem, scene, steps, beats, client):
    run = f"circ-serve-{os.getpid()}"
    serve = subprocess.Popen([fiberfem, "serve", scene, "--run-id", run, "--until", UNTIL, "--threads", "1",
                              "--publish-hz", "1000", "--paused"], stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    try:
        assert client.resolve_run(run, 20) == run
        echo = subprocess.Popen([fiberfem, "ctl", "--run", run, "echo", "--circulation", "--count", "5"],
                                stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        # Paused, the service publishes its state (and circulation) once a second: the echo's
        # first line says its reader is matched before the run goes on.
        first = echo.stdout.readline()
        assert first.startswith("frame 0 "), (first, echo.stderr.read() if echo.poll() is not None else "")
        assert client.send(run, "resume").accepted
        seen = []
        for c in client.circulation_states(run, wait_s=10):
            seen.append(c)
            if c.frame >= 120:
                break
        out, err = echo.communicate(timeout=30)
        out = first + out
        assert echo.returncode == 0, (out, err)
    finally:
        serve.terminate()
        serve.wait(timeout=30)
    frames = [c.frame for c in seen if c.frame > 0]
    assert len(frames) >= 100 and frames == sorted(frames), frames  # published with every state
    for c in seen:
        if c.frame > 0:
            check_sample_against_report(c, steps, beats)
    assert any(c.beat == 1 for c in seen), "no sample after beat 1 completed"
    lines = [l for l in out.splitlines() if l.startswith("frame ")]
    assert len(lines) == 5, out
    for line in lines:
        m = re.match(r"frame (\d+) t=\S+ s: LV (\S+) mmHg (\S+) mL, RV (\S+) mmHg (\S+) mL", line)
        assert m, line
        k = int(m.group(1)) - 1
        if k < 0:
            continue
        assert abs(float(m.group(2)) - steps["lv_pressure_pa"][k] / MMHG) <= 0.006, line
        assert abs(float(m.group(3)) - steps["lv_volume_m3"][k] / ML) <= 0.0006, line
        assert abs(float(m.group(4)) - steps["rv_pressure_pa"][k] / MMHG) <= 0.006, line
    return len(frames)


def replay(fiberfem, archive, client):
    with h5py.File(archive, "r") as f:
        n = f["frames/step"].shape[0]
        step = f["frames/step"][:n]
        names = json.loads(f["frames/circulation"].attrs["columns"])
        table = f["frames/circulation"][:n]
    run = f"circ-replay-{os.getpid()}"
    rep = subprocess.Popen([fiberfem, "replay", archive, "--run-id", run, "--paused", "--every-frame", "--rate", "4",
                            "--exit-at-end"], stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    try:
        assert client.resolve_run(run, 20) == run
        client.circulation_samples(run, wait_s=0.5)  # the paused frame
        # Frame 0 again until it arrives: commands matched do not mean that the circulation
        # topic has (a sample published before that match is not delivered).
        got = {}
        for _ in range(20):
            assert client.send(run, "seek", {"frame": 0}).accepted
            first = [c for c in client.circulation_samples(run, wait_s=1.0) if c.frame == 0]
            if first:
                got[0] = first[0]
                break
        assert client.send(run, "resume").accepted
        for c in client.circulation_states(run, wait_s=10):
            got[c.frame] = c
            if c.frame == step[-1]:
                break
        rep.wait(timeout=30)
    finally:
        if rep.poll() is None:
            rep.terminate()
            rep.wait(timeout=30)
    assert sorted(got) == [int(s) for s in step], (sorted(got)[:5], len(got), n)  # every frame, in order
    for i in range(n):
        c = got[int(step[i])]
        for j, name in enumerate(names):
            assert getattr(c, name) == (int(table[i, j]) if name in ("beat", "pressure_iterations") else table[i, j]), (i, name)
    return len(got)


def main():
    fiberfem, src = sys.argv[1], sys.argv[2]
    scene = os.path.join(src, "configs/scenes/heart-circulation-realtime.yaml")
    with tempfile.TemporaryDirectory() as d:
        report_path, archive = os.path.join(d, "r.json"), os.path.join(d, "a.h5")
        subprocess.run([fiberfem, "run", scene, "--until", UNTIL, "--threads", "1", "--report", report_path, "--archive", archive],
                       check=True, capture_output=True)
        with open(report_path, encoding="utf-8") as f:
            report = json.load(f)
        steps, beats = report_steps(report), report["circulation"]["beats"]
        client = Client("circulation-test")
        served = serve_and_echo(fiberfem, scene, steps, beats, client)
        replayed = replay(fiberfem, archive, client)
    print(f"circulation outputs: ok ({served} served samples equal the report's, {replayed} replayed equal the archive's)")


if __name__ == "__main__":
    main()
