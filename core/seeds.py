"""The range of a seed (a bench file's ``simulation.seed``, the ``--seed`` option): one definition for both.

Lives in core so that the command line can check ``--seed`` without importing the simulator.
"""

from __future__ import annotations

MAX_SEED = 2**63 - 1
"""The largest seed accepted (a non-negative int64: numpy's ``SeedSequence`` takes it as given)."""

__all__ = ["MAX_SEED"]
