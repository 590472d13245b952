"""`fiberfem render` draws the pressure-volume loop beside the heart of a run with a
circulation, from an archive, a scene and a live run, and nothing of it otherwise. Real
processes, real OSMesa images (read back from the PNG files):

- an archive of the circulation heart rendered at 480x270: the inset's box (bottom left, a
  third of the height, docs/rendering.md) holds the LV loop's red and the RV loop's blue;
  rendered with --no-pv-loop it holds neither and its pixels differ;
- between two frames the LV dot (the only red disc: the loop's line is 2 px wide) moves,
  and in the direction of the LV volume's change that h5py reads in the archive (the axes
  only grow over a short run, so a volume change of a tenth of the range moves the dot
  that way);
- the scene feed draws the same inset for the same scene, and a scene without a
  circulation (heart.yaml) none;
- `render --live` of a served run draws it too (DDS loopback).

Usage: pv_inset_test.py PATH/TO/fiberfem SOURCE_DIR   (CYCLONEDDS_URI set)
"""
import glob
import json
import os
import subprocess
import sys
import tempfile
import time

import h5py
import matplotlib.image as mpimg
import numpy as np
from fiberfem_client import Client

W, H = 480, 270
MARGIN = max(6, H // 40)
SIZE = min(H // 3, W // 3)
BOX = (slice(H - MARGIN - SIZE, H - MARGIN), slice(MARGIN, MARGIN + SIZE))  # rows, columns


def frames(d):
    return [(mpimg.imread(p)[..., :3] * 255).astype(int) for p in sorted(glob.glob(os.path.join(d, "frame-*.png")))]


def red(img):  # the LV colour (200, 40, 40)
    r, g, b = img[..., 0], img[..., 1], img[..., 2]
    return (r > 150) & (g < 90) & (b < 90)


def blue(img):  # the RV colour (40, 80, 200)
    r, g, b = img[..., 0], img[..., 1], img[..., 2]
    return (b > 150) & (r < 90) & (g < 130)


def dot_centre(img):
    """Centre of the red pixels whose 5 x 5 neighbourhood is all red: the LV dot only."""
    m = red(img[BOX])
    core = np.zeros_like(m)
    core[2:-2, 2:-2] = np.all([m[2 + dy:m.shape[0] - 2 + dy, 2 + dx:m.shape[1] - 2 + dx]
                               for dy in range(-2, 3) for dx in range(-2, 3)], axis=0)
    ys, xs = np.nonzero(core)
    assert len(xs) > 0, "no LV dot in the inset"
    return xs.mean(), ys.mean()


def render(fiberfem, source, out, *extra):
    subprocess.run([fiberfem, "render", source, "--out", out, "--width", str(W), "--height", str(H), *extra],
                   check=True, capture_output=True, text=True)
    return frames(out)


def main():
    fiberfem, src = sys.argv[1], sys.argv[2]
    scene = os.path.join(src, "configs/scenes/heart-circulation-realtime.yaml")
    with tempfile.TemporaryDirectory() as d:
        archive = os.path.join(d, "a.h5")
        subprocess.run([fiberfem, "run", scene, "--until", "0.5", "--threads", "1", "--archive", archive], check=True,
                       capture_output=True)
        with h5py.File(archive, "r") as f:
            names = json.loads(f["frames/circulation"].attrs["columns"])
            lv_volume = f["frames/circulation"][:, names.index("lv_volume_m3")]
        # Archive: every 10th of 31 frames (steps 0, 10, 20, 30).
        with_loop = render(fiberfem, archive, os.path.join(d, "loop"), "--every", "10")
        without = render(fiberfem, archive, os.path.join(d, "plain"), "--every", "10", "--no-pv-loop")
        assert len(with_loop) == 4 and len(without) == 4, (len(with_loop), len(without))
        last, plain = with_loop[-1], without[-1]
        assert red(last[BOX]).sum() > 30 and blue(last[BOX]).sum() > 30, (red(last[BOX]).sum(), blue(last[BOX]).sum())
        assert red(plain[BOX]).sum() == 0 and blue(plain[BOX]).sum() == 0
        assert np.abs(last[BOX] - plain[BOX]).mean() > 10
        # The dot follows the LV volume: frames 1 and 3 are steps 10 and 30.
        (x1, _), (x3, _) = dot_centre(with_loop[1]), dot_centre(with_loop[3])
        dv = lv_volume[30] - lv_volume[10]
        assert abs(dv) > 0.1 * (lv_volume[:31].max() - lv_volume[:31].min()), dv
        assert abs(x3 - x1) > 2 and np.sign(x3 - x1) == np.sign(dv), (x1, x3, dv)
        # Scene feed: the same scene simulated here draws the inset; heart.yaml none.
        from_scene = render(fiberfem, scene, os.path.join(d, "scene"), "--steps", "30", "--every", "30")
        assert red(from_scene[-1][BOX]).sum() > 30, red(from_scene[-1][BOX]).sum()
        no_circ = render(fiberfem, os.path.join(src, "configs/scenes/heart.yaml"), os.path.join(d, "heart"), "--steps", "10",
                         "--every", "10")
        assert red(no_circ[-1][BOX]).sum() == 0 and blue(no_circ[-1][BOX]).sum() == 0
        # Live: a served run, three frames from the bus. It starts paused (publishing its state
        # and circulation once a second); the renderer joins, draws the first, then it runs.
        run = f"pv-live-{os.getpid()}"
        live_dir = os.path.join(d, "live")
        serve = subprocess.Popen([fiberfem, "serve", scene, "--run-id", run, "--paused"], stdout=subprocess.DEVNULL,
                                 stderr=subprocess.DEVNULL)
        try:
            client = Client("pv-inset-test")
            assert client.resolve_run(run, 30) == run
            renderer = subprocess.Popen([fiberfem, "render", "--live", "--run", run, "--frames", "3", "--out", live_dir,
                                         "--width", str(W), "--height", str(H)], stdout=subprocess.PIPE,
                                        stderr=subprocess.STDOUT, text=True)
            deadline = time.monotonic() + 60
            while not os.path.exists(os.path.join(live_dir, "frame-00000.png")) and renderer.poll() is None \
                    and time.monotonic() < deadline:
                time.sleep(0.05)
            assert client.send(run, "resume").accepted
            out, _ = renderer.communicate(timeout=120)
            assert renderer.returncode == 0, out
        finally:
            serve.terminate()
            serve.wait(timeout=30)
        live = frames(live_dir)
        assert len(live) == 3 and red(live[-1][BOX]).sum() > 10, (len(live), red(live[-1][BOX]).sum(), out)
    print("pv inset: ok")


if __name__ == "__main__":
    main()
