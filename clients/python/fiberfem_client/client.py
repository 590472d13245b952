"""A small client of fiberfem services (docs/python-client.md).

    from fiberfem_client import Client
    c = Client()
    runs = c.discover()                      # {run_id: ServiceStatus}
    run = c.resolve_run()                    # the only run, or pass run_id
    topo = c.topology(run)                   # rest positions (N, 3), tets (E, 4), ...
    for st in c.states(run, count=10):       # positions (n, 3) float32, activation (E,)
        print(st.frame, st.time_s, st.positions[0])
    ack = c.send(run, "set_contraction", {"heart_rate": 90})
    for cs in c.circulation_states(run, count=10):   # a run with a circulation: SI units
        print(cs.frame, cs.lv_pressure_pa / 133.322, cs.lv_volume_m3 * 1e6)

The topics and QoS are those of idl/bus.cpp; use the same CYCLONEDDS_URI as
the service (configs/dds/loopback.xml on one host).
"""

import json
import os
import time
import uuid
from dataclasses import dataclass
from typing import Dict, Iterator, Optional

import numpy as np
from cyclonedds.core import DDSException, Policy, Qos
from cyclonedds.domain import DomainParticipant
from cyclonedds.pub import DataWriter
from cyclonedds.sub import DataReader
from cyclonedds.topic import Topic
from cyclonedds.util import duration

from .types import CirculationState, Command, CommandAck, MeshState, MeshTopology, ServiceStatus

# The QoS of idl/bus.cpp, policy for policy (tests/idl/python_qos_check.py compares them on
# live entities and fails when they drift; docs/dds.md explains each choice).
_RELIABLE = Policy.Reliability.Reliable(duration(seconds=10))
QOS = {
    "topology": Qos(_RELIABLE, Policy.Durability.TransientLocal, Policy.History.KeepLast(1)),
    "state": Qos(_RELIABLE, Policy.Durability.Volatile, Policy.History.KeepLast(1),
                 Policy.Deadline(duration(seconds=2))),
    "command": Qos(_RELIABLE, Policy.Durability.Volatile, Policy.History.KeepAll),
    "ack": Qos(_RELIABLE, Policy.Durability.TransientLocal, Policy.History.KeepLast(1024),
               Policy.DurabilityService(cleanup_delay=0, history=Policy.History.KeepLast(64), max_samples=-1,
                                        max_instances=-1, max_samples_per_instance=-1)),
    "status": Qos(_RELIABLE, Policy.Durability.Volatile, Policy.History.KeepLast(1),
                  Policy.Deadline(duration(seconds=2)), Policy.Liveliness.Automatic(duration(seconds=3))),
    "circulation": Qos(_RELIABLE, Policy.Durability.Volatile, Policy.History.KeepLast(16)),
}
# Readers differ from their topic in three ways: they request no deadline (a service offers
# one), ack readers keep all (the acks of every client of a run share one instance), and
# circulation readers keep 256 samples (a reader polling a few times a second gets them all).
READER_QOS = {
    **QOS,
    "state": Qos(Policy.Deadline(duration(infinite=True)), base=QOS["state"]),
    "status": Qos(Policy.Deadline(duration(infinite=True)), base=QOS["status"]),
    "ack": Qos(Policy.History.KeepAll, base=QOS["ack"]),
    "circulation": Qos(Policy.History.KeepLast(256), base=QOS["circulation"]),
}
TOPIC_NAMES = {
    "topology": "fiberfem_mesh_topology",
    "state": "fiberfem_mesh_state",
    "command": "fiberfem_command",
    "ack": "fiberfem_command_ack",
    "status": "fiberfem_status",
    "circulation": "fiberfem_circulation",
}


class FiberfemError(RuntimeError):
    """No service, no answer, or several runs where one was meant."""


@dataclass
class Ack:
    accepted: bool
    reason: str
    frame: int
    parameter_version: int


@dataclass
class State:
    run_id: str
    frame: int
    time_s: float
    parameter_version: int
    positions: np.ndarray   # (n, 3) float32, metres (n = state nodes or all nodes)
    activation: np.ndarray  # (E,) float32, active tension / peak, 0..1


@dataclass
class Topology:
    run_id: str
    scene_name: str
    scene_hash: str
    replay: bool
    rest_positions: np.ndarray     # (N, 3) float32, metres
    tets: np.ndarray               # (E, 4) int32
    triangles: np.ndarray          # (F, 3) int32, boundary, outward
    triangle_elements: np.ndarray  # (F,) int32
    element_regions: np.ndarray    # (E,) int16
    region_names: list
    fibers: np.ndarray             # (E, 3) float32
    state_nodes: np.ndarray        # nodes the states carry; empty: all
    fixed_nodes: np.ndarray


class Client:
    """One DDS participant with readers of status, acks, states, topology and circulation and a writer of commands."""

    def __init__(self, client_id: Optional[str] = None, domain_id: int = 0):
        self.client_id = client_id or f"py-{os.getpid()}-{uuid.uuid4().hex[:8]}"
        self._next = 0
        self.dp = DomainParticipant(domain_id)
        t = {k: Topic(self.dp, TOPIC_NAMES[k], cls, qos=QOS[k])
             for k, cls in (("topology", MeshTopology), ("state", MeshState), ("status", ServiceStatus))}
        self._status = DataReader(self.dp, t["status"], qos=READER_QOS["status"])
        self._state = DataReader(self.dp, t["state"], qos=READER_QOS["state"])
        self._topology = DataReader(self.dp, t["topology"], qos=READER_QOS["topology"])
        # Absent when access control refuses it (permissions made before the topic existed):
        # everything else still works, the circulation calls raise with the reason.
        self.circulation_refused = ""
        try:
            self._circulation = DataReader(
                self.dp, Topic(self.dp, TOPIC_NAMES["circulation"], CirculationState, qos=QOS["circulation"]),
                qos=READER_QOS["circulation"])
        except DDSException as e:
            self._circulation = None
            self.circulation_refused = ("this identity may not read the circulation (its permissions do not grant "
                                        f"fiberfem_circulation: remake them with scripts/make_security.sh): {e}")
        # The command path, absent when access control refuses it (an observer identity in
        # secure mode, docs/security.md): watching still works, send raises.
        self.commands_refused = ""
        try:
            self._ack = DataReader(self.dp, Topic(self.dp, TOPIC_NAMES["ack"], CommandAck, qos=QOS["ack"]),
                                   qos=READER_QOS["ack"])
            self._command = DataWriter(self.dp, Topic(self.dp, TOPIC_NAMES["command"], Command, qos=QOS["command"]),
                                       qos=QOS["command"])
        except DDSException as e:
            self._ack = self._command = None
            self.commands_refused = ("this identity may not send commands (observer identity: commands need the "
                                     f"operator role, docs/security.md): {e}")
        self.runs: Dict[str, ServiceStatus] = {}
        self._seen: Dict[str, float] = {}  # monotonic time of each run's newest status

    def _note(self, s):
        self.runs[s.run_id] = s
        self._seen[s.run_id] = time.monotonic()

    def _poll_status(self):
        for s in self._status.take(N=64):
            if isinstance(s, ServiceStatus):
                self._note(s)

    def discover(self, wait_s: float = 1.5) -> Dict[str, ServiceStatus]:
        """Runs seen on the domain within wait_s: {run_id: newest ServiceStatus}."""
        self.runs = {}
        end = time.monotonic() + wait_s
        while time.monotonic() < end:
            self._poll_status()
            time.sleep(0.05)
        return dict(self.runs)

    def resolve_run(self, run_id: Optional[str] = None, wait_s: float = 10.0) -> str:
        end = time.monotonic() + wait_s
        while time.monotonic() < end:
            self._poll_status()
            if run_id and run_id in self.runs:
                return run_id
            if not run_id and len(self.runs) == 1:
                time.sleep(0.6)
                self._poll_status()
                if len(self.runs) == 1:
                    return next(iter(self.runs))
            time.sleep(0.05)
        if run_id:
            raise FiberfemError(f"no run '{run_id}' seen on the domain")
        if not self.runs:
            raise FiberfemError("no fiberfem service seen on the domain")
        raise FiberfemError("several runs on the domain, give run_id: " + " ".join(sorted(self.runs)))

    def status(self, run_id: str, wait_s: float = 5.0) -> ServiceStatus:
        end = time.monotonic() + wait_s
        while time.monotonic() < end:
            for s in self._status.take(N=64):
                if isinstance(s, ServiceStatus):
                    self._note(s)
                    if s.run_id == run_id:
                        return s
            time.sleep(0.02)
        raise FiberfemError(f"no status from '{run_id}' in {wait_s} s")

    def topology(self, run_id: str, wait_s: float = 10.0) -> Topology:
        end = time.monotonic() + wait_s
        while time.monotonic() < end:
            for t in self._topology.take(N=16):
                if isinstance(t, MeshTopology) and t.run_id == run_id:
                    return self._topology_of(t)
            time.sleep(0.02)
        raise FiberfemError(f"no topology from '{run_id}' in {wait_s} s")

    @staticmethod
    def _topology_of(t: MeshTopology) -> Topology:
        return Topology(
            t.run_id, t.scene_name, t.scene_hash, t.replay,
            np.asarray(t.rest_positions, dtype=np.float32).reshape(-1, 3),
            np.asarray(t.tets, dtype=np.int32).reshape(-1, 4),
            np.asarray(t.triangles, dtype=np.int32).reshape(-1, 3),
            np.asarray(t.triangle_elements, dtype=np.int32),
            np.asarray(t.element_regions, dtype=np.int16),
            list(t.region_names),
            np.asarray(t.fibers, dtype=np.float32).reshape(-1, 3),
            np.asarray(t.state_nodes, dtype=np.int32),
            np.asarray(t.fixed_nodes, dtype=np.int32))

    def next_state(self, run_id: str, after_frame: int = -1, wait_s: float = 10.0) -> State:
        """The newest state of run_id with a frame after after_frame."""
        end = time.monotonic() + wait_s
        while time.monotonic() < end:
            newest = None
            for s in self._state.take(N=16):
                if isinstance(s, MeshState) and s.run_id == run_id and s.frame > after_frame:
                    newest = s
            if newest is not None:
                return State(newest.run_id, newest.frame, newest.time_s, newest.parameter_version,
                             np.asarray(newest.positions, dtype=np.float32).reshape(-1, 3),
                             np.asarray(newest.activation, dtype=np.float32))
            time.sleep(0.002)
        raise FiberfemError(f"no state from '{run_id}' in {wait_s} s")

    def states(self, run_id: str, count: Optional[int] = None, wait_s: float = 10.0) -> Iterator[State]:
        """Successive states (the newest each time; a slow consumer skips frames)."""
        last, n = -1, 0
        while count is None or n < count:
            s = self.next_state(run_id, last, wait_s)
            last, n = s.frame, n + 1
            yield s

    def circulation_samples(self, run_id: str, after_frame: int = -1, wait_s: float = 10.0) -> list:
        """The CirculationState samples of run_id with a frame after after_frame that have
        arrived, oldest first, waiting up to wait_s for one; [] when none came (a run
        without a circulation publishes none). SI units, the members of idl/circulation.idl."""
        if self._circulation is None:
            raise FiberfemError(self.circulation_refused)
        end = time.monotonic() + wait_s
        while True:
            got = [c for c in self._circulation.take(N=256)
                   if isinstance(c, CirculationState) and c.run_id == run_id and c.frame > after_frame]
            if got or time.monotonic() >= end:
                return sorted(got, key=lambda c: c.frame)
            time.sleep(0.005)

    def circulation_states(self, run_id: str, count: Optional[int] = None, wait_s: float = 10.0) -> Iterator:
        """Successive CirculationState samples of run_id, every one published while reading
        keeps up (the reader holds 256); raises FiberfemError after wait_s without one."""
        last, n = -1, 0
        while count is None or n < count:
            got = self.circulation_samples(run_id, last, wait_s)
            if not got:
                raise FiberfemError(f"no circulation from '{run_id}' in {wait_s} s (a run without a circulation publishes none)")
            for c in got:
                if count is not None and n >= count:
                    return
                last, n = c.frame, n + 1
                yield c

    def send(self, run_id: str, kind: str, args: Optional[dict] = None, wait_s: float = 10.0) -> Ack:
        """Sends a command (docs/commands.md) and waits for its acknowledgement."""
        if self._command is None:
            raise FiberfemError(self.commands_refused)
        end = time.monotonic() + wait_s
        self._poll_status()
        # Commands are volatile: wait for a matched command reader (for all the runs seen,
        # at most 2 s: a run that just ended may still be listed).
        settle = min(end, time.monotonic() + 2.0)
        while time.monotonic() < end and (not self._command.get_matched_subscriptions() or (
                len(self._command.get_matched_subscriptions()) < len(self.runs) and time.monotonic() < settle)):
            time.sleep(0.01)
        if not self._command.get_matched_subscriptions():
            raise FiberfemError(f"no service matched the command topic (is '{run_id}' running?)")
        command = self.post(run_id, kind, args)
        cid = command.command_id
        written = time.monotonic()
        while time.monotonic() < end:
            for a in self.take_acks():
                if a.run_id == run_id and a.command_id == cid:
                    return Ack(a.accepted, a.reason, a.frame, a.parameter_version)
            if time.monotonic() - written >= 1.0:  # unanswered: again under the same id (applied once)
                self._command.write(command)
                written = time.monotonic()
            time.sleep(0.005)
        raise FiberfemError(f"no acknowledgement of '{kind}' from '{run_id}' in {wait_s} s")

    def entities(self) -> dict:
        """The participant's readers ("status", "state", "topology", "ack", "circulation") and command writer
        ("command"; None with "ack" when commands are refused), for a caller that waits on
        them itself (fiberfem web's bridge attaches them to a WaitSet)."""
        return {"status": self._status, "state": self._state, "topology": self._topology, "ack": self._ack,
                "command": self._command, "circulation": self._circulation}

    def post(self, run_id: str, kind: str, args: Optional[dict] = None) -> Command:
        """Writes a command without waiting (its answer comes through take_acks); returns the
        sample, to write again unchanged when unanswered (the service applies an id once)."""
        self._next += 1
        command = Command(run_id=run_id, command_id=f"{self.client_id}-{self._next}", client_id=self.client_id,
                          kind=kind, args=json.dumps(args or {}))
        self._command.write(command)
        return command

    def take_acks(self) -> list:
        """The acknowledgements received since the last call (of every client's commands)."""
        if self._ack is None:
            return []
        return [a for a in self._ack.take(N=256) if isinstance(a, CommandAck)]

    def live(self, run_id: str, lost_after_s: float = 3.0) -> Optional[str]:
        """None when run_id is live (a status within lost_after_s, not "stopped"), else why not."""
        self._poll_status()
        if run_id not in self._seen:
            return "no status seen"
        age = time.monotonic() - self._seen[run_id]
        if age > lost_after_s:
            return f"no status for {age:.1f} s"
        if self.runs[run_id].state == "stopped":
            return "it stopped"
        return None

    def follow(self, run_id: Optional[str] = None, lost_after_s: float = 3.0) -> Iterator[tuple]:
        """Follows a run's states across service restarts and network cuts, forever.

        Yields ("found", run_id, message), ("state", run_id, State), ("lost", run_id, why),
        and ("waiting", None, "") about every 50 ms while no run is followed.
        The rule (as `fiberfem ctl echo --follow`): given run_id, that run id whichever
        service carries it (a service restarted with the same --run-id); given none, the
        only live run, and after a loss the only live run of the same scene. A run is lost
        after lost_after_s without a status, when it reports "stopped", or when another
        process (pid, host) takes its run id (a restart noticed before the silence)."""
        run, scene, who, last = None, None, None, -1
        while True:
            if run is None:
                self._poll_status()
                live = {r: s for r, s in self.runs.items() if self.live(r, lost_after_s) is None}
                if run_id:
                    picks = [run_id] if run_id in live else []
                else:
                    picks = [r for r, s in live.items() if scene is None or s.scene_name == scene]
                if len(picks) == 1:
                    run = picks[0]
                    s = live[run]
                    scene, who, last = s.scene_name, (s.pid, s.host), -1
                    yield ("found", run, f"scene {s.scene_name} on {s.host} (pid {s.pid}), {s.state} at t = {s.time_s:.3f} s")
                else:
                    time.sleep(0.05)
                    yield ("waiting", None, "")
                continue
            why = self.live(run, lost_after_s)
            if why is None and (self.runs[run].pid, self.runs[run].host) != who:
                s = self.runs[run]
                why = f"restarted (pid {who[0]} on {who[1]}, now pid {s.pid} on {s.host})"
            if why is not None:
                self._state.take(N=64)  # the old service's last frames
                yield ("lost", run, why)
                run = None
                continue
            try:
                st = self.next_state(run, last, wait_s=0.2)
            except FiberfemError:
                continue
            last = st.frame
            yield ("state", run, st)
