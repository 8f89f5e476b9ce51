"""THE output guard: no command writes over one of its inputs or over a recording.

One rule in one place. Every writer of a command output (:func:`core.jsonio.write_text_atomic`, hence every
JSON and PNG written through it; :func:`save_npy`; the certificate's PDF and JSON; a salvaged copy) calls
:func:`check_output` on the path before it writes, and the commands call it once more up front so that a bad
``--out`` is refused before any long work starts. The rule:

- an output path must not be the same file as an input of the running command (the CLI registers the files
  and run folders named on the command line with :func:`protect_inputs`; a run folder protects its
  ``recording.h5``, ``bench.yaml`` and ``procedure.yaml``);
- an output path must not be an existing HDF5 file (a recording: nothing but the recorder appends to one);
- an output path must not be an issued document of a run folder (``certificate*.pdf``/``.json``,
  ``noise-report*.pdf``/``.json`` beside a ``recording.h5``): an issued certificate is never overwritten, by
  any command;
- an output path must be creatable: it is not a folder, and its folder exists or can be created (the check
  creates it).

Each refusal is a :class:`core.errors.OutputError` naming the option and the path, one line, exit 2.
"""

from __future__ import annotations

import os
import re
import tempfile
from collections.abc import Iterable, Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import TYPE_CHECKING, BinaryIO

from core.errors import OutputError

if TYPE_CHECKING:
    import numpy as np

HDF5_SIGNATURE = b"\x89HDF\r\n\x1a\n"
"""The first 8 bytes of an HDF5 file (a recording)."""
RUN_FOLDER_INPUTS = ("recording.h5", "bench.yaml", "procedure.yaml")
"""The files of a run folder that a command reading the folder uses as inputs."""

ISSUED_DOCUMENTS = re.compile(r"(certificate|noise-report)(-[A-Za-z0-9-]+)?\.(pdf|json)", re.IGNORECASE)
"""The names of the documents issued into a run folder (benches.certificate_register.free_paths)."""

_protected: list[Path] = []


def protect_inputs(paths: Iterable[str | Path | None]) -> None:
    """Register the inputs of the running command (files, or run folders) until :func:`clear_inputs`."""
    for p in paths:
        if p is None or str(p) == "":
            continue
        path = Path(p)
        try:
            if path.is_dir():
                _protected.extend(path / name for name in RUN_FOLDER_INPUTS if (path / name).exists())
            elif path.exists():
                _protected.append(path)
        except (OSError, ValueError):  # a name too long, a NUL byte: not a file, so nothing to protect
            continue


def clear_inputs() -> None:
    """Forget the registered inputs (the CLI calls it when a command ends)."""
    _protected.clear()


def _same_file(a: Path, b: Path) -> bool:
    try:
        return os.path.samefile(a, b)
    except OSError:
        return False


def is_recording_file(path: Path) -> bool:
    """True if ``path`` is an existing file that starts with the HDF5 signature."""
    try:
        with path.open("rb") as fh:
            return fh.read(len(HDF5_SIGNATURE)) == HDF5_SIGNATURE
    except OSError:
        return False


def check_output(path: str | Path, option: str = "--out", *, inputs: Iterable[str | Path] = ()) -> Path:
    """Refuse an output ``path`` that would replace an input or a recording, or cannot be created.

    Parameters
    ----------
    path : str or Path
        The output file.
    option : str
        The command-line option that named it (for the message).
    inputs : iterable of paths
        Inputs of this command beyond the registered ones (e.g. a run's ``calibration.json``).

    Returns
    -------
    Path
        ``path`` as a Path.
    """
    p = Path(path)
    if p.exists():
        if p.is_dir():
            raise OutputError(f"{option} {p}: is a folder; give a file name")
        for q in [*_protected, *(Path(i) for i in inputs)]:
            if _same_file(p, q):
                raise OutputError(
                    f"{option} {p}: is an input of this command ({q}); an output never replaces an input, "
                    "choose another path"
                )
        if is_recording_file(p):
            raise OutputError(
                f"{option} {p}: is a recording (HDF5); a recording is never overwritten, choose another path"
            )
        if ISSUED_DOCUMENTS.fullmatch(p.name) and (p.parent / "recording.h5").exists():
            raise OutputError(
                f"{option} {p}: is a document issued for this run; an issued certificate is never overwritten, "
                "choose another path"
            )
    try:
        p.parent.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise OutputError(
            f"{option} {p}: its folder cannot be created ({exc.strerror or exc}); choose another path"
        ) from None
    if not os.access(p.parent, os.W_OK | os.X_OK):
        raise OutputError(f"{option} {p}: the folder {p.parent} is not writable; choose another path")
    return p


@contextmanager
def atomic_output(path: str | Path, option: str = "--out", *, overwrite: bool = True) -> Iterator[BinaryIO]:
    """A binary file handle whose bytes appear at ``path`` only when the block ends without an error.

    THE atomic write of every command output (:func:`core.jsonio.write_text_atomic`, :func:`save_npy`): the
    path passes :func:`check_output`; the bytes go to a temporary file in the same folder, are flushed and
    fsynced, and the file is renamed onto ``path`` (``overwrite=True``) or hard-linked to it, which fails with
    ``FileExistsError`` if ``path`` exists (``overwrite=False``: never overwrites). A reader never sees a
    half-written file; on any error the temporary file is removed and ``path`` is untouched. A path that
    cannot be written (a folder given, no permission, the disk full) raises :class:`core.errors.OutputError`
    naming ``option`` and the path.
    """
    p = check_output(path, option)

    def refuse(exc: OSError) -> OutputError:
        return OutputError(f"{option} {p}: cannot be written ({exc.strerror or exc}); choose another path")

    try:
        if p.is_dir():
            raise IsADirectoryError(21, "is a folder; give a file name", str(p))
        p.parent.mkdir(parents=True, exist_ok=True)
        fd, tmp = tempfile.mkstemp(prefix=f".{p.name}.", suffix=".tmp", dir=p.parent)
    except OSError as exc:
        raise refuse(exc) from None
    try:
        with os.fdopen(fd, "wb") as fh:
            yield fh
            fh.flush()
            os.fsync(fh.fileno())
        if overwrite:
            os.replace(tmp, p)
        else:
            os.link(tmp, p)
            os.unlink(tmp)
    except FileExistsError:
        _discard(tmp)
        raise
    except OSError as exc:
        _discard(tmp)
        raise refuse(exc) from None
    except BaseException:
        _discard(tmp)
        raise


def _discard(tmp: str) -> None:
    if os.path.exists(tmp):
        os.unlink(tmp)


def save_npy(path: str | Path, array: np.ndarray, option: str = "--out") -> Path:
    """``np.save`` to exactly ``path`` (no ``.npy`` appended), atomically (:func:`atomic_output`)."""
    import numpy as np  # lazy: numpy (--help time: the CLI entry imports this module)

    with atomic_output(path, option) as fh:
        np.save(fh, array, allow_pickle=False)
    return Path(path)
