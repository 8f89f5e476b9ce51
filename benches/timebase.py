"""A recording's time base: its raw time sources → :class:`analysis.timebase.TimeBase` (docs/methods/time-base.md).

The one place where identification, the certificate and the plots get the mapping t_table = t₀ + (1 + ε) t_unit
of a run: :func:`run_time_base` estimates it from the recorded motions (only the samples around motions are
read), checks it against the recorded host and controller clocks, and :func:`table_in_unit_time` puts the
table's readings on the unit's clock, where every reference is evaluated.

The bench file may declare hardware timing (``unit.time_reference``, BENCH_FORMAT.md): "pps" or "time_tag"
means the table and the unit are stamped on one clock by hardware; then that mapping is used (identity) and the
estimate only checks it — a disagreement beyond 3σ is a warning.
"""

from __future__ import annotations

import math
from dataclasses import replace
from typing import Any

import numpy as np
from numpy.typing import NDArray

from analysis.identification.batch import batch_identify
from analysis.timebase import RunSignals, TimeBase, clock_check, coarse_mapping, estimate_time_base
from analysis.timebase.events import moving_readings

from .recording import Recording, TableReadings, TimeSources
from .recording.layout import IMU_CHUNK
from .reference import interpolate_windows, reference_at

WINDOW_S = 1.5
"""Event window before and after each motion, s (analysis.timebase.events)."""


def _sample_ranges(
    rec: Recording, timing: TimeSources | None, table: TableReadings, fs: float, initial: tuple[float, float]
) -> list[tuple[int, int]]:
    """Row ranges of the samples around motions (all samples if the recording lacks its sample indices).

    A reading's sample is found through the coarse mapping ``initial`` (t₀, ε), not through the samples received
    before it: a link that delivers frames in bursts of seconds makes the latter lag the table by a burst."""
    n = rec.n_samples
    if timing is None or timing.table_sample_index.shape[0] != len(table):
        return [(0, n)]
    mv = moving_readings(table.angles, table.rates, 2e-4, 1e-4)
    if not np.any(mv):
        return []
    # only the starts and ends of motions matter (a long spin's middle is never in an event window)
    edge = mv & ~(np.concatenate([[False], mv[:-1]]) & np.concatenate([mv[1:], [False]]))
    pad = int((WINDOW_S + 1.0) * fs)
    t_first = float(rec.samples(0, 1, ("time",)).time[0]) if n else 0.0
    t0, eps = initial
    k = np.rint(((np.asarray(table.time, float)[edge] - t0) / (1.0 + eps) - t_first) * fs).astype(np.int64)
    lo = np.clip(k - pad, 0, n)
    hi = np.clip(k + pad, 0, n)
    out: list[tuple[int, int]] = []
    for a, b in zip(lo.tolist(), hi.tolist(), strict=True):
        if out and a <= out[-1][1] + IMU_CHUNK:  # one read per stored chunk: a chunk is decompressed whole
            out[-1] = (out[-1][0], max(out[-1][1], b))
        else:
            out.append((a, b))
    return out


def run_signals(
    rec: Recording,
    table: TableReadings,
    *,
    g: float,
    mounting: NDArray[np.float64],
    latency: float,
    timing: TimeSources | None,
    initial: tuple[float, float] = (0.0, 0.0),
) -> RunSignals:
    """The arrays :func:`analysis.timebase.estimate_time_base` needs, read from an open recording (the samples
    around the motions, found with the coarse mapping ``initial``: :func:`initial_mapping`). ``timing``: the
    recording's time sources (:meth:`Recording.timing`, read once by the caller; None when it has none)."""
    fs = float(rec.header.sample_rate_hz)
    ranges = _sample_ranges(rec, timing, table, fs, initial)
    parts = [rec.samples(a, b, ("time", "gyro")) for a, b in ranges]
    keep = [i for i, p in enumerate(parts) if p.time is not None and p.time.size]
    t = np.concatenate([parts[i].time for i in keep]) if keep else np.zeros(0)
    gyr = np.concatenate([parts[i].gyro for i in keep]) if keep else np.zeros((0, 3))
    has_gyro = bool(gyr.size) and bool(np.all(np.isfinite(gyr))) and bool(np.any(gyr != 0))
    acc = np.zeros((t.size, 3))
    if not has_gyro:  # accelerometers only: their specific force is the signal (read only then: it is costly)
        acc = np.concatenate([rec.samples(*ranges[i], ("accel",)).accel for i in keep]) if keep else acc
    sig = RunSignals(
        t=t,
        accel=acc,
        gyro=gyr if has_gyro else None,
        table_time=np.asarray(table.time, float),
        angles=np.asarray(table.angles, float),
        rates=np.asarray(table.rates, float),
        sample_index=None,  # the samples read are only those around motions: the coarse mapping is done here
        g=float(g),
        mounting=np.asarray(mounting, float),
        latency=float(latency),
    )
    return sig


def _unit_time_of(rec: Recording, index: NDArray[np.int64]) -> NDArray[np.float64]:
    """Unit time of samples ``index`` on the unit's sample clock: the first sample's time stamp + index / f_s
    (the counter's clock; within the time stamps' jitter of the recorded ones, and no read per row)."""
    t_first = float(rec.samples(0, 1, ("time",)).time[0])
    return t_first + np.asarray(index, dtype=float) / float(rec.header.sample_rate_hz)


def initial_mapping(rec: Recording, table: TableReadings, timing: TimeSources | None) -> tuple[float, float]:
    """The coarse (t₀, ε) from the reading times against the samples received before each reading
    (:func:`analysis.timebase.coarse_mapping`); (0, 0) when the recording lacks its time sources (``timing`` as
    in :func:`run_signals`)."""
    if timing is None or timing.table_sample_index.shape[0] != len(table) or not rec.n_samples or not len(table):
        return 0.0, 0.0
    tu = _unit_time_of(rec, np.clip(timing.table_sample_index - 1, 0, rec.n_samples - 1))
    sig = RunSignals(
        t=tu,
        accel=np.zeros((tu.size, 3)),
        gyro=None,
        table_time=np.asarray(table.time, float),
        angles=np.asarray(table.angles, float),
        rates=np.asarray(table.rates, float),
        sample_index=np.arange(1, tu.size + 1),
        g=0.0,
        mounting=np.eye(3),
    )
    return coarse_mapping(sig)


def run_time_base(
    rec: Recording,
    table: TableReadings,
    *,
    g: float,
    mounting: NDArray[np.float64],
    latency: float,
    declared: str | None = None,
) -> TimeBase:
    """Estimate (and check) the time base of an open recording; see the module docstring."""
    timing = rec.timing()  # read once: the coarse mapping, the motions' samples and the clock check use it
    initial = initial_mapping(rec, table, timing)
    sig = run_signals(rec, table, g=g, mounting=mounting, latency=latency, timing=timing, initial=initial)
    tb = estimate_time_base(sig, window=WINDOW_S, initial=initial)
    check: dict[str, Any] = {}
    if timing is not None and timing.block_end_sample.size > 2 and rec.n_samples:
        tb_end = _unit_time_of(rec, np.clip(timing.block_end_sample - 1, 0, rec.n_samples - 1))
        ctrl = timing.table_controller_time if np.any(np.isfinite(timing.table_controller_time)) else None
        check = clock_check(tb_end, timing.block_host_time, ctrl, timing.table_host_request,
                            timing.table_host_answer, tb)  # fmt: skip
        check["table_stamped_by"] = "controller" if ctrl is not None else "host"
    notes = list(tb.notes)
    if check.get("consistent") is False:
        notes.append(
            f"the motion-based rate {tb.rate * 1e6:+.3f} ppm disagrees with the {check['rate'] * 1e6:+.3f} ppm the "
            f"host's clock implies (z = {check['z']:.1f}): a clock drifts, or the readings' time stamps are wrong"
        )
    if declared in ("pps", "time_tag"):
        z_off = tb.offset / tb.u_offset if tb.u_offset and math.isfinite(tb.u_offset) else 0.0
        notes.append(
            f"hardware timing declared ({declared}): one clock used; the estimate checks it "
            f"(offset {tb.offset * 1e3:.4f} ms, {z_off:.1f} σ from zero)"
        )
        check["hardware"] = {"declared": declared, "offset_z": z_off, "consistent": bool(abs(z_off) <= 3.0)}
        return replace(TimeBase(method="hardware"), events=tb.events, check={**check, "estimate": tb.as_dict()},
                       notes=notes, misfit=tb.misfit)  # fmt: skip
    return replace(tb, check=check, notes=notes)


def time_base_sensitivity(
    windows: list[tuple[NDArray[np.float64], NDArray[np.float64], tuple[float, float]]],
    table: TableReadings,
    *,
    g: float,
    mounting: NDArray[np.float64],
    latency: float,
    r_var: NDArray[np.float64],
    p0: NDArray[np.float64],
    max_points: int = 200,
    steps: tuple[float, float] = (1e-4, 1e-6),
) -> NDArray[np.float64]:
    """∂x/∂(t₀, ε) of the 18 identified parameters (18, 2): the batch estimate re-solved on the same (thinned)
    samples with the table's clock shifted by ``steps`` (s, relative); the thinned rows carry the weight of the
    samples they stand for, so the prior's pull is the full run's.

    ``windows``: per acquisition window (sample times t (unit clock, s), specific force f_out (n, 3) m/s² body
    frame, reading span). ``table``: the readings already on the unit's clock.
    """
    ts, fo, wt, spans = [], [], [], []
    for t, f, span in windows:
        k = max(1, math.ceil(t.size / max_points))
        idx = np.arange(0, t.size, k)
        ts.append(t[idx])
        fo.append(f[idx])
        w = np.full(idx.size, float(k))
        w[-1] = t.size - k * (idx.size - 1)
        wt.append(w)
        spans.append(span)
    f_out, weights = np.concatenate(fo), np.concatenate(wt)

    def solve(d_off: float, d_rate: float) -> NDArray[np.float64]:
        # THE reference (benches.reference): the table interpolated per window within its span (the rule's
        # many-windows form, benches.reference.interpolate_windows), then turned into f_ref and ω for all windows
        # at once (one vectorised call instead of one per window)
        shifts = [d_off + d_rate * t for t in ts]  # the table seen d_off + d_rate·t later on the unit's clock
        tq = [t + shift - latency for t, shift in zip(ts, shifts, strict=True)]
        sp = [(span[0] + float(sh[0]), span[1] + float(sh[-1])) for span, sh in zip(spans, shifts, strict=True)]
        ang_all, rat_all = interpolate_windows(tq, sp, table.time, table.angles, table.rates)
        f_ref, om = reference_at(ang_all, rat_all, g, mounting)
        return batch_identify(f_out, f_ref, om, r_var, None, p0, weights=weights).x

    x0 = solve(0.0, 0.0)
    return np.column_stack([(solve(steps[0], 0.0) - x0) / steps[0], (solve(0.0, steps[1]) - x0) / steps[1]])


def reference_rate_u(check: dict[str, Any]) -> float:
    """u of the controller clock's rate against the host's (relative; 0 when the run has none): the rate the
    gyro's reference second is corrected by (``benches.identify.reference_clock_factor``), so a gyro scale factor
    inherits it 1 : 1. A short run on a busy host measures it poorly (tens of ppm in a minute): it is carried,
    never assumed away."""
    if not isinstance(check, dict):
        return 0.0
    e_c, u_c = check.get("controller_vs_host_rate"), check.get("u_controller_vs_host_rate")
    if not isinstance(e_c, int | float) or not math.isfinite(e_c):
        return 0.0
    return float(u_c) if isinstance(u_c, int | float) and math.isfinite(u_c) else 0.0


def reference_rate_covariance(names: list[str], check: dict[str, Any]) -> NDArray[np.float64]:
    """Covariance (n, n) of parameters ``names`` from the reference second's u (:func:`reference_rate_u`): u² on
    the gyro scale factors, fully correlated (one reference second for the three)."""
    out = np.zeros((len(names), len(names)))
    u = reference_rate_u(check)
    idx = [k for k, n in enumerate(names) if n.startswith("gyro_S_")]
    if u > 0 and idx:
        out[np.ix_(idx, idx)] = u * u
    return out


def table_in_unit_time(table: TableReadings, tb: TimeBase) -> TableReadings:
    """The readings with their times on the unit's clock (where the reference is evaluated)."""
    if tb.offset == 0.0 and tb.rate == 0.0:
        return table
    return replace(table, time=tb.to_unit_time(table.time))


__all__ = [
    "WINDOW_S",
    "initial_mapping",
    "reference_rate_covariance",
    "reference_rate_u",
    "run_signals",
    "run_time_base",
    "table_in_unit_time",
    "time_base_sensitivity",
]
