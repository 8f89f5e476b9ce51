"""Message transports: the small seam between a text-protocol driver and an open instrument link.

A driver of a message-based instrument (the ACUTROL3000 command language, :mod:`drivers.acutrol`) receives an
**open** :class:`MessageTransport` and never opens links itself; only ``benches/factory.py`` opens them.

* :func:`open_visa` opens a resource string with pyvisa's pure-Python backend (for the factory).
* :class:`VisaTransport` adapts an open pyvisa resource (``TCPIP0::host::9878::SOCKET``, ``GPIB0::1::INSTR``,
  ``ASRL/dev/ttyS0::INSTR`` — opened by the factory with the pure-Python pyvisa-py backend) and turns pyvisa's
  errors into :class:`~drivers.protocols.LinkError`.
* The simulated ACL controller offers an in-memory transport with the same methods
  (:meth:`drivers.sim.acl_controller.AclController.transport`).

One message = one string without its terminator; :meth:`read` returns one reply message with the terminator
(LF, CR-LF) stripped.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Protocol, runtime_checkable

from drivers.protocols import LinkError

if TYPE_CHECKING:
    from pyvisa.resources import MessageBasedResource  # pyvisa itself is imported when a link is opened


@runtime_checkable
class MessageTransport(Protocol):
    """An open, message-based link to one instrument."""

    timeout: float
    """Longest wait for a reply message, s."""

    def write(self, message: str) -> None:
        """Send one program message (the terminator is added by the transport)."""
        ...

    def read(self) -> str:
        """Return the next reply message without its terminator; LinkError if none arrives within ``timeout``."""
        ...

    def query(self, message: str) -> str:
        """``write(message)`` then ``read()``."""
        ...


class VisaTransport:
    """:class:`MessageTransport` over an open pyvisa message-based resource (the caller opened it).

    Parameters
    ----------
    resource : pyvisa resource
        Open ``MessageBasedResource`` with ``read_termination`` set (the factory uses ``"\\n"``; a trailing CR
        is stripped here, so CR-LF replies work too).
    name : str
        The resource string, for messages.
    """

    def __init__(self, resource: MessageBasedResource, name: str = "") -> None:
        self.resource = resource
        self.name = name or str(getattr(resource, "resource_name", "VISA resource"))

    @property
    def timeout(self) -> float:
        """Reply timeout, s (pyvisa keeps milliseconds)."""
        t = self.resource.timeout
        return float("inf") if t is None else float(t) / 1000.0

    @timeout.setter
    def timeout(self, seconds: float) -> None:
        self.resource.timeout = max(1, int(round(float(seconds) * 1000.0)))

    def _fail(self, what: str, exc: Exception) -> LinkError:
        import pyvisa

        if isinstance(exc, pyvisa.errors.VisaIOError) and exc.error_code == pyvisa.constants.StatusCode.error_timeout:
            return LinkError(
                f"{self.name}: no reply within {self.timeout:.3g} s to {what}; check power, cable, address and that "
                "the controller is in remote mode"
            )
        return LinkError(f"{self.name}: link failed on {what} ({exc.__class__.__name__}: {exc})")

    def write(self, message: str) -> None:
        """Send one message."""
        try:
            self.resource.write(message)
        except Exception as exc:  # pyvisa.VisaIOError, OSError, ConnectionError
            raise self._fail(repr(message), exc) from exc

    def read(self) -> str:
        """One reply message, terminator (LF, CR-LF) stripped."""
        try:
            text = self.resource.read()
        except Exception as exc:
            raise self._fail("a read", exc) from exc
        return text.rstrip("\r\n")

    def query(self, message: str) -> str:
        """Write then read."""
        self.write(message)
        return self.read()


def open_visa(resource: str, timeout: float) -> MessageBasedResource:
    """Open a VISA resource with the pure-Python pyvisa-py backend (``ResourceManager("@py")``).

    Called by ``benches/factory.py`` and the loopback harness, never by a driver.

    LF is the read and write terminator (a CR before the LF is stripped by the transport). GPIB resources need
    linux-gpib or gpib-ctypes (and a GPIB board); their absence is reported as a LinkError saying so.
    """
    import pyvisa

    try:
        rm = pyvisa.ResourceManager("@py")
    except Exception as exc:  # pragma: no cover - pyvisa-py missing
        raise LinkError(f"cannot start pyvisa with the pyvisa-py backend ({exc}); install pyvisa-py") from exc
    try:
        res = rm.open_resource(resource, read_termination="\n", write_termination="\n", timeout=int(timeout * 1000))
    except Exception as exc:
        detail = " ".join(str(exc).split())
        if resource.strip().upper().startswith("GPIB"):
            raise LinkError(
                f"cannot open VISA resource {resource!r}: GPIB with pyvisa-py needs linux-gpib or gpib-ctypes "
                f"installed and a GPIB board (or NI-VISA with pyvisa's default backend); pyvisa-py says: {detail}"
            ) from exc
        raise LinkError(f"cannot open VISA resource {resource!r}: {exc.__class__.__name__}: {detail}") from exc
    return res


__all__ = ["MessageTransport", "VisaTransport", "open_visa"]
