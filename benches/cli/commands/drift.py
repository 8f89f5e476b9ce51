"""``tablebench drift``: drift modelling of a static record (tests, ARMA model, online RLS, compensation)."""

from __future__ import annotations

import argparse
import math
import re
from collections.abc import Callable

from analysis.drift.preprocess import DriftInputError
from analysis.units import DISPLAY_UNITS
from benches.cli.analysis_input import InputError, add_input_arguments, load_input, output_dir
from benches.cli.arguments import bounded
from benches.cli.work import Work, figure_png
from core.errors import UsageError
from core.jsonio import write_json, write_text_atomic

EXAMPLES = """examples:
  tablebench drift runs/static-noise-001                          # a recording, all six channels
  tablebench drift runs/static-noise-001 --channel gyro_z --out report/
  tablebench drift data.npy --rate 100 --no-mean --out report/   # the record is already centred
  tablebench drift data.csv --rate 100 --outliers mad --detrend 1 --p-ge-q

output: per channel, outliers replaced, the trend removed, every test (Daniel and reverse-arrangement on
sub-series means and mean squares, Jarque-Bera, Welch periodicity, Ljung-Box on the ARMA residuals) with its
statistic, threshold and verdict, the ARMA(p,q) model chosen by BIC (AIC's choice shown beside it) with the
mean estimated by maximum likelihood and standard errors (Box-Jenkins signs:
x_t - mean - sum phi_j (x_(t-j) - mean) = e_t - sum theta_j e_(t-j)), the online RLS/ELS estimate, and the
standard deviation before/after compensation. A last line per channel says what could not be settled (a fit that
did not converge, a near-cancelling AR/MA root pair); drift.json lists it under "unsettled". With --out DIR:
drift.json (SI) and PNGs per channel (ACF/PACF, PSD, histogram, compensation). Tones found by the periodicity
check are listed for 'tablebench periodic'. Methods: docs/methods/drift.md, analysis/drift/.
"""


def register(sub: argparse._SubParsersAction) -> None:
    """Add the ``drift`` subcommand."""
    p = sub.add_parser(
        "drift",
        help="drift modelling of a static record: stationarity/normality/periodicity tests, ARMA, RLS",
        description="Pre-process a static record (outliers, trend), test it (stationarity, periodicity, "
        "normality), select (by BIC) and estimate an ARMA(p,q) drift model (p, q <= 3) with standard errors, "
        "check the residuals' whiteness, run the online recursive estimator, and compensate the drift with a "
        "Kalman filter and a sliding-window graph (Levenberg-Marquardt) smoother.",
        epilog=EXAMPLES,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    add_input_arguments(p)
    p.add_argument("--channel", dest="channels", help="same as --channels (one or more comma-separated names)")
    p.add_argument(
        "--criterion",
        choices=("bic", "aic"),
        default="bic",
        help="ARMA order criterion (default bic, the spec's; aic over-fits near-cancelling root pairs)",
    )
    p.add_argument(
        "--no-mean",
        action="store_true",
        help="fix the ARMA mean at zero (the record is already centred) instead of estimating it jointly",
    )
    p.add_argument("--p-ge-q", action="store_true", help="only ARMA orders with p >= q (the published method's rule)")
    p.add_argument(
        "--fit",
        choices=("ml", "css"),
        default="ml",
        help="ARMA estimator: exact maximum likelihood (default) or conditional least squares (faster on long records)",
    )
    p.add_argument("--quiet", action="store_true", help="no progress lines on stderr")
    p.add_argument("--outliers", choices=("sigma", "mad"), default="sigma", help="outlier scale: 3σ or MAD")
    p.add_argument(
        "--outlier-k",
        type=bounded(0.0, 100.0, low_open=True),
        default=3.0,
        help="outlier threshold in scale units (default 3)",
    )
    p.add_argument(
        "--detrend",
        type=bounded(0, 10, integer=True),
        default=None,
        metavar="ORDER",
        help="polynomial order (default: by BIC)",
    )
    p.add_argument(
        "--segments",
        type=bounded(2, 100000, integer=True),
        default=50,
        help="sub-series for the stationarity tests (default 50)",
    )
    p.add_argument("--alpha", type=float, default=0.05, help="significance level of the tests (default 0.05)")
    p.add_argument("--forgetting", type=float, default=1.0, help="RLS forgetting factor λ in (0, 1] (default 1)")
    p.add_argument("--keep-tones", action="store_true", help="do not subtract detected tones before the ARMA fit")
    p.add_argument("--no-online", action="store_true", help="skip the online RLS/ELS pass")
    p.add_argument(
        "--measurement-var",
        type=bounded(0.0, 1e12, low_open=True),
        default=None,
        help="R of the compensation model, SI unit² (default: σ²)",
    )
    p.set_defaults(func=run)


def _display(unit: str) -> tuple[float, str]:
    """Scale and label to show a channel's σ in the project's display units (analysis.units.DISPLAY_UNITS):
    gyro error quantities in deg/h, accelerometer ones in µg, SI otherwise."""
    kind = {"rad/s": "gyro_bias", "m/s^2": "acceleration"}.get(unit)
    if kind is None:
        return 1.0, unit
    label, one = DISPLAY_UNITS[kind]
    return one, label


def format_report(result: dict, units: dict[str, str]) -> str:
    """Plain-text report: tests, model with standard errors, online estimate, compensation."""
    lines = []
    for name, ch in result["channels"].items():
        scale, label = _display(units.get(name, "SI"))
        m = ch["model"]
        lines.append(f"== {name}: {ch['samples']} samples at {ch['rate_hz']:g} Hz")
        o = ch["outliers"]
        lines.append(
            f"  outliers ({o['method']}, k={o['k']:g}): {o['replaced']} replaced; "
            f"detrend order {ch['detrend']['order']}"
        )
        lines.append(f"  {'test':<32}{'statistic':>12}{'threshold':>12}  verdict")
        for tname, t in ch["tests"].items():
            lines.append(f"  {tname:<32}{t['statistic']:>12.4g}{t['threshold']:>12.4g}  {t['verdict']}")
        if ch["tones_hz"]:
            lines.append("  tones for 'tablebench periodic': " + ", ".join(f"{f:.4g} Hz" for f in ch["tones_hz"]))
        lines.append("  note: " + ch["tests"]["jarque_bera"]["note"])
        lines.append(
            f"  model ARMA({m['p']},{m['q']}) by {m['criterion'].upper()} "
            f"(by AIC {tuple(ch['order_selection']['by_aic'])}, by BIC {tuple(ch['order_selection']['by_bic'])}), "
            f"{m['method'].upper()} {m['status']}, log-likelihood {m['log_likelihood']:.6g}"
        )
        if m["include_mean"]:
            lines.append(f"    mean     = {m['mean'] / scale:.6g} ± {(m['se_mean'] or math.nan) / scale:.3g} {label}")
        else:
            lines.append("    mean     = 0 (fixed: --no-mean)")
        for j, (v, s) in enumerate(zip(m["phi"], m["se_phi"], strict=True), start=1):
            lines.append(f"    phi_{j}   = {v: .6f} ± {s:.6f}")
        for j, (v, s) in enumerate(zip(m["theta"], m["se_theta"], strict=True), start=1):
            lines.append(f"    theta_{j} = {v: .6f} ± {s:.6f}")
        lines.append(f"    sigma    = {math.sqrt(m['sigma2']) / scale:.4g} {label} (innovation std)")
        mo = m["moment"]
        lines.append(
            f"    moment estimates: phi {[round(v, 5) for v in mo['phi']]}, theta {[round(v, 5) for v in mo['theta']]}"
        )
        on = ch["online"]
        if on.get("run"):
            lines.append(
                f"  online {on['method']} (λ={on['forgetting']:g}): phi {[round(v, 5) for v in on['phi']]}, "
                f"theta {[round(v, 5) for v in on['theta']]}, {on['samples_per_s']:.3g} samples/s"
            )
        c = ch["compensation"]
        after = c.get("std_after_filter")
        txt = f"  std before {c['std_before'] / scale:.4g} {label}"
        if after is not None:
            txt += f", after Kalman prediction {after / scale:.4g} {label}"
        if "std_after_smoother" in c:
            txt += (
                f"; smoother span {c['smoother_samples']} samples: {c['std_before_smoothed_span'] / scale:.4g} → "
                f"{c['std_after_smoother'] / scale:.4g} {label}"
            )
        lines.append(txt)
        lines.append("  " + unsettled_line(ch.get("unsettled", [])))
    return "\n".join(lines)


def unsettled_line(items: list[dict]) -> str:
    """One line: what the ARMA modelling of a channel could not settle, or that everything was settled."""
    if not items:
        return "settled: every ARMA fit converged; no near-cancelling AR/MA root pair in the chosen model"
    parts = []
    for it in items:
        if it["issue"] == "parameter redundancy":
            parts.append(f"{it['item']} has a near-cancelling AR/MA root pair (parameter redundancy)")
        else:
            chosen = " (the chosen model)" if it.get("chosen") else ""
            why = " toward a unit root" if it["issue"] == "boundary" else ""
            parts.append(f"{it['item']}{chosen} not converged{why}, gradient norm {it['gradient_norm']:.3g}")
    return "NOT settled: " + "; ".join(parts) + " (details in drift.json 'unsettled')"


def run(args: argparse.Namespace) -> int:
    """Execute ``tablebench drift``."""
    from analysis.drift.report import MIN_SAMPLES, DriftOptions, analyse_channel  # lazy: scipy (--help time)

    if not 0.0 < args.alpha < 0.5:
        raise UsageError(f"--alpha must be between 0 and 0.5 (e.g. 0.05), got {args.alpha}")
    if not 0.0 < args.forgetting <= 1.0:
        raise UsageError(f"--forgetting must be in (0, 1] (e.g. 0.999), got {args.forgetting}")
    if args.detrend is not None and args.detrend < 0:
        raise UsageError(f"--detrend must be a non-negative polynomial order, got {args.detrend}")
    if args.segments < 4:
        raise UsageError(f"--segments must be at least 4, got {args.segments}")
    if not (args.outlier_k > 0 and math.isfinite(args.outlier_k)):
        raise UsageError(f"--outlier-k must be a positive number, got {args.outlier_k}")
    if args.measurement_var is not None and not args.measurement_var > 0:
        raise UsageError(f"--measurement-var must be positive (SI unit²), got {args.measurement_var}")
    data = load_input(args.input, rate=args.rate, channels=args.channels, step=args.step, min_samples=MIN_SAMPLES)
    out = output_dir(args.out, "drift")
    opts = DriftOptions(
        outlier_method=args.outliers,
        outlier_k=args.outlier_k,
        detrend_order=args.detrend,
        segments=args.segments,
        alpha=args.alpha,
        criterion=args.criterion,
        include_mean=not args.no_mean,
        p_ge_q=args.p_ge_q,
        fit_method=args.fit,
        online=not args.no_online,
        forgetting=args.forgetting,
        measurement_var=args.measurement_var,
        remove_tones=not args.keep_tones,
    )
    names = list(data.channels)

    def compute(work: Work) -> tuple[dict, list[tuple[str, bytes]]]:
        results = {}
        for name in names:
            try:
                results[name] = analyse_channel(data.channels[name], data.rate, name, opts, _progress(work))
            except DriftInputError as exc:
                raise InputError(f"{data.source}: {exc}") from None
            work.advance()
        pngs: list[tuple[str, bytes]] = []
        if out is not None:
            from analysis.drift.plot import plot_channel  # lazy: matplotlib, scipy (--help time)

            for name, res in results.items():
                work.stage(f"plotting {name}")
                for kind, fig in plot_channel(res, name, data.units.get(name, "SI")).items():
                    pngs.append((f"drift_{name}_{kind}.png", figure_png(fig, 100)))
        return results, pngs

    with Work("drift", len(names) + 0.2 * (out is not None), quiet=args.quiet) as work:  # as 'run' does
        results, pngs = work.run(compute, work)
        _report(data, results, out, pngs, work)
    return 0


def _progress(work: Work) -> Callable[[str], None]:
    """The analysis' progress messages as the stage; "(k/N)" in one (the ARMA search) as the part done."""

    def show(msg: str) -> None:
        m = re.search(r"\((\d+)/(\d+)\)", msg)
        if m and int(m.group(2)) > 0:
            work.fraction(int(m.group(1)) / int(m.group(2)), msg)
        else:
            work.stage(msg)

    return show


def _report(data, results: dict, out, pngs: list[tuple[str, bytes]], work: Work) -> None:  # noqa: ANN001
    """Print the report; write drift.json and the plots (all or nothing)."""
    summaries = {name: res.summary for name, res in results.items()}
    result = {
        "source": data.source,
        "rate_hz": data.rate,
        "sign_convention": "x_t - sum phi_j x_(t-j) = e_t - sum theta_j e_(t-j) (Box-Jenkins)",
        "units": data.units,
        "channels": summaries,
    }
    print(f"{data.source}: {len(data.channels)} channel(s) at {data.rate:g} Hz")
    print(format_report(result, data.units))
    if out is not None:
        with work.writing():  # all or nothing: a Ctrl-C now is held until every file is complete
            # null where a number is not available (e.g. σ after the filter of a white residual, se of a fixed mean)
            written = [write_json(out / "drift.json", result, nonfinite="null")]
            written += [write_text_atomic(out / name, png) for name, png in pngs]
        print("wrote " + ", ".join(str(p) for p in written))
