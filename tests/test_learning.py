"""Where the learner's cycles come from: the reference's own, or learning.period_s from t = 0;
a run that holds no whole cycle, or a reference that does not repeat, is refused before any
simulation."""

import numpy as np
import pytest

from stewart_drake.base.errors import InvalidConfigError
from stewart_drake.references.motion import learning_cycles
from stewart_drake.references.organ.breathing import Breathing
from stewart_drake.references.trajectories import hold_home


def test_the_reference_s_cycles_begun_within_the_run():
    starts, scale = learning_cycles(0.0, Breathing(period_s=4.0), 10.0)
    np.testing.assert_array_equal(starts, [0.0, 4.0, 8.0, 12.0])
    np.testing.assert_array_equal(scale, [1.0, 1.0, 1.0])


def test_a_period_of_the_user_s_cuts_any_reference():
    starts, scale = learning_cycles(1.5, hold_home(), 5.0)
    np.testing.assert_array_equal(starts, [0.0, 1.5, 3.0, 4.5, 6.0])  # the last 0.5 s too
    np.testing.assert_array_equal(scale, [1.0, 1.0, 1.0, 1.0])


def test_a_tail_after_the_last_cycle_found_is_corrected_too():
    class Cut:
        """Cycles found up to 8 s only, as a trace's peaks end before the trace does."""

        name = "cut"

        def cycles(self, t_end):
            return np.array([0.0, 4.0, 8.0]), np.array([1.1, 0.9])

        def evaluate(self, t):
            return Breathing(period_s=4.0).evaluate(t)

    starts, scale = learning_cycles(0.0, Cut(), 13.0)
    np.testing.assert_array_equal(starts, [0.0, 4.0, 8.0, 12.0, 16.0])
    np.testing.assert_array_equal(scale, [1.1, 0.9, 1.0, 1.0])
    starts, _ = learning_cycles(0.0, Cut(), 8.0)
    np.testing.assert_array_equal(starts, [0.0, 4.0, 8.0])


def test_what_cannot_be_learned_is_refused_saying_what_to_change():
    with pytest.raises(InvalidConfigError, match="give learning.period_s"):
        learning_cycles(0.0, hold_home(), 5.0)
    with pytest.raises(InvalidConfigError, match=r"the run \(3 s\) holds no whole cycle"):
        learning_cycles(0.0, Breathing(period_s=4.0), 3.0)
