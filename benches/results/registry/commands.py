"""The actions of ``tablebench registry`` (the argument parser is :mod:`benches.cli.commands.registry`).

Each action takes the parsed arguments and returns the text to print (stdout); errors are
:class:`benches.results.registry.store.RegistryError` lines (exit 2).
"""

from __future__ import annotations

import argparse
import datetime as _dt
import json
from collections.abc import Callable
from pathlib import Path

from core.errors import OutputError
from core.jsonio import write_text_atomic

from . import queries
from .record import RunRecordError, bench_settings
from .report import compare_table, due_report, export_text, history_table, plot_trend
from .sink import add_run
from .store import Registry, RegistryError, resolve_url


def open_from_args(args: argparse.Namespace) -> Registry:
    """The registry named by ``--registry`` / ``$TABLEBENCH_REGISTRY`` / ``--runs``."""
    url = resolve_url(args.registry, Path(args.runs))
    if url is None:
        raise RegistryError("--registry off: the registry commands need a registry; give --registry URL")
    if url.startswith("sqlite") and args.action != "add":
        path = Path(url.split(":///", 1)[1])
        if not path.exists():
            raise RegistryError(
                f"registry {path}: no such registry yet; record runs first (tablebench registry add RUN), or give "
                "--registry URL / --runs DIR"
            )
    return Registry(url)


def _history(reg: Registry, serial: str) -> list[queries.CalibrationRow]:
    rows = queries.history(reg, serial)
    if not rows:
        known = ", ".join(u["serial"] for u in queries.units(reg)[:10]) or "none yet"
        raise RegistryError(f"{serial}: no calibrations of this serial number in {reg.where} (units: {known})")
    return rows


def do_add(args: argparse.Namespace) -> str:
    reg = open_from_args(args)
    lines = []
    for run in args.run:
        if not Path(run).is_dir():
            raise RunRecordError(f"{run}: not a run folder; give the folder that holds calibration.json")
        out = add_run(reg, run, operator=args.operator, configuration=args.configuration)
        what = "added" if out.added else "already recorded (nothing changed)"
        certs = f"; certificates recorded: {', '.join(out.certificates_added)}" if out.certificates_added else ""
        lines.append(f"{run}: {what}{certs}")
    return "\n".join(lines)


def do_list(args: argparse.Namespace) -> str:
    reg = open_from_args(args)
    rows = queries.units(reg)
    if not rows:
        return f"no calibrations in {reg.where}"
    out = [f"{'serial':20s} {'cfg':4s} {'n':>4s}  {'first (UTC)':20s} {'last (UTC)':20s} model"]
    for u in rows:
        out.append(f"{u['serial'][:20]:20s} {u['configuration'][:4]:4s} {u['calibrations']:4d}  {u['first'][:19]:20s} "
                   f"{u['last'][:19]:20s} {u['model']}")  # fmt: skip
    return "\n".join(out)


def do_show(args: argparse.Namespace) -> str:
    return history_table(_history(open_from_args(args), args.serial))


def do_trend(args: argparse.Namespace) -> str:
    if not str(args.out).lower().endswith(".png"):
        raise OutputError(f"--out {args.out}: give a .png file name")
    rows = _history(open_from_args(args), args.serial)
    if args.param not in rows[0].names:
        raise RegistryError(f"--param {args.param}: not a parameter of {args.serial}'s calibrations; one of "
                            f"{' '.join(rows[0].names)}")  # fmt: skip
    try:
        path = plot_trend(rows, args.param, Path(args.out))
    except OSError as exc:
        raise OutputError(f"--out {args.out}: cannot be written ({exc.strerror or exc})") from None
    return str(path)


def do_compare(args: argparse.Namespace) -> str:
    reg = open_from_args(args)
    return compare_table(queries.by_run(reg, args.run_a), queries.by_run(reg, args.run_b))


def do_due(args: argparse.Namespace) -> str:
    reg = open_from_args(args)
    now = (
        _dt.datetime.now(_dt.timezone.utc)
        if args.now is None
        else _dt.datetime.fromisoformat(args.now).replace(tzinfo=_dt.timezone.utc)
    )
    serials = [args.serial] if args.serial else sorted({u["serial"] for u in queries.units(reg)})
    out = [f"{'serial':20s} {'cfg':4s} {'last':10s} {'method 1':>9s} {'method 2':>9s}  {'due':10s}  limiting / state"]
    for serial in serials:
        rows = _history(reg, serial)
        by_cfg: dict[str, list[queries.CalibrationRow]] = {}
        for r in rows:
            by_cfg.setdefault(r.configuration, []).append(r)
        for cfg, hist in sorted(by_cfg.items()):
            s = bench_settings(hist[-1].run_folder)[1]
            d = due_report(hist, s, now)
            m2 = "—" if d["method2_control_chart_days"] is None else f"{d['method2_control_chart_days']:.0f} d"
            state = "OVERDUE" if d["overdue"] else ""
            lim = d["method2_limiting_parameter"] or "(staircase only: < 3 calibrations)"
            out.append(f"{serial[:20]:20s} {cfg[:4]:4s} {d['last_calibration'][:10]:10s} "
                       f"{d['method1_staircase_days']:7.0f} d {m2:>9s}  {d['due_utc']:10s}  {lim} {state}")  # fmt: skip
            out.append(f"{'':26s}settings: {d['settings']}")
    out.append("method 1: ILAC-G24 staircase (in tolerance: E_n ≤ 1 against the previous calibration and no FAIL); "
               "method 2: control chart (drift rate against the allowance); due = last + the shorter")  # fmt: skip
    return "\n".join(out)


def do_export(args: argparse.Namespace) -> str:
    rows = _history(open_from_args(args), args.serial)
    text = export_text(rows, args.format)
    if args.format == "json":
        json.loads(text)  # the writer's own check: never a file that does not read back
    try:
        path = write_text_atomic(args.out, text)
    except OSError as exc:
        raise OutputError(f"--out {args.out}: cannot be written ({exc.strerror or exc})") from None
    return str(path)


ACTIONS: dict[str, Callable[[argparse.Namespace], str]] = {
    "add": do_add,
    "list": do_list,
    "show": do_show,
    "trend": do_trend,
    "compare": do_compare,
    "due": do_due,
    "export": do_export,
}

__all__ = ["ACTIONS", "open_from_args"]
