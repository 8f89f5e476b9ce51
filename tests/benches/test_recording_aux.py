"""Auxiliary devices' readings in the recording: /aux/<device> written by Hdf5Recorder.add_aux, read back by
Recording.aux, verified (Fletcher-32) on opening; a channel missing from a reading is NaN there."""

from __future__ import annotations

import math

import numpy as np
import pytest

from benches.recording import Hdf5Recorder, RecordingError, open_recording
from benches.runner import Runner
from drivers.protocols import Reading
from tests.fakes import FakeClock, FakeTable, FakeUnit, fake_steps


def test_aux_readings_round_trip_with_units_and_gaps(tmp_path):
    clock = FakeClock(100.0)
    rec = Hdf5Recorder(tmp_path / "recording.h5", attrs={"sample_rate_hz": 100.0})
    rec.add_aux("chamber", 0.5, Reading({"air": 293.15, "setpoint": 293.15}, {"air": "K", "setpoint": "K"}))
    rec.add_aux("chamber", 1.5, Reading({"air": 294.0}, {"air": "K"}))
    with pytest.raises(RecordingError, match="auxiliary device name"):
        rec.add_aux("bad/name", 0.0, Reading({}, {}))
    runner = Runner(FakeTable(clock), FakeUnit(clock), fake_steps(), rec, position_tolerance=1e-6, block_seconds=0.1)
    try:
        assert runner.run().status == "complete"
        rec.add_aux("chamber", 2.5, Reading({"air": 295.0, "setpoint": 298.15}, {"air": "K", "setpoint": "K"}))
    finally:
        rec.close()
    with open_recording(tmp_path / "recording.h5") as r:
        assert r.aux_names() == ["chamber"]
        a = r.aux("chamber")
        np.testing.assert_array_equal(a.time, [0.5, 1.5, 2.5])
        np.testing.assert_array_equal(a.channels["air"], [293.15, 294.0, 295.0])
        s = a.channels["setpoint"]
        assert s[0] == 293.15 and math.isnan(s[1]) and s[2] == 298.15
        assert a.units == {"air": "K", "setpoint": "K"}
        with pytest.raises(RecordingError, match="no auxiliary device 'oven'"):
            r.aux("oven")
