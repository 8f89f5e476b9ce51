"""Reading the registry: units, a unit's history, one parameter's series, a calibration by run.

Every query is one SQL statement over indexed columns (``ix_calibrations_unit_time``, ``ix_parameters_name``);
``benchmarks/bench_registry.py`` times them against the same query in plain SQL.
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray
from sqlalchemy import func, or_, select

from analysis.identification.model import PARAM_NAMES

from . import schema as S
from .store import Registry, RegistryError


@dataclass(frozen=True)
class CalibrationRow:
    """One calibration of the history (SI).

    Attributes
    ----------
    names, kinds : tuple of str
        The parameters of the rows read together (a unit's history): the accelerometer triad's 18 first
        (:data:`analysis.identification.model.PARAM_NAMES`), then every further parameter any of the rows has
        (the gyro triad's of a whole-unit calibration) in its model's order; ``kinds`` their quantity kinds
        (:data:`analysis.units.DISPLAY_UNITS` keys).
    values, u, expanded : arrays over ``names``
        Estimates, standard uncertainties u and expanded uncertainties U (k = 2; the certificate's when the run
        was certified, else 2u of the identification); NaN for a parameter this calibration's model lacks
        (its ``identified`` entry is then False).
    """

    id: int
    digest: str
    recording_sha256: str
    serial: str
    model: str
    configuration: str
    bench: str
    run_folder: str
    run_utc: str
    procedure_name: str
    procedure_sha256: str
    method: str
    status: str
    operator: str
    decision: str | None
    certificate_number: str | None
    supersedes: str | None
    values: NDArray[np.float64]
    u: NDArray[np.float64]
    expanded: NDArray[np.float64]
    identified: NDArray[np.bool_]
    covariance: str
    certificate_covariance: str | None
    budgets: tuple[str | None, ...]
    as_found_of: int | None
    as_found: str | None
    as_left: str | None
    names: tuple[str, ...]
    kinds: tuple[str, ...]

    def block(self, names: tuple[str, ...] | list[str]) -> list[int]:
        """Indices of ``names`` in this row's arrays (KeyError-free: every row has the accelerometer's)."""
        pos = {n: i for i, n in enumerate(self.names)}
        return [pos[n] for n in names]


def units(reg: Registry) -> list[dict[str, Any]]:
    """Every unit with its number of calibrations and the first and last run time."""
    c, u = S.calibrations.c, S.units.c
    q = (
        select(u.serial, u.model, u.configuration, func.count(c.id), func.min(c.run_utc), func.max(c.run_utc))
        .select_from(S.units.join(S.calibrations, S.calibrations.c.unit_id == u.id))
        .group_by(u.serial, u.model, u.configuration)
        .order_by(u.serial, u.model, u.configuration)
    )
    with reg.connect() as conn:
        return [
            {"serial": r[0], "model": r[1], "configuration": r[2], "calibrations": r[3], "first": r[4], "last": r[5]}
            for r in conn.execute(q)
        ]


def _rows_query(serial: str | None = None) -> Any:
    c, u, b = S.calibrations.c, S.units.c, S.benches.c
    q = (
        select(S.calibrations, u.serial, u.model, u.configuration, b.name.label("bench_name"))
        .select_from(S.calibrations.join(S.units, c.unit_id == u.id).join(S.benches, c.bench_id == b.id))
        .order_by(c.run_utc, c.id)
    )
    return q.where(u.serial == serial) if serial is not None else q


def _params(conn: Any, ids: list[int]) -> dict[int, dict[str, Any]]:
    p = S.parameters.c
    out: dict[int, dict[str, Any]] = {i: {} for i in ids}
    if not ids:
        return out
    for k in range(0, len(ids), 500):
        chunk = ids[k : k + 500]
        for r in conn.execute(select(S.parameters).where(p.calibration_id.in_(chunk))):
            out[r.calibration_id][r.name] = r
    return out


def _names(rows: list[Any], params: dict[int, dict[str, Any]]) -> tuple[tuple[str, ...], tuple[str, ...]]:
    """The parameters of rows read together, and their kinds: the accelerometer's 18 first, then the rest in
    the order the calibrations name them (their ``parameter_names``)."""
    names = list(PARAM_NAMES)
    seen = set(names)
    for r in rows:
        try:
            order = [str(n) for n in json.loads(r.parameter_names)]
        except (TypeError, ValueError):
            order = []
        for n in order + sorted(params[r.id]):
            if n not in seen:
                seen.add(n)
                names.append(n)
    kinds: dict[str, str] = {}
    for r in rows:
        for n, p in params[r.id].items():
            kinds.setdefault(n, p.kind)
    return tuple(names), tuple(kinds.get(n, "") for n in names)


def _to_rows(conn: Any, rows: list[Any]) -> list[CalibrationRow]:
    params = _params(conn, [r.id for r in rows])
    names, kinds = _names(rows, params)
    nan = float("nan")
    out = []
    for r in rows:
        ps = params[r.id]
        missing = [n for n in PARAM_NAMES if n not in ps]
        if missing:
            raise RegistryError(f"registry: calibration {r.digest[:12]} lacks parameters {missing}; add the run again")
        got = [ps.get(n) for n in names]
        out.append(
            CalibrationRow(
                id=r.id,
                digest=r.digest,
                recording_sha256=r.recording_sha256,
                serial=r.serial,
                model=r.model,
                configuration=r.configuration,
                bench=r.bench_name,
                run_folder=r.run_folder,
                run_utc=r.run_utc,
                procedure_name=r.procedure_name,
                procedure_sha256=r.procedure_sha256,
                method=r.method,
                status=r.status,
                operator=r.operator,
                decision=r.decision,
                certificate_number=r.certificate_number,
                supersedes=r.supersedes,
                values=np.array([nan if p is None else p.value for p in got], dtype=float),
                u=np.array([nan if p is None else p.u for p in got], dtype=float),
                expanded=np.array([nan if p is None else p.expanded for p in got], dtype=float),
                identified=np.array([p is not None and bool(p.identified) for p in got]),
                covariance=r.covariance,
                certificate_covariance=r.certificate_covariance,
                budgets=tuple(None if p is None else p.budget for p in got),
                as_found_of=r.as_found_of,
                as_found=r.as_found,
                as_left=r.as_left,
                names=names,
                kinds=kinds,
            )  # fmt: skip
        )
    return out


def history(reg: Registry, serial: str) -> list[CalibrationRow]:
    """Every calibration of the unit with this serial number, oldest first."""
    with reg.connect() as conn:
        return _to_rows(conn, list(conn.execute(_rows_query(serial))))


def every_calibration(reg: Registry) -> list[CalibrationRow]:
    """Every calibration, oldest first."""
    with reg.connect() as conn:
        return _to_rows(conn, list(conn.execute(_rows_query())))


def series(reg: Registry, serial: str, param: str) -> list[dict[str, Any]]:
    """One parameter of one unit over time: run time, value, u, U, identified, bench, certificate (oldest first)."""
    c, u, p, b = S.calibrations.c, S.units.c, S.parameters.c, S.benches.c
    q = (
        select(
            c.run_utc, p.value, p.u, p.expanded, p.identified, b.name, c.certificate_number, u.configuration, c.id
        )  # fmt: skip
        .select_from(
            S.parameters.join(S.calibrations, p.calibration_id == c.id)
            .join(S.units, c.unit_id == u.id)
            .join(S.benches, c.bench_id == b.id)
        )
        .where(u.serial == serial, p.name == param)
        .order_by(c.run_utc, c.id)
    )
    with reg.connect() as conn:
        found = [
            {
                "run_utc": r[0],
                "value": r[1],
                "u": r[2],
                "expanded": r[3],
                "identified": bool(r[4]),
                "bench": r[5],
                "certificate": r[6],
                "configuration": r[7],
                "id": r[8],
            }  # fmt: skip
            for r in conn.execute(q)
        ]
    if not found:
        raise RegistryError(
            f"--param {param}: not a parameter of any calibration of {serial} (see: tablebench registry show {serial})"
        )
    return found


def by_run(reg: Registry, run: str) -> CalibrationRow:
    """The calibration of a run folder, recording SHA-256 or digest (prefix of ≥ 8 hex digits allowed);
    the newest when several calibrations of one recording were recorded."""
    c = S.calibrations.c
    key = str(Path(run).resolve()) if Path(run).exists() else run
    cond = [c.run_folder == key]
    if len(run) >= 8 and all(ch in "0123456789abcdef" for ch in run.lower()):
        cond += [c.recording_sha256.startswith(run.lower()), c.digest.startswith(run.lower())]
    with reg.connect() as conn:
        rows = list(conn.execute(_rows_query().where(or_(*cond))))
        if not rows:
            raise RegistryError(
                f"{run}: no such run in the registry {reg.where}; record it with: tablebench registry add {run}"
            )
        return _to_rows(conn, rows[-1:])[0]


def previous_of(reg: Registry, unit: dict[str, str], run_utc: str, digest: str) -> CalibrationRow | None:
    """The unit's latest calibration (same serial, model, configuration) run before ``run_utc``."""
    c, u = S.calibrations.c, S.units.c
    q = (
        _rows_query()
        .where(u.serial == unit["serial"], u.model == unit["model"], u.configuration == unit["configuration"])
        .where(c.run_utc < run_utc, c.digest != digest)
    )
    with reg.connect() as conn:
        rows = list(conn.execute(q))
        return _to_rows(conn, rows[-1:])[0] if rows else None


def loads(text: str | None) -> Any:
    """JSON column → value (None stays None)."""
    return None if text is None else json.loads(text)


__all__ = ["CalibrationRow", "by_run", "every_calibration", "history", "loads", "previous_of", "series", "units"]
