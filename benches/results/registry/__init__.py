"""The calibration registry: every calibration of every unit, in SQLite by default or a lab's PostgreSQL.

* :mod:`.schema` — the tables (SQLAlchemy Core); :mod:`.migrations` — their Alembic history;
* :mod:`.store` — where the database is, opening it at the newest schema, adding a calibration;
* :mod:`.record` — a run folder as rows (as found / as left from the recording);
* :mod:`.queries` — units, histories, series; :mod:`.stats` — E_n, control limits, s_r / s_R, intervals;
* :mod:`.sink` — the registry as the second results sink, and ``registry add``.

See ``docs/registry.md``.
"""

from __future__ import annotations

from .sink import RegistrySink, add_run, sink_factory
from .store import ENV, AddOutcome, Registry, RegistryError, resolve_url

__all__ = ["ENV", "AddOutcome", "Registry", "RegistryError", "RegistrySink", "add_run", "resolve_url", "sink_factory"]
