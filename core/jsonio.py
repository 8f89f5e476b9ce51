"""One way to write JSON results: strict (no NaN/Infinity tokens), deterministic, atomic.

Non-finite numbers are never written silently: by default they raise; a caller whose format documents
``null`` for "not available" (e.g. the predicted σ of an unobservable parameter) asks for that explicitly.
"""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any, Literal

import numpy as np

from core.outputs import atomic_output

NonFinite = Literal["error", "null"]


def to_jsonable(obj: Any, nonfinite: NonFinite = "error", _path: str = "$") -> Any:
    """Plain JSON data from ``obj``: numpy scalars and arrays become Python numbers and lists; dataclass-like
    objects with ``to_dict()`` are converted; non-finite floats raise ``ValueError`` naming their key path
    (``nonfinite="error"``) or become ``None`` (``nonfinite="null"``)."""
    if hasattr(obj, "to_dict") and callable(obj.to_dict):
        obj = obj.to_dict()
    if isinstance(obj, dict):
        return {str(k): to_jsonable(v, nonfinite, f"{_path}.{k}") for k, v in obj.items()}
    if isinstance(obj, np.ndarray):
        obj = obj.tolist()
    if isinstance(obj, list | tuple):
        return [to_jsonable(v, nonfinite, f"{_path}[{i}]") for i, v in enumerate(obj)]
    if isinstance(obj, np.generic):
        obj = obj.item()
    if isinstance(obj, Path):
        return str(obj)
    if isinstance(obj, float) and not math.isfinite(obj):
        if nonfinite == "null":
            return None
        raise ValueError(f"non-finite number {obj!r} at {_path} cannot be written to JSON")
    return obj


def dumps(obj: Any, nonfinite: NonFinite = "error", indent: int = 1) -> str:
    """Deterministic JSON text (keys in insertion order, UTF-8, trailing newline)."""
    return json.dumps(to_jsonable(obj, nonfinite), indent=indent, ensure_ascii=False, allow_nan=False) + "\n"


def write_text_atomic(path: str | Path, text: str | bytes, *, overwrite: bool = True) -> Path:
    """Write ``text`` to ``path`` atomically through :func:`core.outputs.atomic_output`, so a reader never sees
    a half-written file. With ``overwrite=False`` an existing file raises ``FileExistsError``. A path that
    cannot be written (a file where a folder is needed, no permission, a folder given, the disk full), or
    that would replace an input of the running command or a recording (:func:`core.outputs.check_output`),
    raises :class:`core.errors.OutputError`, naming it."""
    with atomic_output(path, "output", overwrite=overwrite) as fh:
        fh.write(text.encode("utf-8") if isinstance(text, str) else text)
    return Path(path)


def write_json(path: str | Path, obj: Any, nonfinite: NonFinite = "error", indent: int = 1) -> Path:
    """Write ``obj`` as strict JSON to ``path`` atomically (see :func:`dumps`, :func:`write_text_atomic`)."""
    return write_text_atomic(path, dumps(obj, nonfinite, indent))
