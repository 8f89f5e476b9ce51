"""The legend of the pre-run plan's columns, in one place: printed under the plan table (``plan``, ``run``), in
``tablebench plan --help`` and on the certificate (a module of its own, so ``--help`` need not import the plan's
numerics)."""

from __future__ import annotations

PLAN_LEGEND: tuple[str, ...] = (
    "columns (predicted standard uncertainty 1σ, k = 1): prior = the datasheet bound before any data;",
    "  σ white = with the prior, white noise only (the filter's own P); σ total = with the prior, white noise plus",
    "  the bias instability the filter does not model; σ data = σ total from the data alone (no prior), which",
    "  decides 'NOT IDENTIFIED' (σ data above a third of the prior: the motion cannot resolve it)",
)
"""The legend printed under :meth:`analysis.identification.plan.IdentificationPlan.table` (plan, run)."""


def plan_legend_text() -> str:
    """The legend as one paragraph (certificate, help text)."""
    return " ".join(line.strip() for line in PLAN_LEGEND)


__all__ = ["PLAN_LEGEND", "plan_legend_text"]
