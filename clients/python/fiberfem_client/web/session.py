"""One page's WebSocket: what it watches, what it may do, and its frame credit.

Frames flow by credit: the page sends "ready" after it has drawn a frame, and only then
gets the next one, the newest at that moment. A slow page therefore skips frames and
never builds a backlog, and the bus thread never waits for any page."""

import asyncio
import itertools
import json
import traceback
from typing import Optional

from aiohttp import WSMsgType, web

from .hub import Hub
from .protocol import LIVE_KINDS, REPLAY_KINDS, ProtocolError, circulation_message, parse
from .surface import FIELDS, FieldUnavailable

_numbers = itertools.count(1)


class Session:
    def __init__(self, hub: Hub, ws: web.WebSocketResponse, run: Optional[str], refused: str):
        self.hub, self.ws = hub, ws
        self.number = next(_numbers)
        self.run, self.field = run, "activation"
        self.refused = refused  # why this page may not steer ("" when it may)
        self.credit = True
        self.sent_frame = None
        self.circulation_sent = None  # the last circulation frame sent for self.run (None: none yet)
        self.dirty = {"runs", "topology", "status", "circulation"}
        self.wake = asyncio.Event()
        self.wake.set()
        self.force_name = f"web-{self.number}"
        self.pressing: Optional[str] = None  # the run a held force is on

    def poke(self, what: str, run: str):
        if what == "runs" or run == self.run:
            self.dirty.add(what)
            self.wake.set()

    async def serve(self):
        await self._send_json({"type": "hello", "fields": list(FIELDS), "controls": not self.refused,
                               "why_not": self.refused, "session": self.number})
        sender = asyncio.ensure_future(self._send_loop())
        try:
            async for msg in self.ws:
                if msg.type == WSMsgType.TEXT:
                    await self._receive(msg.data)
                elif msg.type == WSMsgType.BINARY:
                    await self._error(None, "the page sends text messages (JSON objects) only")
        finally:
            sender.cancel()
            if self.pressing:
                self.hub.link.post(self.pressing, "clear_force", {"name": self.force_name}, lambda ack, err: None)

    async def _receive(self, text: str):
        try:
            msg = parse(text)
        except ProtocolError as e:
            await self._error(None, str(e))
            return
        kind = msg["type"]
        if kind == "ready":
            self.credit = True
            self.wake.set()
        elif kind == "watch":
            if msg["run"] not in self.hub.link.statuses:
                await self._error(None, f"no run '{msg['run']}' on the domain")
                return
            self.run, self.field = msg["run"], msg["field"]
            self.sent_frame, self.credit = None, True  # a frame in flight is of the old run: not waited for
            self.circulation_sent = None
            self.dirty |= {"topology", "status", "circulation"}
            self.wake.set()
        else:
            await self._steer(msg)

    async def _steer(self, msg: dict):
        rid = msg["id"]
        if self.refused:
            await self._error(rid, f"not permitted: {self.refused}")
            return
        status = self.hub.link.statuses.get(self.run) if self.run else None
        if status is None:
            await self._error(rid, "no run is watched")
            return
        replay, run = status.replay, self.run
        if msg["type"] == "press":
            if replay:
                await self._error(rid, "a replay takes no forces")
                return
            kind, args = "apply_force", {"name": self.force_name, "target": {"point": msg["point"]}, "force": msg["force"]}
            self.pressing = run
        elif msg["type"] == "release":
            if not self.pressing:
                await self._error(rid, "no force is held")
                return
            kind, args, run = "clear_force", {"name": self.force_name}, self.pressing
            self.pressing = None
        else:
            kind, args = msg["kind"], msg["args"]
            kinds = REPLAY_KINDS if replay else LIVE_KINDS
            if kind not in kinds:
                what = "a replay" if replay else "a live run"
                await self._error(rid, f"'{kind}' is not a command of {what} from the page (commands: {', '.join(kinds)})")
                return
        loop = asyncio.get_running_loop()

        def reply(ack, err):  # on the bus thread
            loop.call_soon_threadsafe(lambda: asyncio.ensure_future(self._answer(rid, kind, ack, err)))
        self.hub.link.post(run, kind, args, reply)

    async def _answer(self, rid: int, kind: str, ack, err: str):
        if ack is None:
            await self._error(rid, err)
        else:
            await self._send_json({"type": "ack", "id": rid, "kind": kind, "accepted": ack.accepted,
                                   "reason": ack.reason, "frame": ack.frame, "parameter_version": ack.parameter_version})

    async def _error(self, rid, message: str):
        await self._send_json({"type": "error", "id": rid, "message": message})

    async def _send_json(self, obj: dict):
        if not self.ws.closed:
            await self.ws.send_str(json.dumps(obj))

    async def _send_loop(self):
        while not self.ws.closed:
            await self.wake.wait()
            self.wake.clear()
            try:
                await self._send_pending()
            except ConnectionError:
                return
            except Exception as e:  # a bug must not silence the page: say it there and on stderr
                traceback.print_exc()
                await self._error(None, f"the bridge failed to send: {e!r}")

    async def _send_pending(self):
        dirty, self.dirty = self.dirty, set()
        if "runs" in dirty:
            await self._send_json({"type": "runs", "runs": self.hub.runs()})
            if self.run is None and self.hub.link.statuses:
                self.run = min(dict(self.hub.link.statuses))
                dirty |= {"topology", "status", "circulation"}
        if self.run is None:
            return
        if "topology" in dirty:
            await self._send_topology()
        if "status" in dirty:
            status = self.hub.status(self.run)
            if status is not None:
                await self._send_json(status)
        if "circulation" in dirty:
            await self._send_circulation()
        if self.credit:
            await self._send_frame()

    async def _send_circulation(self):
        """The samples the page has not had (all of the trail after a switch or a restart)."""
        trail = self.hub.circulation(self.run)
        if not trail:
            return
        last = self.circulation_sent
        restart = last is None or trail[-1].frame < last or trail[0].frame > last  # a switch, a reset, or samples missed
        new = trail if restart else [c for c in trail if c.frame > last]
        if not new:
            return
        self.circulation_sent = new[-1].frame
        await self._send_json(circulation_message(self.run, new, restart))

    async def _send_topology(self):
        try:
            surface = self.hub.surface(self.run)
        except FieldUnavailable as e:
            await self._error(None, f"run '{self.run}': {e}")
            return
        if surface is None:
            return
        t = surface.topology
        self.sent_frame = None
        await self._send_json({"type": "topology", "run": self.run, "scene_name": t.scene_name, "replay": t.replay,
                               "vertices": int(surface.nodes.size), "triangles": surface.triangles.ravel().tolist(),
                               "rest": surface.rest.ravel().tolist(), "region_names": t.region_names,
                               "field": self.field})

    async def _send_frame(self):
        try:
            got = self.hub.frame(self.run, self.field)
        except FieldUnavailable as e:
            await self._error(None, f"field '{self.field}': {e}")
            self.field = "activation" if self.field != "activation" else "displacement"
            return
        if got is None or got[0] == self.sent_frame or self.hub.surfaces.get(self.run) is None:
            return
        self.sent_frame, self.credit = got[0], False
        await self.ws.send_bytes(got[1])
