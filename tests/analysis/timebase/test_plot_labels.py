"""The time-base figure's log-axis labels: plain numbers at 1, 2 and 5 times a power of ten (no mathtext)."""

from __future__ import annotations

import pytest

from analysis.timebase.plot import _minor_label


@pytest.mark.parametrize(
    ("value", "label"),
    [(0.2, "0.2"), (0.5, "0.5"), (2.0, "2"), (5.0, "5"), (50.0, "50"), (0.002, "0.002"), (3.0, ""), (0.7, ""),
     (9.0, ""), (0.0, ""), (-2.0, "")],
)  # fmt: skip
def test_minor_labels_are_plain_numbers_at_two_and_five_times_a_decade(value, label):
    assert _minor_label(value) == label
