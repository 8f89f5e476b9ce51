"""``tablebench noise``: the frequency-stability family, confidence intervals and noise-term fit of a static record."""

from __future__ import annotations

import argparse
import math

from benches.cli.analysis_input import InputError, add_input_arguments, load_input, output_dir
from benches.cli.work import Work, figure_png
from core.errors import UsageError
from core.jsonio import write_json, write_text_atomic

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
        "--edf",
        default="tablebench",
        choices=("tablebench", "stable32"),
        help="EDF rules of the χ² intervals: tablebench (default: where Stable32's intervals miss their confidence, "
        "EDFs calibrated by Monte Carlo coverage) or stable32 (Stable32's own rules: with --noise-type set as a "
        "Stable32 run printed, its bounds are reproduced); written to noise.json 'edf_rules'",
    )
    p.add_argument(
        "--remove-drift",
        default=None,
        choices=("linear", "quadratic"),
        help="remove a least-squares linear or quadratic frequency drift from each channel first (phase data: the "
        "quadratic or cubic phase it means); the removed coefficients are written to noise.json",
    )
    p.add_argument(
        "--psd",
        action="store_true",
        help="also the one-sided power spectral density of each channel (Welch, log bins) with N, B, K fitted in the "
        "frequency domain beside the Allan terms (IEEE 952 forms); noise.json 'psd', noise_psd.png (gap-free rate "
        "data only)",
    )
    p.add_argument(
        "--dynamic",
        default=None,
        metavar="WINDOW[:STEP]",
        help="dynamic Allan deviation: overlapping ADEV of a WINDOW-second window moved by STEP seconds (default "
        "WINDOW/4) along the record, drawn as a picture (noise_dynamic.png; values in noise.json 'dynamic')",
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
    options = dict(
        taus=taus,
        confidence=args.confidence,
        published_itotvar=args.published_itotvar,
        estimators=estimators,
        data_type=args.data_type,
        fit_estimator=fit_estimator,
        noise_type=noise_type,
        remove_drift=args.remove_drift,
        edf_rules=args.edf,
    )
    names = list(data.channels)

    def compute(work: Work) -> tuple[dict, list[tuple[str, bytes]]]:
        """One channel at a time (the channels are independent): progress and an ETA per channel."""
        result: dict = {}
        for k, name in enumerate(names):
            work.stage(f"{name} ({k + 1}/{len(names)}): deviations, intervals, noise terms")
            try:
                one = analyse_noise({name: data.channels[name]}, data.rate, data.units, **options)
            except ValueError as exc:
                raise InputError(f"{data.source}: {exc}") from None
            result = one if not result else {**result, "channels": {**result["channels"], **one["channels"]}}
            work.advance()
        result["source"] = data.source
        work.stage("PSD and dynamic Allan deviation" if args.psd or args.dynamic is not None else "report")
        extras = _extras(args, data, result)
        pngs: list[tuple[str, bytes]] = []
        if out is not None:
            from analysis.noise.plot import plot_noise  # lazy: matplotlib (--help time)

            work.stage("plotting")
            pngs.append(("noise.png", figure_png(plot_noise(result, title=f"Noise analysis: {data.source}"), 110)))
            pngs += _extra_pngs(extras, result, data)
        return result, pngs

    with Work("noise", len(names) + 0.2 * (out is not None)) as work:  # the interrupt and progress of 'run'
        result, pngs = work.run(compute, work)
        if out is not None:
            with work.writing():  # all or nothing: a Ctrl-C now is held until every file is complete
                write_json(out / "noise.json", result, nonfinite="null")
                for name, png in pngs:
                    write_text_atomic(out / name, png)
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
        print("wrote " + ", ".join(str(out / name) for name in ["noise.json", *(n for n, _png in pngs)]))
    return 0


def _parse_dynamic(text: str) -> tuple[float, float | None]:
    """``--dynamic WINDOW[:STEP]`` in seconds."""
    win, _, step = text.partition(":")
    try:
        w = float(win)
        s = float(step) if step else None
    except ValueError:
        w, s = math.nan, None
    if not (math.isfinite(w) and w > 0) or (s is not None and not (math.isfinite(s) and s > 0)):
        raise UsageError(f"--dynamic {text!r}: give WINDOW[:STEP] in seconds, e.g. --dynamic 600:60")
    return w, s


def _extras(args: argparse.Namespace, data, result: dict) -> dict:
    """--psd and --dynamic: computed per channel, their JSON parts added to ``result``; the arrays for the plots."""
    extras: dict = {}
    if args.psd:
        from analysis.noise.psd import rate_psd  # lazy: scipy (--help time)

        if args.data_type != "freq":
            raise UsageError("--psd needs rate (frequency) data; drop --data-type phase")
        extras["psd"] = {}
        for name, y in data.channels.items():
            try:
                extras["psd"][name] = p = rate_psd(y, data.rate)
            except ValueError as exc:
                raise InputError(f"{data.source}: channel {name}: {exc}") from None
            terms = {k: {"value": v, "sigma": s, "uncertainty": "standard (1σ)"} for k, (v, s) in p["terms"].items()}
            result["channels"][name]["psd"] = {
                "f_hz": p["f_binned"], "one_sided_psd": p["psd_binned"], "dof": p["dof_binned"], "terms": terms,
            }  # fmt: skip
    if args.dynamic is not None:
        from analysis.noise.dynamic import dynamic_adev  # lazy: scipy (--help time)

        window, step = _parse_dynamic(args.dynamic)
        extras["dynamic"] = {}
        for name, y in data.channels.items():
            try:
                extras["dynamic"][name] = dynamic_adev(y, data.rate, window, step, args.data_type)
            except ValueError as exc:
                raise UsageError(f"--dynamic {args.dynamic}: {exc}") from None
        result["dynamic"] = {"window_s": window, "step_s": step if step is not None else window / 4.0,
                             "channels": extras["dynamic"]}  # fmt: skip
    return extras


def _extra_pngs(extras: dict, result: dict, data) -> list[tuple[str, bytes]]:  # noqa: ANN001
    """noise_psd.png and noise_dynamic.png as PNG bytes (written with the other outputs, all or nothing)."""
    pngs = []
    if "psd" in extras:
        from analysis.noise.plot import plot_psd  # lazy: matplotlib (--help time)

        terms = {k: ch["terms"] for k, ch in result["channels"].items()}
        fig = plot_psd(extras["psd"], terms, 1.0 / data.rate, f"PSD: {data.source}")
        pngs.append(("noise_psd.png", figure_png(fig, 110)))
    if "dynamic" in extras:
        from analysis.noise.plot import plot_dynamic  # lazy: matplotlib (--help time)

        fig = plot_dynamic(extras["dynamic"], f"Dynamic ADEV: {data.source}")
        pngs.append(("noise_dynamic.png", figure_png(fig, 110)))
    return pngs
