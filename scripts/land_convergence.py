#!/usr/bin/env python3
"""Convergence of the accurate tier on Land et al. 2015's problems at full load.

Runs the shipped scenes configs/scenes/land-*-guccione.yaml at several refinements and
element orders with `fiberfem run --report` and prints a Markdown table: the probe values,
their error against the published consensus, unknowns, Newton iterations, factorisations
and wall time. docs/accurate-tier.md shows its output.

    scripts/land_convergence.py [--quick] [--fiberfem build/release/service/fiberfem]
"""
import argparse
import json
import os
import subprocess
import sys
import tempfile

# Published values (Land et al. 2015; REFERENCES.md, ACCURATE.md section 6): deformed z, mm.
REFERENCE = {
    "p1": {"end": 4.1688},
    "p2": {"apex_endo": -26.613, "apex_epi": -28.282},
    "p3": {"apex_endo": -12.4, "apex_epi": -15.5},
}
SCENES = {"p1": "land-beam-guccione.yaml", "p2": "land-ventricle-p2-guccione.yaml", "p3": "land-ventricle-p3-guccione.yaml"}
BEAM = ["[10, 1, 1]", "[20, 2, 2]", "[40, 4, 4]", "[80, 8, 8]"]
SHELL = ["{circumferential: 24, longitudinal: 10, transmural: 2}", "{circumferential: 36, longitudinal: 15, transmural: 3}",
         "{circumferential: 48, longitudinal: 20, transmural: 4}"]


def run(fiberfem, problem, overrides):
    with tempfile.TemporaryDirectory() as d:
        report = os.path.join(d, "r.json")
        args = [fiberfem, "run", os.path.join("configs/scenes", SCENES[problem]), "--report", report]
        for o in overrides:
            args += ["--set", o]
        out = subprocess.run(args, capture_output=True, text=True)
        if not os.path.exists(report):
            return None, out.stdout + out.stderr
        return json.load(open(report)), ""


def row(fiberfem, problem, level, order, overrides):
    r, err = run(fiberfem, problem, overrides + [f"mesh.order={order}"])
    if r is None or r["status"] != "completed":
        return f"| {problem} | {level} | {order} | failed: {(r or {}).get('reason', err)[:80]} | | | | | |"
    values, errors = [], []
    for probe, ref in REFERENCE[problem].items():
        z = next(p for p in r["probes"] if p["name"] == probe)["final_m"][2] * 1e3
        values.append(f"{z:.4f}")
        errors.append(f"{100 * (z - ref) / abs(ref):+.2f}%")
    s = r["static"]
    return (f"| {problem} | {level} | {order} | {' / '.join(values)} | {' / '.join(errors)} | {s['unknowns']} | "
            f"{s['newton_iterations']} | {s['factorisations']} | {r['timing']['wall_s']:.1f} |")


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--fiberfem", default="build/release/service/fiberfem")
    ap.add_argument("--quick", action="store_true", help="the two coarsest levels only")
    a = ap.parse_args()
    beam, shell = (BEAM[:2], SHELL[:1]) if a.quick else (BEAM, SHELL)
    print("| problem | mesh | order | z, mm | error | unknowns | Newton iterations | factorisations | wall s |")
    print("|---|---|---|---|---|---|---|---|---|")
    for order in (1, 2):
        for cells in beam:
            print(row(a.fiberfem, "p1", cells, order, [f"mesh.cells={cells}"]), flush=True)
    for problem in ("p2", "p3"):
        for order in (1, 2):
            for res in shell:
                print(row(a.fiberfem, problem, res, order, [f"mesh.resolution={res}"]), flush=True)


if __name__ == "__main__":
    sys.exit(main())
