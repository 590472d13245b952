#!/usr/bin/env python3
"""Measures `fiberfem web` (docs/web.md, "Measured"): for 0, 1 and 10 headless Chromium pages
on the default heart served in real time, the service's steps/s and real-time factor (from
its status topic), and per page the frames drawn per second, bytes per frame and per
second, and the time from a state's publication (its DDS source timestamp) to the end of
the page's render() of it (median and p99); plus the CPU the service and the bridge use.

    .venv/bin/python scripts/web_measure.py build/release/service/fiberfem [--browsers 0 1 10] [--sockets 10]
        [--seconds 20] [--repeats 1]

Everything runs on this machine on the DDS loopback profile; the pages draw with SwiftShader
(Chromium's software WebGL), so on a machine without a GPU the browsers' own drawing takes
most of the CPU, not the bridge. The `--sockets` rows separate the two: bare WebSocket
clients that take every frame the bridge offers (no drawing), the bridge's work for that
many pages."""

import argparse
import asyncio
import os
import statistics
import struct
import sys
import threading
import time

here = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, os.path.join(here, "..", "tests", "web"))
from harness import Rig, open_page  # noqa: E402

RESET_STATS = "const s = window.fiberfem.stats; s.frames = 0; s.bytes = 0; s.latencies = []; s.started = performance.now();"
READ_STATS = "const s = window.fiberfem.stats; return {frames: s.frames, bytes: s.bytes, latencies: s.latencies, seconds: (performance.now() - s.started) / 1e3};"


def cpu_seconds(pid: int) -> float:
    with open(f"/proc/{pid}/stat") as f:
        fields = f.read().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")


def percentile(values, q):
    v = sorted(values)
    return v[min(len(v) - 1, int(round(q * (len(v) - 1))))] if v else float("nan")


class Sockets:
    """n bare WebSocket clients that ask for the next frame as soon as one arrives: the
    bridge's work for n pages without the browsers' drawing. Latency here is to receipt."""

    def __init__(self, port: int, n: int):
        self.port, self.n = port, n
        self.stats = [{"frames": 0, "bytes": 0, "latencies": [], "seconds": 0.0} for _ in range(n)]
        self.counting = False
        self._stop = threading.Event()
        self._thread = threading.Thread(target=lambda: asyncio.run(self._all()), daemon=True)
        if n:
            self._thread.start()

    async def _one(self, st):
        import aiohttp
        async with aiohttp.ClientSession() as http:
            async with http.ws_connect(f"http://127.0.0.1:{self.port}/ws") as ws:
                while not self._stop.is_set():
                    try:
                        msg = await asyncio.wait_for(ws.receive(), 0.5)
                    except asyncio.TimeoutError:
                        continue
                    if isinstance(msg.data, bytes):
                        if self.counting:
                            st["frames"] += 1
                            st["bytes"] += len(msg.data)
                            st["latencies"].append(time.time() * 1e3 - struct.unpack_from("<d", msg.data, 24)[0])
                        await ws.send_str('{"type": "ready"}')

    async def _all(self):
        await asyncio.gather(*(self._one(st) for st in self.stats))

    def close(self):
        self._stop.set()
        if self.n:
            self._thread.join(5)


def measure(rig: Rig, service_pid: int, bridge_pid: int, pages: int, sockets: int, seconds: float) -> dict:
    drivers = [open_page(rig.port) for _ in range(pages)]
    bare = Sockets(rig.port, sockets)
    try:
        for d in drivers:
            end = time.monotonic() + 60
            while d.execute_script("return window.fiberfem ? window.fiberfem.stats.frames : 0;") < 3:
                assert time.monotonic() < end, "a page drew no frames"
                time.sleep(0.1)
        for d in drivers:
            d.execute_script(RESET_STATS)
        bare.counting = True
        cpu0 = cpu_seconds(service_pid), cpu_seconds(bridge_pid)
        steps, rtf, end = [], [], time.monotonic() + seconds
        while time.monotonic() < end:
            s = rig.witness().status(rig.run_id, wait_s=15)  # a loaded machine may stall a step for seconds
            steps.append(s.frames_per_second)
            rtf.append(s.real_time_factor)
        cpu1 = cpu_seconds(service_pid), cpu_seconds(bridge_pid)
        stats = [d.execute_script(READ_STATS) for d in drivers]
        bare.counting = False
        stats += [dict(st, seconds=seconds) for st in bare.stats]
    finally:
        bare.close()
        for d in drivers:
            d.quit()
    lat = [x for s in stats for x in s["latencies"]]
    frames = sum(s["frames"] for s in stats)
    return {
        "pages": f"{pages} browser{'' if pages == 1 else 's'}" if not sockets else f"{sockets} socket{'' if sockets == 1 else 's'}",
        "steps_per_s": statistics.median(steps),
        "real_time_factor": statistics.median(rtf),
        "service_cpu": (cpu1[0] - cpu0[0]) / seconds,
        "bridge_cpu": (cpu1[1] - cpu0[1]) / seconds,
        "fps": statistics.median([s["frames"] / s["seconds"] for s in stats]) if stats else float("nan"),
        "bytes_per_frame": sum(s["bytes"] for s in stats) / frames if frames else float("nan"),
        "bytes_per_s": statistics.median([s["bytes"] / s["seconds"] for s in stats]) if stats else float("nan"),
        "latency_median_ms": statistics.median(lat) if lat else float("nan"),
        "latency_p99_ms": percentile(lat, 0.99),
        "frames": frames,
    }


def row(r: dict) -> str:
    def f(v, fmt, unit=""):  # no clients: nothing was drawn, the cell stays empty
        return "" if v != v else f"{v:{fmt}}{unit}"
    return (f"| {r['pages']} | {r['steps_per_s']:.1f} | {r['real_time_factor']:.2f} | {100 * r['service_cpu']:.0f} % | "
            f"{100 * r['bridge_cpu']:.0f} % | {f(r['fps'], '.1f')} | {f(r['bytes_per_frame'], '.0f')} | "
            f"{f(r['bytes_per_s'], '.0f')} | {f(r['latency_median_ms'], '.1f', ' ms')} | {f(r['latency_p99_ms'], '.1f', ' ms')} | "
            f"{r['frames']} |")


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("fiberfem", help="the fiberfem binary")
    ap.add_argument("--browsers", type=int, nargs="+", default=[0, 1, 10], help="page counts to measure (default 0 1 10)")
    ap.add_argument("--sockets", type=int, nargs="*", default=[10],
                    help="bare WebSocket client counts to measure after the browsers (default 10)")
    ap.add_argument("--seconds", type=float, default=20.0, help="measuring time of each count, s (default 20)")
    ap.add_argument("--repeats", type=int, default=1, help="rounds over the counts (default 1); each row is one")
    a = ap.parse_args()
    source_dir = os.path.abspath(os.path.join(here, ".."))
    rig = Rig(os.path.abspath(a.fiberfem), source_dir)
    try:
        rig.start([rig.bin, "serve", "--builtin", "heart", "--run-id", rig.run_id], "serve")  # the defaults
        rig.witness().resolve_run(rig.run_id, wait_s=30)
        bridge = rig.bridge()
        service_pid = rig.procs[0].p.pid
        print("| clients | service steps/s | real-time factor | service CPU | bridge CPU | page frames/s | bytes/frame | bytes/s per page | publish-to-paint median | p99 | frames |")
        print("|---|---|---|---|---|---|---|---|---|---|---|")
        for _ in range(a.repeats):
            for n, m in [(n, 0) for n in a.browsers] + [(0, m) for m in a.sockets]:
                r = measure(rig, service_pid, bridge.p.pid, n, m, a.seconds)
                print(row(r), flush=True)
    finally:
        rig.close()
    return 0


if __name__ == "__main__":
    sys.exit(main())
