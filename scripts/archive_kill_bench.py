#!/usr/bin/env python3
"""Frames lost when `fiberfem run --archive` is killed with SIGKILL, against the flush
interval (docs/archive.md). For each flush setting, starts the real binary on a scene,
kills it at random moments (fixed seed) after its first frame, and counts the frames it had
announced (--log-frames) against the frames a SWMR reader finds complete.

    .venv/bin/python scripts/archive_kill_bench.py build/release/service/fiberfem \\
        configs/scenes/heart.yaml [--trials 20] [--flush 1 10 50]
"""
import argparse
import os
import random
import signal
import statistics
import subprocess
import tempfile
import threading
import time

import h5py


def readable_frames(path):
    with h5py.File(path, "r", libver="latest", swmr=True) as f:
        return min(d.shape[0] for d in f["frames"].values())


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("binary")
    ap.add_argument("scene")
    ap.add_argument("--trials", type=int, default=20)
    ap.add_argument("--flush", type=int, nargs="+", default=[1, 10, 50])
    ap.add_argument("--max-delay", type=float, default=2.0, help="kill within this many seconds after the first frame")
    a = ap.parse_args()
    rng = random.Random(20261123)
    env = dict(os.environ, OMP_NUM_THREADS="1")
    print("| flush every (frames) | trials | frames lost: median | max | frames readable: median |")
    print("|---|---|---|---|---|")
    with tempfile.TemporaryDirectory() as work:
        for flush in a.flush:
            lost, kept = [], []
            for t in range(a.trials):
                path = os.path.join(work, f"k{flush}_{t}.h5")
                p = subprocess.Popen([a.binary, "run", a.scene, "--steps", "100000", "--archive", path, "--flush-frames", str(flush),
                                      "--flush-seconds", "0", "--log-frames"], stdout=subprocess.PIPE, text=True, env=env)
                state = {"announced": 0}
                started = threading.Event()

                def follow(stream=p.stdout, state=state, started=started):
                    for line in stream:
                        if line.startswith("frame "):
                            state["announced"] = int(line.split()[1])
                            started.set()

                reader = threading.Thread(target=follow, daemon=True)
                reader.start()
                started.wait(timeout=60)
                time.sleep(rng.uniform(0.05, a.max_delay))
                p.send_signal(signal.SIGKILL)
                p.wait()
                reader.join(timeout=5)
                announced = state["announced"]
                n = readable_frames(path)
                lost.append(announced - n)
                kept.append(n)
            print(f"| {flush} | {a.trials} | {statistics.median(lost):g} | {max(lost)} | {statistics.median(kept):g} |")


if __name__ == "__main__":
    main()
