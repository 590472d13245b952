#!/usr/bin/env python3
"""The per-beat figures of a run with a circulation (`fiberfem run --report FILE`,
docs/report-format.md) as a Markdown table in mL and mmHg: each complete beat's LV
end-diastolic and end-systolic volume, stroke volume, ejection fraction, peak pressure, the
RV's stroke volume and peak pressure, the aortic systolic/diastolic pressure, how far the
RV's stroke volume is from the LV's, and the beat-to-beat change (the largest relative change
from the beat before of the LV's EDV, ESV, SV and peak pressure and the aortic pressures).
Volumes and pressures are the scene's (its `circulation.scale`, not undone). Also prints the
run's wall time per step (the report's timing over the steps it took).

Usage: circulation_beats_table.py REPORT.json
"""
import json
import sys

ML = 1e-6
MMHG = 133.322387415

# The figures whose change from the beat before is the beat-to-beat change.
TRACKED = (("lv", "end_diastolic_volume_m3"), ("lv", "end_systolic_volume_m3"), ("lv", "stroke_volume_m3"),
           ("lv", "peak_pressure_pa"), (None, "systemic_arterial_max_pa"), (None, "systemic_arterial_min_pa"))


def value(beat, side, key):
    return beat[side][key] if side else beat[key]


def change(beat, before):
    if before is None:
        return None
    return max(abs(value(beat, s, k) - value(before, s, k)) / abs(value(before, s, k)) for s, k in TRACKED)


def rows(beats):
    before = None
    for b in beats:
        if not b["complete"]:
            continue
        lv, rv = b["lv"], b["rv"]
        d = change(b, before)
        yield (f"| {b['beat']} | {lv['end_diastolic_volume_m3'] / ML:.2f} | {lv['end_systolic_volume_m3'] / ML:.2f} | "
               f"{lv['stroke_volume_m3'] / ML:.2f} | {lv['ejection_fraction']:.3f} | {lv['peak_pressure_pa'] / MMHG:.1f} | "
               f"{rv['stroke_volume_m3'] / ML:.2f} | {rv['peak_pressure_pa'] / MMHG:.1f} | "
               f"{b['systemic_arterial_max_pa'] / MMHG:.0f}/{b['systemic_arterial_min_pa'] / MMHG:.0f} | "
               f"{100 * (rv['stroke_volume_m3'] / lv['stroke_volume_m3'] - 1):+.1f} % | "
               + ("" if d is None else f"{100 * d:.2f} %") + " |")
        before = b


def main():
    if len(sys.argv) != 2:
        raise SystemExit(__doc__.strip().splitlines()[-1])
    with open(sys.argv[1], encoding="utf-8") as f:
        report = json.load(f)
    circ = report.get("circulation")
    if circ is None:
        raise SystemExit(f"{sys.argv[1]}: no 'circulation' section (the scene has no circulation key)")
    print("| beat | LV EDV (mL) | LV ESV (mL) | LV SV (mL) | LV EF | LV peak (mmHg) | RV SV (mL) | RV peak (mmHg) "
          "| aortic (mmHg) | RV SV - LV SV | beat-to-beat change |")
    print("|---|---|---|---|---|---|---|---|---|---|---|")
    for row in rows(circ["beats"]):
        print(row)
    steps = len(circ["steps"]["time_s"])  # the steps this run took (a resumed run: since its checkpoint)
    print(f"\n{steps} steps, wall time {report['timing']['wall_s']:.0f} s ({report['timing']['wall_s'] / steps:.2f} s a step); "
          f"blood volume {circ['blood_volume_m3'] / ML:.2f} mL, largest drift {circ['max_blood_volume_drift_m3'] / ML:.1e} mL")


if __name__ == "__main__":
    main()
