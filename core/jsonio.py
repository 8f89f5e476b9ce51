"""One way to write JSON results: strict (no NaN/Infinity tokens), deterministic, atomic.

Non-finite numbers are never written silently: by default they raise; a caller whose format documents
``null`` for "not available" (e.g. the predicted σ of an unobservable parameter) asks for that explicitly.
"""

from __future__ import annotations

import json
import math
import os
import tempfile
from pathlib import Path
from typing import Any, Literal

import numpy as np

from core.errors import OutputError
from core.outputs import check_output

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
    """Write ``text`` to ``path`` through a temporary file in the same folder and a rename, so a reader never
    sees a half-written file. With ``overwrite=False`` an existing file raises ``FileExistsError``. A path
    that cannot be created (a file where a folder is needed, no permission, a folder given), or that would
    replace an input of the running command or a recording (:func:`core.outputs.check_output`), raises
    :class:`core.errors.OutputError`, naming it."""
    p = check_output(path, "output")
    data = text.encode("utf-8") if isinstance(text, str) else text
    try:
        if p.is_dir():
            raise IsADirectoryError(21, "is a folder; give a file name", str(p))
        p.parent.mkdir(parents=True, exist_ok=True)
        fd, tmp = tempfile.mkstemp(prefix=f".{p.name}.", suffix=".tmp", dir=p.parent)
    except OSError as exc:
        raise OutputError(f"{p}: cannot be written ({exc.strerror or exc}); choose another output path") from None
    try:
        with os.fdopen(fd, "wb") as fh:
            fh.write(data)
            fh.flush()
            os.fsync(fh.fileno())
        if overwrite:
            os.replace(tmp, p)
        else:
            os.link(tmp, p)  # fails if p exists: never overwrites
            os.unlink(tmp)
    except BaseException:
        if os.path.exists(tmp):
            os.unlink(tmp)
        raise
    return p


def write_json(path: str | Path, obj: Any, nonfinite: NonFinite = "error", indent: int = 1) -> Path:
    """Write ``obj`` as strict JSON to ``path`` atomically (see :func:`dumps`, :func:`write_text_atomic`)."""
    return write_text_atomic(path, dumps(obj, nonfinite, indent))
