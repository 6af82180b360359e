"""The words of a verdict, one vocabulary for every check the package gives one (``verify`` of a
motion alone or with its surrogate, its QA record, the robot's relative latency): what each
means, their order from best to worst, and a command's exit status for each.

- **PASS**: within the tolerance, and the rest the check holds (a latency, a motion it can see).
- **ACTION**: within the tolerance, but an axis beyond the action level (TG-142's: to be
  looked at before it fails).
- **CANNOT JUDGE**: the check cannot tell the motion from none at its tolerance (a motion too
  small to see): not a PASS.
- **FAIL**: beyond the tolerance, or what the check holds does not.
"""

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
    "exit_status",
    "verdict",
    "worst",
]
