"""The words of a verdict, one vocabulary for every check the package gives one (``verify`` of a
motion alone or with its surrogate, its QA record, the robot's relative latency): what each
means, their order from best to worst, and a command's exit status for each; and the rules that
turn a figure and its bound into a verdict (:func:`within`, :func:`axes_within`,
:func:`axis_level`), written here once for every check: a figure at its bound passes, a NaN
never does.

- **PASS**: within the tolerance, and the rest the check holds (a latency, a motion it can see).
- **ACTION**: within the tolerance, but an axis beyond the action level (TG-142's: to be
  looked at before it fails).
- **CANNOT JUDGE**: the check cannot tell the motion from none at its tolerance (a motion too
  small to see): not a PASS.
- **FAIL**: beyond the tolerance, or what the check holds does not.
"""

import numpy as np

PASS, ACTION, CANNOT_JUDGE, FAIL = "PASS", "ACTION", "CANNOT JUDGE", "FAIL"
#: Every verdict, best first, worst last.
VERDICTS = (PASS, ACTION, CANNOT_JUDGE, FAIL)
#: A command's exit status of each verdict: 0 PASS, 2 FAIL (as a refused input), 3 CANNOT
#: JUDGE, 4 ACTION; of several, the worst's (:func:`worst`).
EXIT_STATUS = {PASS: 0, FAIL: 2, CANNOT_JUDGE: 3, ACTION: 4}


def verdict(passed: bool, cannot_judge: bool = False, action: bool = False) -> str:
    """The verdict's word: passed -> ACTION with ``action`` (an axis beyond the action level),
    else PASS; not passed -> CANNOT JUDGE with ``cannot_judge``, else FAIL."""
    if passed:
        return ACTION if action else PASS
    return CANNOT_JUDGE if cannot_judge else FAIL


def within(value: float, bound: float) -> bool:
    """|value| <= bound: one figure (a latency, an RMS error, s or m or rad) within its bound.
    A figure at the bound is within it; a NaN figure or bound never is (a figure that could not
    be measured does not pass)."""
    return bool(abs(value) <= bound)


def axes_within(errors, bounds, judged=None) -> bool:
    """Every judged axis's error within its bound (:func:`within` on each): the rule of a
    motion's fidelity verdict.

    Args:
        errors: (n,) each axis's error (an RMS), in its axis's unit. bounds: (n,) each axis's
            bound, in the same units. judged: (n,) bool, the axes judged (default all); an axis
            left out is not judged whatever its error (a rotation a marker does not measure).
    Returns:
        True when no judged axis is beyond its bound or NaN (True for no judged axis).
    """
    errors = np.asarray(errors, dtype=float)
    bounds = np.broadcast_to(np.asarray(bounds, dtype=float), errors.shape)
    keep = np.ones(errors.shape, bool) if judged is None else np.asarray(judged, dtype=bool)
    return bool(np.all(np.abs(errors[keep]) <= bounds[keep]))


def axis_level(error: float, bound: float, action: float | None = None) -> str:
    """One axis's level: FAIL beyond its ``bound`` (or NaN), ACTION within it but beyond the
    ``action`` level (when one is given), else PASS; the error and both levels in one unit."""
    if not within(error, bound):
        return FAIL
    if action is not None and abs(error) > action:
        return ACTION
    return PASS


def worst(verdicts) -> str:
    """The worst of ``verdicts`` (words of :data:`VERDICTS`) in their order; PASS for none.

    Raises:
        ValueError: a word that is not a verdict.
    """
    return max(verdicts, key=VERDICTS.index, default=PASS)


def exit_status(verdicts) -> int:
    """A command's exit status for ``verdicts``: :data:`EXIT_STATUS` of the worst (2 when any
    FAILs, else 3 when any cannot judge, else 4 when any is ACTION, else 0)."""
    return EXIT_STATUS[worst(verdicts)]


__all__ = [
    "ACTION",
    "CANNOT_JUDGE",
    "EXIT_STATUS",
    "FAIL",
    "PASS",
    "VERDICTS",
    "axes_within",
    "axis_level",
    "exit_status",
    "verdict",
    "within",
    "worst",
]
