"""Shared pytest configuration."""

from __future__ import annotations

import os

import matplotlib

matplotlib.use("Agg")
os.environ.setdefault("MPLBACKEND", "Agg")
# The calibration registry (docs/registry.md) is off for the suite, so that a test issuing a certificate does
# not also build a database in its runs folder; the registry's own tests (tests/benches/registry) name one.
os.environ.setdefault("TABLEBENCH_REGISTRY", "off")
