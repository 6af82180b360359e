"""What a reference is: its cycles, its own where it knows them (the library's motions), cut at
the main motion's peaks where it does not (a trace, a sine), and none for one that never
repeats."""

import numpy as np
import pytest

from stewart_drake.base.errors import InvalidConfigError
from stewart_drake.references.motion import peak_cycles, reference_cycles
from stewart_drake.references.organ.breathing import Breathing
from stewart_drake.references.trajectories import SineTrajectory, hold_home


def test_a_library_motion_gives_its_own_cycles():
    starts, scale = reference_cycles(Breathing(period_s=4.0), 10.0)
    np.testing.assert_array_equal(starts, [0.0, 4.0, 8.0, 12.0])  # the last ends the last
    np.testing.assert_array_equal(scale, [1.0, 1.0, 1.0])


def test_a_reference_without_cycles_is_cut_at_its_peaks():
    # Z = 0.30 + 0.01 sin(pi t): peaks at t = 0.5 + 2 k s, so cycles of 2 s from 0.5 s.
    sine = SineTrajectory(amplitude=(0,) * 5 + (0.01,), frequency_hz=(0,) * 5 + (0.5,))
    assert not hasattr(sine, "cycles")
    starts, scale = reference_cycles(sine, 10.0)
    np.testing.assert_allclose(starts, peak_cycles(sine, 10.0)[0])
    np.testing.assert_allclose(np.diff(starts), 2.0, atol=0.01)  # within the 10 ms search step
    assert 0.0 <= starts[0] <= 2.0 and np.allclose(scale, 1.0, atol=1e-3)


def test_a_reference_that_never_repeats_has_no_cycles():
    with pytest.raises(InvalidConfigError, match="does not repeat: fewer than two cycles"):
        reference_cycles(hold_home(), 10.0)


def test_every_kind_of_reference_evaluates_pose_rate_and_acceleration_per_time():
    for reference in (Breathing(), hold_home(), SineTrajectory()):
        pose, rate, acceleration = reference.evaluate(np.array([0.0, 0.5]))
        assert pose.shape == rate.shape == acceleration.shape == (2, 6)
        assert isinstance(reference.name, str) and reference.name
