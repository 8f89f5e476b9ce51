"""The live view's web server: a read-only page, its vendored assets and a server-sent-events stream.

Starlette + uvicorn in a background thread of the process that runs the bench (``tablebench run --live``) or
that follows a run (``tablebench view``). Every route answers GET only (anything else: 405), and no route
changes anything: the bench is stopped at the bench (Ctrl-C in its terminal), never from a browser. The
server binds to 127.0.0.1 unless the user names another address.

Routes: ``/`` the page; ``/static/<asset>`` the vendored page assets (no CDN: lab networks are often
offline); ``/events`` the event stream (``Last-Event-ID`` resumes after a dropped connection);
``/files/<name>`` the run's results (calibration.json, certificate.json, certificate PDF and plots) once
they exist.
"""

from __future__ import annotations

import asyncio
import socket
import threading
import time
from pathlib import Path

from core.errors import UsageError

from .feed import LiveFeed

DEFAULT_HOST = "127.0.0.1"
DEFAULT_PORT = 8765
"""The live view's port when ``--live`` names none (documented in the README and ``run --help``)."""

STATIC_DIR = Path(__file__).with_name("static")
ASSETS = {
    "live.js": "text/javascript",
    "live.css": "text/css",
    "uPlot.iife.min.js": "text/javascript",
    "uPlot.min.css": "text/css",
}
RESULT_SUFFIXES = (".json", ".pdf", ".png")
RETRY_MS = 1000
KEEPALIVE_S = 10.0


def parse_address(text: str | None) -> tuple[str, int]:
    """``[HOST:]PORT`` (``[::1]:PORT`` for IPv6; empty: the defaults) → (host, port); UsageError if malformed."""
    if text is None or text == "":
        return DEFAULT_HOST, DEFAULT_PORT
    host, sep, port_txt = text.rpartition(":")
    if not sep:
        host, port_txt = DEFAULT_HOST, text
    host = host.strip("[]") or DEFAULT_HOST
    try:
        port = int(port_txt)
    except ValueError:
        port = -1
    if not 0 < port < 65536:
        raise UsageError(f"--live {text}: not [HOST:]PORT; give e.g. --live 8765 or --live 0.0.0.0:8765")
    return host, port


def check_free(host: str, port: int, option: str = "--live") -> None:
    """Refuse, before anything moves, an address that cannot be served (in use, not local, unknown host)."""
    try:
        infos = socket.getaddrinfo(host, port, type=socket.SOCK_STREAM)
    except socket.gaierror as exc:
        raise UsageError(
            f"{option} {host}:{port}: unknown host ({exc.strerror}); name this machine's address"
        ) from None
    family, _, _, _, addr = infos[0]
    with socket.socket(family, socket.SOCK_STREAM) as s:
        s.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)  # as uvicorn does: a closed page's TIME_WAIT is fine
        try:
            s.bind(addr)
        except OSError as exc:
            raise UsageError(
                f"{option} {host}:{port}: cannot serve there ({exc.strerror}); choose another port, e.g. "
                f"{option} {port + 1}"
            ) from None


def build_app(feed: LiveFeed, run_folder: Path | None, server: LiveServer | None = None):  # noqa: ANN201
    """The Starlette application serving ``feed`` (and the results in ``run_folder``)."""
    from starlette.applications import Starlette  # lazy: starlette (--help time)
    from starlette.requests import Request  # lazy: starlette (--help time)
    from starlette.responses import (  # lazy: starlette (--help time)
        FileResponse,
        HTMLResponse,
        PlainTextResponse,
        Response,
        StreamingResponse,
    )
    from starlette.routing import Route  # lazy: starlette (--help time)

    page = (STATIC_DIR / "index.html").read_text(encoding="utf-8")

    async def index(_request: Request) -> Response:
        return HTMLResponse(page, headers={"Cache-Control": "no-store"})

    async def static(request: Request) -> Response:
        name = request.path_params["name"]
        if name not in ASSETS:
            return PlainTextResponse("no such asset", status_code=404)
        return FileResponse(STATIC_DIR / name, media_type=ASSETS[name])

    async def files(request: Request) -> Response:
        name = request.path_params["name"]
        if run_folder is None or "/" in name or name.startswith(".") or not name.endswith(RESULT_SUFFIXES):
            return PlainTextResponse("not a result of this run", status_code=404)
        path = run_folder / name
        if not path.is_file():
            return PlainTextResponse(f"{name} does not exist (yet)", status_code=404)
        return FileResponse(path)

    async def events(request: Request) -> Response:
        header = request.headers.get("last-event-id") or request.query_params.get("last") or "0"
        try:
            last = max(int(header), 0)
        except ValueError:
            last = 0
        generation = server.generation if server is not None else 0

        async def stream():  # noqa: ANN202
            nonlocal last
            yield f"retry: {RETRY_MS}\n\n"
            quiet = time.monotonic()
            while True:
                if server is not None and (server.generation != generation or server.stopping):
                    return  # dropped by the server: the browser reconnects with Last-Event-ID
                new = feed.since(last)
                if new:
                    for ev in new:
                        yield ev.to_sse()
                    last = new[-1].id
                    quiet = time.monotonic()
                elif feed.closed:
                    return
                elif time.monotonic() - quiet > KEEPALIVE_S:
                    yield ": keep-alive\n\n"
                    quiet = time.monotonic()
                if await request.is_disconnected():
                    return
                await asyncio.sleep(0.1)

        return StreamingResponse(
            stream(),
            media_type="text/event-stream",
            headers={"Cache-Control": "no-store", "X-Accel-Buffering": "no"},
        )

    routes = [
        Route("/", index, methods=["GET"]),
        Route("/static/{name}", static, methods=["GET"]),
        Route("/files/{name}", files, methods=["GET"]),
        Route("/events", events, methods=["GET"]),
    ]
    return Starlette(routes=routes)


class LiveServer:
    """The live view served from a background thread.

    Parameters
    ----------
    feed : LiveFeed
    host, port : str, int
        Where to listen (port 0: any free port; :attr:`port` tells which).
    run_folder : Path, optional
        Whose results ``/files/`` serves.
    """

    def __init__(
        self, feed: LiveFeed, host: str = DEFAULT_HOST, port: int = DEFAULT_PORT, run_folder: Path | None = None
    ):
        import uvicorn  # lazy: uvicorn (--help time)

        self.feed = feed
        self.host = host
        self.generation = 0
        self.stopping = False
        config = uvicorn.Config(
            build_app(feed, run_folder, self), host=host, port=port, log_level="error", access_log=False, lifespan="off"
        )
        self._server = uvicorn.Server(config)
        self._thread = threading.Thread(target=self._server.run, name="tablebench-live", daemon=True)
        self.port = port

    def start(self, timeout: float = 10.0) -> LiveServer:
        """Start serving; returns once the socket listens (UsageError if it cannot)."""
        self._thread.start()
        t_end = time.monotonic() + timeout
        while not self._server.started:
            if not self._thread.is_alive() or time.monotonic() > t_end:
                raise UsageError(f"--live {self.host}:{self.port}: the live view could not start; choose another port")
            time.sleep(0.01)
        servers = getattr(self._server, "servers", None) or []
        for srv in servers:
            for sock in srv.sockets:
                self.port = int(sock.getsockname()[1])
                break
        return self

    @property
    def url(self) -> str:
        """The page's address."""
        host = f"[{self.host}]" if ":" in self.host else self.host
        return f"http://{host}:{self.port}/"

    def drop_connections(self) -> None:
        """End every open event stream (the browsers reconnect and continue after their last event)."""
        self.generation += 1

    def close(self, timeout: float = 5.0) -> None:
        """Stop serving (open streams end; the page says the server closed)."""
        self.stopping = True
        self._server.should_exit = True
        if self._thread.is_alive():
            self._thread.join(timeout)
