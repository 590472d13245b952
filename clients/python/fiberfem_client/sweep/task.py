"""One configuration of a sweep, run on a Dask worker (or in the sweep's own process) as the
real `fiberfem run` process: its scene hash first (the resume key), then the run with its
report and, where an error measure needs it, its archive; the row it returns holds the
settings, the outcome and the measures. Nothing here raises: a failure is a row."""

from __future__ import annotations

import ctypes
import hashlib
import json
import math
import os
import shutil
import signal
import socket
import subprocess
import time

from .measures import cost_measures, error_measures

# Row columns that measure time or place, not the result: they differ between two runs of
# the same configuration (everything else is the same bits: the engine is deterministic).
TIMING_COLUMNS = ("wall_s", "engine_s", "steps_per_s", "median_step_s", "wall_s_per_sim_s", "engine_s_per_sim_s",
                  "peak_rss_mb", "started_utc", "worker", "attempt_s")
DONE_STATUSES = ("completed", "failed", "refused")

_binary_hashes: dict = {}


def binary_version(path: str) -> str:
    """SHA-256 of the binary's bytes (cached per path, size and mtime): a rebuilt binary is
    a new version even when its version string is not."""
    st = os.stat(path)
    key = (path, st.st_size, st.st_mtime_ns)
    if key not in _binary_hashes:
        h = hashlib.sha256()
        with open(path, "rb") as f:
            for block in iter(lambda: f.read(1 << 20), b""):
                h.update(block)
        _binary_hashes[key] = h.hexdigest()
    return _binary_hashes[key]


def row_key(scene_sha256: str, binary_sha256: str) -> str:
    return f"{scene_sha256[:20]}-{binary_sha256[:12]}"


def _die_with_parent():
    # The run dies with the worker thread that started it (a worker killed with SIGKILL
    # leaves no orphan run behind; its task is retried elsewhere).
    ctypes.CDLL("libc.so.6", use_errno=True).prctl(1, signal.SIGKILL)  # PR_SET_PDEATHSIG


def _scene_args(job) -> list:
    scene = job["scene"]
    args = ["--builtin", scene[len("builtin:"):]] if scene.startswith("builtin:") else [scene]
    for s in job["overrides"]:
        args += ["--set", s]
    return args


def scene_hash(job):
    """(sha256, None) or (None, the refusal's message) for the configuration's scene."""
    p = subprocess.run([job["binary"], "run", *_scene_args(job), "--scene-hash"], capture_output=True, text=True,
                       timeout=600, preexec_fn=_die_with_parent)
    if p.returncode == 0 and len(p.stdout.strip()) == 64:
        return p.stdout.strip(), None
    return None, _last_lines(p.stderr or p.stdout)


def _last_lines(text: str, n=3) -> str:
    lines = [l for l in text.strip().splitlines() if l.strip()]
    return " | ".join(lines[-n:])[:600]


def _base_row(job, started) -> dict:
    row = {"name": job["name"], "group": job["group"], "values": json.dumps(job["values"], sort_keys=True),
           "overrides": json.dumps(list(job["overrides"])), "started_utc": started,
           "worker": f"{socket.gethostname()}:{os.getpid()}"}
    for k, v in job["values"].items():
        row[f"set:{k}"] = json.dumps(v)
    return row


def run_configuration(job: dict) -> dict:
    """Runs one configuration; `job` holds binary, scene, overrides, name, group, values,
    run_dir, archive (bool), reference ({archive, report} or None), errors, sample_s,
    timeout_s, keep_archive, done_keys."""
    t0 = time.monotonic()
    row = _base_row(job, time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime()))
    try:
        row.update(_run(job, row))
    except Exception as e:  # a row, never the end of the sweep
        row.update(status="error", reason=f"{type(e).__name__}: {e}"[:600])
    row["attempt_s"] = time.monotonic() - t0
    return row


def _run(job, row) -> dict:
    binary = job["binary"]
    out = {"binary_sha256": binary_version(binary)}
    sha, refusal = scene_hash(job)
    if sha is None:
        ident = hashlib.sha256(json.dumps([job["scene"], list(job["overrides"])]).encode()).hexdigest()
        out.update(status="refused", reason=refusal, scene_sha256="",
                   key=row_key("refused" + ident, out["binary_sha256"]))
        return out
    out.update(scene_sha256=sha, key=row_key(sha, out["binary_sha256"]))
    if out["key"] in job.get("done_keys", ()):
        out["status"] = "skipped"
        return out
    run_dir = os.path.join(job["run_dir"], out["key"])
    shutil.rmtree(run_dir, ignore_errors=True)  # a retried attempt starts clean
    os.makedirs(run_dir)
    report_path, archive_path = os.path.join(run_dir, "report.json"), os.path.join(run_dir, "run.h5")
    argv = [binary, "run", *_scene_args(job), "--report", report_path]
    if job["archive"]:
        # Positions only (displacement = positions - rest), no checkpoints: what the measures read.
        argv += ["--set", f"archive.path={archive_path}", "--set", "archive.displacement=false",
                 "--set", "archive.checkpoint_every=0"]
    code, err, peak_kib = _run_with_peak(argv, job["timeout_s"], os.path.join(run_dir, "stdout.txt"))
    report = read_json(report_path)
    out.update(_outcome(code, err, report, job["timeout_s"]))
    out.update(_report_fields(report))
    if report:
        out.update(cost_measures(report, peak_kib))
    if out["status"] == "completed" and job.get("reference"):
        ref = job["reference"]
        out.update(error_measures(archive_path if job["archive"] else None, report, ref["archive"], read_json(ref["report"]),
                                  job["sample_s"], job["errors"]))
    if job["archive"] and not job.get("keep_archive"):
        for p in (archive_path, archive_path[:-3] + ".xdmf"):
            if os.path.exists(p):
                os.remove(p)
    out["run_dir"] = run_dir
    return out


def _run_with_peak(argv, timeout_s, stdout_path):
    """Runs argv; (exit code or None on timeout, stderr, peak resident memory in KiB from
    the kernel's accounting of this child: os.wait4 gives its own rusage)."""
    with open(stdout_path, "wb") as out, open(stdout_path[:-10] + "stderr.txt", "w+b") as errf:
        p = subprocess.Popen(argv, stdout=out, stderr=errf, preexec_fn=_die_with_parent)
        deadline = time.monotonic() + timeout_s
        while True:
            pid, status, usage = os.wait4(p.pid, os.WNOHANG)
            if pid:
                break
            if time.monotonic() > deadline:
                p.kill()
                _, _, ru = os.wait4(p.pid, 0)
                p.returncode = -9
                errf.seek(0)
                return None, errf.read().decode(errors="replace"), ru.ru_maxrss
            time.sleep(0.02)
        p.returncode = os.waitstatus_to_exitcode(status)
        errf.seek(0)
        return p.returncode, errf.read().decode(errors="replace"), usage.ru_maxrss


def read_json(path):
    try:
        with open(path, encoding="utf-8") as f:
            return json.load(f)
    except (OSError, ValueError):
        return None


def _outcome(code, err, report, timeout_s) -> dict:
    if code is None:
        return {"status": "timeout", "reason": f"no result within timeout_s = {timeout_s:g} s"}
    if report is None:
        return {"status": "refused" if code in (1, 2) else "error",
                "reason": _last_lines(err) or f"exit code {code} without a report"}
    status = report.get("status", "error")
    reason = report.get("reason", "") or ("" if code == 0 else _last_lines(err))
    return {"status": status, "reason": reason}


def _report_fields(report) -> dict:
    if not report:
        return {}
    sc, st, so = report.get("scene", {}), report.get("steps", {}), report.get("solver", {})
    row = {"nodes": sc.get("nodes"), "elements": sc.get("elements"), "dt_s": st.get("dt_s"),
           "steps": st.get("completed"), "simulated_time_s": st.get("simulated_time_s"),
           "recovered_steps": st.get("recovered"), "substeps": st.get("substeps"),
           "iterations_mean": so.get("iterations_mean"), "iterations_max": so.get("iterations_max")}
    probes = report.get("probes") or []
    if probes:
        row["probe_final_displacement_m"] = math.dist(probes[0]["final_m"], probes[0]["rest_m"])
    cav = report.get("cavities") or []
    if cav:
        row["ejection_fraction"] = cav[0].get("ejection_fraction")
    return row
