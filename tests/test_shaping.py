"""The shaping of a followed reference (run/shaping.py): a prediction that asks the motors for
more torque than a reference may use is shaped, period by period, into a reference the
validator itself passes, the shaping counted and said; within the limits the followed
reference is given as it is; the shaped reference depends on nothing that arrives later, steps
by no more than its rejoining tolerance, and scales an acceleration by the largest factor the
motors allow.

The stream: the library's breathing (15 mm on X, 4 s) sampled at 5 Hz with 0.1 mm of noise,
0.2 s late: the prediction's revisions ask motor torques of up to 0.69 N m where the motion
itself needs 0.35 N m and a reference may use 0.632 N m (90 % of the motors' 0.702 N m).
"""

import math
from dataclasses import replace

import numpy as np
import pytest

from stewart_drake.references.organ.library import make_motion
from stewart_drake.references.prediction import PredictorSettings
from stewart_drake.references.stream import Stream, follow
from stewart_drake.robot.kinematics import X_HOME
from stewart_drake.robot.statics import motor_effort
from stewart_drake.run.plan import check_reference, make_plan
from stewart_drake.run.scenario_io import load_scenario
from stewart_drake.run.shaping import (
    REJOIN_POSE,
    REJOIN_RATE,
    Shaper,
    ShapingLimits,
    shape_followed,
    shaping_limits,
)

D = 16.0
LATENCY_S = 0.2
MOTION = make_motion("breathing", {})
#: The predictor may be used after 2 s of history and 2 s of record (4 s and 5 s shipped): a short
#: stream reaches it.
SETTINGS = PredictorSettings(history_s=2.0, min_record_s=2.0)


def noisy_stream(noise_m=100e-6, seed=1, duration_s=D, change_after_s=None) -> Stream:
    """MOTION at 5 Hz with ``noise_m`` of Gaussian noise on X, Y, Z, ``LATENCY_S`` late; with
    ``change_after_s``, every sample after it moved by 2 mm on X (another future)."""
    rng = np.random.default_rng(seed)
    t = np.arange(0.0, duration_s + 1e-9, 0.2)
    poses = np.asarray(MOTION.evaluate(t)[0]).copy()
    poses[:, 3:] += rng.normal(0.0, noise_m, (t.size, 3))
    if change_after_s is not None:
        poses[t > change_after_s, 3] += 2e-3
    return Stream(t, poses, LATENCY_S, "noisy breathing")


@pytest.fixture(scope="module")
def plan():
    return make_plan(replace(load_scenario("phantom_hardware"), duration_s=D), with_reference=False)


@pytest.fixture(scope="module")
def followed():
    return follow(noisy_stream(), "linear", SETTINGS)


@pytest.fixture(scope="module")
def shaped(plan, followed):
    return shape_followed(followed, shaping_limits(plan), D)


def _rms_to_truth(reference) -> float:
    t = np.arange(0.0, D, 0.01)
    e = np.asarray(reference.evaluate(t)[0])[:, 3:] - np.asarray(MOTION.evaluate(t)[0])[:, 3:]
    return float(np.sqrt(np.mean(np.sum(e**2, axis=1))))


def test_a_prediction_over_the_torque_limit_is_shaped_into_one_the_validator_passes(
    plan, followed, shaped
):
    """The validator refuses the followed reference (a motor over its torque) and not the true
    motion; it passes the shaped reference, whose largest torque is within the limit and within
    3 % of it (the acceleration scaled no more than the motors need). The shaping is counted:
    periods scaled for the torque, shaped, and at most 0.5 mm from the followed reference,
    which costs the end-to-end error against the true motion less than 10 %."""
    truth = check_reference(plan, MOTION, raise_refused=False, keep_series=False, duration_s=D)
    before = check_reference(plan, followed, raise_refused=False, keep_series=False, duration_s=D)
    after = check_reference(plan, shaped, raise_refused=False, keep_series=False, duration_s=D)
    limit = plan.motor_limits.margin * plan.motor_limits.peak_torque_Nm
    assert truth.ok and truth.peak_torque < 0.7 * limit
    assert not before.ok and before.first_effort_violation.quantity == "torque"
    assert after.ok, after.summary()
    assert 0.97 * limit < after.peak_torque <= limit
    record = shaped.record
    assert record.scaled >= 1 and record.shaped >= record.scaled and record.over == 0
    assert record.limited == 0 and record.joined_s == 0.0 and record.approach == 0
    assert 1e-6 < record.departure_m < 0.5e-3
    assert record.periods == int(np.ceil(D / plan.control_period_s)) + 3
    with_, without = _rms_to_truth(shaped), _rms_to_truth(followed)
    assert 0.9 * without < with_ < 1.1 * without
    words = record.words()
    assert f"shaped to the robot's limits in {record.shaped} of {record.periods} periods" in words
    assert f"scaled for a motor's torque or speed in {record.scaled}" in words


def test_the_approach_to_the_followed_reference_keeps_teleops_box(plan, followed):
    """Started at rest 10 mm below the followed reference's start (as the robot rests, live):
    the reference approaches it within teleop's box (0.05 m/s, 0.5 m/s^2 on X, Y, Z), joins it
    within 2 s, and is then shaped as from the start (the approach not counted as shaped)."""
    shaper = Shaper(shaping_limits(plan))
    h = plan.control_period_s
    x0 = np.asarray(followed.evaluate(0.0)[0]) - np.array([0, 0, 0, 0, 0, 0.01])
    state = shaper.initial_state(x0)
    t = np.arange(0.0, 4.0, h)
    x, v, a = (np.asarray(q) for q in followed.evaluate(t))
    out = np.array([shaper.step(state, t[k], (x[k], v[k], a[k]))[0] for k in range(t.size)])
    record = shaper.record_of(state)
    assert record.joined_s is not None and 0.3 < record.joined_s < 2.0
    before = t < record.joined_s
    assert record.approach == np.count_nonzero(before)
    assert np.max(np.abs(out[before, 15:18])) <= 0.5 and np.max(np.abs(out[before, 9:12])) <= 0.05
    np.testing.assert_array_equal(out[~before, :6][:50], x[~before][:50])  # on it once joined


def test_within_the_limits_the_followed_reference_is_given_as_it_is(plan):
    """The noiseless breathing held (no prediction), its torque within the motors (checked
    first, by the validator): the shaped reference is the followed one, to the bit, and nothing
    is counted shaped. (The regression's path between 5 Hz samples may ask more of the motors:
    on this breathing it peaks at 0.73 N m against 0.63, and is shaped.)"""
    followed = follow(noisy_stream(noise_m=0.0, duration_s=12.0), "none", SETTINGS)
    premise = check_reference(
        plan, followed, raise_refused=False, keep_series=False, duration_s=12.0
    )
    assert premise.ok, premise
    shaped = shape_followed(followed, shaping_limits(plan), 12.0)
    t = np.sort(np.random.default_rng(0).uniform(0.0, 12.0, 5000))
    for mine, theirs in zip(shaped.evaluate(t), followed.evaluate(t)):
        np.testing.assert_array_equal(mine, theirs)
    assert shaped.record.shaped == 0 and shaped.shaped_periods.size == 0
    assert "within the robot's limits throughout" in shaped.record.words()


def test_the_shaped_reference_depends_on_nothing_that_arrives_later(plan, shaped):
    """Every sample after 10 s moved by 2 mm: the shaped reference before 10 s + the latency
    is the same to the bit, and after it is not."""
    other = shape_followed(
        follow(noisy_stream(change_after_s=10.0), "linear", SETTINGS), shaping_limits(plan), D
    )
    t = np.arange(0.0, D, plan.control_period_s)
    early = t < 10.0 + LATENCY_S
    for mine, theirs in zip(shaped.evaluate(t), other.evaluate(t)):
        np.testing.assert_array_equal(mine[early], theirs[early])
    assert np.max(np.abs(shaped.evaluate(t)[0][~early] - other.evaluate(t)[0][~early])) > 1e-4


def test_the_shaped_reference_steps_by_no_more_than_its_rejoining_tolerance(plan, followed, shaped):
    """At every period the pose is where the period before took it at its constant
    acceleration (x + v h + a h^2 / 2), and the rate (v + a h), as closely as the followed
    curve's own are (its third- and second-order terms), or within the rejoining tolerances
    (where it goes back onto the followed reference)."""
    h = plan.control_period_s
    t = np.arange(0.0, D, h)

    def steps(reference):
        x, v, a = reference.evaluate(t)
        carried = x[:-1] + v[:-1] * h + 0.5 * a[:-1] * h**2
        return np.max(np.abs(x[1:] - carried)), np.max(np.abs(v[1:] - v[:-1] - a[:-1] * h))

    (pose, rate), (own_pose, own_rate) = steps(shaped), steps(followed)
    assert pose <= max(own_pose, REJOIN_POSE) + 1e-15, (pose, own_pose)
    assert rate <= max(own_rate, REJOIN_RATE) + 1e-15, (rate, own_rate)
    assert own_pose < REJOIN_POSE  # the followed curve's own third-order term is below it


def _effort_limits(plan):
    motors = plan.motor_limits
    return motors.margin * motors.peak_torque_Nm, motors.servo


def test_an_acceleration_the_motors_cannot_give_is_scaled_by_the_largest_factor_they_allow(
    plan,
):
    """At home, moving 10 mm/s on Z, a followed acceleration of 14 m/s^2 on Z: the motors'
    torque there (numpy's inverse dynamics, not the compiled form the shaper
    reads) is over the limit. The shaped acceleration is that one scaled: within the limit, and
    1 % more of it would be over."""
    shaper = Shaper(shaping_limits(plan))
    limit, servo = _effort_limits(plan)
    geometry = plan.plant_geometry
    x, v, a = X_HOME.copy(), np.zeros(6), np.zeros(6)
    v[5], a[5] = 0.01, 14.0
    assert np.max(np.abs(motor_effort(geometry, x, v, a, servo)[0])) > limit  # the premise
    state = shaper.initial_state(x)
    state[Shaper.V] = v
    state[Shaper.ON_PATH] = state[Shaper.JOINED] = 1.0  # following it
    out, what = shaper.step(state, 0.0, (x, v, a), admissible=True)
    assert what & Shaper.SCALED_FLAG and not what & Shaper.CLIPPED_FLAG
    np.testing.assert_array_equal(out[:12], np.concatenate([x, v]))
    s = out[17] / a[5]
    assert 0.0 < s < 1.0 and np.allclose(out[12:17], 0.0, atol=0.0)
    torque = np.max(np.abs(motor_effort(geometry, x, v, out[12:], servo)[0]))
    more = np.max(np.abs(motor_effort(geometry, x, v, min(1.0, 1.01 * s) * a, servo)[0]))
    assert 0.999 * limit < torque <= limit and more > limit
    np.testing.assert_allclose(state[Shaper.X], x + 1e-3 * v + 0.5e-6 * out[12:], atol=1e-15)


def test_stopping_short_keeps_the_acceleration_and_the_next_rate_in_the_box(plan):
    """Stopped short (its goal 0.2 mm ahead of a pose that moves at 0.0499 m/s on Z towards
    it): the acceleration is within teleop's 0.5 m/s^2 and the next rate within 0.05 m/s; the
    flags say clipped and limited."""
    shaper = Shaper(shaping_limits(plan))
    x, v = X_HOME.copy(), np.zeros(6)
    v[5] = 0.0499
    state = shaper.initial_state(x)
    state[Shaper.V], state[Shaper.JOINED] = v, 1.0
    state[Shaper.GOAL][5] += 2e-4
    state[Shaper.COUNTER] = 1  # not a period that checks the pose: the goal stands
    state[Shaper.LIMITED] = 1.0
    out, what = shaper.step(state, 0.0, (x + 0.01, v, np.zeros(6)))
    assert what & Shaper.CLIPPED_FLAG and what & Shaper.LIMITED_FLAG
    assert np.all(np.abs(out[12:]) <= 0.5 + 1e-12) and out[17] == pytest.approx(-0.5)
    assert np.all(np.abs(state[Shaper.V]) <= 0.05 + 1e-12)


def test_a_pose_that_is_not_admissible_is_not_followed(plan):
    """An admissible set that ends 2.5 mm below the centre on X (a stand-in for a joint limit):
    the breathing (+-7.5 mm) is stopped short of it, said as limited, and follows it again
    above it. Not by construction: the pose is checked every 20 ms and the filter then stops at
    the box's deceleration, so the reference passes the boundary by what its rate carries
    (0.54 mm at the 18 mm/s the held breathing reaches there; 2.2 mm at 32 mm/s); under 3 mm."""
    followed = follow(noisy_stream(noise_m=0.0, duration_s=12.0), "none", SETTINGS)
    bound = -2.5e-3

    def admissible(x):
        return np.asarray(x)[:, 3] >= bound

    limits = replace(shaping_limits(plan), admissible=admissible)
    shaped = shape_followed(followed, limits, 12.0)
    t = np.arange(0.0, 12.0, 0.01)
    x_f, x_s = followed.evaluate(t)[0][:, 3], shaped.evaluate(t)[0][:, 3]
    assert np.min(x_f) < bound - 4e-3  # the premise
    assert np.min(x_s) > bound - 3e-3
    record = shaped.record
    assert record.limited > 0 and record.first_limited_s is not None
    assert "stopped short of a pose not admissible" in record.words()
    above = x_f > bound + 3e-3
    assert np.median(np.abs(x_s - x_f)[above]) < 1e-6


def test_the_limits_are_the_validators(plan):
    """The shaping limits of a run: the robot its validator checks, the motors' limits and
    share, the control period; a bad period refused."""
    limits = shaping_limits(plan)
    assert limits.geometry is plan.plant_geometry and limits.motors == plan.motor_limits
    assert limits.period_s == plan.control_period_s
    torque, speed = limits.effort_limits()
    motors = plan.motor_limits
    assert torque == pytest.approx(motors.margin * motors.peak_torque_Nm, rel=2e-6)
    assert torque < motors.margin * motors.peak_torque_Nm
    assert speed == pytest.approx(motors.margin * motors.max_speed_rad_s, rel=2e-6)
    from stewart_drake.base.errors import InvalidConfigError

    for bad in (0.0, -1e-3, float("nan")):
        with pytest.raises(InvalidConfigError, match="control period"):
            ShapingLimits(limits.geometry, limits.motors, limits.admissible, period_s=bad)
        with pytest.raises(InvalidConfigError, match="following bandwidth"):
            replace(limits, follow_bandwidth_hz=bad)


def test_the_following_filter_is_10_hz_and_stays_stable_at_a_long_period(plan):
    """Back onto the followed reference at 10 Hz (2 pi 10 rad/s) at 1 ms; at a 20 ms period,
    at most 0.5 / h = 25 rad/s (4 Hz). Either way the filter stepped at constant acceleration
    (the step's matrix on the error and its rate, written out) has both poles inside the unit
    circle; 10 Hz at 20 ms would not (a pole at 1.72)."""
    limits = shaping_limits(plan)

    def radius(w, h):
        step = np.array([[1 - (w * h) ** 2 / 2, h - w * h * h], [-h * w * w, 1 - 2 * w * h]])
        return np.max(np.abs(np.linalg.eigvals(step)))

    for h, want in ((1e-3, 2 * np.pi * 10.0), (0.02, 25.0)):
        w = replace(limits, period_s=h).follow_omega()
        assert w == pytest.approx(want, rel=1e-12)
        assert radius(w, h) < 0.96
    assert radius(2 * np.pi * 10.0, 0.02) > 1.5


def test_the_shapers_record_is_in_its_state():
    """Every count of what was shaped lives in the state the caller keeps (a Drake system's
    Context), none in the shaper: one shaper stepping two states apart keeps two records, and a
    state copied mid-run and stepped again gives the same record twice."""
    shaper = Shaper(
        shaping_limits(make_plan(load_scenario("phantom_hardware"), with_reference=False))
    )
    x0 = np.asarray(MOTION.evaluate(0.0)[0])
    at_rest, far = (
        shaper.initial_state(x0),
        shaper.initial_state(x0 - np.array([0, 0, 0, 0, 0, 0.01])),
    )
    for k in range(200):
        t = k * shaper.h
        followed = tuple(np.asarray(q) for q in MOTION.evaluate(t))
        shaper.step(at_rest, t, followed)
        shaper.step(far, t, followed)
        if k == 99:
            copy = far.copy()
    a, b = shaper.record_of(at_rest), shaper.record_of(far)
    assert a.periods == b.periods == 200
    assert a.approach == 0 and a.joined_s == 0.0  # it starts on the motion
    assert b.approach > 0 and (b.joined_s is None or b.joined_s > 0.0)
    for k in range(100, 200):
        t = k * shaper.h
        shaper.step(copy, t, tuple(np.asarray(q) for q in MOTION.evaluate(t)))
    assert shaper.record_of(copy) == b


class _Line:
    """A followed reference moving at a constant rate u from c: x = c + t u, v = u, a = 0."""

    name = "a line"
    end_time = 12.5
    stream = object()
    c, u = np.arange(6.0), np.linspace(0.1, 0.6, 6)

    def evaluate(self, t):
        t = np.asarray(t, dtype=float).reshape(-1)
        return self.c + t[:, None] * self.u, np.tile(self.u, (t.size, 1)), np.zeros((t.size, 6))


def test_a_shaped_reference_reads_its_periods_at_constant_acceleration_and_the_rest_as_followed():
    """Periods 0 and 2 of 10 ms shaped, worked out by hand: within a shaped period x + tau v +
    tau^2 a / 2 and v + tau a from its start; outside them, and before t = 0, the followed."""
    from stewart_drake.run.shaping import ShapedReference

    line, h = _Line(), 0.01
    rows = np.zeros((2, 18))
    rows[0] = np.r_[np.full(6, 1.0), np.full(6, 2.0), np.full(6, 40.0)]
    rows[1] = np.r_[np.full(6, -1.0), np.full(6, 3.0), np.full(6, -100.0)]
    shaped = ShapedReference(line, h, [0, 2], rows.tolist(), "the record")
    assert shaped.name == "a line and shaped" and shaped.end_time == 12.5
    assert shaped.stream is line.stream and shaped.record == "the record"
    assert shaped.shaped_periods.dtype == np.int64 and shaped.values.shape == (2, 18)

    def by_hand(t):
        if 0.0 <= t < h:
            tau, (x, v, a) = t, (1.0, 2.0, 40.0)
        elif 2 * h <= t < 3 * h - 1e-12:
            tau, (x, v, a) = t - 2 * h, (-1.0, 3.0, -100.0)
        else:
            return line.evaluate([t])
        return (np.full((1, 6), x + tau * v + 0.5 * tau**2 * a),
                np.full((1, 6), v + tau * a), np.full((1, 6), a))  # fmt: skip

    for t in (-1e-12, -0.005, 0.0, 0.005, 0.0099, 0.015, 0.02, 0.025, 0.0299, 0.03, 0.5):
        for got, want in zip(shaped.evaluate([t]), by_hand(t), strict=True):
            np.testing.assert_allclose(got, want, rtol=1e-12, atol=1e-15, err_msg=f"t = {t}")
    grid = np.array([[0.0, 0.005], [0.025, 0.5]])
    x, v, a = shaped.evaluate(grid)
    assert x.shape == v.shape == a.shape == (2, 2, 6)
    np.testing.assert_allclose(x[1, 0], -1.0 + 0.005 * 3.0 - 0.5 * 0.005**2 * 100.0)
    none = ShapedReference(line, h, [], np.zeros((0, 18)), "the record")
    for got, want in zip(none.evaluate(grid), line.evaluate(grid.reshape(-1)), strict=True):
        np.testing.assert_array_equal(got, want.reshape(2, 2, 6))


@pytest.mark.parametrize("duration_s", [0.0, -1.0, float("nan"), float("inf")])
def test_a_duration_not_finite_and_positive_is_refused(plan, duration_s):
    from stewart_drake.base.errors import InvalidConfigError

    with pytest.raises(
        InvalidConfigError, match=rf"^the duration must be > 0 s, got {duration_s!r}$"
    ):
        shape_followed(MOTION, shaping_limits(plan), duration_s)


def test_half_a_second_is_shaped_over_its_periods_and_three_beyond(plan):
    shaped = shape_followed(MOTION, shaping_limits(plan), 0.5)
    # The library's breathing starts at rest and fits: nothing shaped over 500 + 3 periods of
    # the plan's 1 ms.
    assert plan.control_period_s == 1e-3
    assert shaped.record.periods == 503 and shaped.record.shaped == 0
    assert shaped.record.joined_s == 0.0 and shaped.shaped_periods.size == 0


@pytest.fixture
def shaper(plan):
    return Shaper(shaping_limits(plan))


def test_the_goal_moves_to_the_farthest_admissible_pose_on_its_segment(shaper):
    """With an admissible set Z <= 0.301 m put in place of the robot's: from Z 0.28 m towards
    0.32 m in 16ths, 8/16 of the way is the last admissible point (0.30 m; 9/16 is 0.3025)."""
    from types import SimpleNamespace

    shaper.limits = SimpleNamespace(admissible=lambda poses: np.asarray(poses)[:, 5] <= 0.301)
    goal, target = np.r_[0, 0, 0, 0, 0, 0.28], np.r_[0.02, 0, 0, 0.04, 0, 0.32]
    np.testing.assert_allclose(shaper.goal_toward(goal, target), goal + 0.5 * (target - goal))
    near = np.r_[0, 0, 0, 0.01, 0, 0.29]
    np.testing.assert_allclose(shaper.goal_toward(goal, near), near)  # all of it admissible
    far = np.r_[0, 0, 0, 0, 0, 1.0]  # 1/16 of the way is 0.325: none of it
    np.testing.assert_array_equal(shaper.goal_toward(goal, far), goal)
    one = np.r_[0, 0, 0, 0, 0, 0.6]  # 1/16 of the way (0.3) admissible, 2/16 (0.32) not
    np.testing.assert_allclose(shaper.goal_toward(goal, one), goal + (one - goal) / 16)
    # In quarters: 2/4 of the way (0.30) is the last admissible point (in 49ths, 25/49: 0.3004).
    np.testing.assert_allclose(shaper.goal_toward(goal, target, points=5)[5], 0.30, rtol=1e-12)
    # The first point not admissible ends the way, whatever lies beyond it.
    shaper.limits = SimpleNamespace(
        admissible=lambda poses: ~np.isclose(np.asarray(poses)[:, 5], 0.28 + 0.04 * 3 / 16)
    )
    np.testing.assert_allclose(shaper.goal_toward(goal, target), goal + 2 / 16 * (target - goal))


def test_periods_passed_as_followed_leave_the_state_where_the_followed_reference_goes(shaper):
    x0 = np.asarray(MOTION.evaluate(0.0)[0])
    state = shaper.initial_state(x0)
    h = shaper.h
    x_f, v_f, a_f = x0 + 0.001, np.full(6, 0.02), np.full(6, -3.0)
    goal = x0 + 0.002
    state[Shaper.LIMITED] = 2.0
    shaper.passed(state, 0.25, 7, (x_f, v_f, a_f), goal)
    np.testing.assert_allclose(state[Shaper.X], x_f + h * v_f + 0.5 * h * h * a_f, rtol=1e-15)
    np.testing.assert_allclose(state[Shaper.V], v_f + h * a_f, rtol=1e-15)
    np.testing.assert_array_equal(state[Shaper.GOAL], goal)
    assert state[Shaper.ON_PATH][0] == state[Shaper.JOINED][0] == 1.0
    assert state[Shaper.LIMITED][0] == 0.0 and state[Shaper.COUNTER][0] == 7
    record = shaper.record_of(state)
    assert record.periods == 7 and record.joined_s == 0.25 and record.shaped == 0
    state[Shaper.LIMITED] = 2.0
    shaper.passed(state, 0.5, 3, (x_f, v_f, a_f))  # no check among them: the goal kept
    np.testing.assert_array_equal(state[Shaper.GOAL], goal)
    assert state[Shaper.LIMITED][0] == 2.0 and state[Shaper.COUNTER][0] == 10
    assert shaper.record_of(state).periods == 10 and shaper.record_of(state).joined_s == 0.25


@pytest.mark.parametrize(
    "base, change, limit, scale",
    [
        (np.full(6, 0.5), np.full(6, 1.0), 1.0, 0.5),  # (1 - 0.5) / 1
        (np.full(6, -0.2), np.full(6, -2.0), 1.0, 0.4),  # towards -1: (-1 + 0.2) / -2
        (np.r_[0.5, 0.9, 0.9, 0.9, 0.9, 0.9], np.r_[1.0, 0, 0, 0, 0, 0], 1.0, 0.5),
        (np.r_[0.5, -0.9, 0, 0, 0, 0], np.r_[1.0, -0.4, 0, 0, 0, 0], 1.0, 0.25),  # the nearer
        (np.full(6, 1.0), np.zeros(6), 1.0, 1.0),  # at the limit, not moving: all of it
        (np.full(6, 0.5), np.full(6, 0.2), 1.0, 1.0),  # within at 1: all of it
        (np.full(6, 0.5), np.full(6, 1e9), math.inf, 1.0),  # no limit
        (np.full(6, 1.5), np.full(6, -1.0), 1.0, None),  # over before any change
        (np.full(6, np.nan), np.zeros(6), 1.0, None),
        (np.full(6, 0.5), np.full(6, np.nan), 1.0, None),
    ],
)
def test_the_largest_scale_of_a_change_within_a_limit(base, change, limit, scale):
    from stewart_drake.run.shaping import _largest_scale

    got = _largest_scale(base, change, limit)
    assert got is None if scale is None else got == pytest.approx(scale, rel=1e-12)


@pytest.mark.parametrize(
    "field, value, words",
    [
        ("period_s", 0.0, "the control period must be > 0, got 0.0"),
        ("period_s", float("nan"), "the control period must be a number, got nan"),
        ("period_s", "0.01", "the control period must be a number, got '0.01'"),
        ("follow_bandwidth_hz", -1.0, "the following bandwidth must be > 0, got -1.0"),
        ("follow_bandwidth_hz", float("inf"), "the following bandwidth must be a number, got inf"),
    ],
)
def test_shaping_limits_out_of_range_are_refused_word_for_word(plan, field, value, words):
    from stewart_drake.base.errors import InvalidConfigError

    with pytest.raises(InvalidConfigError) as refused:
        replace(shaping_limits(plan), **{field: value})
    assert str(refused.value) == words


def test_a_stretch_passes_up_to_the_next_period_that_may_fail(shaper):
    """Periods 3..6 of a chunk of 10 pass (7 may fail): the state ends where the followed
    reference goes after period 6, its goal the pose of the last checked period among them (5),
    its record 4 periods joined from period 3's time."""
    from stewart_drake.run.shaping import _pass_stretch

    n = 10
    t = 2.0 + np.arange(n) * shaper.h
    x = np.arange(n)[:, None] * 1e-3 + np.arange(6) * 0.1
    v = np.arange(n)[:, None] * 1e-2 + np.ones(6)
    a = -np.arange(n)[:, None] + np.zeros(6)
    check = np.zeros(n, dtype=bool)
    check[[1, 5, 8]] = True
    state = shaper.initial_state(x[0])
    stop = _pass_stretch(shaper, state, 3, t, (x, v, a), np.array([1, 7, 9]), check)
    assert stop == 7
    h = shaper.h
    np.testing.assert_allclose(state[Shaper.X], x[6] + h * v[6] + 0.5 * h * h * a[6], rtol=1e-14)
    np.testing.assert_allclose(state[Shaper.V], v[6] + h * a[6], rtol=1e-14)
    np.testing.assert_array_equal(state[Shaper.GOAL], x[5])
    record = shaper.record_of(state)
    assert record.periods == 4 and record.joined_s == pytest.approx(t[3], abs=1e-15)
    # No period after it may fail: to the chunk's end; none checked: the goal kept.
    state = shaper.initial_state(x[0])
    assert _pass_stretch(shaper, state, 6, t, (x, v, a), np.array([1]), np.zeros(n, bool)) == n
    np.testing.assert_array_equal(state[Shaper.GOAL], x[0])
    np.testing.assert_allclose(state[Shaper.X], x[9] + h * v[9] + 0.5 * h * h * a[9], rtol=1e-14)


def test_the_filters_acceleration_by_hand_free_and_in_its_box(shaper):
    """Unboxed, the following filter's a_t + w^2 (x_t - x) + 2 w (v_t - v) at the limits'
    following bandwidth; boxed, teleop's bandwidth and the box of accelerations and of the next
    rate; small enough that no motor's limit scales it."""
    limits = shaper.limits
    x = np.asarray(MOTION.evaluate(0.0)[0])
    v = np.zeros(6)
    target = (x + np.r_[0, 0, 0, 0, 0, 1e-5], np.full(6, 1e-4), np.full(6, 1e-3))
    w = min(2 * np.pi * limits.follow_bandwidth_hz, 0.5 / limits.period_s)  # FOLLOW_OMEGA_H
    from stewart_drake.run.shaping import FOLLOW_OMEGA_H

    assert FOLLOW_OMEGA_H == 0.5
    wanted = target[2] + w * w * (target[0] - x) + 2 * w * (target[1] - v)
    a, flags = shaper._acceleration(x, v, target, boxed=False)
    np.testing.assert_allclose(a, wanted, rtol=1e-12)
    assert flags == 0
    w = 2 * np.pi * limits.filter.bandwidth_hz
    wanted = target[2] + w * w * (target[0] - x) + 2 * w * (target[1] - v)
    assert np.all(np.abs(wanted) < limits.filter.acceleration)
    a, flags = shaper._acceleration(x, v, target, boxed=True)
    np.testing.assert_allclose(a, wanted, rtol=1e-12)
    assert flags == 0
    # Far off, boxed: each axis's acceleration at its box, or at what brings the rate to its
    # limit in one period, whichever is nearer; the flag says it was clipped.
    acc, rate, h = np.asarray(limits.filter.acceleration), np.asarray(limits.filter.rate), shaper.h
    v = 0.999 * rate * np.r_[1, -1, 1, -1, 1, -1]
    far = (x + np.r_[0.1, -0.1, 0.1, -0.1, 0.01, -0.01], np.zeros(6), np.zeros(6))
    w_f = min(2 * np.pi * limits.follow_bandwidth_hz, 0.5 / limits.period_s)
    a, flags = shaper._acceleration(x, v, far, boxed=True)
    wanted = w * w * (far[0] - x) + 2 * w * (0 - v)
    box = np.clip(np.clip(wanted, -acc, acc), (-rate - v) / h, (rate - v) / h)
    assert flags & Shaper.CLIPPED_FLAG and not np.allclose(box, wanted)
    if not flags & Shaper.SCALED_FLAG:
        np.testing.assert_allclose(a, box, rtol=1e-12)
    else:  # a motor's limit scaled it: along the same direction, shorter
        s = a / box
        assert np.allclose(s, s[0]) and 0 <= s[0] < 1
    assert not np.allclose(w, w_f)  # the two bandwidths differ, so each is seen
