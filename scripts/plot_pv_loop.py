#!/usr/bin/env python3
"""Pressure-volume loops from a run report (`fiberfem run --report FILE` of a scene with a
`circulation` key, docs/circulation.md) or from a run archive (`--archive RUN.h5`, its
`/frames/circulation`, docs/archive.md): each ventricle's pressure against its volume,
one curve per beat (the last ones darkest), in mL and mmHg.

Usage: plot_pv_loop.py REPORT.json|RUN.h5 OUT.png [--beats N]   (N: the last N beats, default all)
"""
import argparse
import json
import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

ML = 1e-6
MMHG = 133.322387415


def load_loops(report_path):
    with open(report_path, encoding="utf-8") as f:
        report = json.load(f)
    circ = report.get("circulation")
    if circ is None:
        raise SystemExit(f"{report_path}: no 'circulation' section (the scene has no circulation key)")
    steps = circ["steps"]
    period = circ["period_s"]
    t = steps["time_s"]
    beat_of = [max(0, int((ti - 1e-9) // period)) for ti in t]
    return circ, steps, beat_of


def load_archive_loops(h5_path):
    """The same from an archive: its per-frame columns, each frame's beat being the archive's
    last complete beat plus one (a beat closes at the first frame of the next), and the
    coupled ventricles from the archived scene."""
    import h5py
    import numpy as np
    import yaml

    with h5py.File(h5_path, "r", libver="latest", swmr=True) as f:
        if "frames/circulation" not in f:
            raise SystemExit(f"{h5_path}: no frames/circulation (the run had no circulation key)")
        n = min(f["frames/step"].shape[0], f["frames/circulation"].shape[0])
        names = json.loads(f["frames/circulation"].attrs["columns"])
        table = f["frames/circulation"][:n]
        scene = yaml.safe_load(bytes(f["scene/yaml"][()]).decode())
    steps = {name: table[:, i].tolist() for i, name in enumerate(names)}
    beat_of = [int(b) + 1 for b in np.asarray(steps["beat"])]
    coupled = {"left": "lv", "right": "rv"}
    ventricles = (scene.get("circulation") or {}).get("ventricles") or {}
    return {"coupled_cavities": [coupled[k] for k in ventricles if k in coupled]}, steps, beat_of


def plot(report_path, out_path, last_beats=None):
    archive = report_path.endswith((".h5", ".hdf5"))
    circ, steps, beat_of = load_archive_loops(report_path) if archive else load_loops(report_path)
    beats = sorted(set(beat_of))
    if last_beats:
        beats = beats[-last_beats:]
    fig, axes = plt.subplots(1, 2, figsize=(10, 4.2))
    for ax, side, title in ((axes[0], "lv", "left ventricle"), (axes[1], "rv", "right ventricle")):
        v = steps[f"{side}_volume_m3"]
        p = steps[f"{side}_pressure_pa"]
        for k, b in enumerate(beats):
            idx = [i for i, bi in enumerate(beat_of) if bi == b]
            shade = 0.25 + 0.75 * (k + 1) / len(beats)
            ax.plot([v[i] / ML for i in idx], [p[i] / MMHG for i in idx], color=(0.6 * (1 - shade), 0.1, shade),
                    lw=1.2, label=f"beat {b}")
        ax.set_xlabel("volume (mL)")
        ax.set_ylabel("pressure (mmHg)")
        ax.set_title(title + (" (coupled to the mesh)" if side in circ["coupled_cavities"] else " (lumped)"))
        ax.grid(alpha=0.3)
    axes[0].legend(fontsize=7, loc="upper right")
    fig.tight_layout()
    fig.savefig(out_path, dpi=110)
    print(f"plot_pv_loop: wrote {out_path} ({len(beats)} beats)")


def main(argv):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("report", help="a run report (JSON) or a run archive (.h5)")
    ap.add_argument("out")
    ap.add_argument("--beats", type=int, default=None)
    a = ap.parse_args(argv)
    plot(a.report, a.out, a.beats)


if __name__ == "__main__":
    main(sys.argv[1:])
