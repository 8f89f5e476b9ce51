"""Digests of JSON content: canonical JSON text and a SHA-256 of a document's own values, stored in the document.

Used by calibration.json's tamper evidence (:mod:`benches.calibration_integrity`, ``docs/registry.md``).
"""

from __future__ import annotations

import hashlib
import json
from collections.abc import Mapping
from typing import Any

ALGORITHM = "sha256"
KEY = "integrity"


def canonical(obj: Any) -> str:
    """Canonical JSON text of ``obj`` (sorted keys, no spaces, ASCII, no NaN; Python's shortest round-trip floats)."""
    return json.dumps(obj, sort_keys=True, separators=(",", ":"), ensure_ascii=True, allow_nan=False)


def values_digest(content: Mapping[str, Any]) -> str:
    """SHA-256 (hex) of ``content`` without its ``integrity`` key, as canonical JSON."""
    body = {k: v for k, v in content.items() if k != KEY}
    return hashlib.sha256(canonical(body).encode("ascii")).hexdigest()


def with_integrity(content: Mapping[str, Any], bound_to: str, covers: str) -> dict[str, Any]:
    """``content`` (JSON-ready) with its ``integrity`` block (replacing any old one): the digest of its values
    as a reader will parse them back, and ``bound_to`` (the digest of the data they come from)."""
    body = {k: v for k, v in content.items() if k != KEY}
    plain = json.loads(canonical(body))
    return {
        **body,
        KEY: {
            "algorithm": ALGORITHM,
            "values_sha256": values_digest(plain),
            "recording_sha256": bound_to,
            "covers": covers,
        },  # fmt: skip
    }


__all__ = ["ALGORITHM", "KEY", "canonical", "values_digest", "with_integrity"]
