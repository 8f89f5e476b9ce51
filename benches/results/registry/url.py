"""Where the registry is: the URL a command records into (no database library imported here).

``--registry URL`` (a command option) wins, then the ``TABLEBENCH_REGISTRY`` environment variable, then the
SQLite file ``registry.sqlite`` in the runs folder; ``off`` switches the registry off for that command
(:mod:`.store` opens it; ``docs/registry.md``). Kept apart from :mod:`.store` so that a command that turns out
not to record anything (``identify RUN --out elsewhere.json``) does not import SQLAlchemy to find that out.
"""

from __future__ import annotations

import os
from pathlib import Path

ENV = "TABLEBENCH_REGISTRY"
DEFAULT_FILE = "registry.sqlite"
OFF = "off"


def resolve_url(option: str | None, runs_folder: str | Path | None) -> str | None:
    """The registry URL for a command (None: switched off).

    ``option`` (``--registry``) wins, then :data:`ENV`, then ``<runs folder>/registry.sqlite``.
    """
    given = option if option not in (None, "") else os.environ.get(ENV, "")
    if given and given.strip().lower() == OFF:
        return None
    if not given:
        if runs_folder is None:
            return None
        return f"sqlite:///{Path(runs_folder).resolve() / DEFAULT_FILE}"
    if "://" not in given:
        return f"sqlite:///{Path(given).expanduser().resolve()}"
    if given.startswith("postgresql://") or given.startswith("postgres://"):
        return "postgresql+psycopg://" + given.split("://", 1)[1]
    return given


__all__ = ["DEFAULT_FILE", "ENV", "OFF", "resolve_url"]
