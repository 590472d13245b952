"""Where the configurations run: on a Dask cluster (a local one sized to the machine, or any
scheduler's), or one after another in this process (the baseline the engine's overhead is
measured against). Dask's scheduler does the placing, and re-runs the task of a worker that
dies on another worker; nothing here schedules."""

from __future__ import annotations

import logging
import os
import sys
import time
import uuid

from .task import run_configuration


class SequentialRunner:
    """Every configuration in this process, one after another."""
    description = "sequential, in this process"

    def workers(self) -> int:
        return 1

    def run(self, jobs, on_row, on_tick):
        for job in jobs:
            on_tick(1)
            on_row(run_configuration(job))
        on_tick(0)

    def close(self):
        pass


class DaskRunner:
    """One Dask task per configuration. Without a scheduler address: a local cluster of
    `workers` processes (default: one per core), one thread each."""

    def __init__(self, scheduler: str | None, workers: int | None):
        from distributed import Client, LocalCluster

        self.cluster = None
        if scheduler:
            self.client = Client(scheduler, timeout="30s")
            if workers:
                self.client.wait_for_workers(workers, timeout=120)
            self.description = f"Dask scheduler {scheduler}, {self.workers()} workers"
        else:
            n = workers or len(os.sched_getaffinity(0))  # the cores this process may use
            self.cluster = LocalCluster(n_workers=n, threads_per_worker=1, processes=True, dashboard_address=None,
                                        silence_logs=logging.ERROR)
            self.client = Client(self.cluster)
            self.description = f"local Dask cluster, {n} worker processes"

    def workers(self) -> int:
        return len(self.client.scheduler_info(n_workers=-1)["workers"])

    def run(self, jobs, on_row, on_tick):
        from distributed import as_completed

        futures = {}
        for job in jobs:
            f = self.client.submit(run_configuration, job, key=f"fiberfem-run-{job['name']}-{uuid.uuid4().hex[:8]}",
                                   pure=False)
            futures[f] = job
        keys = {f.key for f in futures}
        pending = as_completed(list(futures))
        while pending.count():
            for f in pending.next_batch(block=False):
                on_row(self._result(f, futures[f]))
            on_tick(self._running(keys))
            time.sleep(0.2)

    def _running(self, keys) -> int:
        # The scheduler's "processing" holds the tasks sent to a worker, queued there or
        # executing: a worker executes as many at a time as it has threads.
        try:
            threads = {w: i["nthreads"] for w, i in self.client.scheduler_info(n_workers=-1)["workers"].items()}
            return sum(min(threads.get(w, 1), sum(1 for k in ks if k in keys))
                       for w, ks in self.client.processing().items())
        except Exception:  # the count is for the progress bar only
            return 0

    @staticmethod
    def _result(future, job) -> dict:
        try:
            return future.result()
        except Exception as e:  # e.g. KilledWorker: the task took down every worker it tried
            return {"name": job["name"], "group": job["group"], "status": "error",
                    "reason": f"{type(e).__name__}: {e}"[:600]}

    def close(self):
        self.client.close()
        if self.cluster is not None:
            self.cluster.close()


class Progress:
    """A bar (tqdm) on a terminal, else a line per finished configuration: done, failed,
    running, and the time left at the rate so far."""

    def __init__(self, total: int, label: str, stream=sys.stderr):
        self.total, self.label, self.stream = total, label, stream
        self.done = self.failed = self.running = self.skipped = 0
        self.t0 = time.monotonic()
        self.bar = None
        if stream.isatty():
            from tqdm import tqdm

            self.bar = tqdm(total=total, desc=label, file=stream, unit="run", dynamic_ncols=True)

    def left_s(self) -> float | None:
        ran = self.done + self.failed - self.skipped
        todo = self.total - self.done - self.failed
        if ran <= 0:
            return None
        return (time.monotonic() - self.t0) / ran * todo

    def _status(self) -> str:
        left = self.left_s()
        return (f"done {self.done}, failed {self.failed}, running {self.running}"
                + (f", left ~{_duration(left)}" if left is not None else ""))

    def tick(self, running: int):
        if running != self.running:
            self.running = running
            if self.bar is not None:
                self.bar.set_postfix_str(self._status())

    def row(self, row: dict):
        if row.get("status") == "skipped":
            self.skipped += 1
        ok = row.get("status") in ("completed", "skipped")
        self.done += ok
        self.failed += not ok
        if self.bar is not None:
            self.bar.update(1)
            self.bar.set_postfix_str(self._status())
        else:
            n = self.done + self.failed
            why = f" ({row.get('reason')})" if not ok and row.get("reason") else ""
            print(f"[{n}/{self.total}] {row.get('name')}: {row.get('status')}{why}; {self._status()}",
                  file=self.stream, flush=True)

    def close(self):
        if self.bar is not None:
            self.bar.close()


def _duration(s: float) -> str:
    return f"{s:.0f} s" if s < 120 else f"{s / 60:.1f} min"
