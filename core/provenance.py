"""Provenance helpers: file and text digests and the installed software version."""

from __future__ import annotations

import hashlib
from importlib.metadata import PackageNotFoundError, version
from pathlib import Path


def file_sha256(path: str | Path) -> str:
    """SHA-256 hex digest of a file (read in 1 MiB chunks)."""
    h = hashlib.sha256()
    with open(path, "rb") as fh:
        for chunk in iter(lambda: fh.read(1 << 20), b""):
            h.update(chunk)
    return h.hexdigest()


def text_sha256(text: str) -> str:
    """SHA-256 hex digest of a text's UTF-8 bytes (a bench or procedure file as recorded)."""
    return hashlib.sha256(text.encode("utf-8")).hexdigest()


def software_version() -> str:
    """The installed tablebench version (``0.0.0+source`` when running from a source tree not installed)."""
    try:
        return version("tablebench")
    except PackageNotFoundError:
        return "0.0.0+source"
