"""`python -m fiberfem_client.sweep SWEEP.yaml [--scheduler ADDRESS] [--workers N] [--out DIR]`
(what `fiberfem sweep` runs): every configuration of the sweep file as a `fiberfem run`
process on Dask, a table, Pareto fronts, plots, the cheapest configuration per goal
(docs/sweeps.md). Exit status: 0 when the sweep ran to its end (failed configurations are
rows), 2 for a bad sweep file or option, 3 when the output directory belongs to another
sweep or is in use, 130 when interrupted."""

import argparse
import os
import shutil
import signal
import sys

from .spec import SweepFileError, load_sweep


def _default_binary():
    env = os.environ.get("FIBERFEM_BIN")
    if env:
        return env
    here = os.path.dirname(os.path.abspath(__file__))
    built = os.path.normpath(os.path.join(here, "../../../../build/release/service/fiberfem"))
    return built if os.path.exists(built) else shutil.which("fiberfem")


def _parser():
    ap = argparse.ArgumentParser(prog="fiberfem sweep", description=__doc__.split("\n\n")[0],
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("sweep", help="the sweep file (YAML, docs/sweeps.md)")
    ap.add_argument("--scheduler", help="address of a running Dask scheduler (tcp://HOST:PORT); default: a local "
                                        "cluster on this machine")
    ap.add_argument("--workers", type=int, help="local cluster: worker processes (default: one per core); with "
                                                "--scheduler: wait until this many workers have joined")
    ap.add_argument("--out", help="output directory (default: sweeps/NAME in the working directory)")
    ap.add_argument("--sequential", action="store_true",
                    help="run the configurations one after another in this process, without Dask")
    ap.add_argument("--list", action="store_true", help="check the sweep file, print its configurations and stop")
    ap.add_argument("--binary", default=_default_binary(),
                    help="the fiberfem binary the workers run (default: the one that called, $FIBERFEM_BIN, or "
                         "build/release/service/fiberfem)")
    return ap


def _interrupt(signum, frame):
    raise KeyboardInterrupt


def main(argv=None):
    ap = _parser()
    a = ap.parse_args(argv)
    if a.workers is not None and a.workers < 1:
        ap.error("--workers must be >= 1")
    if a.sequential and (a.scheduler or a.workers):
        ap.error("--sequential runs without Dask: no --scheduler or --workers")
    try:
        sweep = load_sweep(a.sweep)
    except SweepFileError as e:
        print(f"fiberfem sweep: {e}", file=sys.stderr)
        return 2
    if a.list:
        configs = ([sweep.reference] if sweep.reference else []) + sweep.configurations()
        for c in configs:
            print(f"{c.name}: " + " ".join(f"--set {s}" for s in c.overrides))
        return 0
    if not a.binary or not os.access(a.binary, os.X_OK):
        print(f"fiberfem sweep: no fiberfem binary at {a.binary!r} (give --binary or FIBERFEM_BIN)", file=sys.stderr)
        return 2
    signal.signal(signal.SIGTERM, _interrupt)
    # The numerical libraries and Dask load only for a sweep that runs (--list is quick).
    from .outdir import OutputDirError
    from .runner import DaskRunner, SequentialRunner
    from .study import PrepareError, SweepRun, prepare

    out = a.out or os.path.join("sweeps", sweep.name)
    try:
        run = SweepRun(sweep, out, os.path.abspath(a.binary), None, sys.stderr)
    except OutputDirError as e:
        print(f"fiberfem sweep: {e}", file=sys.stderr)
        return 3
    runner = None
    try:
        prepare(sweep, sys.stderr)
        runner = SequentialRunner() if a.sequential else DaskRunner(a.scheduler, a.workers)
        run.runner = runner
        print(f"fiberfem sweep: {sweep.name}: {len(sweep.configurations())} configurations"
              f"{' and a reference' if sweep.reference else ''} on {runner.description}; output {run.od.path}",
              file=sys.stderr, flush=True)
        df = run.run()
        for line in run.finish(df):
            print(line, flush=True)
        return 0
    except PrepareError as e:
        print(f"fiberfem sweep: {e}", file=sys.stderr)
        return 1
    except (OSError, TimeoutError) as e:  # e.g. no scheduler at --scheduler, or no workers joined
        where = f"the Dask scheduler at {a.scheduler}" if a.scheduler else "the local Dask cluster"
        print(f"fiberfem sweep: {where}: {type(e).__name__}: {e}", file=sys.stderr)
        return 1
    except KeyboardInterrupt:
        print("fiberfem sweep: interrupted; run it again to resume (finished rows are kept)", file=sys.stderr)
        return 130
    finally:
        if runner is not None:
            runner.close()
        run.close()


if __name__ == "__main__":
    sys.exit(main())
