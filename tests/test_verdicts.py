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


def test_a_verdict_by_its_figure_alone_is_pass_or_fail():
    """Without the other two words a check says PASS or FAIL: neither CANNOT JUDGE nor ACTION
    unless the check says so."""
    assert v.verdict(True) == "PASS"
    assert v.verdict(False) == "FAIL"


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


NAN = float("nan")


@pytest.mark.parametrize(
    "value, bound, inside",
    [
        (0.5e-3, 1e-3, True),
        (1e-3, 1e-3, True),  # at the bound: within
        (1.0000001e-3, 1e-3, False),
        (-1e-3, 1e-3, True),  # a latency either way: its size is judged
        (-1.01e-3, 1e-3, False),
        (0.0, 0.0, True),
        (NAN, 1e-3, False),  # a figure that could not be measured never passes
        (0.5e-3, NAN, False),
    ],
)
def test_a_figure_within_its_bound(value, bound, inside):
    assert v.within(value, bound) is inside


@pytest.mark.parametrize(
    "errors, judged, inside",
    [
        ([1e-3, 1e-3, 1e-3, 0.1e-3, 0.1e-3, 0.1e-3], None, True),  # every axis at or under
        ([1e-3, 1e-3, 1e-3, 0.1e-3, 0.1e-3, 0.11e-3], None, False),  # Z over by 10 %
        ([1.1e-3, 0, 0, 0, 0, 0], None, False),  # phi over
        ([1.1e-3, 0, 0, 0, 0, 0], [False, True, True, True, True, True], True),  # not judged
        ([NAN, 0, 0, 0, 0, 0], [False, True, True, True, True, True], True),  # unmeasured
        ([NAN, 0, 0, 0, 0, 0], None, False),  # a judged NaN fails
        ([0, 0, 0, 0, 0, 0], [False] * 6, True),  # nothing judged: nothing beyond
        ([NAN, 0, 0, 0, 0, 0.2e-3], [False, True, True, True, True, True], False),  # Z judged
        ([1.1e-3, 0, 0, 0, 0, 0], [0, 1, 1, 1, 1, 1], True),  # a 0/1 mask is a mask, not indices
        ([0, 0, 0, 0, 0, 0.2e-3], [0, 1, 1, 1, 1, 1], False),
    ],
)
def test_every_judged_axis_within_its_bound(errors, judged, inside):
    """Rotations' bound 1 mrad, translations' 0.1 mm (rad and m per axis)."""
    bounds = [1e-3] * 3 + [0.1e-3] * 3
    assert v.axes_within(errors, bounds, judged) is inside


@pytest.mark.parametrize(
    "error, action, level",
    [
        (0.2e-3, None, "PASS"),
        (0.5e-3, None, "PASS"),  # at the tolerance
        (0.6e-3, None, "FAIL"),
        (0.2e-3, 0.3e-3, "PASS"),
        (0.3e-3, 0.3e-3, "PASS"),  # at the action level: not beyond it
        (0.4e-3, 0.3e-3, "ACTION"),
        (0.6e-3, 0.3e-3, "FAIL"),  # an action level never softens a FAIL
        (NAN, 0.3e-3, "FAIL"),
    ],
)
def test_one_axis_level_against_a_tolerance_of_half_a_millimetre(error, action, level):
    assert v.axis_level(error, 0.5e-3, action) == level
