"""scripts/plot_pv_loop.py on a real run: `fiberfem run` of the circulation heart for two
beats writes a report; the script draws its loops into a PNG of the expected size with
both panels drawn (coloured pixels in each half), and refuses a report without a
circulation.

Usage: pv_loop_plot_test.py PATH/TO/fiberfem SOURCE_DIR
"""
import json
import os
import subprocess
import sys
import tempfile

import matplotlib.image as mpimg
import numpy as np


def main():
    fiberfem, src = sys.argv[1], sys.argv[2]
    scene = os.path.join(src, "configs/scenes/heart-circulation-realtime.yaml")
    script = os.path.join(src, "scripts/plot_pv_loop.py")
    with tempfile.TemporaryDirectory() as d:
        report = os.path.join(d, "r.json")
        subprocess.run([fiberfem, "run", scene, "--until", "1.6667", "--set", "solver.threads=1", "--report", report],
                       check=True, capture_output=True)
        png = os.path.join(d, "pv.png")
        subprocess.run([sys.executable, script, report, png], check=True)
        img = mpimg.imread(png)
        assert img.shape[0] > 300 and img.shape[1] > 800, img.shape
        rgb = img[..., :3]
        coloured = (np.abs(rgb[..., 0] - rgb[..., 2]) > 0.2)  # the loops' red-blue lines
        half = img.shape[1] // 2
        left, right = coloured[:, :half].sum(), coloured[:, half:].sum()
        assert left > 200 and right > 200, (left, right)
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
    print("pv loop plot: ok")


if __name__ == "__main__":
    main()
