#!/usr/bin/env python3
"""Plot a recorded fiberfem run: a probe's displacement and the cavity volumes over time.

    python docs/examples/plot_run.py RUN.h5 [--probe NAME] [--out PREFIX]

Reads the archive directly with h5py (docs/archive.md: /frames/time, /frames/probe_displacements,
/frames/cavity_volumes and their `names` attributes). Writes PREFIX.png with matplotlib when it
is installed, and always PREFIX.csv (time_s, the probe's x y z displacement in m, each cavity's
volume in mL). Works on a file that is still being written (opened as a SWMR reader).
"""
import argparse
import csv
import json
import sys

import h5py
import numpy as np


def load(path, probe=None):
    with h5py.File(path, "r", libver="latest", swmr=True) as f:
        if f.attrs.get("format") not in ("fiberfem-archive", b"fiberfem-archive"):
            sys.exit(f"{path}: not a fiberfem archive")
        n = min(f["frames/step"].shape[0], f["frames/time"].shape[0])  # complete frames
        t = f["frames/time"][:n]
        probes = json.loads(f["frames/probe_displacements"].attrs["names"])
        cavities = json.loads(f["frames/cavity_volumes"].attrs["names"])
        if probes:
            name = probe or probes[0]
            if name not in probes:
                sys.exit(f"{path}: no probe '{name}' (probes: {', '.join(probes)})")
            u = f["frames/probe_displacements"][:n, probes.index(name), :]
        else:
            name, u = None, np.zeros((n, 3))
        vols = f["frames/cavity_volumes"][:n, :] if cavities else np.zeros((n, 0))
    return t, name, u, cavities, vols


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("archive")
    ap.add_argument("--probe", help="probe name (default: the first)")
    ap.add_argument("--out", default="run", help="output prefix (PREFIX.csv, PREFIX.png)")
    a = ap.parse_args()
    t, name, u, cavities, vols = load(a.archive, a.probe)

    with open(a.out + ".csv", "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(["time_s"] + [f"{name}_u{c}_m" for c in "xyz"] * (name is not None) + [f"{c}_volume_ml" for c in cavities])
        for i in range(len(t)):
            row = [repr(float(t[i]))]
            if name is not None:
                row += [repr(float(v)) for v in u[i]]
            row += [repr(float(v) * 1e6) for v in vols[i]]
            w.writerow(row)
    print(f"wrote {a.out}.csv ({len(t)} frames)")

    try:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        print("matplotlib not installed: CSV only")
        return
    fig, axes = plt.subplots(2, 1, figsize=(7, 6), sharex=True)
    if name is not None:
        for c, lab in enumerate("xyz"):
            axes[0].plot(t, u[:, c] * 1e3, label=lab)
        axes[0].set_ylabel(f"{name} displacement (mm)")
        axes[0].legend()
    for k, c in enumerate(cavities):
        axes[1].plot(t, vols[:, k] * 1e6, label=c)
    axes[1].set_ylabel("cavity volume (mL)")
    axes[1].set_xlabel("time (s)")
    if cavities:
        axes[1].legend()
    fig.tight_layout()
    fig.savefig(a.out + ".png", dpi=100)
    print(f"wrote {a.out}.png")


if __name__ == "__main__":
    main()
