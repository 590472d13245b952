#!/usr/bin/env python3
"""The archive in the tools users open it with, against independent sources.

    interop_test.py MODE FIBERFEM_BIN SOURCE_DIR      MODE: h5py | meshio | paraview | example

Each mode records the default heart for a few steps with the real binary (with a JSON run
report), then checks:
  h5py     the archive read directly: layout, units, steps; each probe's displacement
           interpolated from the float32 positions agrees with the run report's (computed by
           the engine in double) to float32 round-off, and the recorded probe column equals it
  meshio   `fiberfem archive export-meshio`: meshio's TimeSeriesReader sees every step, the
           mesh and a displaced position equal to the archive's
  paraview the sidecar in pvpython (ParaView's default Xdmf3 reader): time steps, points,
           cells, a displaced position and displacement equal to the archive's
  example  docs/examples/plot_run.py writes the probe and cavity series of the archive
"""
import csv
import json
import os
import shutil
import subprocess
import sys
import tempfile

import h5py
import numpy as np

STEPS = 30


def fail(msg):
    print("FAIL:", msg)
    sys.exit(1)


def check(cond, msg):
    if not cond:
        fail(msg)


def record(binary, source, work, extra=()):
    scene = os.path.join(source, "configs", "scenes", "heart.yaml")
    run = os.path.join(work, "run.h5")
    report = os.path.join(work, "report.json")
    p = subprocess.run([binary, "run", scene, "--steps", str(STEPS), "--archive", run, "--report", report, *extra],
                       capture_output=True, text=True)
    check(p.returncode == 0, f"fiberfem run failed: {p.stdout}{p.stderr}")
    with open(report) as f:
        return run, json.load(f)


def mode_h5py(binary, source, work):
    run, rep = record(binary, source, work)
    with h5py.File(run, "r") as f:
        check(f.attrs["format"] in (b"fiberfem-archive", "fiberfem-archive"), "format attribute")
        check(int(f.attrs["format_version"]) == 1, "format_version")
        check(f.attrs["length_unit"] in (b"m", "m"), "length unit")
        x = f["frames/positions"]
        rest = f["mesh/rest_positions"][:]
        tets = f["mesh/tets"][:]
        check(x.dtype == np.float32 and x.shape == (STEPS + 1, rep["scene"]["nodes"], 3), f"positions {x.dtype} {x.shape}")
        check(tets.shape == (rep["scene"]["elements"], 4), "tets shape")
        check(list(f["frames/step"][:]) == list(range(STEPS + 1)), "steps 0..N")
        check(f["frames/positions"].attrs["unit"] in (b"m", "m"), "positions unit")
        check(f["frames/activation"].shape == (STEPS + 1, tets.shape[0]), "activation shape")
        check(f["scene"].attrs["sha256"].decode() == rep["scene"]["sha256"], "scene hash equals the report's")
        yaml_text = bytes(f["scene/yaml"][:]).decode()
        check("contraction" in yaml_text, "scene YAML text")
        names = json.loads(f["scene/probes"].attrs["names"])
        elem = f["scene/probes/element"][:]
        w = f["scene/probes/weights"][:]
        last = x[-1].astype(np.float64)
        for k, p in enumerate(rep["probes"]):
            check(names[k] == p["name"], "probe names")
            nodes = tets[elem[k]]
            u = sum(w[k, a] * (last[nodes[a]] - rest[nodes[a]]) for a in range(4))
            ref = np.array(p["displacement_m"])
            err = np.abs(u - ref).max()
            # float32 positions of ~0.05 m: round-off about 4e-9 m per coordinate
            check(err < 2e-8, f"probe {p['name']}: interpolated {u} vs report {ref} (error {err:.3g} m)")
            rec = f["frames/probe_displacements"][-1, k, :]
            check(np.array_equal(rec, ref), f"recorded probe column {rec} != report {ref}")
        d = f["frames/displacement"][-1].astype(np.float64)
        check(np.abs(d - (last - rest)).max() < 1e-8, "displacement = positions - rest")
        cps = f["checkpoints/step"][:]
        check(cps[0] == 0 and cps[-1] == STEPS, f"checkpoints at steps {cps}")
    print(f"h5py: {STEPS + 1} frames, probes agree with the run report")


def mode_meshio(binary, source, work):
    import meshio

    run, _ = record(binary, source, work)
    out = os.path.join(work, "export.xdmf")
    p = subprocess.run([binary, "archive", "export-meshio", run, out], capture_output=True, text=True)
    check(p.returncode == 0, p.stdout + p.stderr)
    with h5py.File(run, "r") as f:
        rest = f["mesh/rest_positions"][:]
        tets = f["mesh/tets"][:]
        x = f["frames/positions"][:]
        t = f["frames/time"][:]
        act = f["frames/activation"][:]
    with meshio.xdmf.TimeSeriesReader(out) as r:
        points, cells = r.read_points_cells()
        check(r.num_steps == STEPS + 1, f"meshio sees {r.num_steps} steps")
        check(np.array_equal(points, rest), "meshio points are the rest positions")
        check(cells[0].type == "tetra" and np.array_equal(cells[0].data, tets), "meshio cells are the tets")
        for k in (0, STEPS // 2, STEPS):
            tk, pd, cd = r.read_data(k)
            check(tk == t[k], f"time of step {k}")
            check(np.array_equal(pd["positions"], x[k].astype(np.float64)), f"positions of step {k}")
            check(np.abs(pd["displacement"] - (x[k] - rest)).max() < 1e-12, f"displacement of step {k}")
            check(np.array_equal(cd["activation"][0], act[k].astype(np.float64)), f"activation of step {k}")
    print(f"meshio: {STEPS + 1} steps, points, cells and positions equal the archive's")


def mode_paraview(binary, source, work):
    pvpython = shutil.which("pvpython")
    check(pvpython is not None, "pvpython not found (Debian python3-paraview, scripts/setup.sh)")
    run, _ = record(binary, source, work)
    xdmf = os.path.join(work, "run.xdmf")
    frame, node = 20, 700
    probe = os.path.join(os.path.dirname(os.path.abspath(__file__)), "paraview_probe.py")
    p = subprocess.run([pvpython, "--force-offscreen-rendering", probe, xdmf, str(frame), str(node)], capture_output=True,
                       text=True, timeout=240)
    lines = [l for l in p.stdout.splitlines() if l.startswith("{")]
    check(p.returncode == 0 and lines, f"pvpython failed: {p.stdout[-2000:]}{p.stderr[-2000:]}")
    seen = json.loads(lines[-1])
    with h5py.File(run, "r") as f:
        x = f["frames/positions"][:]
        rest = f["mesh/rest_positions"][:]
        t = f["frames/time"][:]
        act = f["frames/activation"][frame]
        ne = f["mesh/tets"].shape[0]
    check(len(seen["times"]) == STEPS + 1, f"ParaView sees {len(seen['times'])} time steps")
    check(np.allclose(seen["times"], t, rtol=0, atol=1e-12), "time values")
    check(seen["points"] == x.shape[1] and seen["cells"] == ne, f"points {seen['points']} cells {seen['cells']}")
    check(seen["cell_type"] == 10, "VTK_TETRA cells")
    check(np.array_equal(np.array(seen["position"], dtype=np.float32), x[frame, node]),
          f"position {seen['position']} vs archive {x[frame, node]}")
    moved = np.abs(x[frame, node] - rest[node]).max()
    check(moved > 1e-6, f"node {node} should have moved at frame {frame} ({moved})")
    check(np.abs(np.array(seen["displacement"]) - (x[frame, node] - rest[node])).max() < 1e-8, "displacement")
    check(abs(seen["activation_range"][1] - float(act.max())) < 1e-3, "activation range")
    check(seen["region_range"] == [0.0, 0.0], "region")
    print(f"paraview ({seen['reader']}): {len(seen['times'])} steps, {seen['points']} points, {seen['cells']} cells")


def mode_example(binary, source, work):
    run, rep = record(binary, source, work)
    script = os.path.join(source, "docs", "examples", "plot_run.py")
    prefix = os.path.join(work, "plot")
    p = subprocess.run([sys.executable, script, run, "--out", prefix], capture_output=True, text=True)
    check(p.returncode == 0, p.stdout + p.stderr)
    with open(prefix + ".csv") as f:
        rows = list(csv.DictReader(f))
    check(len(rows) == STEPS + 1, f"{len(rows)} rows")
    name = rep["probes"][0]["name"]
    last = [float(rows[-1][f"{name}_u{c}_m"]) for c in "xyz"]
    check(last == rep["probes"][0]["displacement_m"], f"probe {last} vs report {rep['probes'][0]['displacement_m']}")
    check(float(rows[0]["lv_volume_ml"]) > 10 and float(rows[-1]["lv_volume_ml"]) < float(rows[0]["lv_volume_ml"]),
          "the LV volume shrinks as the heart contracts")
    if "wrote" in p.stdout and os.path.exists(prefix + ".png"):
        check(os.path.getsize(prefix + ".png") > 1000, "png")
    print("example: plot_run.py wrote the probe and cavity series")


def main():
    mode, binary, source = sys.argv[1:4]
    os.environ["OMP_NUM_THREADS"] = "1"
    with tempfile.TemporaryDirectory(prefix="fiberfem-interop-") as work:
        {"h5py": mode_h5py, "meshio": mode_meshio, "paraview": mode_paraview, "example": mode_example}[mode](binary, source, work)


if __name__ == "__main__":
    main()
