"""Schema 0002: the values digest (tamper evidence), as found / as left, every certificate issue.

Existing calibrations keep every row: their digest becomes ``v1-<recording SHA-256>`` (recorded before
calibration.json carried one), their certificate number and decision move into ``certificates`` (issue date
and JSON digest unknown: empty), and the calibration keeps its latest number and decision as before.

Revision ID: 0002
Revises: 0001
"""

import sqlalchemy as sa
from alembic import op

revision = "0002"
down_revision = "0001"
branch_labels = None
depends_on = None


def upgrade() -> None:
    with op.batch_alter_table("calibrations") as b:
        b.add_column(sa.Column("digest", sa.String(80), nullable=True))
        b.add_column(sa.Column("as_found_of", sa.Integer, nullable=True))
        b.add_column(sa.Column("as_found", sa.Text, nullable=True))
        b.add_column(sa.Column("as_left", sa.Text, nullable=True))
    cal = sa.table(
        "calibrations",
        sa.column("id", sa.Integer),
        sa.column("recording_sha256", sa.String),
        sa.column("digest", sa.String),
        sa.column("certificate_number", sa.String),
        sa.column("supersedes", sa.String),
        sa.column("decision", sa.String),
    )
    conn = op.get_bind()
    rows = conn.execute(sa.select(cal.c.id, cal.c.recording_sha256, cal.c.certificate_number, cal.c.supersedes,
                                  cal.c.decision)).all()  # fmt: skip
    for r in rows:
        conn.execute(sa.update(cal).where(cal.c.id == r.id).values(digest="v1-" + r.recording_sha256))
    with op.batch_alter_table("calibrations") as b:
        b.alter_column("digest", existing_type=sa.String(80), nullable=False)
        b.drop_constraint("uq_calibrations_recording", type_="unique")
        b.create_unique_constraint("uq_calibrations_digest", ["digest"])
    op.create_index("ix_calibrations_recording", "calibrations", ["recording_sha256"])
    certs = op.create_table(
        "certificates",
        sa.Column("number", sa.String(32), primary_key=True),
        sa.Column("calibration_id", sa.Integer, sa.ForeignKey("calibrations.id", ondelete="CASCADE"), nullable=False),
        sa.Column("supersedes", sa.String(32), nullable=False),
        sa.Column("verdict", sa.String(32), nullable=False),
        sa.Column("issue_date", sa.String(32), nullable=False),
        sa.Column("json_sha256", sa.String(64), nullable=False),
    )
    issued = [
        {"number": r.certificate_number, "calibration_id": r.id, "supersedes": r.supersedes or "",
         "verdict": r.decision or "", "issue_date": "", "json_sha256": ""}
        for r in rows if r.certificate_number
    ]  # fmt: skip
    if issued:
        op.bulk_insert(certs, issued)


def downgrade() -> None:
    op.drop_table("certificates")
    op.drop_index("ix_calibrations_recording", "calibrations")
    with op.batch_alter_table("calibrations") as b:
        b.drop_constraint("uq_calibrations_digest", type_="unique")
        b.create_unique_constraint("uq_calibrations_recording", ["recording_sha256"])
        for c in ("as_left", "as_found", "as_found_of", "digest"):
            b.drop_column(c)
