"""filterpy's ``KalmanFilter`` without the import cost of the rest of filterpy (issue 32).

``from filterpy.kalman import KalmanFilter`` executes ``filterpy/__init__.py`` (every subpackage, among them
``filterpy.stats`` → ``scipy.stats`` and ``filterpy.discrete_bayes`` → ``scipy.ndimage``) and
``filterpy/kalman/__init__.py`` (the EKF, UKF, IMM, … modules): about 0.6–0.8 s of a command's start, of
which the identification uses one class. The class lives in ``filterpy/kalman/kalman_filter.py``, which itself
needs only numpy, ``filterpy.common`` (numpy, ``scipy.linalg``) and ``filterpy.stats.logpdf`` — the last one
only in the ``log_likelihood``/``likelihood`` properties, which the identification never reads.

:func:`kalman_filter_class` therefore executes filterpy's own ``kalman_filter.py`` and ``filterpy.common`` with
the three package modules ``filterpy``, ``filterpy.kalman`` and ``filterpy.stats`` standing in as bare
placeholders (``logpdf`` forwards to the real ``filterpy.stats.logpdf``, importing it when first called), takes
the ``KalmanFilter`` class, and then removes every ``filterpy`` module it loaded from ``sys.modules``: the
process's module table is exactly as before, so a later ``import filterpy.kalman`` (tests, other analyses)
imports the whole package the ordinary way. The class returned is filterpy's code, unchanged; when filterpy is
already imported, it is that module's class.
"""

from __future__ import annotations

import importlib
import importlib.util
import sys
import threading
import types
from typing import Any

_LOCK = threading.Lock()
_CLASS: list[type] = []


def _logpdf(*args: Any, **kwargs: Any) -> Any:
    """``filterpy.stats.logpdf``, imported on first use (only ``KalmanFilter.log_likelihood`` calls it)."""
    from filterpy.stats import logpdf  # lazy: scipy.stats

    return logpdf(*args, **kwargs)


def _placeholder(name: str, path: list[str] | None) -> types.ModuleType:
    mod = types.ModuleType(name, f"placeholder for {name} while filterpy's kalman_filter.py is loaded")
    if path is not None:
        mod.__path__ = path
    return mod


def _isolated_load() -> type:
    spec = importlib.util.find_spec("filterpy")
    if spec is None or not spec.submodule_search_locations:
        raise ImportError("filterpy is not installed (pip install filterpy)")
    root = list(spec.submodule_search_locations)
    stats = _placeholder("filterpy.stats", None)
    stats.logpdf = _logpdf  # type: ignore[attr-defined]
    placeholders = {
        "filterpy": _placeholder("filterpy", root),
        "filterpy.kalman": _placeholder("filterpy.kalman", [f"{p}/kalman" for p in root]),
        "filterpy.stats": stats,
    }
    sys.modules.update(placeholders)
    try:
        return importlib.import_module("filterpy.kalman.kalman_filter").KalmanFilter
    finally:
        for name in [n for n in sys.modules if n == "filterpy" or n.startswith("filterpy.")]:
            del sys.modules[name]


def kalman_filter_class() -> type:
    """filterpy's ``KalmanFilter`` class (``filterpy.kalman.kalman_filter.KalmanFilter``), loaded once.

    When ``filterpy`` is already imported, its own class; otherwise the class loaded as the module docstring
    describes (``sys.modules`` unchanged afterwards)."""
    with _LOCK:
        if not _CLASS:
            if "filterpy" in sys.modules:
                from filterpy.kalman import KalmanFilter

                _CLASS.append(KalmanFilter)
            else:
                _CLASS.append(_isolated_load())
        return _CLASS[0]


__all__ = ["kalman_filter_class"]
