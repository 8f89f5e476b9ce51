"""THE reference function: table at t − latency, never interpolated across a motion boundary."""

from __future__ import annotations

import numpy as np

from benches.identify import acquisition_span
from benches.reference import interpolate_table, reference_for_window


def test_no_interpolation_towards_a_reading_of_the_next_motion():
    # a spin at 0.5 rad/s on the inner gimbal; the controller's next reading comes 0.5 s after the window,
    # when the table is already decelerating towards the next position (angle 10 rad, rate 0)
    rate = 0.5
    tt = np.array([0.0, 1.0, 2.0, 2.5 + 0.5])
    ang = np.zeros((4, 3))
    rat = np.zeros((4, 3))
    ang[:3, 2] = rate * tt[:3]
    rat[:3, 2] = rate
    ang[3, 2], rat[3, 2] = 10.0, 0.0
    t = np.linspace(2.0, 2.5, 51)  # samples after the last in-window reading
    a_naive, _ = interpolate_table(t, tt, ang, rat)
    a_span, r_span = interpolate_table(t, tt, ang, rat, span=acquisition_span(1.0, 2.5, 0.0, 100.0))
    np.testing.assert_allclose(a_span[:, 2], rate * t, rtol=0, atol=1e-12)  # extrapolated with the reported rate
    np.testing.assert_allclose(r_span[:, 2], rate)
    assert np.max(np.abs(a_naive[:, 2] - rate * t)) > 1.0  # what the old, unrestricted interpolation did


def test_latency_takes_the_table_at_t_minus_latency():
    tt = np.linspace(0.0, 10.0, 101)
    ang = np.zeros((101, 3))
    ang[:, 2] = 0.3 * tt
    rat = np.zeros((101, 3))
    rat[:, 2] = 0.3
    t = np.array([5.0])
    f0, w0, a0, _, _ = reference_for_window(t, tt, ang, rat, g=9.8, mounting=None, latency=0.0)
    f1, w1, a1, _, _ = reference_for_window(t, tt, ang, rat, g=9.8, mounting=None, latency=0.01)
    np.testing.assert_allclose(a0[0, 2] - a1[0, 2], 0.3 * 0.01, rtol=1e-9)
    np.testing.assert_allclose(w0, w1)
    assert not np.allclose(f0, f1)
