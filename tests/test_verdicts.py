"""The one vocabulary of verdicts (stewart_drake/base/verdicts.py): each word, their order and
the exit status of each, as docs/organ_motion.md tells a user (``verify``'s exit status: 0 PASS,
2 FAIL, 3 CANNOT JUDGE, 4 ACTION; of several, the worst)."""

import pytest

from stewart_drake.base import verdicts as v


@pytest.mark.parametrize(
    "passed, cannot_judge, action, word",
    [
        (True, False, False, "PASS"),
        (True, False, True, "ACTION"),
        (True, True, False, "PASS"),  # passed: the motion was seen, whatever else was said
        (False, False, False, "FAIL"),
        (False, True, False, "CANNOT JUDGE"),
        (False, False, True, "FAIL"),  # an action level never softens a FAIL
        (False, True, True, "CANNOT JUDGE"),
    ],
)
def test_each_verdict_word(passed, cannot_judge, action, word):
    assert v.verdict(passed, cannot_judge, action) == word


@pytest.mark.parametrize(
    "words, worst, status",
    [
        ((), "PASS", 0),
        (("PASS",), "PASS", 0),
        (("PASS", "ACTION"), "ACTION", 4),
        (("ACTION", "CANNOT JUDGE", "PASS"), "CANNOT JUDGE", 3),
        (("CANNOT JUDGE", "FAIL"), "FAIL", 2),
        (("FAIL", "PASS", "PASS"), "FAIL", 2),
    ],
)
def test_the_worst_verdict_and_its_exit_status(words, worst, status):
    words = tuple(words)
    assert v.worst(words) == worst
    assert v.exit_status(words) == status


@pytest.mark.parametrize("bad", ["pass", "OK", "", "FAILED"])
def test_a_word_that_is_no_verdict_is_refused(bad):
    with pytest.raises(ValueError):
        v.worst(("PASS", bad))
