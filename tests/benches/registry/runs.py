"""Run folders for the registry tests: one fake-bench recording, many calibrations of it (cheap to make)."""

from __future__ import annotations

import copy
import json
import os
from pathlib import Path

from analysis.identification.model import PARAM_NAMES
from benches.calibration_integrity import with_integrity
from tests.certificate_fixtures import calibration_fixture, record


class RunFactory:
    """Records one fake run once; :meth:`make` gives run folders that share it (hard links) with their own
    calibration.json (the fixture's values, optionally shifted)."""

    def __init__(self, root: Path) -> None:
        self.root = root
        self.base = root / "_base"
        self.base.mkdir(parents=True, exist_ok=True)
        record(self.base / "recording.h5")
        self.cal = calibration_fixture(self.base, seed=3)

    def make(self, name: str, *, shift: dict[str, float] | None = None, created_utc: str = "",
             runs: str = "runs", serial: str | None = None) -> Path:  # fmt: skip
        run = self.root / runs / name
        run.mkdir(parents=True, exist_ok=True)
        os.link(self.base / "recording.h5", run / "recording.h5")
        cal = copy.deepcopy(self.cal)
        for n, dv in (shift or {}).items():
            cal["parameters"][n]["value"] += dv
        if created_utc:
            cal["run"]["created_utc"] = created_utc
        if serial is not None:
            cal["run"]["unit"]["serial_number"] = serial
        (run / "calibration.json").write_text(json.dumps(with_integrity(cal), indent=1), encoding="utf-8")
        return run


def value(run: Path, name: str) -> float:
    """A parameter's value (SI) in a run's calibration.json."""
    return float(json.loads((run / "calibration.json").read_text())["parameters"][name]["value"])


__all__ = ["PARAM_NAMES", "RunFactory", "value"]
