"""`python -m fiberfem_client.web --static DIR [--port 8080] [--listen ADDRESS] [--run ID]
[--read-only]`: the bridge behind `fiberfem web` (docs/web.md)."""

import argparse
import asyncio
import os
import secrets
import signal
import sys


def parse_args(argv):
    ap = argparse.ArgumentParser(prog="fiberfem web")
    ap.add_argument("--static", required=True, help="folder of the bundled page (index.html, app.js)")
    ap.add_argument("--port", type=int, default=8080, help="TCP port, in [1, 65535] (default 8080)")
    ap.add_argument("--listen", default="127.0.0.1", help="address to listen on (default 127.0.0.1)")
    ap.add_argument("--run", help="run shown first (default: the first run seen)")
    ap.add_argument("--read-only", action="store_true", help="pages watch only: no commands")
    a = ap.parse_args(argv)
    if not 1 <= a.port <= 65535:
        ap.error(f"--port {a.port}: must be in [1, 65535]")
    if not os.path.isfile(os.path.join(a.static, "index.html")) or not os.path.isfile(os.path.join(a.static, "app.js")):
        ap.error(f"--static {a.static}: no bundled page there (index.html, app.js); build it: scripts/setup.sh")
    return a


def main(argv=None):
    a = parse_args(argv)
    try:
        import aiohttp  # noqa: F401
    except ImportError:
        print("fiberfem web: the Python package aiohttp is missing from this environment: run scripts/setup.sh",
              file=sys.stderr)
        return 3
    from ..client import Client
    from .bus_link import BusLink
    from .hub import Hub
    from .server import Access, is_loopback, make_app, run_forever

    try:
        token = None if is_loopback(a.listen) else secrets.token_urlsafe(18)
    except ValueError as e:
        print(f"fiberfem web: {e}", file=sys.stderr)
        return 2
    loop = asyncio.new_event_loop()
    asyncio.set_event_loop(loop)
    hub = Hub(loop)
    client = Client(client_id=f"web-{os.getpid()}")
    hub.link = BusLink(client, hub.from_bus)
    hub.link.start()
    app = make_app(hub, Access(a.read_only, token, client.commands_refused), a.static, a.run)
    host = f"[{a.listen}]" if ":" in a.listen else a.listen
    url = f"http://{host}:{a.port}/" + (f"?token={token}" if token else "")

    def ready():
        print(f"fiberfem web: serving {url}" + (" (read-only)" if a.read_only else ""), flush=True)
        if token:
            print(f"fiberfem web: commands need the token: {token}", flush=True)

    loop.add_signal_handler(signal.SIGINT, loop.stop)
    loop.add_signal_handler(signal.SIGTERM, loop.stop)
    try:
        run_forever(app, a.listen, a.port, ready)
    except OSError as e:
        print(f"fiberfem web: cannot listen on {a.listen} port {a.port}: {e.strerror or e}", file=sys.stderr)
        return 2
    finally:
        hub.link.stop()
    return 0


if __name__ == "__main__":
    sys.exit(main())
