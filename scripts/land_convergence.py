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
    "p3": {"apex_endo": -12.35, "apex_epi": -15.45},
}
SCENES = {"p1": "land-beam-guccione.yaml", "p2": "land-ventricle-p2-guccione.yaml", "p3": "land-ventricle-p3-guccione.yaml"}
BEAM = ["[10, 1, 1]", "[20, 2, 2]", "[40, 4, 4]", "[80, 8, 8]"]
SHELL = ["{circumferential: 24, longitudinal: 10, transmural: 2}", "{circumferential: 36, longitudinal: 15, transmural: 3}",
         "{circumferential: 48, longitudinal: 20, transmural: 4}"]
# Problem 3's scene grades its rings towards the apex (mesh.apex_grading 1.5) and needs six
# layers through the wall; its shipped mesh is 24 / 10 / 6.
SHELL_P3 = ["{circumferential: 24, longitudinal: 10, transmural: 3}", "{circumferential: 24, longitudinal: 10, transmural: 6}",
            "{circumferential: 36, longitudinal: 15, transmural: 6}", "{circumferential: 48, longitudinal: 20, transmural: 6}"]


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


# The element and incompressibility forms compared: Taylor-Hood P2/P1 (the benchmark's exact
# incompressibility), and the volumetric penalty at two bulk moduli (the default, 100 times
# the law's small-strain shear modulus, and ten times that) on both orders.
def models(quick):
    m = [("P2/P1 mixed", 2, [])]
    for factor in ([100] if quick else [100, 1000]):
        for order in (1, 2):
            m.append((f"P{order} penalty {factor}G", order, ["regions[0].material.incompressible=false", f"@bulk {factor}"]))
    return m


def shear(problem):
    # Small-strain shear modulus of the scene's law (io/scene_laws.cpp): C b_t / 2.
    return {"p1": 2000 * 2 / 2, "p2": 10000 * 1 / 2, "p3": 2000 * 2 / 2}[problem]


def row(fiberfem, problem, level, model, overrides):
    label, order, extra = model
    sets = [o for o in extra if not o.startswith("@bulk")]
    for o in extra:
        if o.startswith("@bulk"):
            sets.append(f"regions[0].material.bulk_modulus={float(o.split()[1]) * shear(problem)}")
    r, err = run(fiberfem, problem, overrides + [f"mesh.order={order}"] + sets)
    if r is None or r["status"] != "completed":
        reason = (r or {}).get("reason", err).split(";")[0][:70]
        return f"| {problem} | {level} | {label} | failed: {reason} | | | | | |"

    values, errors = [], []
    for probe, ref in REFERENCE[problem].items():
        z = next(p for p in r["probes"] if p["name"] == probe)["final_m"][2] * 1e3
        values.append(f"{z:.4f}")
        errors.append(f"{100 * (z - ref) / abs(ref):+.2f}%")
    s = r["static"]
    return (f"| {problem} | {level} | {label} | {' / '.join(values)} | {' / '.join(errors)} | {s['unknowns']} | "
            f"{s['newton_iterations']} | {s['factorisations']} | {r['timing']['wall_s']:.1f} |")


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--fiberfem", default="build/release/service/fiberfem")
    ap.add_argument("--quick", action="store_true", help="the two coarsest levels only")
    a = ap.parse_args()
    beam, shell = (BEAM[:2], SHELL[:1]) if a.quick else (BEAM, SHELL)
    print("| problem | mesh | elements | z, mm | error | unknowns | Newton iterations | factorisations | wall s |")
    print("|---|---|---|---|---|---|---|---|---|")
    for model in models(a.quick):
        for cells in beam:
            print(row(a.fiberfem, "p1", cells, model, [f"mesh.cells={cells}"]), flush=True)
    for problem in ("p2", "p3"):
        for model in models(a.quick):
            levels = shell if problem == "p2" or a.quick else SHELL_P3
            if problem == "p3" and model[0] != "P2/P1 mixed":
                levels = levels[:2]  # the penalty forms on problem 3's two coarsest levels only
            for res in levels:
                print(row(a.fiberfem, problem, res, model, [f"mesh.resolution={res}"]), flush=True)


if __name__ == "__main__":
    sys.exit(main())
