"""Schema 0001: units, benches, calibrations (one per recording), parameters.

Revision ID: 0001
Revises:
"""

import sqlalchemy as sa
from alembic import op

revision = "0001"
down_revision = None
branch_labels = None
depends_on = None

F64 = sa.Float(precision=53)


def upgrade() -> None:
    op.create_table(
        "units",
        sa.Column("id", sa.Integer, primary_key=True, autoincrement=True),
        sa.Column("serial", sa.String(128), nullable=False),
        sa.Column("model", sa.String(128), nullable=False),
        sa.Column("configuration", sa.String(64), nullable=False),
        sa.UniqueConstraint("serial", "model", "configuration", name="uq_units_identity"),
    )
    op.create_table(
        "benches",
        sa.Column("id", sa.Integer, primary_key=True, autoincrement=True),
        sa.Column("name", sa.String(256), nullable=False),
        sa.Column("table_model", sa.String(128), nullable=False),
        sa.Column("table_serial", sa.String(128), nullable=False),
        sa.UniqueConstraint("name", "table_model", "table_serial", name="uq_benches_identity"),
    )
    op.create_table(
        "calibrations",
        sa.Column("id", sa.Integer, primary_key=True, autoincrement=True),
        sa.Column("recording_sha256", sa.String(64), nullable=False),
        sa.Column("unit_id", sa.Integer, sa.ForeignKey("units.id"), nullable=False),
        sa.Column("bench_id", sa.Integer, sa.ForeignKey("benches.id"), nullable=False),
        sa.Column("run_folder", sa.Text, nullable=False),
        sa.Column("run_utc", sa.String(32), nullable=False),
        sa.Column("recorded_utc", sa.String(32), nullable=False),
        sa.Column("procedure_name", sa.String(256), nullable=False),
        sa.Column("procedure_sha256", sa.String(64), nullable=False),
        sa.Column("method", sa.String(32), nullable=False),
        sa.Column("status", sa.String(32), nullable=False),
        sa.Column("operator", sa.String(128), nullable=False),
        sa.Column("software_version", sa.String(64), nullable=False),
        sa.Column("parameter_names", sa.Text, nullable=False),
        sa.Column("covariance", sa.Text, nullable=False),
        sa.Column("certificate_covariance", sa.Text, nullable=True),
        sa.Column("decision", sa.String(32), nullable=True),
        sa.Column("certificate_number", sa.String(32), nullable=True),
        sa.Column("supersedes", sa.String(32), nullable=True),
        sa.UniqueConstraint("recording_sha256", name="uq_calibrations_recording"),
    )
    op.create_index("ix_calibrations_unit_time", "calibrations", ["unit_id", "run_utc"])
    op.create_table(
        "parameters",
        sa.Column("calibration_id", sa.Integer, sa.ForeignKey("calibrations.id", ondelete="CASCADE"), primary_key=True),
        sa.Column("name", sa.String(32), primary_key=True),
        sa.Column("kind", sa.String(32), nullable=False),
        sa.Column("value", F64, nullable=False),
        sa.Column("u", F64, nullable=False),
        sa.Column("expanded", F64, nullable=False),
        sa.Column("identified", sa.Boolean, nullable=False),
        sa.Column("budget", sa.Text, nullable=True),
    )
    op.create_index("ix_parameters_name", "parameters", ["name", "calibration_id"])


def downgrade() -> None:
    for t in ("parameters", "calibrations", "benches", "units"):
        op.drop_table(t)
