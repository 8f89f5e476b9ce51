"""A real PostgreSQL server for the registry tests, started from the machine's binaries (Debian: postgresql-15).

``initdb`` refuses to run as root: as root the server runs as the ``postgres`` system user (``runuser``), in a
temporary data directory it owns, listening on 127.0.0.1 at a free port with trust authentication, and is
stopped at the end of the session. :func:`find_binaries` returns None where no PostgreSQL is installed; the
tests then say so in one line of the session summary (never silently).
"""

from __future__ import annotations

import os
import shutil
import socket
import subprocess
import tempfile
import time
from pathlib import Path

SEARCH = ("/usr/lib/postgresql/*/bin", "/usr/pgsql-*/bin", "/usr/local/pgsql/bin")


def find_binaries() -> Path | None:
    """The newest PostgreSQL bin directory with initdb and pg_ctl (PATH first), or None."""
    on_path = shutil.which("initdb")
    if on_path and shutil.which("pg_ctl"):
        return Path(on_path).resolve().parent
    found = []
    for pattern in SEARCH:
        root = Path("/")
        found += [p for p in root.glob(pattern.lstrip("/")) if (p / "initdb").exists() and (p / "pg_ctl").exists()]
    if not found:
        return None

    def version(p: Path) -> tuple[int, ...]:
        digits = "".join(ch if ch.isdigit() else " " for ch in str(p))
        return tuple(int(x) for x in digits.split()) or (0,)

    return max(found, key=version)


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


class PostgresServer:
    """A throw-away server; :meth:`url` gives an SQLAlchemy URL of a new empty database."""

    def __init__(self, bindir: Path) -> None:
        self.bindir = bindir
        self.root = Path(tempfile.mkdtemp(prefix="tablebench-pg-"))
        self.data = self.root / "data"
        self.port = _free_port()
        self._as_root = os.geteuid() == 0
        self._n = 0
        os.chmod(self.root, 0o755)
        if self._as_root:
            shutil.chown(self.root, "postgres", "postgres")

    def _run(self, *cmd: str, timeout: float = 120) -> subprocess.CompletedProcess:
        full = ["runuser", "-u", "postgres", "--", *cmd] if self._as_root else list(cmd)
        return subprocess.run(full, capture_output=True, text=True, timeout=timeout, check=False, cwd=self.root)

    def start(self) -> None:
        r = self._run(str(self.bindir / "initdb"), "-D", str(self.data), "-U", "postgres", "--auth=trust",
                      "-E", "UTF8", "--locale=C")  # fmt: skip
        if r.returncode != 0:
            raise RuntimeError(f"initdb failed: {r.stderr.strip()[-400:]}")
        opts = f"-c listen_addresses=127.0.0.1 -p {self.port} -k {self.root} -c fsync=off -c max_connections=60"
        r = self._run(str(self.bindir / "pg_ctl"), "-D", str(self.data), "-o", opts, "-l",
                      str(self.root / "server.log"), "-w", "-t", "60", "start")  # fmt: skip
        if r.returncode != 0:
            logf = self.root / "server.log"
            log = logf.read_text(errors="replace")[-400:] if logf.exists() else ""
            raise RuntimeError(f"pg_ctl start failed: {r.stderr.strip()[-300:]} {log}")
        deadline = time.monotonic() + 30
        while time.monotonic() < deadline:
            try:
                with socket.create_connection(("127.0.0.1", self.port), timeout=1):
                    return
            except OSError:
                time.sleep(0.2)
        raise RuntimeError("the PostgreSQL server did not accept connections within 30 s")

    def new_database(self) -> str:
        """Create an empty database; its URL (``postgresql+psycopg://postgres@127.0.0.1:PORT/NAME``)."""
        import psycopg

        self._n += 1
        name = f"tb{os.getpid()}_{self._n}"
        with psycopg.connect(f"host=127.0.0.1 port={self.port} user=postgres dbname=postgres", autocommit=True) as c:
            c.execute(f'CREATE DATABASE "{name}"')
        return f"postgresql+psycopg://postgres@127.0.0.1:{self.port}/{name}"

    def stop(self) -> None:
        try:
            self._run(str(self.bindir / "pg_ctl"), "-D", str(self.data), "-m", "immediate", "-w", "stop", timeout=60)
        finally:
            shutil.rmtree(self.root, ignore_errors=True)
