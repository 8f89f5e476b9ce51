"""``tablebench noise``: Allan/total variance and noise-term fit of a static record."""

from __future__ import annotations

import argparse
import json
import math

EXAMPLES = """examples:
  tablebench noise runs/static-noise-001                     # a recording (static-noise procedure)
  tablebench noise runs/static-noise-001 --channels gyro_x,gyro_y,gyro_z --out report/
  tablebench noise data.npy --rate 200 --out report/         # one column per channel, SI units
  tablebench noise data.csv --rate 100 --taus log            # CSV, optional header row of channel names

output: a table of noise terms per channel (fit by weighted non-negative least squares, each with 1σ), and
with --out DIR: noise.json (SI; deviations in the data's unit) and noise.png (log-log Allan deviation with
confidence band, fitted terms). Gyro terms are shown in arcsec, °/√h, °/h, °/h/√h, °/h²; accelerometer
terms in mm/s, µg/√Hz, µg, µg/√s, µg/s. Estimators and EDF: analysis/noise/allan.py.
"""

MIN_SAMPLES = 64
"""Shortest record accepted: a few octaves of τ with several blocks each."""
MAX_ALL_TAUS = 200_000
"""Longest record for ``--taus all`` (every m: O(N²) work)."""


def register(sub: argparse._SubParsersAction) -> None:
    """Add the ``noise`` subcommand."""
    from benches.analysis_input import add_input_arguments

    p = sub.add_parser(
        "noise",
        help="Allan / total variance and noise terms (Q, N, B, K, R) of a static record",
        description="Compute the non-overlapping, overlapping, total and modified Allan deviations of each "
        "channel of a static record, with χ² confidence intervals, and fit the IEEE 952 / 1293 noise terms "
        "(quantisation Q, white noise N, bias instability B, random walk K, ramp R).",
        epilog=EXAMPLES,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    add_input_arguments(p)
    p.add_argument(
        "--taus",
        default="octave",
        choices=("octave", "log", "all"),
        help="τ grid: octave (m = 1, 2, 4, …; default), log (10 per decade) or all (small records only)",
    )
    p.add_argument(
        "--confidence",
        type=float,
        default=0.683,
        help="two-sided probability of the confidence intervals (default 0.683)",
    )
    p.add_argument(
        "--published-itotvar",
        action="store_true",
        help="also report the published 'improved total variance' (paper reproduction; no better than ADEV)",
    )
    p.set_defaults(func=run)


def _fmt(v: float | None) -> str:
    return "—" if v is None or not math.isfinite(v) else f"{v:.4g}"


def format_table(result: dict) -> str:
    """The noise terms of every channel as a plain-text table (display units)."""
    lines = []
    for name, ch in result["channels"].items():
        lines.append(f"{name} ({ch['unit']}), fit χ²/dof = {_fmt(ch['fit']['chi2_red'])}")
        for t, d in ch["terms_display"].items():
            s = ch["slope_terms"].get(t, {})
            slope = ""
            if s:
                sv = to_display_value(t, s["value"], ch["unit"])
                slope = f"   slope-line ≤ {_fmt(sv)}{' (observed)' if s.get('observed') else ''}"
            lines.append(f"  {t}  {_fmt(d['value']):>10} ± {_fmt(d['sigma']):<9} {d['unit']:<10}{slope}")
    return "\n".join(lines)


def to_display_value(term: str, value_si: float, unit: str) -> float:
    """A term value converted to its display unit."""
    from analysis.noise.terms import to_display

    return to_display(term, value_si, unit)[0]


def run(args: argparse.Namespace) -> int:
    """Execute ``tablebench noise``."""
    from analysis.noise.terms import analyse_noise
    from benches.analysis_input import InputError, load_input, output_dir
    from core.errors import UsageError

    if not 0.0 < args.confidence < 1.0:
        raise UsageError(f"--confidence must be between 0 and 1 (e.g. 0.683 or 0.95), got {args.confidence}")
    data = load_input(args.input, rate=args.rate, channels=args.channels, step=args.step, min_samples=MIN_SAMPLES)
    n = len(next(iter(data.channels.values())))
    if args.taus == "all" and n > MAX_ALL_TAUS:
        raise UsageError(
            f"--taus all costs O(N²): {n} samples is too many (limit {MAX_ALL_TAUS}); use --taus log or octave"
        )
    out = output_dir(args.out, "noise")
    try:
        result = analyse_noise(
            data.channels,
            data.rate,
            data.units,
            taus=args.taus,
            confidence=args.confidence,
            published_itotvar=args.published_itotvar,
        )
    except ValueError as exc:
        raise InputError(f"{data.source}: {exc}") from None
    result["source"] = data.source
    print(f"{data.source}: {len(data.channels)} channel(s), {n} samples at {data.rate:g} Hz ({n / data.rate:.1f} s)")
    print(format_table(result))
    if out is not None:
        from analysis.noise.plot import plot_noise

        (out / "noise.json").write_text(json.dumps(result, indent=1, allow_nan=False), encoding="utf-8")
        plot_noise(result, out / "noise.png", title=f"Noise analysis: {data.source}")
        print(f"wrote {out / 'noise.json'} and {out / 'noise.png'}")
    return 0
