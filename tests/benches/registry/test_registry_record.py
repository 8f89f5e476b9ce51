"""The registry's record of a run the process has just identified: as found / as left from the identification's
own windows (not read again) with the same numbers as from the recording read afresh, and the line saying where
the registry put the calibration."""

from __future__ import annotations

import json

import numpy as np
import pytest

import benches.identify as identify
from analysis.identification.model import centripetal
from benches.results import CalibrationDocument, CertificateDocument
from benches.results.registry import record
from benches.results.registry.record import as_found_as_left, bench_settings, window_moments
from benches.results.registry.sink import RegistrySink
from tests.benches.registry.runs import RunFactory


@pytest.fixture(scope="module")
def factory(tmp_path_factory) -> RunFactory:
    return RunFactory(tmp_path_factory.mktemp("registry-record"))


def _by_np_mean(w) -> np.ndarray:
    """The moments as the registry first formed them: ``np.mean`` of each per-sample quantity."""
    return np.array(
        [
            np.mean(w.f_out - w.f_ref, axis=0),
            w.f_ref.mean(axis=0),
            np.mean(w.f_ref * w.f_ref, axis=0),
            centripetal(w.omega).mean(axis=0),
        ]
    )


def _forget() -> None:
    record._MOMENTS.clear()
    identify._RECENT.clear()


def test_window_moments_are_the_means_of_the_per_sample_values_to_the_last_bit(factory):
    _forget()
    windows = identify.load_run(factory.base).windows
    assert windows
    for w in windows:
        assert np.array_equal(window_moments(w.f_out, w.f_ref, w.omega), _by_np_mean(w)), w.name
    rng = np.random.default_rng(11)
    for n in (1, 2, 7, 1000, 40_001):  # g-sized values with small differences, rates up to a few rad/s
        f_ref = rng.normal(0, 9.8, (n, 3))
        f_out = f_ref + rng.normal(0, 1e-3, (n, 3))
        omega = rng.normal(0, 3.0, (n, 6))[:, ::2]  # a strided view, as a column selection gives
        w = identify.StepWindow("w", "hold", np.arange(n, dtype=float), f_out, f_ref, omega)
        assert np.array_equal(window_moments(f_out, f_ref, omega), _by_np_mean(w)), n


def test_as_found_as_left_reused_from_the_identification_equal_those_of_the_recording_read_again(factory, monkeypatch):
    """After identify_run the registry takes the identification's windows (the recording is not read again) and
    its as found / as left equal, to the last bit, those formed from the recording read afresh."""
    run = factory.make("reuse")
    _forget()
    result = identify.identify_run(run)
    x = np.asarray(result.x)[: len(record.PARAM_NAMES)]
    x_found = x + 1e-4
    reads = []
    real = identify._identification_data
    monkeypatch.setattr(identify, "_identification_data", lambda *a, **k: reads.append(1) or real(*a, **k))
    reused = as_found_as_left(run, x, x_found, result.recording_sha256)
    assert reads == []  # taken from the identification just made
    _forget()
    again = as_found_as_left(run, x, x_found, result.recording_sha256)
    assert reads == [1]  # read and referenced afresh
    assert json.dumps(reused, sort_keys=True) == json.dumps(again, sort_keys=True)


def test_bench_settings_of_the_run_just_identified_equal_those_read_from_its_recording(factory):
    run = factory.make("settings")
    _forget()
    read = bench_settings(run)
    identify.identify_run(run)
    assert identify.recent_data(run) is not None
    assert bench_settings(run) == read
    _forget()


def test_the_registry_says_which_unit_which_calibration_and_where(factory, tmp_path):
    url = f"sqlite:///{tmp_path / 'lab' / 'registry.sqlite'}"
    sink = RegistrySink(url)
    r1 = factory.make("said-1", created_utc="2026-01-10T09:00:00Z")
    r2 = factory.make("said-2", created_utc="2026-04-10T09:00:00Z", shift={"b_x": 1e-4})
    where = str(tmp_path / "lab" / "registry.sqlite")
    lines = []
    for run in (r1, r2, r2):
        doc = CalibrationDocument(run=run, result=None, path=run / "calibration.json")  # type: ignore[arg-type]
        lines.append(sink.report("calibration", sink.calibration(doc)))
    assert lines[0].startswith("registry: SIM-U-0001") and lines[0].endswith(f" in {where}")
    assert "calibration 1 of 1 (id 1)" in lines[0] and "calibration 2 of 2 (id 2)" in lines[1]
    assert lines[2].endswith(f"calibration 2 of 2 (id 2), already recorded in {where}")
    # a calibration written elsewhere than the run folder is not recorded, and nothing is said
    other = CalibrationDocument(run=r1, result=None, path=tmp_path / "elsewhere.json")  # type: ignore[arg-type]
    assert sink.report("calibration", sink.calibration(other)) is None
    # a certificate with nothing new to record (this run has none) says nothing either
    cert = CertificateDocument(run=r1, certificate=None)  # type: ignore[arg-type]
    assert sink.report("certificate", sink.certificate(cert)) is None


def test_a_dropped_registry_closes_its_connections_at_once(registry_url):
    """A Registry that is dropped without close() releases its pool then, not whenever the cyclic garbage collector
    next runs (psycopg warns about every connection still open at that moment, in whatever command runs then)."""
    import gc
    import warnings

    from benches.results.registry import Registry

    def use() -> None:
        Registry(registry_url).count()

    with warnings.catch_warnings(record=True) as seen:
        warnings.simplefilter("always")
        use()
        gc.collect()
    assert [w for w in seen if issubclass(w.category, ResourceWarning)] == []
