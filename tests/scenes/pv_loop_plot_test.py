"""scripts/plot_pv_loop.py on a real run: `fiberfem run` of the circulation heart for two
beats writes a report and an archive; the script draws the loops of either into a PNG of
the expected size with both panels drawn (coloured pixels in each half), and refuses a
report without a circulation. The archive's per-frame circulation (read with h5py) equals
the report's per-step columns at the same step, and `fiberfem archive export-circulation`
writes the same numbers as CSV, on either tier; an archive without a circulation has no such dataset and
both tools refuse it by name.

Usage: pv_loop_plot_test.py PATH/TO/fiberfem SOURCE_DIR
"""
import csv
import json
import os
import subprocess
import sys
import tempfile

import h5py
import matplotlib.image as mpimg
import numpy as np


def check_drawn(png):
    img = mpimg.imread(png)
    assert img.shape[0] > 300 and img.shape[1] > 800, img.shape
    rgb = img[..., :3]
    coloured = (np.abs(rgb[..., 0] - rgb[..., 2]) > 0.2)  # the loops' red-blue lines
    half = img.shape[1] // 2
    left, right = coloured[:, :half].sum(), coloured[:, half:].sum()
    assert left > 200 and right > 200, (left, right)


def check_archive(fiberfem, archive, report, d):
    steps = report["circulation"]["steps"]
    with h5py.File(archive, "r") as f:
        n = f["frames/step"].shape[0]
        step = f["frames/step"][:n]
        names = json.loads(f["frames/circulation"].attrs["columns"])
        table = f["frames/circulation"][:n]
    assert list(step) == list(range(n)) and n == len(steps["time_s"]) + 1, (n, len(steps["time_s"]))
    for name, column in steps.items():  # frame k is the state after step k; the report's row k - 1
        assert np.array_equal(table[1:, names.index(name)], np.asarray(column)), name
    out = os.path.join(d, "c.csv")
    subprocess.run([fiberfem, "archive", "export-circulation", archive, out], check=True, capture_output=True)
    with open(out, newline="", encoding="utf-8") as f:
        rows = list(csv.reader(f))
    assert rows[0] == ["step"] + names, rows[0]
    assert np.array_equal(np.asarray(rows[1:], dtype=float), np.column_stack([step, table]))


def main():
    fiberfem, src = sys.argv[1], sys.argv[2]
    scene = os.path.join(src, "configs/scenes/heart-circulation-realtime.yaml")
    script = os.path.join(src, "scripts/plot_pv_loop.py")
    with tempfile.TemporaryDirectory() as d:
        report, archive = os.path.join(d, "r.json"), os.path.join(d, "a.h5")
        subprocess.run([fiberfem, "run", scene, "--until", "1.6667", "--set", "solver.threads=1", "--report", report,
                        "--archive", archive], check=True, capture_output=True)
        png = os.path.join(d, "pv.png")
        subprocess.run([sys.executable, script, report, png], check=True)
        check_drawn(png)
        from_archive = os.path.join(d, "pv-archive.png")
        subprocess.run([sys.executable, script, archive, from_archive], check=True)
        check_drawn(from_archive)
        with open(report, encoding="utf-8") as f:
            check_archive(fiberfem, archive, json.load(f), d)
        # A report without a circulation section: a clear error, no image.
        with open(report, encoding="utf-8") as f:
            r = json.load(f)
        del r["circulation"]
        bare = os.path.join(d, "bare.json")
        with open(bare, "w", encoding="utf-8") as f:
            json.dump(r, f)
        res = subprocess.run([sys.executable, script, bare, os.path.join(d, "x.png")], capture_output=True, text=True)
        assert res.returncode != 0 and "no 'circulation' section" in (res.stderr + res.stdout), res
        assert not os.path.exists(os.path.join(d, "x.png"))
        # The accurate tier (lv-beat.yaml's cavity as the LV, a neo-Hookean law, small
        # strain): its archive carries the circulation as the real-time tier's does.
        acc_report, acc_archive = os.path.join(d, "acc.json"), os.path.join(d, "acc.h5")
        subprocess.run([fiberfem, "run", os.path.join(src, "configs/scenes/lv-beat.yaml"), "--set", "mesh.refine=0.5",
                        "--set", "solver.until=0.2", "--set", "contraction.peak_tension=500.0", "--set",
                        "regions[0].material={law: neo_hookean, E: 40000.0, nu: 0.3, density: 1060.0}", "--set",
                        "circulation={ventricles: {left: lv}, scale: {pressure: 0.00125, volume: 0.015}}",
                        "--report", acc_report, "--archive", acc_archive], check=True, capture_output=True)
        with open(acc_report, encoding="utf-8") as f:
            acc = json.load(f)
        assert acc["dynamic"]["tier"] == "accurate", acc["dynamic"]
        check_archive(fiberfem, acc_archive, acc, d)
        # An archive of a run without a circulation: no /frames/circulation, clear errors.
        plain = os.path.join(d, "plain.h5")
        subprocess.run([fiberfem, "run", os.path.join(src, "configs/scenes/heart.yaml"), "--until", "0.05", "--archive", plain],
                       check=True, capture_output=True)
        with h5py.File(plain, "r") as f:
            assert "frames/circulation" not in f
        res = subprocess.run([fiberfem, "archive", "export-circulation", plain, os.path.join(d, "x.csv")], capture_output=True,
                             text=True)
        assert res.returncode == 1 and "has no circulation" in res.stderr, res
        res = subprocess.run([sys.executable, script, plain, os.path.join(d, "x.png")], capture_output=True, text=True)
        assert res.returncode != 0 and "no frames/circulation" in (res.stderr + res.stdout), res
    print("pv loop plot: ok")


if __name__ == "__main__":
    main()
