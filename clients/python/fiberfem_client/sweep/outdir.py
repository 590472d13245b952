"""A sweep's output directory: which sweep owns it, a lock against a second sweep writing
into it at the same time, and the rows finished so far (rows.jsonl, one JSON object per
line, appended and flushed as each configuration ends, so an interrupted sweep resumes)."""

from __future__ import annotations

import fcntl
import json
import os

from .task import DONE_STATUSES

OWNER_FILE = "sweep.json"
ROWS_FILE = "rows.jsonl"


class OutputDirError(RuntimeError):
    """The output directory belongs to another sweep or is in use."""


class OutputDir:
    def __init__(self, path: str, sweep_name: str, sweep_path: str):
        self.path = os.path.abspath(path)
        os.makedirs(self.path, exist_ok=True)
        self._lock = open(os.path.join(self.path, ".lock"), "a+")
        try:
            fcntl.flock(self._lock, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            raise OutputDirError(f"{self.path} is in use by another sweep that is still running "
                                 f"(pid {self._lock_owner()}); two sweeps never share an output directory") from None
        self._lock.seek(0), self._lock.truncate(), self._lock.write(str(os.getpid())), self._lock.flush()
        self._claim(sweep_name, sweep_path)
        self.runs = os.path.join(self.path, "runs")
        os.makedirs(self.runs, exist_ok=True)

    def _lock_owner(self) -> str:
        self._lock.seek(0)
        return self._lock.read().strip() or "unknown"

    def _claim(self, name, sweep_path):
        owner = os.path.join(self.path, OWNER_FILE)
        if os.path.exists(owner):
            with open(owner, encoding="utf-8") as f:
                held = json.load(f)
            if held.get("sweep") != name:
                raise OutputDirError(f"{self.path} holds the results of sweep '{held.get('sweep')}' "
                                     f"(from {held.get('file')}), not '{name}': give another --out")
        elif any(e not in (".lock",) for e in os.listdir(self.path)):
            raise OutputDirError(f"{self.path} is not empty and holds no sweep: give an empty or new --out")
        with open(owner + ".tmp", "w", encoding="utf-8") as f:
            json.dump({"sweep": name, "file": sweep_path}, f, indent=2)
        os.replace(owner + ".tmp", owner)

    def rows(self) -> list:
        """Every row recorded, oldest first (a torn last line from a kill is ignored)."""
        path = os.path.join(self.path, ROWS_FILE)
        if not os.path.exists(path):
            return []
        out = []
        with open(path, encoding="utf-8") as f:
            for line in f:
                try:
                    out.append(json.loads(line))
                except ValueError:
                    continue
        return out

    def done(self) -> dict:
        """key -> the latest finished row (completed, failed or refused: not re-run)."""
        return {r["key"]: r for r in self.rows() if r.get("key") and r.get("status") in DONE_STATUSES}

    def append(self, row: dict):
        with open(os.path.join(self.path, ROWS_FILE), "a", encoding="utf-8") as f:
            f.write(json.dumps(row, sort_keys=True, allow_nan=True) + "\n")
            f.flush()
            os.fsync(f.fileno())

    def close(self):
        self._lock.close()
