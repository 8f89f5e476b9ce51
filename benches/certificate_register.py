"""Document control: the certificate register kept in the runs folder.

Every certificate gets its number from the register file ``certificate-register.jsonl`` in the folder that
holds the run folders (the run folder's parent, ``runs/`` by default): one JSON line per number issued, in
order. Numbers are ``TB-000001``, ``TB-000002``, … — monotonic, never reused (a number is consumed when it is
allocated, even if writing the certificate then fails). Two processes issuing at the same moment are
serialised by a lock file created with ``O_CREAT | O_EXCL`` (a lock left by a dead process is broken after
checking its process id). A re-issue for the same run gets a new number and names the one it supersedes.
Files are never overwritten: :func:`free_paths` picks ``certificate.pdf`` for a run's first certificate and
``certificate-<number>.pdf`` after that.
"""

from __future__ import annotations

import datetime as _dt
import json
import os
import time
from collections.abc import Callable
from dataclasses import asdict, dataclass
from pathlib import Path

from core.errors import UserError
from core.outputs import check_output

REGISTER_NAME = "certificate-register.jsonl"
LOCK_NAME = "certificate-register.lock"
PREFIX = "TB-"


class RegisterError(UserError, RuntimeError):
    """The certificate register cannot be read or written; the message names the file and the fix."""


@dataclass(frozen=True)
class Registration:
    """One line of the register.

    Attributes
    ----------
    number : str
        The certificate number (``TB-000042``).
    serial : int
    run : str
        The run folder (resolved path).
    recording_sha256 : str
    supersedes : str
        The number this certificate replaces ('' for a run's first certificate).
    issued_utc : str
    pdf, json : str
        Where the certificate was written.
    """

    number: str
    serial: int
    run: str
    recording_sha256: str
    supersedes: str
    issued_utc: str
    pdf: str
    json: str


class _Lock:
    """An exclusive lock file (O_EXCL); a lock whose writer process is gone is broken."""

    def __init__(self, path: Path, timeout_s: float = 30.0) -> None:
        self.path = path
        self.timeout_s = timeout_s

    def __enter__(self) -> _Lock:
        t0 = time.monotonic()
        while True:
            try:
                fd = os.open(self.path, os.O_CREAT | os.O_EXCL | os.O_WRONLY, 0o644)
            except FileExistsError:
                if self._stale():
                    try:
                        os.unlink(self.path)
                    except FileNotFoundError:
                        pass
                    continue
                if time.monotonic() - t0 > self.timeout_s:
                    raise RegisterError(
                        f"{self.path}: the certificate register is locked by another process; if none is issuing "
                        "a certificate, delete this lock file"
                    ) from None
                time.sleep(0.05)
                continue
            except OSError as exc:
                raise RegisterError(f"{self.path}: cannot lock the certificate register ({exc.strerror})") from None
            with os.fdopen(fd, "w") as fh:
                fh.write(str(os.getpid()))
            return self

    def _stale(self) -> bool:
        try:
            pid = int(self.path.read_text().strip() or "0")
        except (OSError, ValueError):
            return False  # being written right now, or unreadable: wait
        if pid <= 0:
            return False
        try:
            os.kill(pid, 0)
        except ProcessLookupError:
            return True
        except PermissionError:
            return False
        return False

    def __exit__(self, *exc: object) -> None:
        try:
            os.unlink(self.path)
        except FileNotFoundError:
            pass


class CertificateRegister:
    """The register in ``folder`` (created on first use)."""

    def __init__(self, folder: str | Path) -> None:
        self.folder = Path(folder)
        self.path = self.folder / REGISTER_NAME

    @classmethod
    def for_run(cls, run: str | Path) -> CertificateRegister:
        """The register of the runs folder holding ``run``."""
        return cls(Path(run).resolve().parent)

    def entries(self) -> list[Registration]:
        """Every number issued so far, in order."""
        if not self.path.exists():
            return []
        out: list[Registration] = []
        try:
            lines = self.path.read_text(encoding="utf-8").splitlines()
        except (OSError, UnicodeDecodeError) as exc:
            raise RegisterError(f"{self.path}: cannot read the certificate register ({exc})") from None
        for k, line in enumerate(lines, 1):
            if not line.strip():
                continue
            try:
                d = json.loads(line)
                out.append(Registration(**{f: d[f] for f in Registration.__dataclass_fields__}))
            except (ValueError, KeyError, TypeError):
                raise RegisterError(
                    f"{self.path}:{k}: not a register line; the register is damaged — restore it from a backup "
                    "(numbers must never be reused)"
                ) from None
        return out

    def latest_for(self, run: str | Path) -> Registration | None:
        """The last certificate issued for ``run`` (None if none)."""
        key = str(Path(run).resolve())
        hits = [e for e in self.entries() if e.run == key]
        return hits[-1] if hits else None

    def allocate(
        self, run: str | Path, recording_sha256: str, paths: Callable[[str], tuple[Path, Path]]
    ) -> Registration:
        """Allocate the next number for ``run`` (under the lock) and record it; names the one it supersedes.

        ``paths(number)`` gives the PDF and JSON paths the certificate will be written to.
        """
        try:
            self.folder.mkdir(parents=True, exist_ok=True)
        except OSError as exc:
            raise RegisterError(f"{self.folder}: cannot create the runs folder ({exc.strerror})") from None
        with _Lock(self.folder / LOCK_NAME):
            entries = self.entries()
            serial = max((e.serial for e in entries), default=0) + 1
            key = str(Path(run).resolve())
            prev = [e for e in entries if e.run == key]
            number = f"{PREFIX}{serial:06d}"
            pdf, json_path = paths(number)
            reg = Registration(
                number=number,
                serial=serial,
                run=key,
                recording_sha256=recording_sha256,
                supersedes=prev[-1].number if prev else "",
                issued_utc=_dt.datetime.now(_dt.timezone.utc).strftime("%Y-%m-%dT%H:%M:%SZ"),
                pdf=str(pdf),
                json=str(json_path),
            )
            try:
                with open(self.path, "a", encoding="utf-8") as fh:
                    fh.write(json.dumps(asdict(reg), sort_keys=True) + "\n")
                    fh.flush()
                    os.fsync(fh.fileno())
            except OSError as exc:
                raise RegisterError(f"{self.path}: cannot write the certificate register ({exc.strerror})") from None
        return reg


def free_paths(run: Path, number: str, stem: str = "certificate") -> tuple[Path, Path]:
    """Default PDF/JSON paths: ``<stem>.pdf`` if free, else ``<stem>-<number>.pdf`` (never overwritten); the stem
    is ``certificate``, or ``noise-report`` for the noise report of a static record."""
    pdf, js = run / f"{stem}.pdf", run / f"{stem}.json"
    if pdf.exists() or js.exists():
        pdf, js = run / f"{stem}-{number}.pdf", run / f"{stem}-{number}.json"
    return pdf, js


def write_new(path: Path, data: bytes) -> None:
    """Write ``data`` to a file that must not exist yet (atomic: temporary file + link; never overwrites)."""
    check_output(path)
    tmp = path.with_name(f".{path.name}.{os.getpid()}.tmp")
    try:
        tmp.write_bytes(data)
        os.link(tmp, path)  # fails if ``path`` exists
    except FileExistsError:
        raise RegisterError(f"{path}: already exists; a certificate is never overwritten (choose a new name)") from None
    except OSError as exc:
        raise RegisterError(f"{path}: cannot write the certificate ({exc.strerror})") from None
    finally:
        try:
            tmp.unlink()
        except FileNotFoundError:
            pass


__all__ = ["CertificateRegister", "RegisterError", "Registration", "free_paths", "write_new"]
