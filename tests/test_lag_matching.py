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
from stewart_drake.station.bus.servos import SurrogateServoConfig
from stewart_drake.station.surrogate.bus_servo import SurrogateDrive
from stewart_drake.station.surrogate.encoder_relative_latency import relative_latency
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


@pytest.mark.parametrize(
    "change, words",
    [
        (dict(axis=2), "translation"),
        (dict(reference_rate=np.zeros(3)), "alike"),
        (dict(reference=np.full(5, np.nan), reference_rate=np.zeros(5)), "not finite"),
        (dict(period_s=0.0), "period_s"),
        (dict(memory_s=-1.0), "memory_s"),
        (dict(max_rate=1.5), "max_rate"),
        (dict(min_speed_m_s=0.0), "min_speed"),
    ],
)
def test_wrong_settings_are_refused(change, words):
    args = dict(period_s=H, reference=np.zeros(5), reference_rate=np.zeros(5), axis=Z) | change
    with pytest.raises(InvalidConfigError, match=words):
        PlatformLagMatch(**args)


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
