"""The registry's database: where it is (URL), opening it at the newest schema, and adding one calibration.

Where: ``--registry URL`` (a command option), else the ``TABLEBENCH_REGISTRY`` environment variable, else the
SQLite file ``registry.sqlite`` in the runs folder. A URL is an SQLAlchemy URL (``sqlite:///path``,
``postgresql://user@host/db``; the ``postgresql`` driver is psycopg 3, the extra ``tablebench[postgres]``);
a bare path is an SQLite file. ``off`` switches the registry off for that command.

Opening upgrades the schema to the newest Alembic revision (:mod:`.migrations`), serialised between
processes (PostgreSQL: a transaction-level advisory lock; SQLite: ``BEGIN IMMEDIATE``), so two benches that
open a new database at the same moment create it once. A new, empty database is created directly at the newest
schema (:mod:`.schema`) and stamped with its revision in Alembic's own table, as ``alembic stamp`` does, without
importing Alembic or running every migration (a test checks that the migrations give exactly that schema).

Adding is idempotent and safe under concurrency: every row is inserted with ``ON CONFLICT DO NOTHING`` on its
natural key (unit: serial, model, configuration; bench: name, table model and serial; calibration: the values
digest; certificate: its number), in one transaction; a second writer of the same calibration waits for the
first and then inserts nothing. See ``docs/registry.md``.
"""

from __future__ import annotations

import weakref
from collections.abc import Iterator, Mapping
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from sqlalchemy import (
    Column,
    Connection,
    Engine,
    MetaData,
    PrimaryKeyConstraint,
    String,
    Table,
    create_engine,
    event,
    func,
    inspect,
    select,
    text,
    update,
)
from sqlalchemy.dialects.sqlite import insert as sqlite_insert
from sqlalchemy.engine import make_url
from sqlalchemy.exc import ArgumentError, DBAPIError, NoSuchModuleError, SQLAlchemyError

from benches.results.sink import SinkError

from . import schema as S
from .url import DEFAULT_FILE, ENV, OFF, resolve_url

_LOCK_KEY = 0x7462_7265_6731  # "tbreg1": the advisory lock of schema upgrades (PostgreSQL)
MIGRATIONS = Path(__file__).with_name("migrations")
_ALEMBIC_VERSION = Table(
    "alembic_version",
    MetaData(),
    Column("version_num", String(32), nullable=False),
    PrimaryKeyConstraint("version_num", name="alembic_version_pkc"),
)
"""Alembic's version table, as Alembic itself creates it (``alembic.runtime.migration``)."""


class RegistryError(SinkError):
    """The registry cannot be opened, read or written; the message names it and the fix."""


def display_url(url: str) -> str:
    """The URL without its password (for messages)."""
    try:
        return make_url(url).render_as_string(hide_password=True)
    except (ArgumentError, ValueError):
        return url


def _sqlite_setup(engine: Engine) -> None:
    @event.listens_for(engine, "connect")
    def _connect(dbapi_conn: Any, _rec: Any) -> None:
        dbapi_conn.isolation_level = None  # SQLAlchemy emits BEGIN itself (below)
        cur = dbapi_conn.cursor()
        cur.execute("PRAGMA foreign_keys = ON")
        cur.execute("PRAGMA busy_timeout = 60000")
        cur.close()

    @event.listens_for(engine, "begin")
    def _begin(conn: Connection) -> None:
        conn.exec_driver_sql("BEGIN IMMEDIATE")  # writers queue at the start, no lock upgrade deadlock


@dataclass(frozen=True)
class AddOutcome:
    """What :meth:`Registry.add` did.

    Attributes
    ----------
    calibration_id : int
    added : bool
        False when the calibration was already there (nothing changed for it).
    certificates_added : tuple of str
        Certificate numbers newly recorded.
    place, of : int
        The calibration is the unit's ``place``-th of ``of`` in the registry (by run time; 0 when not stated).
    serial, model : str
        The unit's.
    """

    calibration_id: int
    added: bool
    certificates_added: tuple[str, ...]
    place: int = 0
    of: int = 0
    serial: str = ""
    model: str = ""


class Registry:
    """An open registry database (see the module docstring).

    Parameters
    ----------
    url : str
        SQLAlchemy URL (:func:`resolve_url`).
    upgrade : bool
        Bring the schema to the newest revision on opening (default). False: open as it is (migration tests).
    """

    def __init__(self, url: str, *, upgrade: bool = True) -> None:
        self.url = url
        self.where = display_url(url)
        try:
            if url.startswith("sqlite"):
                path = url.split(":///", 1)[1] if ":///" in url else ""
                if path and path != ":memory:":
                    Path(path).parent.mkdir(parents=True, exist_ok=True)
                self.engine = create_engine(url, connect_args={"timeout": 60})
                _sqlite_setup(self.engine)
            else:
                self.engine = create_engine(url, pool_pre_ping=True, connect_args=self._pg_args(url))
        except (ArgumentError, NoSuchModuleError, ValueError) as exc:
            raise RegistryError(
                f"registry {self.where}: not a usable database URL ({exc}); give sqlite:///FILE or "
                "postgresql://USER@HOST/DB (PostgreSQL needs: pip install 'tablebench[postgres]')"
            ) from None
        except ImportError as exc:
            raise RegistryError(
                f"registry {self.where}: the database driver is not installed ({exc}); for PostgreSQL: "
                "pip install 'tablebench[postgres]'"
            ) from None
        except OSError as exc:
            raise RegistryError(f"registry {self.where}: cannot create its folder ({exc.strerror})") from None
        # the pool's connections are closed when this object goes (a dropped Registry would otherwise leave them to
        # the cyclic garbage collector, whenever it runs, and psycopg warns about each one still open then)
        self._release = weakref.finalize(self, self.engine.dispose)
        if upgrade:
            self.upgrade()

    @staticmethod
    def _pg_args(url: str) -> dict[str, Any]:
        return {"connect_timeout": 10} if "+psycopg" in url else {}

    # ---- connections and errors ----------------------------------------------------------------------------
    @contextmanager
    def _guard(self, doing: str) -> Iterator[None]:
        try:
            yield
        except RegistryError:
            raise
        except DBAPIError as exc:
            reason = str(exc.orig).strip().splitlines()[0] if exc.orig is not None else str(exc)
            raise RegistryError(f"registry {self.where}: cannot {doing} ({reason})") from None
        except SQLAlchemyError as exc:
            raise RegistryError(f"registry {self.where}: cannot {doing} ({exc.__class__.__name__}: {exc})") from None
        except OSError as exc:
            raise RegistryError(f"registry {self.where}: cannot {doing} ({exc})") from None

    @contextmanager
    def begin(self, doing: str = "write") -> Iterator[Connection]:
        """A transaction (committed on success), database errors as one :class:`RegistryError` line."""
        with self._guard(doing), self.engine.begin() as conn:
            yield conn

    @contextmanager
    def connect(self, doing: str = "read") -> Iterator[Connection]:
        """A read connection, database errors as one :class:`RegistryError` line."""
        with self._guard(doing), self.engine.connect() as conn:
            yield conn

    def close(self) -> None:
        """Release the connections."""
        self.engine.dispose()

    # ---- schema --------------------------------------------------------------------------------------------
    def revision(self) -> str | None:
        """The schema revision of the database (None: empty)."""
        from alembic.runtime.migration import MigrationContext  # lazy: alembic (--help time)

        with self.connect("read its schema version") as conn:
            return MigrationContext.configure(conn).get_current_revision()

    def _is_current(self) -> bool:
        """True when the database is at the newest revision, read from Alembic's own table without importing
        Alembic (a third of a reading command's start-up); anything else goes through Alembic."""
        with self.connect("read its schema version") as conn:
            if not inspect(conn).has_table("alembic_version"):
                return False
            rows = conn.execute(text("SELECT version_num FROM alembic_version")).all()
        return [r[0] for r in rows] == [S.SCHEMA_VERSION]

    def upgrade(self, target: str = "head") -> None:
        """Bring the schema to ``target`` (default the newest), once, whoever else is opening it."""
        if target == "head" and (self._is_current() or self._create_if_empty()):
            return
        from alembic import command  # lazy: alembic (--help time)
        from alembic.config import Config  # lazy: alembic (--help time)

        cfg = Config()
        cfg.set_main_option("script_location", str(MIGRATIONS))
        with self._guard("upgrade its schema"), self.engine.connect() as conn:
            sqlite = conn.dialect.name == "sqlite"
            raw = conn.connection.driver_connection if sqlite else None
            if raw is not None:  # SQLite alters a table by copy-and-move: keep ON DELETE CASCADE from firing
                raw.execute("PRAGMA foreign_keys = OFF")
            try:
                with conn.begin():
                    if conn.dialect.name == "postgresql":
                        conn.exec_driver_sql(f"SELECT pg_advisory_xact_lock({_LOCK_KEY})")
                    cfg.attributes["connection"] = conn
                    command.upgrade(cfg, target)
                    if raw is not None and conn.exec_driver_sql("PRAGMA foreign_key_check").first() is not None:
                        raise RegistryError(f"registry {self.where}: the schema upgrade broke a reference; "
                                            "nothing was changed — restore the database from its backup")  # fmt: skip
            finally:
                if raw is not None:
                    raw.execute("PRAGMA foreign_keys = ON")

    def _create_if_empty(self) -> bool:
        """A database without any table: create the newest schema (:data:`.schema.metadata`) and stamp its
        revision, in one transaction under the upgrade's lock; True when the database is then at the newest
        revision (created here, or by another process meanwhile), False when it has tables of an older schema
        (the migrations bring those up)."""
        with self._guard("create its schema"), self.engine.begin() as conn:  # SQLite: BEGIN IMMEDIATE
            if conn.dialect.name == "postgresql":
                conn.exec_driver_sql(f"SELECT pg_advisory_xact_lock({_LOCK_KEY})")
            tables = inspect(conn).get_table_names()
            if tables:
                if "alembic_version" not in tables:
                    return False
                rows = conn.execute(text("SELECT version_num FROM alembic_version")).all()
                return [r[0] for r in rows] == [S.SCHEMA_VERSION]
            S.metadata.create_all(conn)
            _ALEMBIC_VERSION.create(conn)
            conn.execute(_ALEMBIC_VERSION.insert().values(version_num=S.SCHEMA_VERSION))
        return True

    # ---- writing -------------------------------------------------------------------------------------------
    def add(self, rec: Mapping[str, Any]) -> AddOutcome:
        """Record one calibration (a :func:`benches.results.registry.record.run_record` mapping); idempotent."""
        with self.begin("record the calibration") as conn:
            unit_id = self._upsert_id(conn, S.units, rec["unit"])
            bench_id = self._upsert_id(conn, S.benches, rec["bench"])
            row = dict(rec["calibration"], unit_id=unit_id, bench_id=bench_id)
            ins = self._insert(conn, S.calibrations).values(**row).on_conflict_do_nothing(index_elements=["digest"])
            added = conn.execute(ins.returning(S.calibrations.c.id)).first() is not None
            cal_id = conn.execute(
                select(S.calibrations.c.id).where(S.calibrations.c.digest == row["digest"])
            ).scalar_one()
            if added:
                conn.execute(
                    self._insert(conn, S.parameters),
                    [dict(p, calibration_id=cal_id) for p in rec["parameters"]],
                )
            new_certs = []
            for cert in rec.get("certificates", []):
                ins = self._insert(conn, S.certificates).values(**cert, calibration_id=cal_id)
                ins = ins.on_conflict_do_nothing(index_elements=["number"]).returning(S.certificates.c.number)
                if conn.execute(ins).first() is not None:
                    new_certs.append(cert["number"])
            if new_certs:
                self._latest_certificate(conn, cal_id, rec)
                p = S.parameters.c
                for par in rec["parameters"]:
                    conn.execute(
                        update(S.parameters)
                        .where(p.calibration_id == cal_id, p.name == par["name"])
                        .values(expanded=par["expanded"], budget=par["budget"])
                    )
            place, of = self._place(conn, unit_id, cal_id)
        unit = rec["unit"]
        return AddOutcome(cal_id, added, tuple(new_certs), place, of, str(unit["serial"]), str(unit["model"]))

    @staticmethod
    def _place(conn: Connection, unit_id: int, cal_id: int) -> tuple[int, int]:
        """(the calibration's place in its unit's history by run time, the unit's number of calibrations)."""
        c = S.calibrations.c
        this = conn.execute(select(c.run_utc).where(c.id == cal_id)).scalar_one()
        of_unit = select(func.count()).select_from(S.calibrations).where(c.unit_id == unit_id)
        before = of_unit.where((c.run_utc < this) | ((c.run_utc == this) & (c.id <= cal_id)))
        return int(conn.execute(before).scalar_one()), int(conn.execute(of_unit).scalar_one())

    @staticmethod
    def _insert(conn: Connection, table: Any) -> Any:
        if conn.dialect.name == "postgresql":
            from sqlalchemy.dialects.postgresql import insert as pg_insert  # lazy: sqlalchemy postgresql (--help time)

            return pg_insert(table)
        return sqlite_insert(table)

    def _upsert_id(self, conn: Connection, table: Any, values: Mapping[str, Any]) -> int:
        keys = [c for c in values]
        conn.execute(self._insert(conn, table).values(**values).on_conflict_do_nothing(index_elements=keys))
        cond = [table.c[k] == v for k, v in values.items()]
        return int(conn.execute(select(table.c.id).where(*cond)).scalar_one())

    @staticmethod
    def _latest_certificate(conn: Connection, cal_id: int, rec: Mapping[str, Any]) -> None:
        """The calibration row names its latest certificate (highest number), its decision and covariance."""
        c = S.certificates.c
        last = conn.execute(
            select(c.number, c.supersedes, c.verdict).where(c.calibration_id == cal_id).order_by(c.number.desc())
        ).first()
        if last is None:
            return
        values: dict[str, Any] = {"certificate_number": last.number, "supersedes": last.supersedes,
                                  "decision": last.verdict}  # fmt: skip
        cert_cov = rec.get("certificate_covariance", {}).get(last.number)
        if cert_cov is not None:
            values["certificate_covariance"] = cert_cov
        conn.execute(update(S.calibrations).where(S.calibrations.c.id == cal_id).values(**values))

    # ---- reading -------------------------------------------------------------------------------------------
    def has_calibration(self, digest: str) -> bool:
        """True when a calibration with this digest is recorded."""
        with self.connect() as conn:
            q = select(S.calibrations.c.id).where(S.calibrations.c.digest == digest)
            return conn.execute(q).first() is not None

    def count(self) -> int:
        """Number of calibrations."""
        with self.connect() as conn:
            return int(conn.execute(select(func.count()).select_from(S.calibrations)).scalar_one())


__all__ = ["DEFAULT_FILE", "ENV", "OFF", "AddOutcome", "Registry", "RegistryError", "display_url", "resolve_url"]
