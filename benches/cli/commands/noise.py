"""``tablebench noise``: the frequency-stability family, confidence intervals and noise-term fit of a static record."""

from __future__ import annotations

import argparse
import math

from benches.cli.analysis_input import InputError, add_input_arguments, load_input, output_dir
from core.errors import UsageError
from core.jsonio import write_json

EXAMPLES = """examples:
  tablebench noise runs/static-noise-001                     # a recording (static-noise procedure)
  tablebench noise runs/static-noise-001 --channels gyro_x,gyro_y,gyro_z --out report/
  tablebench noise data.npy --rate 200 --out report/         # one column per channel, SI units
  tablebench noise data.csv --rate 100 --taus decade         # CSV, optional header row of channel names
  tablebench noise run1 --estimators oadev,mdev,htotdev,theoh,mtie --taus 0.1,1,10,100
  tablebench noise angle.npy --rate 200 --data-type phase    # integrated angle (rad) instead of rate

estimators: adev oadev mdev tdev hdev ohdev totdev mtotdev ttotdev htotdev theo1 theobr theoh mtie tierms
(equal to allantools; theobr/theoh as Stable32; noise type by lag-1 ACF / B1, EDF by Greenhall's algorithm and
the published total-family/Theo1 fits, χ² intervals: analysis/noise/stability.py, analysis/noise/confidence.py).
NaN samples are gaps: terms touching them are skipped (the count per τ is in noise.json).

output: a table of noise terms per channel, read two ways:
  fit         weighted non-negative least squares of σ²(τ) = 3Q²/τ² + N²/τ + (2 ln2/π)B² + K²τ/3 + R²τ²/2 on
              --fit-estimator over every τ, each term with its standard uncertainty 1σ;
  slope-line  IEEE Std 952 Annex C: a line of the term's slope (−1, −½, 0, +½, +1 in log-log for Q, N, B, K,
              R) moved up until it touches the curve, the term read off it (N = σ√τ, B = σ/0.664, K = σ√(3/τ)…).
              Each term's line lies under the curve, so the reading is an UPPER BOUND. Read only at τ where the
              deviation is known well whatever the noise type (≥ 200 degrees of freedom for every plausible type);
              "≤ value (≤ hi)" gives the reading and the top of its 95 % interval (Bonferroni over the points
              read); "(observed)": the curve's slope there matches the term's, the term dominates at that τ;
              "BELOW FIT": even the top of the interval is under the fitted term — check the fit.
and with --out DIR: noise.json (per estimator and τ: value, term count, EDF,
interval, noise type α; SI, deviations in the data's rate unit) and noise.png (every chosen estimator with its
intervals, fitted terms). Gyro terms are shown in arcsec, deg/√h, deg/h, deg/h/√h, deg/h²; accelerometer
terms in mm/s, µg/√Hz, µg, µg/√s, µg/s.
"""

MIN_SAMPLES = 64
"""Shortest record accepted: a few octaves of τ with several blocks each."""
MAX_ALL_TAUS = 200_000
"""Longest record for ``--taus all`` (every m: O(N²) work)."""
MAX_ALL_TAUS_TOTAL = 5_000
"""Longest record for ``--taus all`` with MTOTDEV/HTOTDEV/TTOTDEV/Theo1/TheoH (O(N·m) per τ: O(N³) in all)."""
DEFAULT_ESTIMATORS = "adev,oadev,mdev,totdev"


def register(sub: argparse._SubParsersAction) -> None:
    """Add the ``noise`` subcommand."""

    p = sub.add_parser(
        "noise",
        help="stability family (ADEV … HTOTDEV, Theo1, MTIE) and noise terms (Q, N, B, K, R) of a static record",
        description="Compute the chosen frequency-stability deviations of each channel of a static record "
        "(frequency or phase data, NaN gaps skipped), with noise type, EDF and χ² confidence interval per τ, and "
        "fit the IEEE 952 / 1293 noise terms (quantisation Q, white noise N, bias instability B, random walk K, "
        "ramp R).",
        epilog=EXAMPLES,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    add_input_arguments(p)
    p.add_argument(
        "--taus",
        default="octave",
        metavar="GRID|LIST",
        help="τ grid: octave (m = 1, 2, 4, …; default), decade (1, 2, 4, 10, 20, 40, …), log (10 per decade), "
        "all (small records only) or a comma-separated list of τ in seconds",
    )
    p.add_argument(
        "--estimators",
        default=DEFAULT_ESTIMATORS,
        metavar="LIST",
        help=f"comma-separated estimators (default {DEFAULT_ESTIMATORS}; see below)",
    )
    p.add_argument(
        "--data-type",
        default="freq",
        choices=("freq", "phase"),
        help="freq: rate / specific force (default); phase: integrated angle / velocity",
    )
    p.add_argument(
        "--fit-estimator",
        default="oadev",
        metavar="NAME",
        help="deviation used for the noise-term fit and slope reading (default oadev): adev, oadev, totdev, "
        "theoh (Allan model) or hdev, ohdev, htotdev (Hadamard model, no rate-ramp term)",
    )
    p.add_argument(
        "--confidence",
        type=float,
        default=0.683,
        help="two-sided probability of the confidence intervals (default 0.683)",
    )
    p.add_argument(
        "--noise-type",
        default=None,
        metavar="TYPE[@LO:HI],…",
        help="set the power-law noise type by hand instead of identifying it (as Stable32 allows); the intervals "
        "and the fit use it: one type for every τ (e.g. wfm or 0), or types per τ range in seconds "
        "(e.g. wpm@0.01:0.5,wfm@0.5:20,rwfm@20:1e4; τ outside every range keep the identified type). Types: "
        "wpm (α=2), fpm (1), wfm (0), ffm (-1), rwfm (-2)",
    )
    p.add_argument(
        "--remove-drift",
        default=None,
        choices=("linear", "quadratic"),
        help="remove a least-squares linear or quadratic frequency drift from each channel first (phase data: the "
        "quadratic or cubic phase it means); the removed coefficients are written to noise.json",
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
                hv = to_display_value(t, s["hi"], ch["unit"])
                flags = (" (observed)" if s.get("observed") else "") + (" BELOW FIT" if s.get("below_fit") else "")
                slope = f"   slope-line ≤ {_fmt(sv)} (≤ {_fmt(hv)} at 95 %, τ = {s['tau']:.3g} s){flags}"
            lines.append(f"  {t}  {_fmt(d['value']):>10} ± {_fmt(d['sigma']):<9} {d['unit']:<10}{slope}")
    return "\n".join(lines)


def to_display_value(term: str, value_si: float, unit: str) -> float:
    """A term value converted to its display unit."""
    from analysis.noise.terms import to_display  # lazy: scipy (--help time)

    return to_display(term, value_si, unit)[0]


def _parse_taus(text: str) -> str | list[float]:
    """``--taus``: a grid name or a comma-separated list of τ in seconds."""

    t = text.strip().lower()
    if t in ("octave", "decade", "log", "all"):
        return t
    try:
        vals = [float(v) for v in t.split(",") if v.strip()]
    except ValueError:
        raise UsageError(
            f"--taus {text!r}: use octave, decade, log, all or a comma-separated list of τ in seconds (e.g. 0.1,1,10)"
        ) from None
    if not vals or not all(math.isfinite(v) and v > 0 for v in vals):
        raise UsageError(f"--taus {text!r}: τ values must be positive seconds")
    return vals


NOISE_TYPES = {"wpm": 2, "fpm": 1, "wfm": 0, "ffm": -1, "rwfm": -2}
"""``--noise-type`` names → α (S_y ∝ f^α)."""


def _alpha(text: str, whole: str) -> int:
    t = text.strip().lower()
    if t in NOISE_TYPES:
        return NOISE_TYPES[t]
    try:
        a = int(t)
    except ValueError:
        a = None
    if a is None or not -2 <= a <= 2:
        raise UsageError(
            f"--noise-type {whole!r}: {text!r} is not a noise type; use wpm, fpm, wfm, ffm, rwfm or α from -2 to 2"
        )
    return a


def parse_noise_type(text: str | None) -> int | list[tuple[float, float, int]] | None:
    """``--noise-type``: one type for every τ, or TYPE@LO:HI per τ range (s), comma-separated."""
    if text is None:
        return None
    parts = [s.strip() for s in text.split(",") if s.strip()]
    if not parts:
        raise UsageError("--noise-type is empty; e.g. --noise-type wfm or --noise-type wpm@0.01:1,wfm@1:100")
    if len(parts) == 1 and "@" not in parts[0]:
        return _alpha(parts[0], text)
    ranges = []
    for s in parts:
        kind, sep, span = s.partition("@")
        lo, sep2, hi = span.partition(":")
        try:
            tau_lo, tau_hi = float(lo), float(hi)
        except ValueError:
            tau_lo = tau_hi = math.nan
        if not sep or not sep2 or not (math.isfinite(tau_lo) and math.isfinite(tau_hi) and 0 <= tau_lo <= tau_hi):
            raise UsageError(
                f"--noise-type {text!r}: {s!r} needs TYPE@LO:HI with 0 ≤ LO ≤ HI in seconds (e.g. wfm@0.5:20)"
            )
        ranges.append((tau_lo, tau_hi, _alpha(kind, text)))
    return ranges


def _parse_estimators(text: str) -> tuple[str, ...]:
    from analysis.noise.stability import ESTIMATORS  # lazy: scipy (--help time)

    names = [e.strip().lower() for e in text.split(",") if e.strip()]
    if not names:
        raise UsageError(f"--estimators is empty; choose from {','.join(ESTIMATORS)}")
    bad = [e for e in names if e not in ESTIMATORS]
    if bad:
        raise UsageError(f"--estimators: unknown {', '.join(bad)}; choose from {','.join(ESTIMATORS)}")
    return tuple(dict.fromkeys(names))


def _parse_fit_estimator(text: str) -> str:
    """``--fit-estimator``: one of :data:`analysis.noise.terms.FIT_ESTIMATORS`, else a UsageError saying why."""
    from analysis.noise.stability import ESTIMATORS  # lazy: scipy (--help time)
    from analysis.noise.terms import FIT_ESTIMATORS  # lazy: scipy (--help time)

    name = text.strip().lower()
    if name in FIT_ESTIMATORS:
        return name
    why = (
        "its noise terms have no fixed gain (modified variances: m-dependent, white PM as τ^-3)"
        if name in ("mdev", "tdev", "mtotdev", "ttotdev")
        else "it is biased against the Allan variance except for white FM (use theoh)"
        if name == "theo1"
        else "its one bias factor, taken at long τ, mis-scales short τ with mixed noise (use theoh)"
        if name == "theobr"
        else "it is not a variance of the power-law noise model"
        if name in ESTIMATORS
        else "unknown estimator"
    )
    raise UsageError(f"--fit-estimator {text}: {why}; choose from {','.join(FIT_ESTIMATORS)}")


def run(args: argparse.Namespace) -> int:
    """Execute ``tablebench noise``."""
    from analysis.noise.terms import analyse_noise  # lazy: scipy (--help time)

    if not 0.0 < args.confidence < 1.0:
        raise UsageError(f"--confidence must be between 0 and 1 (e.g. 0.683 or 0.95), got {args.confidence}")
    if args.channels is not None and not args.channels.strip(" ,"):
        raise UsageError("--channels is empty; name the channels (e.g. gyro_x,gyro_y) or omit it for all")
    taus = _parse_taus(args.taus)
    estimators = _parse_estimators(args.estimators)
    fit_estimator = _parse_fit_estimator(args.fit_estimator)
    noise_type = parse_noise_type(args.noise_type)
    data = load_input(
        args.input, rate=args.rate, channels=args.channels, step=args.step, min_samples=MIN_SAMPLES, allow_gaps=True
    )
    n = len(next(iter(data.channels.values())))
    slow = {"mtotdev", "ttotdev", "htotdev", "theo1", "theobr", "theoh"} & set(estimators)
    limit = MAX_ALL_TAUS_TOTAL if slow else MAX_ALL_TAUS
    if taus == "all" and n > limit:
        raise UsageError(
            f"--taus all costs O(N²){' · m for ' + ','.join(sorted(slow)) if slow else ''}: {n} samples is too many "
            f"(limit {limit}); use --taus octave, decade or log"
        )
    out = output_dir(args.out, "noise")
    try:
        result = analyse_noise(
            data.channels,
            data.rate,
            data.units,
            taus=taus,
            confidence=args.confidence,
            published_itotvar=args.published_itotvar,
            estimators=estimators,
            data_type=args.data_type,
            fit_estimator=fit_estimator,
            noise_type=noise_type,
            remove_drift=args.remove_drift,
        )
    except ValueError as exc:
        raise InputError(f"{data.source}: {exc}") from None
    result["source"] = data.source
    print(f"{data.source}: {len(data.channels)} channel(s), {n} samples at {data.rate:g} Hz ({n / data.rate:.1f} s)")
    for name, ch in result["channels"].items():
        g = ch["gaps"]
        if g["samples"]:
            print(f"{name}: {g['runs']} gap(s), {g['samples']} NaN sample(s); terms touching them skipped")
    total_gaps = sum(ch["gaps"]["runs"] for ch in result["channels"].values())
    if not total_gaps:
        print("gaps: none")
    print(format_table(result))
    if out is not None:
        from analysis.noise.plot import plot_noise  # lazy: matplotlib (--help time)

        write_json(out / "noise.json", result, nonfinite="null")
        fig = plot_noise(result, title=f"Noise analysis: {data.source}")
        fig.savefig(out / "noise.png", dpi=110)
        print(f"wrote {out / 'noise.json'} and {out / 'noise.png'}")
    return 0
