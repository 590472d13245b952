"""`python -m fiberfem_client watch [--run ID]`: print a run's frames, following it across
service restarts and network cuts (docs/python-client.md). Lines as `fiberfem ctl echo
--follow`: "following run ...", "frame N t=... s vV: n nodes", "lost run ...: why"."""

import argparse
import sys
import time

from .client import Client


def main(argv=None):
    ap = argparse.ArgumentParser(prog="python -m fiberfem_client")
    sub = ap.add_subparsers(dest="command", required=True)
    w = sub.add_parser("watch", help="print a run's frames, following it across restarts")
    w.add_argument("--run", help="run id to follow (default: the only run, then the only run of its scene)")
    w.add_argument("--count", type=int, default=0, help="stop after this many frames (default: until Ctrl-C)")
    w.add_argument("--lost-after", type=float, default=3.0, help="a run is lost after this long without a status, s")
    w.add_argument("--timeout", type=float, default=10.0, help="give up after this long with no run to follow, s")
    a = ap.parse_args(argv)
    if a.count < 0 or a.lost_after <= 0 or a.timeout <= 0:
        ap.error("--count must be >= 0, --lost-after and --timeout > 0")
    c = Client()
    shown, since_run, following = 0, time.monotonic(), False
    events = c.follow(a.run, a.lost_after)
    try:
        while a.count == 0 or shown < a.count:
            if not following and time.monotonic() - since_run > a.timeout:
                print(f"fiberfem_client: no run to follow for {a.timeout} s", file=sys.stderr)
                return 4
            kind, run, what = next(events)
            if kind == "waiting":
                continue
            since_run = time.monotonic()
            if kind == "found":
                following = True
                print(f"following run {run}: {what}", flush=True)
            elif kind == "lost":
                following = False
                print(f"lost run {run}: {what}", flush=True)
            else:
                p = what.positions
                print(f"frame {what.frame} t={what.time_s:.4f} s v{what.parameter_version}: {p.shape[0]} nodes", flush=True)
                shown += 1
    except KeyboardInterrupt:
        pass
    return 0


if __name__ == "__main__":
    sys.exit(main())
