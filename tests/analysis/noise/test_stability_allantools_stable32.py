"""Every Stable32 run with printed confidence bounds in allantools' test folders (tests/data/noise/allantools/
README.md): with the α Stable32 printed set by hand (``noise_type``, issue 30) and Stable32's EDF rules
(``edf_rules="stable32"``), every row's bounds equal Stable32's within 0.1 % (the issue asks 1 %; OCXO 0.3 %, see
``VALUE_RTOL``), the term counts exactly and the deviations to Stable32's printed digits."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from analysis.noise.stability import stability
from tests import REPO_ROOT

DATA = REPO_ROOT / "tests" / "data" / "noise" / "allantools"

RECORDS = {
    "phasedat": ("PHASE.DAT", "phase", 1.0),
    "ocxo": ("ocxo_frequency.txt.xz", "freq", 1e7),  # Stable32 ran on the readings / 10 MHz (its header: mean 1)
    "pink_frequency": ("pink_frequency.txt.xz", "freq", 1.0),
    "gps": ("gps_1pps_phase_data.txt.gz", "phase", 1.0),
    "Cs5071A": ("5071A_phase.txt.gz", "phase", 1.0),
    "Keysight53230A_ti_noise_floor": ("tic_phase.txt.xz", "phase", 1.0),
}
RUNS = sorted(p.relative_to(DATA).as_posix() for p in DATA.glob("*/*.txt"))

VALUE_RTOL = {"ocxo": 2e-3}
"""The OCXO deviations differ from Stable32's by up to 1.6e-3 (both signs, every statistic alike), the bounds
by the same: Stable32 read a converted copy of the record (``ocxo_frequency.001``, header mean 1.000000e+00), not
the text file allantools stores; allantools' own test prints (does not assert) the same differences. Elsewhere
the deviations agree to Stable32's five printed digits."""

BOUND_RTOL = {"ocxo": 3e-3}
"""Bounds: Stable32's within 0.1 % (measured: 0.06 %, PHASE.DAT HDEV at EDF 2.9, where Stable32's χ² quantiles are
an iterative approximation); the OCXO's within 0.3 % (its deviations differ by up to 0.16 %, ``VALUE_RTOL``)."""


def _stable32_rows(path: Path) -> np.ndarray:
    """AF, τ, #, α, min, value, max of every printed row (rows commented out by allantools included)."""
    rows = []
    for line in path.read_text(encoding="latin-1").splitlines():
        f = line.lstrip("#").split()
        if len(f) >= 7 and f[0].isdigit():
            rows.append([float(v) for v in f[:7]])
    return np.array(rows)


_records: dict[str, np.ndarray] = {}


def _record(folder: str) -> np.ndarray:
    if folder not in _records:
        name, _kind, scale = RECORDS[folder]
        _records[folder] = np.loadtxt(DATA / folder / name, comments="#") / scale
    return _records[folder]


def _estimator(run: str) -> str:
    stem = Path(run).stem.lower()
    for prefix in ("phase_dat_", "tic_", "stable32_", "s32_"):
        stem = stem.removeprefix(prefix)
    return stem.split("_")[0]


def _compare(run: str):
    folder = run.split("/")[0]
    ref = _stable32_rows(DATA / run)
    name = _estimator(run)
    rate = float(ref[0, 0] / ref[0, 1])
    ranges = [(tau, tau, int(alpha)) for tau, alpha in zip(ref[:, 1], ref[:, 3], strict=True)]
    est = stability(_record(folder), rate, (name,), ref[:, 1], RECORDS[folder][1], noise_type=ranges,
                    edf_rules="stable32")  # fmt: skip
    return folder, name, ref, est.estimates[name]


def test_every_reference_file_with_bounds_is_here() -> None:
    assert len(RUNS) == 42
    assert {r.split("/")[0] for r in RUNS} == set(RECORDS)


@pytest.mark.parametrize("run", RUNS)
def test_noise_type_set_by_hand_reproduces_stable32_bounds(run: str) -> None:
    folder, name, ref, est = _compare(run)
    m = ref[:, 0].astype(int)
    np.testing.assert_array_equal(est.m, m)
    np.testing.assert_array_equal(est.alpha[:, 0], ref[:, 3].astype(int))
    np.testing.assert_array_equal(est.n_terms[:, 0], ref[:, 2].astype(int))
    value = est.unbiased()[:, 0] if name in ("totdev", "htotdev") else est.dev[:, 0]
    np.testing.assert_allclose(value, ref[:, 5], rtol=VALUE_RTOL.get(folder, 1e-4))
    rtol = BOUND_RTOL.get(folder, 1e-3)
    np.testing.assert_allclose(est.lo[:, 0], ref[:, 4], rtol=rtol)
    np.testing.assert_allclose(est.hi[:, 0], ref[:, 6], rtol=rtol)
