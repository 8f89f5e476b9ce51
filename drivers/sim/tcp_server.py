"""Lifecycle shared by the single-client loopback servers of the simulated devices."""

from __future__ import annotations

import logging
import select
import socket
import threading
from typing import Any

log = logging.getLogger(__name__)


class SingleClientServer:
    """Mixin: a listening socket served by one thread for one client at a time.

    Subclasses call :meth:`_listen` in their constructor, then start ``_thread`` once they are set up.
    """

    _listener: socket.socket
    _thread: threading.Thread
    _stop: threading.Event
    _client: socket.socket | None
    _client_lock: threading.Lock

    port: int
    name: str = "simulated device"

    def _listen(self, port: int, thread_name: str) -> None:
        """Listen on 127.0.0.1:``port`` (0: ephemeral; the bound one is :attr:`port`) and prepare the serving
        thread ``thread_name:PORT`` (not started)."""
        self._listener = socket.create_server(("127.0.0.1", port))
        self._listener.setblocking(False)
        self.port = self._listener.getsockname()[1]
        self._stop = threading.Event()
        self._client = None
        self._client_lock = threading.Lock()
        self._thread = threading.Thread(target=self._serve, name=f"{thread_name}:{self.port}", daemon=True)

    def _handle(self, conn: socket.socket) -> None:
        """Serve one connected client until it goes away or the server stops (subclasses)."""
        raise NotImplementedError

    def _on_idle(self) -> None:
        """Called every 50 ms while no client is connected (e.g. a watchdog check)."""

    def _on_client_gone(self) -> None:
        """Called after a client has gone (e.g. stop the table if motion was commanded)."""

    def _serve(self) -> None:
        """Accept one client at a time and hand it to :meth:`_handle`; runs in ``_thread``."""
        while not self._stop.is_set():
            self._on_idle()
            r, _, _ = select.select([self._listener], [], [], 0.05)
            if not r:
                continue
            try:
                conn, addr = self._listener.accept()
            except OSError:
                continue
            conn.setblocking(True)
            conn.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
            with self._client_lock:
                self._client = conn
            log.info("%s: client %s connected", self.name, addr)
            try:
                self._handle(conn)
            except OSError as exc:
                log.info("%s: client gone (%s)", self.name, exc)
            except Exception:  # a bug must not kill the server thread silently
                log.exception("%s: internal error; dropping the client", self.name)
            finally:
                with self._client_lock:
                    self._client = None
                try:
                    conn.close()
                except OSError:
                    pass
                self._on_client_gone()

    def disconnect(self) -> None:
        """Drop the current client connection (simulates a pulled cable); the server keeps listening."""
        with self._client_lock:
            if self._client is not None:
                try:
                    self._client.shutdown(socket.SHUT_RDWR)
                except OSError:
                    pass

    def close(self) -> None:
        """Stop serving, drop the client, close the listener and join the thread (idempotent)."""
        if self._stop.is_set():
            return
        self._stop.set()
        self.disconnect()
        self._thread.join(timeout=2.0)
        try:
            self._listener.close()
        except OSError:
            pass

    def __enter__(self) -> Any:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
