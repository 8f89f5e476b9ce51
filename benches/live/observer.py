"""What a run publishes to the live view: a runner observer that turns blocks into a few small events.

Per block it costs two ``reduceat`` calls (min/max of the block's samples per column) and, every
``publish_s`` wall seconds, one event with the columns closed since the last one, the table's latest reading
against its demand, the link's health and the bench time elapsed and left. Estimates are published when the
streaming identifier has fused new data. Display units come from ``analysis.units`` (one place).
"""

from __future__ import annotations

import json
import math
import time
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from analysis.units import DISPLAY_UNITS, to_display
from drivers.protocols import ImuBlock, TableState
from procedures.steps import Step

from .feed import LiveFeed, MinMaxDecimator

COLUMNS = 1200
"""Columns of the channel plots for the estimated duration (min/max per column; the run may go on longer)."""
AXES = ("outer", "middle", "inner")
CHANNELS = ("accel_x", "accel_y", "accel_z", "gyro_x", "gyro_y", "gyro_z")


def _r(x: float, digits: int = 6) -> float | None:
    """A JSON-safe rounded number (None for NaN/∞)."""
    return round(float(x), digits) if math.isfinite(x) else None


def _demand(step: Step) -> dict[str, Any]:
    """The table demand of a step, display units: angles (deg) where it holds an attitude, rates (deg/s)."""
    angles = getattr(step, "angles", None)
    if angles is not None and not all(math.isfinite(float(a)) for a in angles):
        angles = None
    rates = [0.0, 0.0, 0.0]
    axis = getattr(step, "axis", None)
    if step.kind == "spin" and axis is not None and int(axis) >= 0:
        rates[int(axis)] = to_display("rate", float(step.rate))
    return {
        "angles": None if angles is None else [_r(to_display("angle", float(a)), 4) for a in angles],
        "rates": [_r(r, 4) for r in rates],
    }


class LiveObserver:
    """Runner observer feeding a :class:`LiveFeed`.

    Parameters
    ----------
    feed : LiveFeed
    steps : sequence of Step
        The compiled procedure's steps (for the step list and each step's demand).
    sample_rate : float
        Hz, the unit's nominal rate (bench time = samples / rate).
    estimated_s : float
        Estimated bench duration of the procedure, s.
    info : dict
        Bench and procedure names etc. for the page header.
    identifier : object, optional
        The run's streaming identifier (``benches.identify.LiveIdentifier``); its estimates are published.
    publish_s : float
        At most one channel event per this many wall seconds (and one per step end).
    """

    def __init__(
        self,
        feed: LiveFeed,
        steps: Sequence[Step],
        *,
        sample_rate: float,
        estimated_s: float,
        info: dict[str, Any],
        identifier: Any = None,
        publish_s: float = 0.25,
        start_sample: int = 0,
    ) -> None:
        self.feed = feed
        self.steps = {s.index: s for s in steps}
        self.rate = float(sample_rate)
        self.estimated_s = max(float(estimated_s), 1.0)
        self.identifier = identifier
        self.publish_s = float(publish_s)
        self._n = int(start_sample)
        self._dec = MinMaxDecimator(len(CHANNELS), max(self.estimated_s / COLUMNS, 1.0 / self.rate))
        self._sent_bins = 0
        self._pending: list[tuple[np.ndarray, np.ndarray]] = []
        self._last_pub = 0.0
        self._step: int | None = None
        self._fused = -1
        self._health = {"frames_rejected": 0, "frames_dropped": 0, "resets": 0, "duplicates": 0}
        self._link_events: list[str] = []
        self._table: TableState | None = None
        self._t0 = time.monotonic()
        kinds = self._parameter_kinds()
        feed.publish(
            "run",
            {
                **{k: v for k, v in info.items() if k != "parameters"},
                "estimated_s": _r(self.estimated_s, 3),
                "sample_rate_hz": self.rate,
                "channels": list(CHANNELS),
                "channel_units": [DISPLAY_UNITS["acceleration"][0]] * 3 + [DISPLAY_UNITS["rate"][0]] * 3,
                "axes": list(AXES),
                "parameters": [{"name": n, "unit": DISPLAY_UNITS[k][0]} for n, k in kinds]
                or info.get("parameters", []),
                "steps": [
                    {
                        "index": s.index,
                        "name": s.name,
                        "kind": s.kind,
                        "text": getattr(s, "text", ""),
                        "group": s.group or "",
                    }
                    for s in steps
                ],
            },
        )

    # ---- the runner's observer interface ---------------------------------------------------------------------
    def on_block(self, step: Step, block: ImuBlock, table: TableState, counts: bool) -> None:
        """Decimate the block, note the link's health; publish at most every ``publish_s`` wall seconds."""
        if self._step != step.index:
            self._step = step.index
            self.feed.publish("step", {"index": step.index, "name": step.name, "state": "running",
                                       "bench_s": _r(self._n / self.rate, 3), "demand": _demand(step)})  # fmt: skip
        n = len(block)
        if n:  # decimated in batches at publication: per block only a reference is kept
            self._pending.append((block.accel, block.gyro))
        self._n += n
        self._table = table
        h = self._health
        h["frames_rejected"] += int(block.rejected)
        h["frames_dropped"] += int(block.dropped)
        h["resets"] += int(block.resets)
        h["duplicates"] += int(block.duplicates)
        if block.events:
            self._link_events = (self._link_events + list(block.events))[-20:]
        now = time.monotonic()
        if now - self._last_pub >= self.publish_s:
            self._publish(step)
            self._last_pub = now

    def on_step_end(self, step: Step, record: Any) -> None:
        """Publish what is pending and the step's end."""
        self._publish(step)
        self.feed.publish("step", {"index": step.index, "name": step.name, "state": str(record.status),
                                   "bench_s": _r(self._n / self.rate, 3)})  # fmt: skip

    # ---- events ----------------------------------------------------------------------------------------------
    def _decimate_pending(self) -> None:
        """Min/max of the samples received since the last publication into the columns (one batch)."""
        if not self._pending:
            return
        accel = np.concatenate([a for a, _g in self._pending])
        gyro = np.concatenate([g for _a, g in self._pending])
        self._pending.clear()
        n = accel.shape[0]
        x = np.empty((n, 6))
        np.divide(accel, DISPLAY_UNITS["acceleration"][1], out=x[:, :3])
        np.divide(gyro, DISPLAY_UNITS["rate"][1], out=x[:, 3:])
        self._dec.add((self._n - n + np.arange(n)) / self.rate, x)

    def _publish(self, step: Step) -> None:
        self._decimate_pending()
        merged = len(self._dec) < self._sent_bins
        start = 0 if merged else self._sent_bins
        _, lo, hi, _ = self._dec.closed_since(start)
        st = self._table
        bench_s = self._n / self.rate
        data: dict[str, Any] = {
            "bench_s": _r(bench_s, 3),
            "remaining_s": _r(max(self.estimated_s - bench_s, 0.0), 3),
            "wall_s": _r(time.monotonic() - self._t0, 3),
            "bin_s": self._dec.bin_s,
            "start": start,
            "replace": merged,
            "lo": [[_r(v, 4) for v in row] for row in lo],
            "hi": [[_r(v, 4) for v in row] for row in hi],
            "health": dict(
                self._health,
                link_events=self._link_events,
                checksums="ok" if self._health["frames_rejected"] == 0 else "frames rejected",
            ),  # fmt: skip
        }
        if st is not None:
            data["table"] = {
                "time_s": _r(st.time, 4),
                "angles": [_r(to_display("angle", float(a)), 4) for a in st.angles],
                "rates": [_r(to_display("rate", float(w)), 4) for w in st.rates],
                "status": int(st.status),
                "demand": _demand(step),
            }
        self._sent_bins = len(self._dec)
        self.feed.publish("bins", data)
        self._publish_estimates(step)

    def _parameter_kinds(self) -> list[tuple[str, str]]:
        ident = self.identifier
        if ident is None:
            return []
        return list(ident.parameter_kinds())

    def _publish_estimates(self, step: Step) -> None:
        ident = self.identifier
        if ident is None:
            return
        filt = ident.filter
        if filt.n_samples == self._fused or not filt.n_samples:
            return
        self._fused = filt.n_samples
        x, s = filt.estimate, filt.sigma
        kinds = self._parameter_kinds()
        unseen = ident.unseen() if hasattr(ident, "unseen") else set()
        seen = [n not in unseen for n, _k in kinds]  # an unseen estimate is the prior's: no number shown for it
        self.feed.publish(
            "estimates",
            {
                "bench_s": _r(self._n / self.rate, 3),
                "step": step.name,
                "values": [_r(to_display(k, float(x[i])), 6) if seen[i] else None for i, (_n, k) in enumerate(kinds)],
                "u": [_r(to_display(k, float(s[i])), 6) if seen[i] else None for i, (_n, k) in enumerate(kinds)],
                "identified": seen,
                "u_meaning": "filter white-noise 1σ (k = 1); null: not identified yet (the motion so far does not "
                "see it)",
            },
        )

    def finish(self, status: str, reason: str = "") -> None:
        """The run ended (any status): close the last column and say so."""
        self._decimate_pending()
        self._dec.flush()
        if self._step is not None:
            self._publish(self.steps.get(self._step) or next(iter(self.steps.values())))
        self.feed.publish("end", {"status": status, "reason": reason, "bench_s": _r(self._n / self.rate, 3)})


def publish_result(feed: LiveFeed, folder: Path) -> None:
    """Publish the run's results (calibration.json's values ± u, the certificate's verdict) and their links."""
    data: dict[str, Any] = {"files": []}
    cal = folder / "calibration.json"
    if cal.is_file():
        try:
            c = json.loads(cal.read_text(encoding="utf-8"))
        except (OSError, ValueError):
            c = {}
        params = c.get("parameters") or {}
        data["parameters"] = [
            {
                "name": name,
                "value": p.get("display_value"),
                "u": p.get("display_u"),
                "unit": p.get("display_unit"),
                "identified": bool(p.get("identified", True)),
            }
            for name, p in params.items()
        ]
        data["u_meaning"] = "u = the identification's combined standard uncertainty (k = 1)"
        for key in ("time_base", "timebase"):
            if isinstance(c.get(key), dict):
                data["time_base"] = c[key]
        data["files"].append("calibration.json")
    cert = folder / "certificate.json"
    if cert.is_file():
        try:
            data["verdict"] = json.loads(cert.read_text(encoding="utf-8")).get("verdict")
        except (OSError, ValueError):
            pass
        data["files"].append("certificate.json")
    data["files"] += sorted(p.name for p in folder.glob("certificate*.pdf"))
    feed.publish("result", data)
