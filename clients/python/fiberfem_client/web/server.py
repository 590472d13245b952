"""The HTTP side of `fiberfem web` (aiohttp): the page's files and the /ws WebSocket.

Who may steer: nobody with --read-only; nobody when the DDS identity may not write commands
(an observer in secure mode); on an address other than loopback, only pages that pass the
token printed at start (`?token=...`, compared in constant time)."""

import asyncio
import hmac
import ipaddress
import os
import socket
from typing import Optional

from aiohttp import web

from .hub import Hub
from .protocol import MAX_MESSAGE_BYTES
from .session import Session


def is_loopback(address: str) -> bool:
    """True when every address the name resolves to is a loopback one."""
    try:
        infos = socket.getaddrinfo(address, None)
    except OSError as e:
        raise ValueError(f"--listen {address}: {e.strerror or e}") from None
    return all(ipaddress.ip_address(i[4][0]).is_loopback for i in infos)


class Access:
    def __init__(self, read_only: bool, token: Optional[str], commands_refused: str):
        self.read_only, self.token, self.commands_refused = read_only, token, commands_refused

    def refused(self, request: web.Request) -> str:
        """Why a page may not steer ("" when it may)."""
        if self.read_only:
            return "this bridge runs --read-only"
        if self.commands_refused:
            return self.commands_refused
        if self.token is not None:
            given = request.query.get("token", "")
            if not hmac.compare_digest(given.encode(), self.token.encode()):
                return "commands need the token printed when fiberfem web started (open the page as /?token=...)"
        return ""


def make_app(hub: Hub, access: Access, static_dir: str, default_run: Optional[str]) -> web.Application:
    async def index(request: web.Request):
        return web.FileResponse(os.path.join(static_dir, "index.html"), headers={"Cache-Control": "no-cache"})

    async def websocket(request: web.Request):
        ws = web.WebSocketResponse(max_msg_size=MAX_MESSAGE_BYTES, heartbeat=20)
        await ws.prepare(request)
        session = Session(hub, ws, default_run, access.refused(request))
        hub.sessions.add(session)
        try:
            await session.serve()
        finally:
            hub.sessions.discard(session)
        return ws

    app = web.Application()
    app.router.add_get("/", index)
    app.router.add_get("/ws", websocket)
    app.router.add_static("/", static_dir, show_index=False)
    return app


async def serve(app: web.Application, listen: str, port: int) -> web.AppRunner:
    runner = web.AppRunner(app, handle_signals=False)
    await runner.setup()
    await web.TCPSite(runner, listen, port).start()
    return runner


def run_forever(app: web.Application, listen: str, port: int, on_ready):
    loop = asyncio.get_event_loop()
    runner = loop.run_until_complete(serve(app, listen, port))
    on_ready()
    try:
        loop.run_forever()
    finally:
        loop.run_until_complete(runner.cleanup())
