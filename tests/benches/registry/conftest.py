"""Registry tests run on both engines: SQLite, and a real PostgreSQL server started here (pgserver.py).

Where no PostgreSQL is installed, the session summary says so in one line and only SQLite runs.
"""

from __future__ import annotations

from collections.abc import Iterator

import pytest

from tests.benches.registry.pgserver import PostgresServer, find_binaries

_PG_BIN = find_binaries()
ENGINES = ("sqlite", "postgresql") if _PG_BIN is not None else ("sqlite",)
_STATUS: list[str] = []


@pytest.fixture(scope="session")
def pg_server() -> Iterator[PostgresServer]:
    assert _PG_BIN is not None
    server = PostgresServer(_PG_BIN)
    server.start()
    _STATUS.append(f"registry tests: real PostgreSQL server from {_PG_BIN} on 127.0.0.1:{server.port}")
    try:
        yield server
    finally:
        server.stop()


@pytest.fixture(params=ENGINES)
def registry_url(request, tmp_path) -> str:
    """An empty registry database of each engine (SQLite file; a new PostgreSQL database)."""
    if request.param == "sqlite":
        return f"sqlite:///{tmp_path / 'registry.sqlite'}"
    return request.getfixturevalue("pg_server").new_database()


def pytest_terminal_summary(terminalreporter) -> None:
    if _PG_BIN is None:
        terminalreporter.write_line(
            "registry tests: NO PostgreSQL installed (no initdb/pg_ctl; Debian: apt install postgresql-15) — "
            "the PostgreSQL cases did NOT run, SQLite only"
        )
    for line in _STATUS:
        terminalreporter.write_line(line)
