"""The registry's tables (SQLAlchemy Core), at the schema version of the newest migration.

One definition serves both engines (SQLite, PostgreSQL). Numbers are SI; matrices and budgets are JSON text
(exact: Python's shortest round-trip repr of each float), so both engines return the same bytes for
``registry export``. Times are UTC ISO-8601 text (``2026-11-27T18:00:00Z``), which sorts as time.

Schema versions (Alembic revisions in :mod:`.migrations`):

* ``0001``: units, benches, calibrations (one per recording: ``recording_sha256`` unique; decision and
  certificate number kept on the calibration), parameters;
* ``0002``: the values digest of calibration.json (tamper evidence; one calibration per digest), as found /
  as left, and a ``certificates`` table (every issue of a certificate and what it supersedes).
"""

from __future__ import annotations

from sqlalchemy import (
    Boolean,
    Column,
    Float,
    ForeignKey,
    Index,
    Integer,
    MetaData,
    String,
    Table,
    Text,
    UniqueConstraint,
)

SCHEMA_VERSION = "0002"
"""The Alembic revision these tables describe (the head)."""

metadata = MetaData()

units = Table(
    "units",
    metadata,
    Column("id", Integer, primary_key=True, autoincrement=True),
    Column("serial", String(128), nullable=False),
    Column("model", String(128), nullable=False),
    Column("configuration", String(64), nullable=False),
    UniqueConstraint("serial", "model", "configuration", name="uq_units_identity"),
)

benches = Table(
    "benches",
    metadata,
    Column("id", Integer, primary_key=True, autoincrement=True),
    Column("name", String(256), nullable=False),
    Column("table_model", String(128), nullable=False),
    Column("table_serial", String(128), nullable=False),
    UniqueConstraint("name", "table_model", "table_serial", name="uq_benches_identity"),
)

calibrations = Table(
    "calibrations",
    metadata,
    Column("id", Integer, primary_key=True, autoincrement=True),
    Column("digest", String(80), nullable=False),
    Column("recording_sha256", String(64), nullable=False),
    Column("unit_id", Integer, ForeignKey("units.id"), nullable=False),
    Column("bench_id", Integer, ForeignKey("benches.id"), nullable=False),
    Column("run_folder", Text, nullable=False),
    Column("run_utc", String(32), nullable=False),
    Column("recorded_utc", String(32), nullable=False),
    Column("procedure_name", String(256), nullable=False),
    Column("procedure_sha256", String(64), nullable=False),
    Column("method", String(32), nullable=False),
    Column("status", String(32), nullable=False),
    Column("operator", String(128), nullable=False),
    Column("software_version", String(64), nullable=False),
    Column("parameter_names", Text, nullable=False),
    Column("covariance", Text, nullable=False),
    Column("certificate_covariance", Text, nullable=True),
    Column("decision", String(32), nullable=True),
    Column("certificate_number", String(32), nullable=True),
    Column("supersedes", String(32), nullable=True),
    Column("as_found_of", Integer, nullable=True),
    Column("as_found", Text, nullable=True),
    Column("as_left", Text, nullable=True),
    UniqueConstraint("digest", name="uq_calibrations_digest"),
    Index("ix_calibrations_unit_time", "unit_id", "run_utc"),
    Index("ix_calibrations_recording", "recording_sha256"),
)

parameters = Table(
    "parameters",
    metadata,
    Column("calibration_id", Integer, ForeignKey("calibrations.id", ondelete="CASCADE"), primary_key=True),
    Column("name", String(32), primary_key=True),
    Column("kind", String(32), nullable=False),
    Column("value", Float(precision=53), nullable=False),
    Column("u", Float(precision=53), nullable=False),
    Column("expanded", Float(precision=53), nullable=False),
    Column("identified", Boolean, nullable=False),
    Column("budget", Text, nullable=True),
    Index("ix_parameters_name", "name", "calibration_id"),
)

certificates = Table(
    "certificates",
    metadata,
    Column("number", String(32), primary_key=True),
    Column("calibration_id", Integer, ForeignKey("calibrations.id", ondelete="CASCADE"), nullable=False),
    Column("supersedes", String(32), nullable=False),
    Column("verdict", String(32), nullable=False),
    Column("issue_date", String(32), nullable=False),
    Column("json_sha256", String(64), nullable=False),
)

__all__ = ["SCHEMA_VERSION", "benches", "calibrations", "certificates", "metadata", "parameters", "units"]
