"""Where the shipped bench and procedure files live, and resolving short names like ``ten-step`` to them.

The shipped YAML files are package data of the installed ``benches`` and ``procedures`` packages. A name
given by the user is used as a path if that file exists (relative to the current directory); otherwise a
shipped file with that name (with or without ``.yaml``) is used. Filesystem paths only: nothing of
``benches`` is imported here (procedures sit below benches in the dependency order).
"""

from __future__ import annotations

from pathlib import Path

from core.yaml_source import ConfigError

PACKAGE_PROCEDURES: Path = Path(__file__).resolve().parent
"""Folder of the shipped procedure files."""
PACKAGE_BENCHES: Path = PACKAGE_PROCEDURES.parent / "benches"
"""Folder of the shipped bench files."""
DEFAULT_BENCH_NAME: str = "sim"
DEFAULT_PROCEDURE_NAME: str = "ten-step"


def shipped(folder: Path) -> list[str]:
    """Names (stems) of the YAML files shipped in ``folder``, sorted."""
    return sorted(p.stem for p in folder.glob("*.yaml"))


def shipped_procedures() -> list[str]:
    """Names of the shipped procedures (e.g. ``ten-step``)."""
    return shipped(PACKAGE_PROCEDURES)


def resolve_file(name: str | Path, folder: Path, kind: str) -> Path:
    """``name`` as a path if it exists, else the shipped ``folder/name`` or ``folder/name.yaml``.

    Raises
    ------
    ConfigError
        If neither exists; the message lists the shipped names.
    """
    p = Path(name)
    if p.is_file():
        return p
    if p.parent == Path("."):
        for cand in (folder / p.name, folder / f"{p.name}.yaml"):
            if cand.is_file():
                return cand
    names = ", ".join(shipped(folder)) or "none"
    raise ConfigError(p, None, f"no such {kind} file; give a path or one of the shipped {kind}s: {names}")


def resolve_procedure(name: str | Path) -> Path:
    """A procedure path from a path or a shipped name (``ten-step``, ``ten-step.yaml``)."""
    return resolve_file(name, PACKAGE_PROCEDURES, "procedure")


def resolve_bench(name: str | Path) -> Path:
    """A bench path from a path or a shipped name (``sim``, ``sim.yaml``)."""
    return resolve_file(name, PACKAGE_BENCHES, "bench")


def default_bench_path() -> Path:
    """The default bench: ``benches/sim.yaml`` in the current directory if present, else the shipped one."""
    local = Path("benches") / f"{DEFAULT_BENCH_NAME}.yaml"
    if local.is_file():
        return local
    return PACKAGE_BENCHES / f"{DEFAULT_BENCH_NAME}.yaml"
