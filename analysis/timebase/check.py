"""Independent bounds on the time base from the recorded host and controller clocks, and misfit causes.

The host's clock sees the unit's blocks arrive (transport latency, batching) and the controller's readings
requested and answered. Straight lines through those give the unit's rate against the host and the
controller's rate against the host, hence a rate for t_table against t_unit that does not use the motions at
all: the motion-based estimate is checked against it (docs/methods/time-base.md: "bounded by what the
controller's and the host's clocks say"). The controller's line uses only the readings with the shortest
request→answer time (a minimum-delay filter, as NTP's: a busy host's or a queue's delay does not enter); the
unit's uses every block (their arrival delay is a stationary sawtooth of the link's bursts, whose lower
envelope aliases with the unit's rate and is not safer). σ of a slope is from the residuals. Seconds throughout.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from numpy.typing import NDArray

from analysis.timebase.model import TimeBase


def _slope(x: NDArray[np.float64], y: NDArray[np.float64]) -> tuple[float, float, float]:
    """Slope of y on x, its σ (from the residuals), and the residuals' standard deviation."""
    ok = np.isfinite(x) & np.isfinite(y)
    x, y = x[ok], y[ok]
    if x.size < 3 or np.ptp(x) <= 0:
        return math.nan, math.nan, math.nan
    xc = x - x.mean()
    sxx = float(np.sum(xc * xc))  # element-wise sums: a BLAS dot can stall on a loaded machine
    b = float(np.sum(xc * (y - y.mean()))) / sxx
    r = y - y.mean() - b * xc
    s = math.sqrt(float(np.sum(r * r)) / (x.size - 2))
    return b, s / math.sqrt(sxx), s


def _fastest(x: NDArray[np.float64], y: NDArray[np.float64], delay: NDArray[np.float64]) -> NDArray[np.bool_]:
    """The points whose transport ``delay`` is in its lowest fifth (a minimum-delay filter, as NTP's): their
    time stamps bracket the event tightly, a queue's or a busy host's delay does not enter. All points when
    those are fewer than 10 or span less than half of ``x``."""
    ok = np.isfinite(x) & np.isfinite(y) & np.isfinite(delay)
    if np.count_nonzero(ok) < 10:
        return np.isfinite(x) & np.isfinite(y)
    keep = ok & (delay <= np.quantile(delay[ok], 0.2))
    if np.count_nonzero(keep) < 10 or np.ptp(x[keep]) < 0.5 * np.ptp(x[ok]):
        return np.isfinite(x) & np.isfinite(y)
    return keep


def clock_check(
    t_unit_block_end: NDArray[np.float64],
    block_host_time: NDArray[np.float64],
    table_controller_time: NDArray[np.float64] | None,
    table_host_request: NDArray[np.float64],
    table_host_answer: NDArray[np.float64],
    estimate: TimeBase,
) -> dict[str, Any]:
    """The rate the host's clock implies for t_table against t_unit, compared with ``estimate``.

    Parameters
    ----------
    t_unit_block_end : unit time of each block's last sample, s; block_host_time : its host arrival time, s.
    table_controller_time : the controller's clock per reading (NaN or None: readings are stamped by the host).
    table_host_request, table_host_answer : the host's clock when each reading was requested/answered, s.
    estimate : the motion-based estimate to check.

    Returns
    -------
    dict
        ``unit_vs_host_rate`` (host seconds per unit second − 1) and its ``u``; ``controller_vs_host_rate``;
        ``rate`` and ``u_rate`` implied for the time base; ``z`` = (estimate − implied)/combined u;
        ``consistent`` (|z| ≤ 3); ``link_latency_spread_s`` (the unit's arrival scatter about the line);
        ``reading_latency_spread_s`` (request→answer spread of the readings).
    """
    out: dict[str, Any] = {}
    e_uh, u_uh, spread = _slope(np.asarray(t_unit_block_end, float), np.asarray(block_host_time, float))
    if not math.isfinite(e_uh):
        return out
    out.update(unit_vs_host_rate=e_uh - 1.0, u_unit_vs_host_rate=u_uh, link_latency_spread_s=spread)
    h_mid = 0.5 * (np.asarray(table_host_request, float) + np.asarray(table_host_answer, float))
    rtt = np.asarray(table_host_answer, float) - np.asarray(table_host_request, float)
    if np.any(np.isfinite(rtt)):
        out["reading_latency_spread_s"] = float(np.nanstd(rtt))
    have_ctrl = table_controller_time is not None and np.any(np.isfinite(table_controller_time))
    if have_ctrl:
        ct = np.asarray(table_controller_time, float)
        fast = _fastest(h_mid, ct, rtt)
        e_ch, u_ch, _ = _slope(h_mid[fast], ct[fast])
        if not math.isfinite(e_ch):
            return out
        out.update(controller_vs_host_rate=e_ch - 1.0, u_controller_vs_host_rate=u_ch)
        rate = e_ch * e_uh - 1.0
        u = math.hypot(u_ch * e_uh, u_uh * e_ch)
    else:
        rate, u = e_uh - 1.0, u_uh
    out.update(rate=rate, u_rate=u)
    if math.isfinite(estimate.u_rate):
        comb = math.hypot(u, estimate.u_rate)
        z = (estimate.rate - rate) / comb if comb > 0 else math.inf
        out.update(z=z, consistent=bool(abs(z) <= 3.0))
    return out


def misfit_cause(estimate: TimeBase, host_stamped: bool, carried: float) -> str | None:
    """One line naming the cause when the timing misfit around motions exceeds what the budget carries, else None.

    Two misfits are tested. Within a motion: the timing jitter the events' residuals show beyond the unit's and
    the encoder's noise (:attr:`TimingEvent.jitter`, median over the motions; a reading whose time stamp jitters
    turns the reference by ω·jitter). The budget carries ``carried`` (s; the caller's: the table's attitude
    accuracy over the fastest rate of the identified steps) and 3 × that is the limit. Between motions: the
    per-motion offsets scatter about the fitted line by more than 3 × their own σ (Birge ratio > 3; the offset's
    u is already scaled by it, but a scatter that large means the model t₀ + (1 + ε) t does not hold).

    The cause is named from the recorded clocks: readings stamped by the host whose answer latency jitters
    (the host's request → answer spread explains the jitter), a unit link whose frames arrive in bursts (its
    arrival scatter does), or otherwise — between motions — a latency or a clock that changes during the run,
    and — within motions — time stamps that are not latched with the angles.
    """
    if not estimate.events:
        return None
    r = np.array([e.residual for e in estimate.events])
    scatter = float(np.sqrt(np.mean(r * r))) if len(estimate.events) >= 3 else 0.0
    within = float(np.median([e.jitter for e in estimate.events]))
    bad_within = within > 3.0 * max(carried, 1e-9)
    bad_between = math.isfinite(estimate.misfit) and estimate.misfit > 3.0 and len(estimate.events) >= 3
    if not (bad_within or bad_between):
        return None
    worst = within if bad_within else scatter
    if bad_within:
        base = (
            f"timing misfit around the motions: the table's time stamps jitter by {within * 1e3:.3f} ms within "
            f"the motions, beyond the {3 * carried * 1e3:.3f} ms the uncertainty budget carries (3 × the table's "
            "attitude accuracy over the fastest spin rate)"
        )
    else:
        base = (
            f"timing misfit around the motions: the clock offset changes between motions by {scatter * 1e3:.3f} ms "
            f"(Birge ratio {estimate.misfit:.1f} about one offset and rate), beyond what the uncertainty budget "
            "carries"
        )
    ck = estimate.check
    rl = ck.get("reading_latency_spread_s")
    ll = ck.get("link_latency_spread_s")
    if host_stamped and rl is not None and rl > 0.3 * worst:
        return (
            f"{base}: the table's readings are stamped by the host when they arrive and their latency jitters "
            f"by {rl * 1e3:.2f} ms; configure the controller's time variable (turntable.acl.time_variable)"
        )
    if ll is not None and ll > 0.3 * worst:
        return (
            f"{base}: the unit's frames arrive in bursts (arrival scatter {ll * 1e3:.2f} ms about a steady "
            "clock); check the serial link / device-server buffering"
        )
    if bad_within:
        return (
            f"{base}: the readings' time stamps are not latched with their angles; check the controller's time "
            "variable and that the positions and the time are read in one message"
        )
    return (
        f"{base}: a latency or a clock changes during the run (not a constant rate); check the unit's and the "
        "controller's clocks and the host's load"
    )
