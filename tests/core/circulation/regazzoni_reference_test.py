"""The lumped circulation (core/circulation) against the PyPI package `circulation`
(ComputationalPhysiology), an independent implementation of Regazzoni et al.'s model, with
the same parameters and initial state: after five beats the two agree on the left
ventricle's volumes and pressures and the aortic pressures (both with small steps: our
backward Euler at 0.25 ms, the package's forward Euler at 0.1 ms).

Usage: regazzoni_reference_test.py PATH/TO/circulation_trajectory
"""
import csv
import io
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np
from circulation.regazzoni2020 import Regazzoni2020

BEATS = 5


def paper_parameters():
    p = Regazzoni2020.default_parameters()
    from circulation.base import remove_units

    p = remove_units(p)
    p["HR"] = 75.0 / 60.0
    ch = p["chambers"]
    ch["LA"].update(EA=0.07, EB=0.09, TC=0.17, TR=0.17, tC=0.8, V0=4.0)
    ch["LV"].update(EA=2.75, EB=0.08, TC=0.34, TR=0.17, tC=0.0, V0=5.0)
    ch["RA"].update(EA=0.06, EB=0.07, TC=0.17, TR=0.17, tC=0.8, V0=4.0)
    ch["RV"].update(EA=0.55, EB=0.05, TC=0.34, TR=0.17, tC=0.0, V0=10.0)
    for v in p["valves"].values():
        v.update(Rmin=0.0075, Rmax=75006.2)
    p["circulation"]["SYS"].update(R_AR=0.8, C_AR=1.2, R_VEN=0.26, C_VEN=60.0, L_AR=5e-3, L_VEN=5e-4)
    p["circulation"]["PUL"].update(R_AR=0.1625, C_AR=10.0, R_VEN=0.1625, C_VEN=16.0, L_AR=5e-4, L_VEN=5e-4)
    return p


def initial_state():
    return dict(V_LA=65.0, V_LV=120.0, V_RA=65.0, V_RV=145.0, p_AR_SYS=80.0, p_VEN_SYS=30.0,
                p_AR_PUL=35.0, p_VEN_PUL=24.0, Q_AR_SYS=0.0, Q_VEN_SYS=0.0, Q_AR_PUL=0.0, Q_VEN_PUL=0.0)


def last_beat(t, period, *series):
    sel = t > (BEATS - 1) * period + 1e-9
    return [np.asarray(s)[sel] for s in series]


def main():
    exe = sys.argv[1]
    out = subprocess.run([exe, "0.00025", str(BEATS)], check=True, capture_output=True, text=True).stdout
    rows = list(csv.DictReader(io.StringIO(out)))
    ours = {k: np.array([float(r[k]) for r in rows]) for k in rows[0]}
    total = ours["total"]
    assert np.max(np.abs(total - total[0])) < 1e-9 * total[0], "blood volume not conserved"

    with tempfile.TemporaryDirectory() as out:  # the package writes its parameters there
        model = Regazzoni2020(parameters=paper_parameters(), initial_state=initial_state(), verbose=False,
                              outdir=Path(out))
        hist = model.solve(num_beats=BEATS, dt=1e-4, dt_eval=1e-3)
    period = 0.8
    ref_t = np.asarray(model.times_eval)[: len(hist["V_LV"])]
    ref = {k: np.asarray(hist[k]) for k in ("V_LV", "p_LV", "p_AR_SYS", "V_RV", "p_AR_PUL")}

    (o_t, o_vlv, o_plv, o_pao, o_vrv, o_ppa) = last_beat(ours["t"], period, ours["t"], ours["V_LV"], ours["p_LV"],
                                                        ours["p_AR_SYS"], ours["V_RV"], ours["p_AR_PUL"])
    (r_vlv, r_plv, r_pao, r_vrv, r_ppa) = last_beat(ref_t, period, ref["V_LV"], ref["p_LV"], ref["p_AR_SYS"],
                                                    ref["V_RV"], ref["p_AR_PUL"])
    checks = [
        ("LV end-diastolic volume, mL", o_vlv.max(), r_vlv.max(), 0.002),
        ("LV end-systolic volume, mL", o_vlv.min(), r_vlv.min(), 0.002),
        ("LV peak pressure, mmHg", o_plv.max(), r_plv.max(), 0.002),
        ("aortic systolic pressure, mmHg", o_pao.max(), r_pao.max(), 0.002),
        ("aortic diastolic pressure, mmHg", o_pao.min(), r_pao.min(), 0.002),
        ("RV end-diastolic volume, mL", o_vrv.max(), r_vrv.max(), 0.002),
        ("pulmonary arterial systolic pressure, mmHg", o_ppa.max(), r_ppa.max(), 0.002),
    ]
    failed = False
    for name, a, b, tol in checks:
        rel = abs(a - b) / abs(b)
        print(f"{name}: fiberfem {a:.3f}, circulation package {b:.3f}, relative difference {rel:.4f} (allowed {tol})")
        failed |= rel > tol
    sys.exit(1 if failed else 0)


if __name__ == "__main__":
    main()
