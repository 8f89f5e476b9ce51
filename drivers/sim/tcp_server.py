"""Lifecycle shared by the single-client loopback servers of the simulated devices."""

from __future__ import annotations

import socket
import threading
from typing import Any


class SingleClientServer:
    """Mixin: a listening socket served by one thread for one client at a time.

    Subclasses set ``_listener`` (socket), ``_thread`` (threading.Thread), ``_stop`` (threading.Event),
    ``_client`` (socket or None) and ``_client_lock`` (threading.Lock) in their constructor.
    """

    _listener: socket.socket
    _thread: threading.Thread
    _stop: threading.Event
    _client: socket.socket | None
    _client_lock: threading.Lock

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
