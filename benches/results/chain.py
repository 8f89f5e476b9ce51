"""The chain each command publishes to: the run folder, then every registered copy sink (the registry).

A copy sink is registered by name with a factory (:func:`register_copy_sink`); :func:`sinks_for_run` builds
the chain for one run folder. A factory that fails (a registry URL that cannot be reached) costs one line and
the chain goes on without it: the run folder stays the record (``docs/extending.md``, a results store).
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from pathlib import Path
from typing import Any

from .registry.sink import sink_factory
from .run_folder import RunFolderSink
from .sink import ResultSink, ResultSinks, SinkError, _say_stderr

CopyFactory = Callable[[Path, Mapping[str, Any]], "ResultSink | None"]
_COPY_FACTORIES: dict[str, CopyFactory] = {}


def register_copy_sink(name: str, factory: CopyFactory) -> None:
    """Register a further sink built for every command that publishes results.

    ``factory(runs_folder, options)`` returns the sink, or None when it is switched off by ``options``
    (e.g. ``{"registry": "off"}``). Registering the same name again replaces it.
    """
    _COPY_FACTORIES[name] = factory


def unregister_copy_sink(name: str) -> None:
    """Remove a sink registered with :func:`register_copy_sink` (no error if absent)."""
    _COPY_FACTORIES.pop(name, None)


def sinks_for_run(
    run: str | Path,
    options: Mapping[str, Any] | None = None,
    say: Callable[[str], None] = _say_stderr,
    tell: Callable[[str], None] | None = None,
) -> ResultSinks:
    """The chain for a run folder: the run folder itself, then every registered copy sink.

    ``options`` are the command's sink options (``registry``: a URL, or "off"); ``say`` takes the line of a
    copy that cannot take a result, ``tell`` each copy's line saying where it put one (:class:`ResultSinks`).
    """
    runs_folder = Path(run).resolve().parent
    copies: list[ResultSink] = []
    for name, factory in _COPY_FACTORIES.items():
        try:
            sink = factory(runs_folder, dict(options or {}))
        except SinkError as exc:
            say(f"{exc}; the run folder keeps the result")
            continue
        except Exception as exc:  # noqa: BLE001
            say(f"{name}: not available ({exc.__class__.__name__}: {exc}); the run folder keeps the result")
            continue
        if sink is not None:
            copies.append(sink)
    return ResultSinks(RunFolderSink(), copies, say=say, tell=tell)


def _registry(runs_folder: Path, options: Mapping[str, Any]) -> ResultSink | None:
    """The calibration registry (:mod:`benches.results.registry`), on unless ``options["registry"]`` is "off"."""
    return sink_factory(runs_folder, options)


register_copy_sink("registry", _registry)

__all__ = ["register_copy_sink", "sinks_for_run", "unregister_copy_sink"]
