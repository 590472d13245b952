"""Bad sweep files get a clear error naming the key (exit status 2), through the real
`fiberfem sweep` command; a good file lists its configurations; a missing interpreter gets
a message saying how to make one."""

import os
import subprocess
import sys
import tempfile

from sweep_support import BIN, TINY, Tally

HEAD = "sweep: bad\nscene: {scene}\n"
GROUP = "groups:\n  - name: a\n    vary: {solver.dt: [0.01, 0.02]}\n"
# (file text after the head, text the message must contain)
CASES = [
    ("", "groups: is required"),
    ("groups: []\n", "groups: must be a non-empty list"),
    ("groups:\n  - vary: {solver.dt: [0.01]}\n", "groups[0].name"),
    ("groups:\n  - name: a\n    vary: {solver.dt: []}\n", "groups[0].vary.solver.dt: an empty list"),
    ("groups:\n  - name: a\n    vary: {solver.dt: {log: [0.01, 0.1]}}\n", "groups[0].vary.solver.dt.num"),
    ("groups:\n  - name: a\n    vary: {solver.dt: {log: [-1, 0.1], num: 3}}\n", "groups[0].vary.solver.dt.log"),
    ("groups:\n  - name: a\n    vary: {solver.dt: {uniform: [0.01, 0.1]}}\n", "groups[0].vary.solver.dt"),
    ("groups:\n  - name: a\n    sample: {count: 0}\n    vary: {solver.dt: {uniform: [0.01, 0.1]}}\n",
     "groups[0].sample.count"),
    ("groups:\n  - name: a\n    sample: {count: 3}\n    vary: {solver.dt: {normal: [0.01, 0.1]}}\n",
     "groups[0].vary.solver.dt.normal"),
    ("groups:\n  - name: a\n    combine: zip\n    vary: {solver.dt: [0.01, 0.02], solver.tolerance: [1.0e-6]}\n",
     "groups[0].vary: combine: zip"),
    (GROUP + "  - name: a\n", "groups[1].name: 'a' is used twice"),
    ("groups:\n  - name: a\n    colour: red\n", "groups[0].colour: unknown key"),
    (GROUP + "reference: {converged: true}\nerrors: [probe, speed]\n", "errors[1]: unknown error measure 'speed'"),
    (GROUP + "errors: [l2]\n", "reference: error measures need a reference"),
    ("groups:\n  - name: a\n    vary: {contraction.peak_tension: [1, 2]}\nreference: converged\n",
     "reference.finest.contraction.peak_tension: say which value"),
    (GROUP + "reference: {group: nope}\n", "reference.group: no group named 'nope'"),
    (GROUP + "reference: {group: a}\n", "reference.group: group 'a' has 2 configurations"),
    (GROUP + "reference: converged\ngoals: [{error: l2, max: -1}]\n", "goals[0].max: must be > 0"),
    (GROUP + "reference: converged\ngoals: [{error: pressure, max: 1}]\n", "goals[0].error"),
    (GROUP + "cost: money\n", "cost: must be one of"),
    (GROUP + "timeout_s: 0\n", "timeout_s: must be > 0"),
    (GROUP + "set: {solver.dt: null}\n", "set.solver.dt: needs a value"),
    (GROUP + "prepare: [{run: [], creates: m.msh}]\n", "prepare[0].run: must be a non-empty list"),
    (GROUP + "prepare: [{run: [python, make.py]}]\n", "prepare[0].creates"),
    (GROUP + "sample_s: fast\n", "sample_s: must be a finite number"),
    (GROUP + "groups2: 1\n", "groups2: unknown key"),
]


def run(path):
    return subprocess.run([BIN, "sweep", path, "--list"], capture_output=True, text=True, timeout=60)


def main():
    t = Tally()
    scene = os.path.join(os.path.dirname(TINY), "../../configs/scenes/cantilever-along.yaml")
    with tempfile.TemporaryDirectory() as d:
        for i, (body, expected) in enumerate(CASES):
            path = os.path.join(d, f"bad{i}.yaml")
            with open(path, "w") as f:
                f.write(HEAD.format(scene=os.path.abspath(scene)) + body)
            p = run(path)
            t.check(p.returncode == 2 and expected in p.stderr and path in p.stderr,
                    f"case {i}: expected exit 2 and '{expected}', got {p.returncode}: {p.stderr.strip()}")
        for text, expected in [("sweep: [unclosed\n", "not YAML"), ("- a\n- b\n", "must be a mapping"),
                               ("sweep: x\nscene: nowhere.yaml\ngroups: [{name: a}]\n", "scene: no scene file at")]:
            path = os.path.join(d, "other.yaml")
            with open(path, "w") as f:
                f.write(text)
            p = run(path)
            t.check(p.returncode == 2 and expected in p.stderr, f"'{expected}': {p.returncode} {p.stderr.strip()}")
        p = run(os.path.join(d, "missing.yaml"))
        t.check(p.returncode == 2 and "cannot read" in p.stderr, f"a missing file: {p.stderr.strip()}")
    # Seeded samples: the same seed draws the same configurations, another seed others, and
    # each value lies in its range (log-uniform between its ends).
    with tempfile.TemporaryDirectory() as d:
        lists = {}
        for seed in (1, 1, 2):
            path = os.path.join(d, f"sample{seed}.yaml")
            with open(path, "w") as f:
                f.write(HEAD.format(scene=os.path.abspath(scene)) + "groups:\n  - name: s\n"
                        f"    sample: {{count: 5, seed: {seed}}}\n"
                        "    vary: {solver.dt: {loguniform: [0.001, 0.1]}, solver.rotation: [svd, polar]}\n")
            p = run(path)
            lists.setdefault(seed, []).append(p.stdout)
            dts = [float(l.split("solver.dt=")[1].split()[0]) for l in p.stdout.splitlines()]
            t.check(p.returncode == 0 and len(dts) == 5 and all(0.001 <= x <= 0.1 for x in dts),
                    f"seed {seed}: 5 draws in range: {p.stdout}")
        t.check(lists[1][0] == lists[1][1] and lists[1][0] != lists[2][0], "seeded draws repeat, other seeds differ")
    good = run(TINY)
    t.check(good.returncode == 0 and good.stdout.count("\n") == 8 and "reference: " in good.stdout,
            f"the tiny sweep lists its reference and 7 configurations: {good.stdout}")
    t.check("--set solver.dt=0.025 --set solver.threads=1 --set mesh.cells=[20, 2, 2] --set solver.tolerance=1e-10"
            in good.stdout,
            "the converged reference: the finest step, the finest mesh, the tolerance set")
    env = dict(os.environ, FIBERFEM_PYTHON="/nonexistent/python")
    p = subprocess.run([BIN, "sweep", TINY, "--list"], capture_output=True, text=True, env=env)
    t.check(p.returncode == 1 and "no Python interpreter at /nonexistent/python" in p.stderr
            and "scripts/setup.sh" in p.stderr, f"a missing interpreter is named: {p.stderr.strip()}")
    return t.finish()


if __name__ == "__main__":
    sys.exit(main())
