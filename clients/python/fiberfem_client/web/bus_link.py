"""The bridge's side of the bus: one thread that owns the DDS entities of one Client.

It waits on the readers (a Cyclone WaitSet, no polling), keeps each run's newest status,
topology and state, writes the commands the pages post and matches their acknowledgements,
keeps a trail of each run's circulation samples (a run with a circulation), and hands
everything to the asyncio side through `notify` (called from this thread). A
state that arrives while the pages are still drawing the last one replaces it: nothing
queues, so a slow page never holds the service back (the state reader is keep-last-1).

Only this thread writes the dictionaries of runs; the asyncio side reads single keys or
takes copies (`dict(...)`), both atomic under the GIL, never iterates them in place. A
circulation trail is a tuple, replaced whole, so a reader never sees one half written."""

import queue
import threading
import time
from dataclasses import dataclass
from typing import Callable, Dict, Optional

import numpy as np
from cyclonedds.core import InstanceState, ReadCondition, SampleState, ViewState, WaitSet
from cyclonedds.util import duration

from ..client import Ack, Client, State, Topology
from ..types import CirculationState, MeshState, MeshTopology, ServiceStatus

LOST_AFTER_S = 3.0      # a run without a status this long is dropped from the list
RESEND_AFTER_S = 1.0    # an unanswered command is written again under its id (as ctl does)
ANSWER_WITHIN_S = 10.0  # then the page is told there was no answer
CIRCULATION_TRAIL = 600  # circulation samples kept per run for the page's loop (10 s of states at 60/s)


@dataclass
class Received:
    """A state as it arrived: its source timestamp (the service's clock at publication,
    ms since the epoch) and when the bridge took it."""
    state: State
    source_ms: float
    bridge_ms: float


@dataclass
class Pending:
    command: object
    reply: Callable[[Optional[Ack], str], None]
    written: float
    first: float


class BusLink:
    def __init__(self, client: Client, notify: Callable[[str, str], None]):
        self.client = client
        self.notify = notify  # notify(what, run_id), what in {"runs", "status", "topology", "state", "circulation"}
        self.statuses: Dict[str, object] = {}
        self.seen: Dict[str, float] = {}
        self.topologies: Dict[str, Topology] = {}
        self.states: Dict[str, Received] = {}
        self.circulation: Dict[str, tuple] = {}  # run: its newest CirculationState samples, oldest first
        self._outbox: "queue.Queue" = queue.Queue()
        self._pending: Dict[str, Pending] = {}
        self._stop = False
        self._waitset = WaitSet(client.dp)
        mask = SampleState.NotRead | ViewState.Any | InstanceState.Any
        self._dds = client.entities()
        for name in ("status", "state", "topology", "ack", "circulation"):
            reader = self._dds[name]
            if reader is not None:
                self._waitset.attach(ReadCondition(reader, mask))
        self._thread = threading.Thread(target=self._run, name="fiberfem-bus", daemon=True)

    def start(self):
        self._thread.start()

    def stop(self):
        self._stop = True
        self._waitset.set_trigger(True)
        self._thread.join(timeout=5)

    def post(self, run_id: str, kind: str, args: dict, reply: Callable[[Optional[Ack], str], None]):
        """Queues a command for the bus thread; reply(ack, error) is called from that thread."""
        self._outbox.put((run_id, kind, args, reply))
        self._waitset.set_trigger(True)

    def commands_matched(self) -> bool:
        """Whether a service reads commands (assumed when the binding cannot tell: cyclonedds
        0.10 has no matched-subscription query; an unread command then times out)."""
        writer = self._dds["command"]
        if writer is None:
            return False
        matched = getattr(writer, "get_matched_subscriptions", None)
        return matched is None or bool(matched())

    def _run(self):
        while not self._stop:
            self._waitset.wait(duration(milliseconds=200))
            self._waitset.set_trigger(False)
            self._take_statuses()
            self._take_topologies()
            self._take_states()
            self._take_circulation()
            self._write_commands()
            self._take_acks()
            self._drop_lost_runs()

    def _take_statuses(self):
        fresh = set()
        for s in self._dds["status"].take(N=64):
            if isinstance(s, ServiceStatus):
                new = s.run_id not in self.statuses
                self.statuses[s.run_id] = s
                self.seen[s.run_id] = time.monotonic()
                fresh.add(s.run_id)
                if new:
                    self.notify("runs", s.run_id)
        for run in fresh:
            self.notify("status", run)

    def _take_topologies(self):
        for t in self._dds["topology"].take(N=16):
            if isinstance(t, MeshTopology):
                self.topologies[t.run_id] = Client._topology_of(t)
                self.notify("topology", t.run_id)

    def _take_states(self):
        newest: Dict[str, tuple] = {}
        for s in self._dds["state"].take(N=64):
            if isinstance(s, MeshState):
                newest[s.run_id] = (s, s.sample_info.source_timestamp / 1e6)
        now_ms = time.time() * 1e3
        for run, (s, source_ms) in newest.items():
            state = State(s.run_id, s.frame, s.time_s, s.parameter_version,
                          np.asarray(s.positions, dtype=np.float32).reshape(-1, 3),
                          np.asarray(s.activation, dtype=np.float32))
            self.states[run] = Received(state, source_ms, now_ms)
            self.notify("state", run)

    def _take_circulation(self):
        reader = self._dds["circulation"]
        if reader is None:  # refused by access control: the page shows no loop
            return
        fresh: Dict[str, list] = {}
        for c in reader.take(N=256):
            if isinstance(c, CirculationState):
                fresh.setdefault(c.run_id, []).append(c)
        for run, got in fresh.items():
            got.sort(key=lambda c: c.frame)
            trail = list(self.circulation.get(run, ()))
            if trail and got[0].frame < trail[-1].frame:  # a reset or a seek back: the trail starts again
                trail = []
            for c in got:  # a frame published again (a command while paused republishes the state) replaces its sample
                if trail and c.frame == trail[-1].frame:
                    trail[-1] = c
                else:
                    trail.append(c)
            self.circulation[run] = tuple(trail[-CIRCULATION_TRAIL:])
            self.notify("circulation", run)

    def _write_commands(self):
        while True:
            try:
                run_id, kind, args, reply = self._outbox.get_nowait()
            except queue.Empty:
                return
            if not self.commands_matched():
                reply(None, f"no service reads commands (is '{run_id}' running?)")
                continue
            command = self.client.post(run_id, kind, args)
            now = time.monotonic()
            self._pending[command.command_id] = Pending(command, reply, now, now)

    def _take_acks(self):
        for a in self.client.take_acks():
            p = self._pending.pop(a.command_id, None)
            if p is not None:
                p.reply(Ack(a.accepted, a.reason, a.frame, a.parameter_version), "")
        now = time.monotonic()
        for cid, p in list(self._pending.items()):
            if now - p.first > ANSWER_WITHIN_S:
                del self._pending[cid]
                p.reply(None, f"no acknowledgement of '{p.command.kind}' in {ANSWER_WITHIN_S:g} s")
            elif now - p.written > RESEND_AFTER_S:
                self._dds["command"].write(p.command)
                p.written = now

    def _drop_lost_runs(self):
        now = time.monotonic()
        for run in [r for r, t in self.seen.items() if now - t > LOST_AFTER_S]:
            for d in (self.seen, self.statuses, self.topologies, self.states, self.circulation):
                d.pop(run, None)
            self.notify("runs", run)
