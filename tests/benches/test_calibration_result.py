"""The typed calibration result: versioned load/save, strict writing, explicit not-identified state."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from analysis.identification.model import PARAM_NAMES
from benches.calibration_result import (
    FORMAT_VERSION,
    NOT_IDENTIFIED,
    CalibrationFormatError,
    CalibrationResult,
    ParameterEstimate,
)


def _result(identified: bool = True) -> CalibrationResult:
    rng = np.random.default_rng(1)
    a = rng.normal(size=(18, 18))
    cov = a @ a.T * 1e-12 + np.eye(18) * 1e-12
    params = {
        n: ParameterEstimate(n, k, float(rng.normal()) * 1e-4, math.sqrt(cov[i, i]), 0.5 * math.sqrt(cov[i, i]), 1e-3,
                             identified or not n.startswith("r_"))
        for i, (n, k) in enumerate(zip(PARAM_NAMES, ["bias"] * 3 + ["scale"] * 3 + ["misalignment"] * 6
                                       + ["quadratic"] * 3 + ["size_effect"] * 3, strict=True))
    }  # fmt: skip
    extra = {
        "plan": {"predicted_sigma": {n: (math.inf if n.startswith("r_") else 1e-6) for n in PARAM_NAMES}},
        "information": {"rank": 15, "condition": math.inf},
        "noise_source": {"source": "configured"},
    }
    return CalibrationResult(params, cov, cov * 0.25, np.full(3, 2e-8), "kalman", "recording.h5", "ab" * 32, extra)


def test_round_trip_is_exact_and_versioned(tmp_path):
    r = _result(identified=False)
    p = r.save(tmp_path / "calibration.json")
    d = json.loads(p.read_text(encoding="utf-8"))
    assert d["format_version"] == FORMAT_VERSION and "u = the identification" in d["uncertainty"]
    # an infinite predicted σ is the explicit "not identified" state, never NaN/∞/null
    assert d["plan"]["predicted_sigma"]["r_x"] == NOT_IDENTIFIED and d["parameters"]["r_x"]["identified"] is False
    assert d["information"]["condition"] == "infinite (rank-deficient)"
    back = CalibrationResult.load(p)
    np.testing.assert_array_equal(back.x, r.x)
    np.testing.assert_array_equal(back.covariance, r.covariance)
    np.testing.assert_array_equal(back.covariance_white, r.covariance_white)
    x, skipped = back.compensation_vector()
    assert skipped == ["r_x", "r_y", "r_z"] and np.all(x[15:] == 0) and np.all(x[:15] == r.x[:15])


def test_a_non_finite_number_is_never_written(tmp_path):
    r = _result()
    r.covariance[2, 2] = math.nan
    with pytest.raises(ValueError, match="non-finite"):
        r.save(tmp_path / "c.json")
    assert not (tmp_path / "c.json").exists()


def test_load_refuses_other_versions_and_bad_numbers_with_the_key_named(tmp_path):
    d = _result().to_dict()
    p = tmp_path / "c.json"
    p.write_text(json.dumps({**d, "format_version": 99}), encoding="utf-8")
    with pytest.raises(CalibrationFormatError, match="format_version 99"):
        CalibrationResult.load(p)
    bad = json.loads(json.dumps(d))
    bad["parameters"]["S_y"]["u"] = None
    p.write_text(json.dumps(bad), encoding="utf-8")
    with pytest.raises(CalibrationFormatError, match=r"parameters\.S_y"):
        CalibrationResult.load(p)
    p.write_text('{"format": "tablebench-calibration", "format_version": 2, "parameters": {"b_x": {"value": 1e154',
                 encoding="utf-8")  # fmt: skip
    with pytest.raises(CalibrationFormatError, match="not readable JSON"):
        CalibrationResult.load(p)


def test_version_1_files_are_still_read(tmp_path):
    d = _result().to_dict()
    v1 = json.loads(json.dumps(d))
    v1["format_version"] = 1
    del v1["covariance_white"]
    for p in v1["parameters"].values():
        p["sigma"], p["sigma_white"], p["identifiable"] = p.pop("u"), p.pop("u_white"), p.pop("identified")
    r = CalibrationResult.from_dict(v1)
    np.testing.assert_allclose(np.sqrt(np.diag(r.covariance_white)), [p.u_white for p in r.parameters.values()])
