"""The tuner study's seeded task families: deterministic by seed, within the motors' reach,
rates and accelerations the derivatives of the pose, bad requests refused by name."""

import numpy as np
import pytest

from stewart_drake.base.errors import InvalidConfigError
from stewart_drake.robot import limits, statics
from stewart_drake.robot.geometry import StewartGeometry
from stewart_drake.tuner import study_runs as sr
from stewart_drake.tuner.tasks import FAMILIES, LOAD_MARGIN, WaypointTrajectory, make_task


@pytest.mark.parametrize("family", FAMILIES)
def test_tasks_are_deterministic_valid_and_differ_by_seed(family):
    g = StewartGeometry()
    t = np.arange(0.0, 3.0, 1e-3)
    a, b, c = (make_task(family, s, 3.0, g, 0.702) for s in (7, 7, 8))
    xa, xb, xc = (task.reference.evaluate(t)[0] for task in (a, b, c))
    np.testing.assert_array_equal(xa, xb)
    assert family == "paper" or np.abs(xa - xc).max() > 1e-3
    x, xd, xdd = a.reference.evaluate(t)
    assert limits.validate_trajectory(g, t, x, x_dot=xd, x_ddot=xdd, raise_refused=False).ok


def test_waypoint_rates_and_accelerations_are_the_derivatives_of_the_pose():
    task = make_task("surgical", 3, 4.0)  # min-jerk segments and tremor sines
    t = np.arange(0.0, 4.0, 1e-4)
    x, v, a = task.reference.evaluate(t)
    np.testing.assert_allclose(np.gradient(x, t, axis=0)[1:-1], v[1:-1], atol=2e-3)
    np.testing.assert_allclose(np.gradient(v, t, axis=0)[2:-2], a[2:-2], atol=0.5)
    still = WaypointTrajectory((0.0, 1.0), ((0, 0, 0, 0, 0, 0.3),) * 2)
    assert not np.any(still.evaluate(np.linspace(-1, 2, 50))[1])


def test_a_disturbed_hold_stays_within_the_motors_reach():
    g, peak = StewartGeometry(), 0.702
    for seed in range(4):
        task = make_task("disturbed_hold", seed, 3.0, g, peak)
        d = task.disturbance
        t = np.arange(0.0, 3.0, 0.05)
        worst = max(
            np.abs(statics.tool_load_torques(g, x, w)).max()
            for x, w in zip(task.reference.evaluate(t)[0], d.wrench(t))
        )
        assert worst <= LOAD_MARGIN * peak + 1e-9 and d.magnitude > 0


@pytest.mark.parametrize("family", ["dash_hold", "multisine", "surgical"])
def test_every_task_reference_is_within_the_motors_reach(family):
    # Inverse dynamics on a 1 ms grid (finer than the 5 ms check inside make_task), and a
    # multi-sine still moves: shrinking fits it, it does not flatten it.
    g, peak = StewartGeometry(), 0.702
    t = np.arange(0.0, 3.0, 1e-3)
    for seed in (0, 1, 2, 101, 104):
        x, _, xdd = make_task(family, seed, 3.0, g, peak).reference.evaluate(t)
        T = statics.feedforward_torques(g, x, xdd, mode="inverse_dynamics")
        assert np.abs(T).max() <= LOAD_MARGIN * peak * 1.01
        assert np.ptp(x[:, :3], axis=0).max() > 0.02  # > 20 mrad of motion


def test_bad_task_requests_are_refused_by_name():
    with pytest.raises(InvalidConfigError, match="unknown task family 'dance'"):
        make_task("dance")
    with pytest.raises(InvalidConfigError, match="task seed must be an integer >= 0"):
        make_task("dash_hold", -1)


def test_speed_schedule_is_soft_at_rest_and_stiff_in_motion():
    t, ratios = sr.speed_schedule("dash_hold", 0, 3.0, "paper_hardware")
    _, v, _ = make_task("dash_hold", 0, 3.0).reference.evaluate(np.asarray(t))
    still = np.linalg.norm(v, axis=1) == 0
    assert np.allclose(np.asarray(ratios)[still], sr.R_HOLD)
    assert max(ratios) == pytest.approx(sr.R_MOVE)
