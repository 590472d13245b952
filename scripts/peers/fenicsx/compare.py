#!/usr/bin/env python3
"""Side-by-side timing of fiberfem's accurate tier and FEniCSx (dolfinx) on Land et al.
2015 problems 1 and 2: the same meshes, elements (P2/P1 Taylor-Hood tetrahedra), law and
quadrature, one process and one thread each. Each refinement runs both codes in turn,
`--repeats` times (alternating which goes first), and the table gives medians. Writes
OUT/results.json and OUT/table.md and prints the table. Documented in
docs/peer-comparison.md.

  scripts/peers/fenicsx/compare.py [--repeats 3] [--finest-repeats N] [--problems 1 2] [--cells 20 40 80]
      [--resolutions 24,10,2 32,14,3 48,20,4] [--apex-grading 1] [--out build/peer-compare]
"""
import argparse
import json
import math
import os
import shutil
import statistics
import subprocess
import sys
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
REPO = HERE.parents[2]

# Converged references (mm): problem 1 extrapolated from P2/P1 and Q2/Q1 refinements,
# problem 2 from curved Q2 hexahedra with 96k unknowns (both FEniCSx, see the doc).
PROBLEMS = {
    1: {"scene": "configs/scenes/land-beam-guccione.yaml", "script": "land_problem1.py", "load_steps": 2,
        "levels": [20, 40, 80], "reference": {"end": 4.1688}},
    2: {"scene": "configs/scenes/land-ventricle-p2-guccione.yaml", "script": "land_problem2.py", "load_steps": 10,
        "levels": [(24, 10, 2), (32, 14, 3), (48, 20, 4)],
        "reference": {"apex_endo": -26.613, "apex_epi": -28.282}},
}
TARGET_ERRORS = (0.005, 0.002, 0.001)


def one_thread_env(cache):
    env = dict(os.environ)
    env.update({"OMP_NUM_THREADS": "1", "OPENBLAS_NUM_THREADS": "1", "MKL_NUM_THREADS": "1",
                "XDG_CACHE_HOME": str(cache),
                "CYCLONEDDS_URI": f"file://{REPO}/configs/dds/loopback.xml"})
    return env


def level_name(problem, level):
    return f"{level} x {max(1, level // 10)} x {max(1, level // 10)} cells" if problem == 1 else \
        "resolution {} {} {}".format(*level)


def run_fiberfem(args, problem, level, out, env):
    spec = PROBLEMS[problem]
    if problem == 1:
        m = max(1, level // 10)
        override = f"mesh.cells=[{level},{m},{m}]"
    else:
        override = "mesh.resolution={{circumferential: {}, longitudinal: {}, transmural: {}}}".format(*level)
    report = out / "fiberfem.json"
    cmd = [str(args.fiberfem), "run", str(REPO / spec["scene"]), "--threads", "1", "--set", override,
           "--report", str(report)]
    if problem == 2:
        cmd += ["--set", f"mesh.apex_grading={args.apex_grading}"]
    t0 = time.perf_counter()
    subprocess.run(cmd, check=True, env=env, stdout=subprocess.DEVNULL, cwd=REPO)
    process = time.perf_counter() - t0
    r = json.loads(report.read_text())
    if not r["static"]["converged"]:
        raise RuntimeError(f"fiberfem did not converge: {cmd}")
    probes = {p["name"]: 1e3 * p["final_m"][2] for p in r["probes"]}
    return {"wall_s": r["timing"]["wall_s"], "process_s": process, "probes": probes,
            "unknowns": r["static"]["unknowns"], "newton_iterations": r["static"]["newton_iterations"],
            "load_steps": r["static"]["load_steps"]}


def run_fenicsx(args, problem, level, out, env):
    spec = PROBLEMS[problem]
    mesh_args = (["--cells", str(level)] if problem == 1
                 else ["--resolution", *map(str, level), "--apex-grading", str(args.apex_grading)])
    report = out / "fenicsx.json"
    cmd = [args.python, str(HERE / spec["script"]), *mesh_args, "--load-steps", str(spec["load_steps"]),
           "--report", str(report)]
    t0 = time.perf_counter()
    subprocess.run(cmd, check=True, env=env, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, cwd=HERE)
    process = time.perf_counter() - t0
    r = json.loads(report.read_text())
    if not r["converged"]:
        raise RuntimeError(f"FEniCSx did not converge: {cmd}")
    # The mesh is built outside the timed span: problem 2's is made by a numpy port of
    # fiberfem's generator, which is not FEniCSx's to answer for.
    return {"wall_s": r["timing"]["wall_s"] - r["timing"]["mesh_s"], "process_s": process,
            "probes": r["probes_z_mm"], "unknowns": r["free_unknowns"], "newton_iterations": r["newton_iterations"],
            "load_steps": r["load_steps"], "setup_s": r["timing"]["setup_s"], "mesh_s": r["timing"]["mesh_s"]}


def error(problem, probes):
    """Largest relative error of the probes against the converged reference."""
    ref = PROBLEMS[problem]["reference"]
    return max(abs(probes[k] - v) / abs(v) for k, v in ref.items())


def measure(args, problem, env, work):
    """Per level: the median of `repeats` alternated runs of each code."""
    rows = []
    spec = PROBLEMS[problem]
    # The first FEniCSx run of a problem compiles its forms (FFCx + C compiler) into an
    # empty cache; later runs load them. Timed separately, not in the table's medians.
    cold = run_fenicsx(args, problem, spec["levels"][0], work, env)
    for i, level in enumerate(spec["levels"]):
        runs = {"fiberfem": [], "fenicsx": []}
        repeats = args.finest_repeats if i == len(spec["levels"]) - 1 and args.finest_repeats else args.repeats
        for rep in range(repeats):
            order = ("fiberfem", "fenicsx") if rep % 2 == 0 else ("fenicsx", "fiberfem")
            for code in order:
                fn = run_fiberfem if code == "fiberfem" else run_fenicsx
                runs[code].append(fn(args, problem, level, work, env))
                print(f"problem {problem}, {level_name(problem, level)}, {code}: "
                      f"{runs[code][-1]['wall_s']:.2f} s", file=sys.stderr, flush=True)
        row = {"level": level_name(problem, level)}
        for code, rs in runs.items():
            row[code] = dict(rs[-1])
            row[code]["wall_s"] = statistics.median(r["wall_s"] for r in rs)
            row[code]["process_s"] = statistics.median(r["process_s"] for r in rs)
            row[code]["all_wall_s"] = [r["wall_s"] for r in rs]
            row[code]["error"] = error(problem, row[code]["probes"])
        rows.append(row)
    return {"rows": rows, "cold_fenicsx_setup_s": cold["setup_s"],
            "warm_fenicsx_setup_s": rows[0]["fenicsx"]["setup_s"]}


def time_at_error(rows, code, target):
    """Time at `target` error on the log-log line between the two levels that bracket it;
    None outside the measured range."""
    pts = sorted((r[code]["error"], r[code]["wall_s"]) for r in rows)
    for (e0, t0), (e1, t1) in zip(pts, pts[1:]):
        if e0 <= target <= e1 and e0 < e1:
            f = (math.log(target) - math.log(e0)) / (math.log(e1) - math.log(e0))
            return math.exp(math.log(t0) + f * (math.log(t1) - math.log(t0)))
    return None


def table(problem, result):
    ref = PROBLEMS[problem]["reference"]
    names = list(ref)
    lines = [f"### Problem {problem}", "",
             "| mesh | free unknowns | " + " | ".join(f"{n} z, fiberfem / FEniCSx (mm)" for n in names) +
             " | error, fiberfem / FEniCSx | Newton iterations, fiberfem / FEniCSx | time fiberfem (s) | "
             "time FEniCSx (s) | FEniCSx / fiberfem |",
             "|---|---|" + "---|" * len(names) + "---|---|---|---|---|"]
    for r in result["rows"]:
        a, b = r["fiberfem"], r["fenicsx"]
        probes = " | ".join(f"{a['probes'][n]:.4f} / {b['probes'][n]:.4f}" for n in names)
        lines.append(f"| {r['level']} | {a['unknowns']} / {b['unknowns']} | {probes} | "
                     f"{100 * a['error']:.3f}% / {100 * b['error']:.3f}% | "
                     f"{a['newton_iterations']} / {b['newton_iterations']} | {a['wall_s']:.2f} | "
                     f"{b['wall_s']:.2f} | {b['wall_s'] / a['wall_s']:.2f} |")
    lines += ["", "| error | time fiberfem (s) | time FEniCSx (s) | FEniCSx / fiberfem |", "|---|---|---|---|"]
    for target in TARGET_ERRORS:
        ta, tb = time_at_error(result["rows"], "fiberfem", target), time_at_error(result["rows"], "fenicsx", target)
        if ta is None or tb is None:
            lines.append(f"| {100 * target:.1f}% | outside the measured range | | |")
        else:
            lines.append(f"| {100 * target:.1f}% | {ta:.2f} | {tb:.2f} | {tb / ta:.2f} |")
    lines += ["", f"FEniCSx form compilation (first run, empty cache): {result['cold_fenicsx_setup_s']:.1f} s "
              f"of setup, against {result['warm_fenicsx_setup_s']:.2f} s from the cache.", ""]
    return "\n".join(lines)


def versions(args):
    """One line naming what ran: date, cores, the fiberfem commit, FEniCSx's parts."""
    commit = subprocess.run(["git", "-C", str(REPO), "rev-parse", "--short", "HEAD"], capture_output=True,
                            text=True).stdout.strip()
    peer = subprocess.run([args.python, "-c", "import dolfinx, ufl, ffcx, basix; from petsc4py import PETSc; "
                           "print(f'dolfinx {dolfinx.__version__}, UFL {ufl.__version__}, FFCx {ffcx.__version__}, "
                           "basix {basix.__version__}, PETSc ' + '.'.join(map(str, PETSc.Sys.getVersion())))"],
                          capture_output=True, text=True).stdout.strip()
    return (f"{time.strftime('%Y-%m-%d', time.gmtime())}, {os.cpu_count()} cores; fiberfem {commit}; {peer}; "
            f"one process and one thread each; medians of {args.repeats} alternated runs per refinement"
            + (f" ({args.finest_repeats} on the finest)" if args.finest_repeats else "") + ".\n")


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=3, help="runs of each code per refinement (default 3)")
    ap.add_argument("--finest-repeats", type=int, help="runs of each code on the finest refinement "
                                                          "(default: --repeats)")
    ap.add_argument("--problems", type=int, nargs="+", default=[1, 2], choices=[1, 2])
    ap.add_argument("--out", type=Path, default=REPO / "build" / "peer-compare", help="working directory")
    ap.add_argument("--fiberfem", type=Path, default=REPO / "build" / "release" / "service" / "fiberfem")
    ap.add_argument("--python", default="/usr/bin/python3", help="the Python that imports dolfinx")
    ap.add_argument("--cells", type=int, nargs="+", help="problem 1 refinements: cells along the beam "
                                                          "(default 20 40 80)")
    ap.add_argument("--apex-grading", type=float, default=1.0,
                    help="problem 2: mesh.apex_grading of both codes' meshes (default 1: evenly spaced rings)")
    ap.add_argument("--resolutions", nargs="+", help="problem 2 refinements as C,L,T (default 24,10,2 "
                                                     "32,14,3 48,20,4)")
    args = ap.parse_args()
    if args.cells:
        PROBLEMS[1]["levels"] = args.cells
    if args.resolutions:
        PROBLEMS[2]["levels"] = [tuple(int(v) for v in r.split(",")) for r in args.resolutions]
    args.out, args.fiberfem = args.out.resolve(), args.fiberfem.resolve()
    args.out.mkdir(parents=True, exist_ok=True)
    cache = args.out / "ffcx-cache"
    shutil.rmtree(cache, ignore_errors=True)
    env = one_thread_env(cache)
    results, text = {}, [versions(args)]
    for problem in args.problems:
        results[problem] = measure(args, problem, env, args.out)
        text.append(table(problem, results[problem]))
        (args.out / "results.json").write_text(json.dumps(results, indent=1))
        (args.out / "table.md").write_text("\n".join(text))
    print("\n".join(text))


if __name__ == "__main__":
    main()
