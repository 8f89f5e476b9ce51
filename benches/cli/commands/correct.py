"""``tablebench correct``: apply a calibration to raw unit data (f_out → f, ω_out → ω_ib: the exact inverse model).

The equations (``docs/methods/gyro-calibration.md``, and on the certificate): the accelerometer's
f = (I+S+T)⁻¹ (f_out − b − D(f∘f) − diag(r) c(ω)), solved by Newton's iteration; the gyro's
ω_ib = (I+S_g+T_g)⁻¹ (ω_out − b_g − G f) (with S2 and A: Newton's iteration), f the compensated specific
force; the two are iterated together until nothing changes at the rounding level.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import Any

import numpy as np

from analysis.identification.model import correct
from benches.calibration_integrity import load_verified
from benches.cli.analysis_input import InputError, read_npy, recording_path
from benches.cli.work import Work
from core.errors import UsageError
from core.outputs import check_output, save_npy

EXAMPLES = """examples:
  tablebench correct runs/RUN/calibration.json raw.npy --out corrected.npy
        # raw.npy: (n, 3) specific force in m/s² (body frame), or (n, 6) with the gyro rates (rad/s); with a
        # whole-unit calibration (gyro_* parameters) the gyro channels are corrected too and the output is
        # (n, 6) [f m/s², ω_ib rad/s]; otherwise the raw rates serve the size-effect term only
  tablebench correct runs/RUN/calibration.json runs/OTHER --out corrected.npy
        # a recording: only its hold/spin acquisition windows (listed with their times), rates from the
        # recorded table readings; the sample times are written to corrected_time.npy
  tablebench correct runs/THERMAL/thermal_calibration.json runs/OTHER --out corrected.npy
        # a thermal calibration (tablebench thermal): the parameters at each sample's own temperature (the
        # recording's temperature channel); output (n, 6) [f m/s², ω_ib rad/s]
  tablebench correct thermal_calibration.json raw.npy --out corrected.npy --outside-range warn
        # raw.npy (n, 7): [f_out m/s², ω_out rad/s, unit temperature K]; outside the calibrated temperature
        # range: refused by default, or applied with a warning (--outside-range warn)
"""


def register(sub: argparse._SubParsersAction) -> None:
    """Add the ``correct`` subcommand."""
    p = sub.add_parser(
        "correct",
        help="apply a calibration to raw unit data (accelerometer, and gyro with a whole-unit calibration)",
        description="Compensate raw unit output with an identified model: solve "
        "f_out = f + (S+T) f + b + D(f∘f) + diag(r) c(ω) for f exactly (Newton iteration per sample, not a "
        "first-order shortcut) and, with a whole-unit calibration, ω_out = (I+S_g+T_g) ω_ib + b_g + G f "
        "(+ S2 ω² + A|ω|) for ω_ib, the two iterated together. Parameters the calibration marks as not "
        "identified are left out (set to 0).",
        epilog=EXAMPLES,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    p.add_argument("calibration", metavar="CALIBRATION.json")
    p.add_argument("input", metavar="RAW.npy|RUN", help="(n,3) or (n,6) .npy in SI, or a recording")
    p.add_argument(
        "--out", required=True, metavar="FILE.npy",
        help="corrected specific force (n, 3), m/s², or (n, 6) [f, ω_ib rad/s] with a whole-unit calibration",
    )  # fmt: skip
    p.add_argument(
        "--outside-range", choices=["refuse", "warn"], default="refuse",
        help="thermal calibration: samples outside the calibrated temperature range are refused (default) or "
        "compensated with the extrapolated model and a warning",
    )  # fmt: skip
    p.set_defaults(func=run)


def load_calibration_vector(path: str | Path) -> tuple[np.ndarray, list[str]]:
    """The parameter vector of a calibration.json (not-identified parameters zeroed) and their names."""
    return load_verified(path)[0].compensation_vector()  # refuses an edited or implausible file


def run(args: argparse.Namespace) -> int:
    """Execute ``tablebench correct``."""
    if not str(args.out).lower().endswith(".npy"):
        raise UsageError(f"--out {args.out}: give a .npy file name (the corrected samples are a NumPy array)")
    check_output(args.out)  # before the work: never over an input or a recording
    from benches.thermal.document import is_thermal_file  # lazy: scipy (--help time)

    if is_thermal_file(args.calibration):
        return _run_thermal(args)
    cal = load_verified(args.calibration)[0]  # refuses an edited, unsealed or implausible file
    x, skipped = cal.compensation_vector()
    model = cal.error_model
    src = recording_path(args.input)
    if src.suffix.lower() not in (".h5", ".hdf5") and not src.exists():
        raise InputError(f"{src}: no such file")

    def compute(work: Work) -> tuple[np.ndarray, np.ndarray | None, list[str]]:
        """Read the input and correct it (in the worker: Ctrl-C answered at once, progress with an ETA)."""
        work.stage("reading the input")
        f_out, omega, gyro_out, times, notes = _read_input(src, model)
        work.advance(0.5, "correcting the samples")
        try:
            if gyro_out is not None:
                f = model.correct_outputs(x, np.hstack([f_out, gyro_out]))  # type: ignore[attr-defined]
            else:
                f = correct(x[:18], f_out, omega)
        except ValueError as exc:
            raise UsageError(str(exc)) from None
        return f, times, notes

    t_path = Path(args.out).with_name(Path(args.out).stem + "_time.npy")
    with Work("correct", 1.0) as work:  # the interrupt and progress of 'run' (benches.cli.work)
        f, times, notes = work.run(compute, work)
        for line in notes:
            print(line, file=sys.stderr)
        with work.writing():  # all or nothing: a Ctrl-C now is held until both files are complete
            save_npy(args.out, f)
            if times is not None:
                save_npy(t_path, times)
    if times is not None:
        print(f"sample times (bench s) → {t_path}", file=sys.stderr)
    if skipped:
        print(f"not applied (not identified): {', '.join(skipped)}", file=sys.stderr)
    print(f"corrected {f.shape[0]} samples → {args.out}")
    return 0


_Arrays = tuple[np.ndarray, np.ndarray, np.ndarray | None, np.ndarray | None, list[str]]


def _read_input(src: Path, model: Any) -> _Arrays:
    """(f_out, ω, gyro output or None, bench times or None, notes for the user) of a recording or an .npy file."""
    notes: list[str] = []
    if src.suffix.lower() in (".h5", ".hdf5"):
        from benches.identify import IdentificationError, load_run  # lazy: filterpy, scipy (--help time)

        try:
            rr = load_run(src, with_gyro=model.n_axes == 6)
        except IdentificationError as exc:
            raise UsageError(str(exc)) from None
        f_out = np.concatenate([w.f_out for w in rr.windows])
        gyro_out = np.concatenate([w.gyro for w in rr.windows]) if model.n_axes == 6 else None  # type: ignore[misc]
        omega = np.concatenate([w.omega for w in rr.windows])
        times = np.concatenate([w.t for w in rr.windows])
        notes.append(
            f"{src}: returns only the samples of the {len(rr.windows)} hold/spin acquisition windows "
            "(warm-up, moves, settling and ramps are left out, as in the identification); bench times:"
        )
        for w in rr.windows:
            notes.append(f"  {w.name:<24s} {w.kind:<5s} {w.t[0]:10.3f} – {w.t[-1]:10.3f} s  ({len(w.t)} samples)")
        return f_out, omega, gyro_out, times, notes
    data = read_npy(src)  # the one loader: shape checked against the file size before allocating
    if data.ndim != 2 or data.shape[1] not in (3, 6):
        raise InputError(f"{src}: expected a numeric (n, 3) or (n, 6) array in SI units, got {data.shape}")
    if not np.all(np.isfinite(data)):
        raise InputError(f"{src}: contains NaN/inf; remove them first")
    f_out = data[:, :3].astype(float)
    omega = data[:, 3:6].astype(float) if data.shape[1] == 6 else np.zeros_like(f_out)
    gyro_out = omega if data.shape[1] == 6 and model.n_axes == 6 else None
    return f_out, omega, gyro_out, None, notes


def _thermal_input(src: Path) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray | None]:
    """(f_out, ω_out, temperature K, times or None) of a recording's windows or of an (n, 7) .npy."""
    if src.suffix.lower() in (".h5", ".hdf5"):
        from benches.identify import IdentificationError  # lazy: filterpy, scipy (--help time)
        from benches.thermal.identify import window_samples  # lazy: filterpy, scipy (--help time)

        try:
            f_out, gyro, temp, times = window_samples(src)
        except IdentificationError as exc:
            raise UsageError(str(exc)) from None
        return f_out, gyro, temp, times
    if not src.exists():
        raise InputError(f"{src}: no such file")
    data = read_npy(src)
    if data.ndim != 2 or data.shape[1] != 7:
        raise InputError(
            f"{src}: a thermal calibration needs (n, 7) [f_out m/s², ω_out rad/s, unit temperature K], got {data.shape}"
        )
    if not np.all(np.isfinite(data)):
        raise InputError(f"{src}: contains NaN/inf; remove them first")
    return data[:, :3].astype(float), data[:, 3:6].astype(float), data[:, 6].astype(float), None


def _run_thermal(args: argparse.Namespace) -> int:
    """``correct`` with a thermal_calibration.json: parameters at each sample's temperature."""
    from benches.thermal.correct import OutsideRangeError, thermal_correct  # lazy: scipy (--help time)
    from benches.thermal.document import load_thermal  # lazy: scipy (--help time)

    tf = load_thermal(args.calibration)
    src = recording_path(args.input)

    def compute(work: Work) -> tuple[np.ndarray, np.ndarray | None, str | None]:
        work.stage("reading the input")
        f_out, gyro, temp, times = _thermal_input(src)
        work.advance(0.5, "correcting the samples at their temperatures")
        try:
            out, warning = thermal_correct(tf.model, f_out, gyro, temp, args.outside_range)
        except OutsideRangeError as exc:
            raise UsageError(f"{args.input}: {exc}") from None
        return out, times, warning

    t_path = Path(args.out).with_name(Path(args.out).stem + "_time.npy")
    with Work("correct", 1.0) as work:
        out, times, warning = work.run(compute, work)
        if warning is not None:
            print(f"warning: {warning}", file=sys.stderr)
        with work.writing():
            save_npy(args.out, out)
            if times is not None:
                save_npy(t_path, times)
    if times is not None:
        print(f"sample times (bench s) → {t_path}", file=sys.stderr)
    print(f"corrected {out.shape[0]} samples with the thermal model (T_ref "
          f"{tf.model.reference - 273.15:g} °C) → {args.out}")  # fmt: skip
    return 0
