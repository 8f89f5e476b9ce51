"""Decision rule for the conformity statement of a calibration certificate (ILAC-G8:09/2019 style).

Per parameter with a tolerance limit L on |x| (a symmetric specification |x| ≤ L) and the expanded
uncertainty U = k·u (k = 2), the rule is ILAC-G8's **guarded acceptance with guard band w = U** on both
sides (§ 4.2.2 "binary statement with guard band"; shared risk is not used):

* ``PASS``          |x̂| + U ≤ L: the whole coverage interval lies inside the tolerance;
* ``FAIL``          |x̂| − U > L: the whole coverage interval lies outside;
* ``UNDECIDED``     otherwise — U straddles the limit (the estimate alone says inside/outside, which is
                    reported as a note, never as a pass); this includes U ≥ L, where no outcome of this
                    measurement could demonstrate conformity;
* ``NOT EVALUATED`` the procedure cannot identify the parameter (information rank or plan: e.g. the size
                    effect r with the published 1.6 °/s ten-step sequence); its value is prior-dominated;
* ``INVALID``       the estimate or its uncertainty is not finite, the recording failed its integrity
                    check, or the identification is rank-deficient where it had to be full rank —
                    nothing can be concluded and the overall result can never be PASS;
* ``NO LIMIT``      the bench gives no limit for it (reported, not judged).

Overall (:func:`overall_verdict`): INVALID if any parameter is INVALID or the data failed integrity;
FAIL if any parameter FAILs; INCOMPLETE for an incomplete run; INCONCLUSIVE if any limited parameter is
UNDECIDED or NOT EVALUATED; PASS if at least one limited parameter passed and all did; NO LIMITS if the bench
gives none.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

PASS = "PASS"
FAIL = "FAIL"
UNDECIDED = "UNDECIDED"
NOT_EVALUATED = "NOT EVALUATED"
INVALID = "INVALID"
NO_LIMIT = "NO LIMIT"
PARAMETER_VERDICTS = (PASS, FAIL, UNDECIDED, NOT_EVALUATED, INVALID, NO_LIMIT)

OVERALL_VERDICTS = ("PASS", "FAIL", "INCONCLUSIVE", "INCOMPLETE", "INVALID", "NO LIMITS")


@dataclass(frozen=True)
class Conformity:
    """The decision for one parameter.

    Attributes
    ----------
    verdict : str
        One of :data:`PARAMETER_VERDICTS`.
    reason : str
        Plain-words reason (empty for a clean PASS / NO LIMIT).
    """

    verdict: str
    reason: str = ""


def decide(
    value: float,
    expanded: float,
    limit: float | None,
    *,
    identified: bool = True,
    integrity_ok: bool = True,
    full_rank: bool = True,
) -> Conformity:
    """Conformity of one parameter (module docstring). ``value``, ``expanded`` (U) and ``limit`` in one unit."""
    if not integrity_ok:
        return Conformity(INVALID, "the recording failed its integrity check")
    if not (isinstance(value, int | float) and math.isfinite(value)):
        return Conformity(INVALID, f"the estimate is not a finite number ({value!r})")
    if not identified:
        return Conformity(NOT_EVALUATED, "this procedure cannot identify it (prior-dominated estimate)")
    if not (isinstance(expanded, int | float) and math.isfinite(expanded) and expanded >= 0):
        return Conformity(INVALID, f"its uncertainty is not a finite number ({expanded!r})")
    if not full_rank:
        return Conformity(INVALID, "the identification is rank-deficient")
    if limit is None:
        return Conformity(NO_LIMIT)
    if not (math.isfinite(limit) and limit > 0):
        return Conformity(INVALID, f"its limit is not a positive finite number ({limit!r})")
    a = abs(value)
    if a + expanded <= limit:
        return Conformity(PASS)
    if a - expanded > limit:
        return Conformity(FAIL, "the estimate exceeds the limit by more than U")
    if expanded >= limit:
        return Conformity(UNDECIDED, "U is not smaller than the limit: no outcome of this procedure shows conformity")
    side = "inside" if a <= limit else "outside"
    return Conformity(UNDECIDED, f"U straddles the limit (the estimate itself lies {side})")


def overall_verdict(
    verdicts: Sequence[str],
    limited: Sequence[bool],
    *,
    complete: bool = True,
    integrity_ok: bool = True,
    full_rank: bool = True,
) -> str:
    """The certificate's overall result (module docstring).

    Parameters
    ----------
    verdicts : sequence of str
        Per-parameter verdicts from :func:`decide`.
    limited : sequence of bool
        Whether the bench gives a limit for each parameter (a NOT EVALUATED parameter without a limit does
        not make the result inconclusive).
    complete, integrity_ok, full_rank : bool
        Run completeness, the recording's integrity, and whether the identification had full rank (a
        rank-deficient identification is at best INCONCLUSIVE, never PASS).
    """
    if len(verdicts) != len(limited):
        raise ValueError("one 'limited' flag per verdict")
    bad = [v for v in verdicts if v not in PARAMETER_VERDICTS]
    if bad:
        raise ValueError(f"unknown parameter verdict(s) {bad}")
    if not integrity_ok or INVALID in verdicts:
        return "INVALID"
    if FAIL in verdicts:
        return "FAIL"
    if not complete:
        return "INCOMPLETE"
    judged = [v for v, lim in zip(verdicts, limited, strict=True) if lim]
    if not judged:
        return "NO LIMITS"
    if UNDECIDED in judged or NOT_EVALUATED in judged or not full_rank:
        return "INCONCLUSIVE"
    return "PASS"


__all__ = [
    "FAIL",
    "INVALID",
    "NOT_EVALUATED",
    "NO_LIMIT",
    "OVERALL_VERDICTS",
    "PARAMETER_VERDICTS",
    "PASS",
    "UNDECIDED",
    "Conformity",
    "decide",
    "overall_verdict",
]
