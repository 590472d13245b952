"""Error measures of a run against the reference run (from both archives and reports) and
its cost measures (from its report and the process's resource use); docs/sweeps.md.

Both runs are sampled every `sample_s` of simulated time, each interpolated linearly in
time between its recorded frames (so steps that do not divide the sample interval still
compare at the same instants). When the meshes differ, the reference's displacement is
interpolated linearly at the run's rest nodes, inside the reference element that holds
each node (or the nearest one, for nodes of a curved surface just outside it)."""

from __future__ import annotations

import math

import h5py
import numpy as np



class Trace:
    """What an archive recorded: frame times, rest nodes, tets, displacements, probe
    displacements and cavity volumes."""

    def __init__(self, path: str):
        with h5py.File(path, "r") as f:
            n = min(len(f["frames/step"]), len(f["frames/time"]), len(f["frames/positions"]))
            self.time = np.asarray(f["frames/time"][:n], dtype=np.float64)
            self.rest = np.asarray(f["mesh/rest_positions"][:], dtype=np.float64)
            self.tets = np.asarray(f["mesh/tets"][:], dtype=np.int64)
            self.u = np.asarray(f["frames/positions"][:n], dtype=np.float64) - self.rest[None]
            self.probes = np.asarray(f["frames/probe_displacements"][:n]) if "frames/probe_displacements" in f else None
            self.volumes = np.asarray(f["frames/cavity_volumes"][:n]) if "frames/cavity_volumes" in f else None

    def at(self, series, times):
        """`series` (frames first) interpolated linearly in time at `times`."""
        flat = series.reshape(len(self.time), -1)
        out = np.empty((len(times), flat.shape[1]))
        for c in range(flat.shape[1]):
            out[:, c] = np.interp(times, self.time, flat[:, c])
        return out.reshape((len(times),) + series.shape[1:])

    def u_at(self, times):
        idx = np.searchsorted(self.time, times, side="right") - 1
        idx = np.clip(idx, 0, len(self.time) - 2) if len(self.time) > 1 else np.zeros_like(idx)
        if len(self.time) == 1:
            return np.repeat(self.u[:1], len(times), axis=0)
        t0, t1 = self.time[idx], self.time[idx + 1]
        w = np.clip((times - t0) / np.where(t1 > t0, t1 - t0, 1.0), 0.0, 1.0)
        return self.u[idx] * (1 - w)[:, None, None] + self.u[idx + 1] * w[:, None, None]


def sample_times(run: Trace, ref: Trace, sample_s: float):
    end = min(run.time[-1], ref.time[-1])
    return np.arange(0, int(math.floor(end / sample_s + 1e-9)) + 1) * sample_s


def _barycentric(points, corners):
    """Barycentric weights of points (M, 3) in tets given by their corners (M, 4, 3)."""
    t = np.transpose(corners[:, 1:] - corners[:, :1], (0, 2, 1))
    lam = np.linalg.solve(t, (points - corners[:, 0])[..., None])[..., 0]
    return np.concatenate([1 - lam.sum(axis=1, keepdims=True), lam], axis=1)


def interpolation_weights(ref: Trace, points, candidates=16):
    """For each point, the reference tet that holds it (or nearest: the candidate whose
    smallest barycentric weight is largest) and its four weights."""
    from scipy.spatial import cKDTree

    centroids = ref.rest[ref.tets].mean(axis=1)
    k = min(candidates, len(ref.tets))
    _, cand = cKDTree(centroids).query(points, k=k)
    cand = cand.reshape(len(points), k)
    best_tet = np.empty(len(points), dtype=np.int64)
    best_w = np.empty((len(points), 4))
    best_min = np.full(len(points), -np.inf)
    for j in range(k):
        tets = cand[:, j]
        w = _barycentric(points, ref.rest[ref.tets[tets]])
        better = w.min(axis=1) > best_min
        best_tet[better], best_w[better], best_min[better] = tets[better], w[better], w.min(axis=1)[better]
    return ref.tets[best_tet], best_w


def reference_at_nodes(run: Trace, ref: Trace, u_ref):
    """Reference displacements (S, Nref, 3) at the run's rest nodes: (S, Nrun, 3)."""
    if run.rest.shape == ref.rest.shape and np.allclose(run.rest, ref.rest, rtol=0, atol=1e-12):
        return u_ref
    nodes, w = interpolation_weights(ref, run.rest)
    return np.einsum("snkc,nk->snc", u_ref[:, nodes], w)


def _last_beat_ef(report):
    cav = (report or {}).get("cavities") or []
    if not cav:
        return None
    beats = [b for b in cav[0].get("beats", []) if b.get("complete")]
    return (beats[-1] if beats else cav[0]).get("ejection_fraction")


# Need both runs' archives; the others ("ef", "settled", the circulation's) the reports only.
ARCHIVE_ERRORS = ("probe", "l2", "volume", "phase")


def _final_probe_displacement(report):
    probes = (report or {}).get("probes") or []
    if not probes:
        return None
    return np.asarray(probes[0]["final_m"], dtype=np.float64) - np.asarray(probes[0]["rest_m"], dtype=np.float64)


def _last_circulation_beat(report):
    """The left ventricle of the last complete beat of the report's circulation, or None."""
    beats = [b for b in ((report or {}).get("circulation") or {}).get("beats", []) if b.get("complete")]
    return beats[-1]["lv"] if beats else None


def _circulation_errors(run_report, ref_report, wanted) -> dict:
    """Relative errors (fractions of the reference's) of the LV's end-diastolic and
    end-systolic volumes, stroke volume and peak pressure in the last complete beat; the
    ejection fraction's in percentage points; pv_loop_err the largest of the four relative
    errors. NaN without a circulation."""
    lv, ref = _last_circulation_beat(run_report), _last_circulation_beat(ref_report)
    keys = {"edv_err": "end_diastolic_volume_m3", "esv_err": "end_systolic_volume_m3",
            "stroke_volume_err": "stroke_volume_m3", "peak_lv_pressure_err": "peak_pressure_pa"}
    if lv is None or ref is None:
        rel = {c: math.nan for c in keys}
        ef_pp = math.nan
    else:
        rel = {c: abs(lv[k] - ref[k]) / abs(ref[k]) if ref[k] else math.nan for c, k in keys.items()}
        ef_pp = 100.0 * (lv["ejection_fraction"] - ref["ejection_fraction"])
    out = {}
    if "pv_loop" in wanted:
        worst = math.nan if any(math.isnan(v) for v in rel.values()) else max(rel.values())
        out.update(pv_loop_err=worst, edv_err=rel["edv_err"], esv_err=rel["esv_err"], lv_ef_err_pp=ef_pp)
    if "stroke_volume" in wanted:
        out["stroke_volume_err"] = rel["stroke_volume_err"]
    if "peak_lv_pressure" in wanted:
        out["peak_lv_pressure_err"] = rel["peak_lv_pressure_err"]
    return out


def report_error_measures(run_report, ref_report, wanted) -> dict:
    """The error columns that come from the two reports alone ("ef", "settled", and the
    circulation's "pv_loop", "stroke_volume", "peak_lv_pressure")."""
    out = _circulation_errors(run_report, ref_report, wanted)
    if "ef" in wanted:
        ef, efr = _last_beat_ef(run_report), _last_beat_ef(ref_report)
        out["ef_err_pp"] = 100.0 * (ef - efr) if ef is not None and efr is not None else math.nan
        out["ef_err_abs_pp"] = abs(out["ef_err_pp"])
    if "settled" in wanted:
        u, ur = _final_probe_displacement(run_report), _final_probe_displacement(ref_report)
        if u is None or ur is None or not np.linalg.norm(ur) > 0:
            out["settled_err"] = out["settled_err_m"] = math.nan
        else:
            out["settled_err_m"] = float(np.linalg.norm(u - ur))
            out["settled_err"] = out["settled_err_m"] / float(np.linalg.norm(ur))
    return out


def error_measures(run_archive, run_report, ref_archive, ref_report, sample_s, wanted) -> dict:
    """The error columns of `wanted` measures (ERROR_MEASURES keys) of a run against the
    reference; NaN where the scene has no such quantity (no probe, no cavity). The archives
    may be None when no wanted measure needs them (ARCHIVE_ERRORS)."""
    out = report_error_measures(run_report, ref_report, wanted)
    if not any(e in ARCHIVE_ERRORS for e in wanted):
        return out
    run, ref = Trace(run_archive), Trace(ref_archive)
    times = sample_times(run, ref, sample_s)
    if "probe" in wanted:
        out.update(_probe_errors(run, ref, times))
    if "l2" in wanted:
        u, ur = run.u_at(times), reference_at_nodes(run, ref, ref.u_at(times))
        den = float(np.sum(ur ** 2))
        out["l2_err"] = math.sqrt(float(np.sum((u - ur) ** 2)) / den) if den > 0 else math.nan
    if "volume" in wanted:
        if run.volumes is not None and ref.volumes is not None and run.volumes.shape[1] and ref.volumes.shape[1]:
            v, vr = run.at(run.volumes[:, 0], times), ref.at(ref.volumes[:, 0], times)
            out["volume_err"] = float(np.max(np.abs(v - vr)) / ref.volumes[0, 0])
        else:
            out["volume_err"] = math.nan
    if "phase" in wanted:
        out["phase_err_ms"] = 1e3 * (_event_time(run, times, run_report) - _event_time(ref, times, ref_report))
        out["phase_err_abs_ms"] = abs(out["phase_err_ms"])
    return out


def _peak_time(times, s, k) -> float:
    """Time of the extremum at sample k, refined by the parabola through k-1, k, k+1."""
    if k <= 0 or k >= len(s) - 1:
        return float(times[k])
    den = s[k - 1] - 2 * s[k] + s[k + 1]
    shift = 0.5 * (s[k - 1] - s[k + 1]) / den if den != 0 else 0.0
    return float(times[k] + shift * (times[1] - times[0]))


def _event_time(trace: Trace, times, report) -> float:
    """With a cavity: the time of its least volume in the last beat (the report's
    contraction period); else the probe's first peak (the first local maximum of |u| above
    half its largest value). NaN when the scene has neither."""
    period = ((report or {}).get("contraction") or {}).get("period_s")
    if trace.volumes is not None and trace.volumes.shape[1] and period:
        v = trace.at(trace.volumes[:, 0], times)
        window = np.flatnonzero(times >= times[-1] - period - 1e-9)
        k = int(window[np.argmin(v[window])])
        return _peak_time(times, v, k)
    if trace.probes is None or not trace.probes.shape[1]:
        return math.nan
    s = np.linalg.norm(trace.at(trace.probes[:, 0], times), axis=1)
    for k in range(1, len(s) - 1):
        if s[k] >= 0.5 * s.max() and s[k] >= s[k - 1] and s[k] > s[k + 1]:
            return _peak_time(times, s, k)
    return math.nan


def _probe_errors(run: Trace, ref: Trace, times) -> dict:
    nan = {"probe_err": math.nan, "probe_err_m": math.nan, "final_err": math.nan}
    if run.probes is None or ref.probes is None or not run.probes.shape[1] or not ref.probes.shape[1]:
        return nan
    p, pr = run.at(run.probes[:, 0], times), ref.at(ref.probes[:, 0], times)
    dist = np.linalg.norm(p - pr, axis=1)
    scale = float(np.max(np.linalg.norm(pr, axis=1)))
    final_scale = float(np.linalg.norm(pr[-1]))
    return {
        "probe_err": float(dist.max()) / scale if scale > 0 else math.nan,
        "probe_err_m": float(dist.max()),
        "final_err": float(dist[-1]) / final_scale if final_scale > 0 else math.nan,
    }


def cost_measures(report: dict, peak_rss_kib: int) -> dict:
    steps, timing = report.get("steps", {}), report.get("timing", {})
    sim = steps.get("simulated_time_s") or 0.0
    return {
        "wall_s": timing.get("wall_s", math.nan),
        "engine_s": timing.get("engine_s", math.nan),
        "steps_per_s": timing.get("steps_per_s", math.nan),
        "median_step_s": timing.get("median_step_s", math.nan),
        "wall_s_per_sim_s": timing.get("wall_s", math.nan) / sim if sim > 0 else math.nan,
        "engine_s_per_sim_s": timing.get("engine_s", math.nan) / sim if sim > 0 else math.nan,
        "peak_rss_mb": peak_rss_kib / 1024.0,
    }
