"""Registry tests run on both engines: SQLite, and a real PostgreSQL server started here (pgserver.py).

Where no PostgreSQL is installed, the end of the run says so in one line (``tests.NOTES``) and only SQLite runs.
"""

from __future__ import annotations

from collections.abc import Iterator

import pytest

from tests import NOTES
from tests.benches.registry.pgserver import PostgresServer, find_binaries

_PG_BIN = find_binaries()
ENGINES = ("sqlite", "postgresql") if _PG_BIN is not None else ("sqlite",)
if _PG_BIN is None:
    NOTES.append(
        "registry tests: NO PostgreSQL installed (no initdb/pg_ctl; Debian: apt install postgresql-15) — the "
        "PostgreSQL cases did NOT run, SQLite only"
    )


@pytest.fixture(scope="session")
def pg_server() -> Iterator[PostgresServer]:
    assert _PG_BIN is not None
    server = PostgresServer(_PG_BIN)
    server.start()
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
