"""What every page shares: the bus link's runs, each run's surface, and the newest frame
encoded once per field however many pages draw it. Lives on the asyncio loop; the bus
thread reaches it only through `from_bus` (call_soon_threadsafe)."""

import asyncio
from typing import Dict, Optional, Tuple

from .bus_link import BusLink
from .protocol import encode_frame, status_message
from .surface import FieldUnavailable, Surface


class Hub:
    def __init__(self, loop: asyncio.AbstractEventLoop):
        self.loop = loop
        self.link: Optional[BusLink] = None
        self.sessions = set()
        self.surfaces: Dict[str, Surface] = {}
        self._frames: Dict[Tuple[str, str], Tuple[int, bytes]] = {}
        self._beats: Dict[str, Tuple[float, float]] = {}  # run: (time_s, beats) at its last status

    def from_bus(self, what: str, run: str):
        self.loop.call_soon_threadsafe(self._on_bus, what, run)

    def _on_bus(self, what: str, run: str):
        if what == "topology":
            self.surfaces.pop(run, None)
        if what == "status":
            self._count_beats(run)
        for s in list(self.sessions):
            s.poke(what, run)

    def runs(self) -> list:
        return [{"run_id": r, "scene_name": s.scene_name, "host": s.host, "replay": s.replay, "state": s.state}
                for r, s in sorted(dict(self.link.statuses).items())]  # a copy: the bus thread adds runs

    def status(self, run: str) -> Optional[dict]:
        s = self.link.statuses.get(run)
        return None if s is None else status_message(s, self._beats.get(run, (0.0, 0.0))[1])

    def circulation(self, run: str) -> tuple:
        """The run's newest circulation samples, oldest first (empty for a run without one)."""
        return self.link.circulation.get(run, ())

    def surface(self, run: str) -> Optional[Surface]:
        """The run's surface, built from its topology at first use (raises FieldUnavailable)."""
        if run not in self.surfaces:
            topo = self.link.topologies.get(run)
            if topo is None:
                return None
            self.surfaces[run] = Surface.of(topo)
        return self.surfaces[run]

    def frame(self, run: str, field: str) -> Optional[Tuple[int, bytes]]:
        """(frame number, encoded frame) of the run's newest state in a field, or None."""
        got = self.link.states.get(run)
        surface = self.surface(run)
        if got is None or surface is None:
            return None
        cached = self._frames.get((run, field))
        if cached is not None and cached[0] == got.state.frame:
            return cached
        st = got.state
        if st.positions.shape[0] <= surface.state_rows.max(initial=-1):
            raise FieldUnavailable(f"a state of {st.positions.shape[0]} nodes does not fit the topology")
        data = encode_frame(st.frame, st.time_s, got.source_ms, got.bridge_ms, st.parameter_version, field,
                            surface.positions(st), surface.field(field, st))
        self._frames[(run, field)] = (st.frame, data)
        return self._frames[(run, field)]

    def _count_beats(self, run: str):
        """Beats since the run's time zero, integrated over statuses from its heart rate (a
        rate change counts from the status that reports it; a reset or seek back restarts)."""
        s = self.link.statuses.get(run)
        if s is None:
            return
        t_prev, beats = self._beats.get(run, (0.0, 0.0))
        if s.time_s < t_prev:
            t_prev, beats = 0.0, 0.0
        self._beats[run] = (s.time_s, beats + (s.time_s - t_prev) * s.heart_rate_bpm / 60.0)
