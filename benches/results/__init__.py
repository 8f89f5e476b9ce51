"""Results and where they go: the :class:`ResultSink` protocol (:mod:`.sink`), the run folder as the first
sink and the record (:mod:`.run_folder`), and the calibration registry as the second (:mod:`.registry`).

``docs/extending.md`` (a results store) shows how to add a sink; ``docs/registry.md`` describes the registry.
"""

from __future__ import annotations

from .chain import register_copy_sink, sinks_for_run, unregister_copy_sink
from .sink import (
    KINDS,
    AnalysisDocument,
    CalibrationDocument,
    CertificateDocument,
    ResultSink,
    ResultSinks,
    SinkError,
    completed,
)

__all__ = [
    "KINDS",
    "AnalysisDocument",
    "CalibrationDocument",
    "CertificateDocument",
    "ResultSink",
    "ResultSinks",
    "SinkError",
    "completed",
    "register_copy_sink",
    "sinks_for_run",
    "unregister_copy_sink",
]
