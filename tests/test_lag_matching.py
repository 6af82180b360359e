"""Lag matching: the platform's lag behind its reference estimated each period from its pose, and
the surrogate's command delayed by it; the run's relative latency then judges the carriage
against its own undelayed reference, so a matching that did not match FAILs.

The platforms here are synthetic: a reference and the same reference given a known lag, offset
and noise; the estimate is held to the lag it was given, not to anything the estimator says.
"""

import math

import numpy as np
import pytest

from stewart_drake.base.errors import InvalidConfigError
from stewart_drake.live.session_surrogate import judged_relative_latency as relative_latency
from stewart_drake.station.bus.servos import SurrogateServoConfig
from stewart_drake.station.surrogate.bus_servo import SurrogateDrive
from stewart_drake.station.surrogate.lag_matching import (
    MAX_DELAY_S,
    MAX_RATE,
    PlatformLagMatch,
)

H = 0.01
Z = 5


def _breath(t):
    """An irregular breath along Z, m: two harmonics and a slower third (not one period)."""
    return (
        0.008 * np.sin(2 * np.pi * t / 4.2)
        + 0.002 * np.sin(4 * np.pi * t / 4.2 + 0.7)
        + 0.001 * np.sin(2 * np.pi * t / 11.0)
    )


def _breath_rate(t):
    w1, w3 = 2 * np.pi / 4.2, 2 * np.pi / 11.0
    return (
        0.008 * w1 * np.cos(w1 * t)
        + 0.002 * 2 * w1 * np.cos(2 * w1 * t + 0.7)
        + 0.001 * w3 * np.cos(w3 * t)
    )


def _match(seconds=40.0, **kw):
    t = np.arange(int(seconds / H) + 1) * H
    return t, PlatformLagMatch(H, 0.3 + _breath(t), _breath_rate(t), Z, **kw)


def _feed(match, t, lag_s, offset_m=0.0, noise_m=0.0, seed=0):
    """The platform ``lag_s`` late on its reference, offset and noisy, fed period by period;
    the delays after each period."""
    rng = np.random.default_rng(seed)
    pose = np.zeros(6)
    delays = np.empty(t.size)
    for k, tk in enumerate(t):
        pose[Z] = 0.3 + _breath(tk - lag_s) + offset_m + noise_m * rng.standard_normal()
        delays[k] = match.update(tk, pose)
    return delays


@pytest.mark.parametrize("lag_s", [0.0264, 0.012, -0.002, 0.065])
def test_the_delay_converges_on_the_lag_the_platform_was_given(lag_s):
    t, match = _match()
    # 4 um of noise (a crank count's worth at the platform) and a 0.3 mm sag.
    delays = _feed(match, t, lag_s, offset_m=-3e-4, noise_m=4e-6)
    # A second of readings before the delay moves (a line through less cannot tell a lag
    # from an offset).
    assert np.all(delays[t < 0.985] == 0.0) and delays[t > 1.5][0] != 0.0
    settled = t > 25.0
    assert np.max(np.abs(delays[settled] - lag_s)) < 1e-4, delays[settled][[0, -1]]
    assert abs(match.estimate_s - lag_s) < 1e-4
    # Never faster than its rate limit: the carriage's speed changes by at most 0.5 %.
    assert np.max(np.abs(np.diff(delays))) <= MAX_RATE * H * (1 + 1e-12)
    # From nothing to the lag takes |lag| / rate at least.
    reached = np.argmax(np.abs(delays - lag_s) < 1e-3)
    assert t[reached] >= (abs(lag_s) - 1e-3) / MAX_RATE - H


def test_a_still_reference_leaves_the_command_undelayed():
    t = np.arange(2000) * H
    match = PlatformLagMatch(H, np.full(t.size, 0.3), np.zeros(t.size), Z)
    pose = np.zeros(6)
    rng = np.random.default_rng(1)
    for tk in t:
        pose[Z] = 0.3 + 4e-6 * rng.standard_normal()
        assert match.update(tk, pose) == 0.0
    assert math.isnan(match.estimate_s)


def test_a_lag_beyond_the_bound_is_held_at_the_bound_and_a_reading_without_a_pose_is_skipped():
    t, match = _match(60.0)
    delays = _feed(match, t, 0.35)
    assert delays[-1] == pytest.approx(MAX_DELAY_S, abs=1e-12)
    assert match.estimate_s > MAX_DELAY_S
    before = match.delay_s
    assert match.update(60.01, np.full(6, np.nan)) == before


def test_the_platform_leading_gives_a_negative_delay():
    t, match = _match()
    delays = _feed(match, t, -0.03)
    assert delays[-1] == pytest.approx(-0.03, abs=3e-4)


_AXIS_ONLY = r"^the matched axis must be a translation \(3\.\.5\), got "
_AXIS_OR_UNIT = (
    r"^the matched axis must be a translation \(3\.\.5\) or a \(3,\) unit direction, got "
)
_UNIT = np.array([0.6, 0.0, 0.8])


@pytest.mark.parametrize(
    "change, words",
    [
        (dict(axis=2), _AXIS_ONLY + "2$"),
        (dict(axis=6), _AXIS_ONLY + "6$"),
        (dict(axis=True), _AXIS_OR_UNIT + "True$"),  # a bool is not a coordinate
        (dict(axis=[0.6, 0.8]), _AXIS_OR_UNIT),
        (dict(axis=[np.nan, 0.0, 1.0]), _AXIS_OR_UNIT),
        (dict(axis=(1 + 2e-6) * _UNIT), _AXIS_OR_UNIT),  # 2e-6 off a unit length
        (dict(reference_rate=np.zeros(3)), "alike"),
        (dict(reference=np.zeros(1), reference_rate=np.zeros(1)), r"n >= 2, got \(1,\)"),
        (
            dict(reference=np.full(5, np.nan), reference_rate=np.zeros(5)),
            "^the platform's reference for lag matching is not finite$",
        ),
        (dict(period_s=0.0), r"^period_s must be > 0 s, got 0\.0$"),
        (dict(memory_s=-1.0), r"^memory_s must be > 0 s, got -1\.0$"),
        (dict(memory_s=math.inf), r"^memory_s must be > 0 s, got inf$"),
        (dict(max_rate=1.5), "max_rate"),
        (dict(max_rate=1.0), "max_rate 1.0"),
        (dict(max_delay_s=math.inf), "max_delay_s inf"),
        (dict(min_speed_m_s=0.0), "min_speed"),
        (dict(t0=math.nan), "^t0 must be finite, got nan$"),
    ],
)
def test_wrong_settings_are_refused(change, words):
    args = dict(period_s=H, reference=np.zeros(5), reference_rate=np.zeros(5), axis=Z) | change
    with pytest.raises(InvalidConfigError, match=words):
        PlatformLagMatch(**args)


def test_the_limits_at_their_edges_and_each_axis_are_taken():
    pose = np.array([0.1, 0.2, 0.3, 1.0, 2.0, 3.0])
    for axis, y in ((3, 1.0), (4, 2.0), (5, 3.0), (_UNIT, 0.6 + 0.8 * 3.0)):
        match = PlatformLagMatch(H, np.zeros(2), np.zeros(2), axis)
        assert match.coordinate(pose) == pytest.approx(y, rel=1e-15)
    PlatformLagMatch(H, np.zeros(2), np.zeros(2), (1 + 5e-7) * _UNIT)  # within 1e-6
    PlatformLagMatch(H, np.zeros(2), np.zeros(2), Z, max_rate=0.0, max_delay_s=0.0)
    match = PlatformLagMatch(H, np.zeros(2), np.zeros(2), Z)
    assert match.state.shape == (6,) and not match.state.any() and math.isnan(match.estimate_s)


def test_the_reference_is_read_linear_between_samples_and_held_at_its_ends():
    match = PlatformLagMatch(H, [1.0, 2.0, 4.0], [10.0, 20.0, 40.0], Z, t0=1.0)
    for t, want in (
        (0.5, (1.0, 10.0)),
        (1.0, (1.0, 10.0)),
        (1.005, (1.5, 15.0)),
        (1.0175, (3.5, 35.0)),
        (1.02, (4.0, 40.0)),
        (9.0, (4.0, 40.0)),
    ):
        assert match._at(t) == pytest.approx(want, rel=1e-12)


def test_the_fit_waits_for_a_second_of_readings_and_a_reference_that_moves():
    """The first estimate at the reading that completes MIN_HISTORY_S (100 at 10 ms); none at
    all while the reference's rate varies by less than min_speed_m_s RMS."""
    t = np.arange(3000) * H
    w = 2 * np.pi / 4.0
    lam = math.exp(-H / 6.0)  # the 6 s memory

    def moving_from(g):
        """The first reading, from the 100th, whose weighted variance of the rate reaches
        (0.2 mm/s)^2, worked out here over the readings so far."""
        for k in range(99, g.size):
            weights = lam ** (k - np.arange(k + 1))
            mean = weights @ g[: k + 1] / weights.sum()
            if weights @ g[: k + 1] ** 2 / weights.sum() - mean**2 >= (2e-4) ** 2:
                return k + 1
        return None

    for amplitude_m, first in ((0.005, 100), (0.4e-4 / w, None), (4e-4 / w, 139)):
        # Rate RMS about its mean, amplitude w / sqrt(2), over whole cycles: 5.6, 0.028 and
        # 0.28 mm/s; over the first second's readings, the slowest that moves has 0.2 mm/s
        # only after 1.39 s.
        c, g = amplitude_m * np.sin(w * t), amplitude_m * w * np.cos(w * t)
        assert moving_from(g) == first
        match = PlatformLagMatch(H, c, g, Z)
        pose = np.zeros(6)
        estimates = []
        for tk in t:
            pose[Z] = amplitude_m * np.sin(w * (tk - 0.02))
            match.update(tk, pose)
            estimates.append(match.estimate_s)
        found = np.flatnonzero(np.isfinite(estimates))
        if first is None:
            assert found.size == 0 and match.delay_s == 0.0
        else:
            assert found[0] + 1 == first
            assert match.delay_s == pytest.approx(0.02, abs=1e-3)


class _Line:
    def __call__(self, t):
        return float(_breath(t)), float(_breath_rate(t)), 0.0


def test_the_drive_takes_its_command_the_delay_late():
    drive = SurrogateDrive(SurrogateServoConfig(), H)
    drive.command = _Line()
    drive.reading(0.0, 0.0)
    assert drive.delay_s == 0.0 and drive.commanded(3.0)[0] == pytest.approx(_breath(3.0))
    t, drive.lag_match = _match()
    for tk in t[:3000]:
        pose = np.zeros(6)
        pose[Z] = 0.3 + _breath(tk - 0.02)
        drive.platform_reading(tk, pose)
    assert drive.delay_s == pytest.approx(0.02, abs=3e-4)
    assert drive.commanded(30.0)[0] == pytest.approx(float(_breath(30.0 - drive.delay_s)))
    _, s_c = drive.torque(30.0)
    assert s_c == pytest.approx(float(_breath(30.0 - drive.delay_s)))


def _run_pair(platform_lag, carriage_delay, servo_lag=0.0):
    """The judged run: the platform ``platform_lag`` late on its reference; the carriage's
    command its trace ``carriage_delay`` late, followed ``servo_lag`` late."""
    t = np.arange(0.0, 20.0, H)
    x_c = np.zeros((t.size, 6))
    x_c[:, Z] = 0.3 + _breath(t)
    x_m = x_c.copy()
    x_m[:, Z] = 0.3 + _breath(t - platform_lag)
    s_ref = _breath(t + 0.4)
    s_cmd = _breath(t + 0.4 - carriage_delay)
    s_m = _breath(t + 0.4 - carriage_delay - servo_lag)
    delays = np.full(t.size, carriage_delay)
    return relative_latency(
        t, x_m, x_c, s_m, s_cmd, PERIOD, t_from=2.0, s_reference=s_ref, delays_s=delays
    )


PERIOD = 0.01


def test_a_matched_carriage_is_judged_against_its_own_trace():
    judged = _run_pair(0.026, 0.025, 0.0004)
    assert judged.passed and "PASS" in judged.line()
    assert judged.surrogate_lag_s == pytest.approx(0.0254, abs=2e-4)
    assert judged.servo_lag_s == pytest.approx(0.0004, abs=2e-4)
    assert judged.matching_delay_s == pytest.approx(0.025, abs=1e-12)
    assert judged.relative_s == pytest.approx(0.0006, abs=3e-4)
    line = judged.line()
    assert "s against s_ref, its trace" in line and "delayed +25.0 ms on average" in line


@pytest.mark.parametrize(
    "platform_lag, carriage_delay, relative",
    [
        (0.0, 0.025, -0.025),  # a delay the platform did not need
        (0.026, 0.0, 0.026),  # no matching where the platform is late
        (0.026, -0.026, 0.052),  # a delay of the wrong sign
    ],
)
def test_a_matching_that_does_not_match_fails(platform_lag, carriage_delay, relative):
    judged = _run_pair(platform_lag, carriage_delay)
    assert judged.relative_s == pytest.approx(relative, abs=3e-4)
    assert not judged.passed and "FAIL" in judged.line()


def _goal_diagram(lag_s, seconds=30.0, offset=0.0005):
    """A LagMatchedGoal fed a platform ``lag_s`` late on its reference (a TrajectorySource of
    its state), in a Diagram: (simulator, the goal system, the signal's samples)."""
    from pydrake.systems.analysis import Simulator
    from pydrake.systems.framework import DiagramBuilder
    from pydrake.systems.primitives import TrajectorySource
    from pydrake.trajectories import PiecewisePolynomial

    from stewart_drake.station.surrogate.lag_matched_goal import LagMatchedGoal

    t = offset + np.arange(int(seconds / H) + 1) * H
    match = PlatformLagMatch(H, 0.3 + _breath(t), _breath_rate(t), Z, t0=t[0])
    signal = (t, 0.5 * _breath(t + 0.4), 0.5 * _breath_rate(t + 0.4), np.zeros(t.size))
    fine = np.arange(0.0, seconds + H, 0.001)
    state = np.zeros((12, fine.size))
    state[Z] = 0.3 + _breath(fine - lag_s)
    builder = DiagramBuilder()
    platform = builder.AddSystem(TrajectorySource(PiecewisePolynomial.FirstOrderHold(fine, state)))
    goal = builder.AddSystem(LagMatchedGoal(match, signal, H, offset))
    builder.Connect(platform.get_output_port(), goal.get_input_port())
    return Simulator(builder.Build()), goal, signal


def test_the_goal_system_takes_the_signal_as_late_as_the_platform_is():
    simulator, goal, (t, p, v, _) = _goal_diagram(0.026)
    context = goal.GetMyContextFromRoot(simulator.get_context())
    # At the start, no delay: the signal's samples exactly, at the controller's instants.
    for k in (0, 1, 7):
        simulator.AdvanceTo(t[k])
        np.testing.assert_allclose(goal.get_output_port().Eval(context)[:2], [p[k], v[k]])
    simulator.AdvanceTo(29.0)
    assert goal.delay_s(context) == pytest.approx(0.026, abs=2e-4)
    now = simulator.get_context().get_time()
    late = now - goal.delay_s(context)
    np.testing.assert_allclose(
        goal.get_output_port().Eval(context)[:2],
        [0.5 * _breath(late + 0.4), 0.5 * _breath_rate(late + 0.4)],
        atol=3e-6,  # linear between the 10 ms samples
    )


def _small_goal(resolution_m=0.0):
    """A LagMatchedGoal over three samples 10 ms apart from t = 1 s, worked by hand below."""
    from stewart_drake.station.surrogate.lag_matched_goal import LagMatchedGoal

    t = 1.0 + np.arange(3) * H
    match = PlatformLagMatch(H, 0.3 + _breath(t), _breath_rate(t), Z, t0=t[0])
    signal = (t, [0.0, 0.001, 0.003], [1.0, 2.0, 4.0], [10.0, 20.0, 40.0])
    return LagMatchedGoal(match, signal, H, 0.0005, resolution_m)


def test_the_goal_is_linear_between_samples_and_holds_its_ends():
    goal = _small_goal()
    halfway = {1.005: [0.0005, 1.5, 15.0], 1.0175: [0.0025, 3.5, 35.0]}  # by hand
    for t, want in halfway.items():
        np.testing.assert_allclose(goal.goal_at(t), want, rtol=1e-12, atol=1e-15)
    for t in (0.5, 1.0):  # before the first sample: the first held
        np.testing.assert_allclose(goal.goal_at(t), [0.0, 1.0, 10.0], atol=1e-15)
    for t in (1.02, 1.0201, 5.0):  # at and after the last sample: the last held
        np.testing.assert_allclose(goal.goal_at(t), [0.003, 4.0, 40.0], atol=1e-15)


def test_the_goal_rounds_its_position_only_to_the_stage_resolution():
    goal = _small_goal(resolution_m=0.0004)
    # p 0.5 mm -> 0.4 mm (1.25 counts -> 1), 2.5 mm -> 2.4 mm (6.25 -> 6); the rate and the
    # acceleration as they are.
    np.testing.assert_allclose(goal.goal_at(1.005), [0.0004, 1.5, 15.0], rtol=1e-12)
    np.testing.assert_allclose(goal.goal_at(1.0175), [0.0024, 3.5, 35.0], rtol=1e-12)
    np.testing.assert_allclose(_small_goal(0.0).goal_at(1.0175)[0], 0.0025, rtol=1e-12)


def test_the_goal_system_declares_what_its_docstring_says():
    goal = _small_goal()
    assert goal.num_input_ports() == 1 and goal.num_output_ports() == 1
    assert goal.get_input_port().get_name() == "platform_state"
    assert goal.get_input_port().size() == 12
    assert goal.get_output_port().get_name() == "goal" and goal.get_output_port().size() == 3
    context = goal.CreateDefaultContext()
    assert context.num_discrete_state_groups() == 1
    assert context.get_discrete_state(0).size() == 6  # the estimator's state, as the match's
