"""benchmarks/bench_release.py: the run's stages from the lines it prints, the registry record as its own row,
and a table that keeps every stage of either tree (the release has no registry) without mis-pairing rounds."""

from __future__ import annotations

import re

from benchmarks.bench_release import MARKS, REGISTRY, run_stages, table

NOW_LINES = [
    "bench: sim", "step 1/40 warm-up", "run complete: 1000 samples", "recording: R/recording.h5",
    "calibration: R/calibration.json", "registry: SIM-U-0001 (SIM-QA) calibration 2 of 2 (id 2) in R/registry.sqlite",
    "registry: certificate TB-000002 with SIM-U-0001 calibration 2 of 2 (id 2) in R/registry.sqlite",
    "certificate: R/certificate.pdf (PASS)",
]  # fmt: skip


def _marks(lines):
    marks = {}
    for t, line in enumerate(lines):
        for key, pattern in MARKS:
            if key not in marks and re.match(pattern, line):
                marks[key] = (float(t), 10.0 * t)
    return marks


def test_the_registry_row_spans_from_the_calibration_line_to_the_registry_line():
    stages = run_stages(_marks(NOW_LINES), (9.0, 90.0))
    assert stages["— identification after the run"] == (2.0, 20.0)  # run complete (2) → calibration (4)
    assert stages[REGISTRY] == (1.0, 10.0)  # calibration (4) → its registry line (5), not the certificate's
    assert stages["— certificate"] == (2.0, 20.0)  # registry (5) → certificate (7)


def test_without_a_registry_line_the_certificate_starts_at_the_calibration_line():
    release = [ln for ln in NOW_LINES if not ln.startswith("registry:")]  # the release's lines
    stages = run_stages(_marks(release), (7.0, 70.0))
    assert REGISTRY not in stages
    assert stages["— certificate"] == (1.0, 10.0)  # calibration (3) → certificate (4)
    # a registry that could not record the calibration says so on stderr ("registry …: not recorded"), and a
    # later line for the certificate alone is not taken for the calibration's
    down = [*release[:4], "registry sqlite:///x: not recorded (disk I/O error)", release[4]]
    assert REGISTRY not in run_stages(_marks(down), (7.0, 70.0))


def test_the_table_keeps_a_stage_one_tree_lacks_and_pairs_ratios_round_by_round():
    base = [{"a": (1.0, 1.0), "— certificate": (2.0, 2.0)}, {"a": (2.0, 2.0), "— certificate": (4.0, 4.0)}]
    now = [
        {"a": (1.0, 1.0), REGISTRY: (0.5, 0.4), "— certificate": (1.0, 1.0)},
        {"a": (4.0, 4.0), REGISTRY: (0.7, 0.6), "— certificate": (2.0, 2.0)},
    ]
    rows = table({"base": base, "now": now}).splitlines()[2:]
    assert [r.split(" | ")[0].removeprefix("| ") for r in rows] == ["a", REGISTRY, "— certificate"]
    a, reg, cert = (r.split(" | ") for r in rows)
    assert a[3] == "**1.50**"  # median of the per-round ratios 1.0 and 2.0 (not the ratio of medians, 1.67)
    assert reg[1] == "—" and reg[2] == "0.6 s" and reg[3] == "—" and reg[6].startswith("—")  # base has none
    assert cert[3] == "**0.50**"
