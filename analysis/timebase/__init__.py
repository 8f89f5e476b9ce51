"""The time base of a run: how the unit's sample clock maps to the table's clock (docs/methods/time-base.md).

Pure maths: :func:`estimate_time_base` (motions → offset and rate with uncertainties),
:func:`clock_check` (bounds from the recorded host and controller clocks), :class:`TimeBase` (the typed result).
"""

from analysis.timebase.check import clock_check, misfit_cause
from analysis.timebase.estimate import RunSignals, coarse_mapping, estimate_time_base
from analysis.timebase.model import IDENTITY, TimeBase, TimingEvent

__all__ = [
    "IDENTITY",
    "RunSignals",
    "TimeBase",
    "TimingEvent",
    "clock_check",
    "coarse_mapping",
    "estimate_time_base",
    "misfit_cause",
]
