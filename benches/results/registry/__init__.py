"""The calibration registry: every calibration of every unit, in SQLite by default or a lab's PostgreSQL.

* :mod:`.schema` — the tables (SQLAlchemy Core); :mod:`.migrations` — their Alembic history;
* :mod:`.store` — where the database is, opening it at the newest schema, adding a calibration;
* :mod:`.record` — a run folder as rows (as found / as left from the recording);
* :mod:`.queries` — units, histories, series; :mod:`.stats` — E_n, control limits, s_r / s_R, intervals;
* :mod:`.sink` — the registry as the second results sink, and ``registry add``.

See ``docs/registry.md``.
"""

from __future__ import annotations

import importlib
from typing import Any

_LAZY = {
    "ENV": "url",
    "resolve_url": "url",
    "AddOutcome": "store",
    "Registry": "store",
    "RegistryError": "store",
    "RegistrySink": "sink",
    "add_run": "sink",
    "sink_factory": "sink",
}
"""Names imported on first use: the sink reads recordings (h5py, the identification), which the reading
commands (``registry list/show/trend``) never need, and the store imports SQLAlchemy, which a command that
records nothing (``identify RUN --out elsewhere.json``) never needs — a technician's wait is mostly imports."""


def __getattr__(name: str) -> Any:
    if name in _LAZY:
        return getattr(importlib.import_module(f".{_LAZY[name]}", __name__), name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


__all__ = ["ENV", "AddOutcome", "Registry", "RegistryError", "RegistrySink", "add_run", "resolve_url", "sink_factory"]
