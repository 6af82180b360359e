"""The LQI step's stages (:mod:`~stewart_drake.control.lqi.step`) against the numbers they must
give, computed here in numpy from the equations: the law T = T_ff - K e (eq. 34), the clipping
and anti-windup, the pending torques of the delay, the integral (eq. 23) and its carry-over at a
gain change, the governor's hold, the friction feed-forward, the features' ring buffer, what
``observe`` says is due, and the estimator's chord step.

test_lqi_step.py holds the compiled step equal to its uncompiled reference; these tests hold
either to the equations, so they run as well with the JIT off (``NUMBA_DISABLE_JIT=1``, where
the stages are plain Python): tools/mutation.py runs them to mutate step.py.
"""

import numpy as np
import pytest

from stewart_drake.control.estimator import PoseEstimator
from stewart_drake.control.lqi import layout, step
from stewart_drake.control.lqi.controller import LqiController
from stewart_drake.control.lqi.driver import LqiDriver
from stewart_drake.robot import kinematics
from stewart_drake.robot.geometry import X_HOME, StewartGeometry

GEOMETRY = StewartGeometry()
H = 1e-3


def _controller(
    delay=0, limit=None, window=None, transfer="integral", estimator=False, friction=0.0
):
    est = PoseEstimator(GEOMETRY, H, 2 * np.pi / 2**17) if estimator else None
    driver = LqiDriver(
        schedule_period_s=2e-2,
        gain_transfer=transfer,
        friction_compensation_Nm=friction,
        friction_rate_rad_s=0.5,
    )
    return LqiController(
        GEOMETRY,
        driver,
        period_s=H,
        torque_limit_Nm=limit,
        delay_periods=delay,
        estimator=est,
        feature_window=window,
    )


def _case(c: LqiController, seed: int, torque_scale: float = 0.05):
    """(u, state): a pose near home, a reference near it, a feed-forward, an integral, pending
    torques, a perturbed gain and, with a window, a partly filled ring."""
    rng = np.random.default_rng(seed)
    lay = c.layout
    x = X_HOME + rng.uniform(-1, 1, 6) * [0.05, 0.05, 0.05, 0.005, 0.005, 0.005]
    u = np.zeros(lay.u_size)
    state = c._initial_state(x, np.zeros(6), np.zeros(6), c.K_initial)
    if c.estimator is not None:
        u[lay.pose_in] = kinematics.ik(GEOMETRY, x)
        state[lay.x_hat] = np.concatenate([x + rng.normal(0, 1e-5, 6), rng.normal(0, 0.02, 6)])
        state[lay.J_inv] = np.linalg.inv(kinematics.jacobian(GEOMETRY, x)).reshape(-1)
    else:
        u[lay.pose_in] = np.concatenate([x, rng.normal(0, 0.05, 6)])
    u[lay.x_d] = np.concatenate([x + rng.normal(0, 1e-3, 6), rng.normal(0, 0.05, 12)])
    u[lay.T_ff] = rng.normal(0, torque_scale, 6)
    u[lay.omega] = 1.0, 1.0
    u[lay.T_applied] = rng.normal(0, 0.2, lay.T_applied.stop - lay.T_applied.start)
    state[lay.status][[layout.SATURATED_STEPS, layout.GOVERNED_STEPS]] = 5.0, 7.0
    state[lay.z] = rng.normal(0, 1e-4, 6)
    state[lay.e_bar] = rng.normal(0, 1e-3, 6)
    state[lay.counter] = 3.0
    state[lay.K] = (c.K_initial * (1 + 0.1 * rng.normal(size=c.K_initial.shape))).reshape(-1)
    state[lay.K_old] = c.K_initial.reshape(-1)
    state[lay.pending] = rng.normal(0, 0.05, lay.pending.stop - lay.pending.start)
    if lay.window.stop > lay.window.start:
        w = (lay.window.stop - lay.window.start - 2) // layout.WINDOW_ROW
        state[lay.window][:-2] = rng.normal(0, 0.1, layout.WINDOW_ROW * w)
        state[lay.window][-2:] = w - 2, w - 1  # two rows free, the head at the ring's end
    return u, state


def _error(c, u, state, ref=None):
    """e = [x - x_d (12), z (6), pending (6 d)] (eqs. 23-25, block order), from ``u``'s pose."""
    lay = c.layout
    x = state[lay.x_hat] if c.estimator is not None else u[lay.pose_in]
    ref = u[lay.x_d] if ref is None else ref
    return np.concatenate([x[:12] - ref[:12], state[lay.z], state[lay.pending]])


def _K(c, state, part="K"):
    return state[getattr(c.layout, part)].reshape(6, c.n)


def _act(c, u, state, mode=0):
    after = state.copy()
    flags = step.act(c._constants, u, after, c._bounds, mode)
    return flags, after


def _close(a, b):
    np.testing.assert_allclose(a, b, rtol=1e-12, atol=1e-12 * max(1.0, np.abs(b).max()))


def test_act_applies_the_law_integrates_and_records_what_it_did():
    """T = T_ff - K e, z+ = z + h e_x, |z+| in the status, e_bar = e_x, the pending torques
    shifted with the newest T - T_ff first, the governor's hold the reference at rest, and the
    features' sample [e_bar, T_applied] written at the ring's head."""
    c = _controller(delay=2, limit=100.0, window=4)
    lay = c.layout
    u, state = _case(c, 1)
    e = _error(c, u, state)
    flags, after = _act(c, u, state)
    assert flags == 0
    T = u[lay.T_ff] - _K(c, state) @ e
    _close(after[lay.T], T)
    z = state[lay.z] + H * e[:6]
    _close(after[lay.z], z)
    _close(after[lay.status][layout.INTEGRAL_NORM], np.linalg.norm(z))
    _close(after[lay.e_bar], e[:6])
    _close(after[lay.pending], np.concatenate([T - u[lay.T_ff], state[lay.pending][:6]]))
    hold = np.concatenate([u[lay.x_d][:6], np.zeros(12), u[lay.T_ff]])
    np.testing.assert_array_equal(after[lay.hold], hold)
    assert after[lay.status][layout.SATURATED_STEPS] == state[lay.status][layout.SATURATED_STEPS]
    assert after[lay.status][layout.GOVERNED_STEPS] == state[lay.status][layout.GOVERNED_STEPS]
    window, w = after[lay.window], 4
    row = window[layout.WINDOW_ROW * (w - 1) : layout.WINDOW_ROW * w]
    np.testing.assert_array_equal(row, np.concatenate([state[lay.e_bar], u[lay.T_applied]]))
    np.testing.assert_array_equal(window[: layout.WINDOW_ROW * (w - 1)], state[lay.window][:36])
    assert (window[-2], window[-1]) == (w - 1, 0)  # one more row, the head wraps to the first
    for n_valid, head in ((w, 1), (w, 2)):  # full, then a full ring stays full
        flags, after = _act(c, u, after)
        assert (after[lay.window][-2], after[lay.window][-1]) == (n_valid, head)


def test_a_non_finite_sample_is_flagged_and_not_buffered():
    c = _controller(window=3)
    lay = c.layout
    u, state = _case(c, 2)
    u[lay.T_applied.start + 2] = np.nan
    flags, after = _act(c, u, state)
    assert flags == layout.NONFINITE_SAMPLE
    np.testing.assert_array_equal(after[lay.window], state[lay.window])


def _with(c: LqiController, **constants) -> None:
    """Change some of ``c``'s step constants (``layout`` names in lower case), read-only as the
    controller keeps them."""
    c._constants = c._constants.copy()
    for name, value in constants.items():
        c._constants[getattr(layout, name.upper())] = value
    c._constants.setflags(write=False)


@pytest.mark.parametrize("anti_windup", [True, False])
def test_a_command_past_the_limit_is_clipped_and_the_integral_holds(anti_windup):
    """Each motor's command clipped to +-limit (the feedback's share, T - T_ff, goes to the
    pending torques as clipped), counted in the status; with anti-windup z does not move."""
    c = _controller(delay=1, limit=5.0)
    lay = c.layout
    u, state = _case(c, 3)
    e = _error(c, u, state)
    T = u[lay.T_ff] - _K(c, state) @ e
    limit = float(np.median(np.abs(T)))  # three motors clipped, three not
    _with(c, anti_windup=float(anti_windup), torque_limit=limit)
    flags, after = _act(c, u, state)
    _close(after[lay.T], np.clip(T, -limit, limit))
    _close(after[lay.pending], np.clip(T, -limit, limit) - u[lay.T_ff])
    assert (
        after[lay.status][layout.SATURATED_STEPS] == state[lay.status][layout.SATURATED_STEPS] + 1
    )
    z = state[lay.z] if anti_windup else state[lay.z] + H * e[:6]
    _close(after[lay.z], z)
    _close(after[lay.status][layout.INTEGRAL_NORM], np.linalg.norm(z))


def test_a_command_within_or_beyond_all_numbers_is_not_clipped():
    """Within the limit: no clipping, not counted. An infinite command is not clipped either:
    it reaches the guard, which names it."""
    c = _controller(limit=5.0)
    lay = c.layout
    u, state = _case(c, 4)
    flags, after = _act(c, u, state)
    _close(after[lay.T], u[lay.T_ff] - _K(c, state) @ _error(c, u, state))
    assert after[lay.status][layout.SATURATED_STEPS] == state[lay.status][layout.SATURATED_STEPS]
    u[lay.T_ff.start + 1] = np.inf
    flags, after = _act(c, u, state)
    assert after[lay.T][1] == np.inf
    assert after[lay.status][layout.SATURATED_STEPS] == state[lay.status][layout.SATURATED_STEPS]


@pytest.mark.parametrize("transfer", ["integral", "feedback", "none"])
def test_a_gain_change_carries_over_what_its_mode_says(transfer):
    """At a gain change (K_old the gain before): "integral" keeps the integral torque,
    K_I z_new = K_I,old z; "feedback" keeps the whole feedback, K e_new = K_old e; "none" keeps
    z (the torque steps). z_new is then integrated as usual."""
    c = _controller(delay=1, transfer=transfer)
    lay = c.layout
    u, state = _case(c, 5)
    e = _error(c, u, state)
    K, K_old = _K(c, state), _K(c, state, "K_old")
    flags, after = _act(c, u, state, layout.GAIN_CHANGED)
    z_new = after[lay.z] - H * e[:6]  # before this period's integration
    if transfer == "integral":
        _close(K[:, 12:18] @ z_new, K_old[:, 12:18] @ state[lay.z])
        assert np.abs(z_new - state[lay.z]).max() > 1e-3 * np.abs(state[lay.z]).max()
    elif transfer == "feedback":
        _close(after[lay.T], u[lay.T_ff] - K_old @ e)
    else:
        _close(z_new, state[lay.z])
    e_new = e.copy()
    e_new[12:18] = z_new
    _close(after[lay.T], u[lay.T_ff] - K @ e_new)
    flags, unchanged = _act(c, u, state, 0)  # without the flag the gain change is not seen
    _close(unchanged[lay.z], state[lay.z] + H * e[:6])


def test_a_gain_change_while_clipped_carries_z_over_and_holds_it():
    """At a gain change in a clipped period with anti-windup: z is the carried-over z
    (K_I z = K_I,old z_before), not integrated."""
    c = _controller(limit=5.0, transfer="integral")
    lay = c.layout
    u, state = _case(c, 14)
    _with(c, torque_limit=1e-3)  # every command clipped
    flags, after = _act(c, u, state, layout.GAIN_CHANGED)
    assert (
        after[lay.status][layout.SATURATED_STEPS] == state[lay.status][layout.SATURATED_STEPS] + 1
    )
    K, K_old = _K(c, state), _K(c, state, "K_old")
    _close(K[:, 12:18] @ after[lay.z], K_old[:, 12:18] @ state[lay.z])


def test_a_singular_integral_gain_keeps_z():
    """K_I singular: no z carries the integral torque over, so z is kept (a torque step rather
    than no control)."""
    c = _controller(transfer="integral")
    lay = c.layout
    u, state = _case(c, 6)
    K = _K(c, state).copy()
    K[:, 12:18] = 0.0
    state[lay.K] = K.reshape(-1)
    e = _error(c, u, state)
    flags, after = _act(c, u, state, layout.GAIN_CHANGED)
    _close(after[lay.z], state[lay.z] + H * e[:6])


def test_a_governed_period_follows_the_hold():
    """GOVERNED: the reference and its feed-forward are the governor's hold [pose, rate, acc,
    T_ff], which stays, and the period is counted."""
    c = _controller(limit=10.0)
    lay = c.layout
    u, state = _case(c, 7)
    rng = np.random.default_rng(70)
    hold = np.concatenate([u[lay.x_d][:18] + rng.normal(0, 1e-3, 18), rng.normal(0, 0.05, 6)])
    state[lay.hold] = hold
    flags, after = _act(c, u, state, layout.GOVERNED)
    e = _error(c, u, state, ref=hold[:18])
    _close(after[lay.T], hold[18:] - _K(c, state) @ e)
    np.testing.assert_array_equal(after[lay.hold], hold)
    assert after[lay.status][layout.GOVERNED_STEPS] == state[lay.status][layout.GOVERNED_STEPS] + 1


def test_the_friction_feed_forward_adds_coulomb_friction_at_the_reference_s_crank_rates():
    """T_ff + f tanh(theta_dot_d / rate), theta_dot_d = J x_dot_d (J from the estimator's
    inverse Jacobian); the pending torques stay the feedback's share. A singular J_inv: no
    compensation this period."""
    f = 0.02
    plain, comp = _controller(1, estimator=True), _controller(1, estimator=True, friction=f)
    lay = comp.layout
    u, state = _case(comp, 8)
    theta_dot = 0.5 * np.array([-2.0, -0.7, -0.1, 0.05, 0.4, 1.3])  # crank rates, rad/s
    u[lay.x_d][6:12] = state[lay.J_inv].reshape(6, 6) @ theta_dot  # the reference's rate
    expected = f * np.tanh(theta_dot / 0.5)
    _, a = _act(plain, u, state)
    _, b = _act(comp, u, state)
    _close(b[lay.T] - a[lay.T], expected)
    _close(b[lay.pending], a[lay.pending])
    state[lay.J_inv] = 0.0
    _, a = _act(plain, u, state)
    _, b = _act(comp, u, state)
    _close(b[lay.T], a[lay.T])


def test_observe_says_what_is_due_and_step_acts_only_when_nothing_is():
    """A re-solve is due when the schedule period has passed (the counter restarts at 1) or
    the weights on the port changed; the governor when a finite feed-forward exceeds its
    bound (0.9 of the limit); then step leaves the law to Python. Otherwise it acts."""
    c = _controller(limit=1.0)
    lay = c.layout
    bound = 0.9 * 1.0
    u, state = _case(c, 9)
    s = state.copy()
    need, flags = step.step(c._constants, c._legs, u, s, c._bounds)
    assert need == 0 and s[lay.counter][0] == state[lay.counter][0] + 1
    _, acted = _act(c, u, state)
    acted[lay.counter] = s[lay.counter]
    np.testing.assert_array_equal(s, acted)
    for counter, omega, T_ff_0, due in (
        (c.steps_per_schedule - 1, (1.0, 1.0), 0.0, 0),
        (c.steps_per_schedule, (1.0, 1.0), 0.0, layout.NEED_SCHEDULE),
        (1, (2.0, 1.0), 0.0, layout.NEED_SCHEDULE),
        (1, (1.0, 0.5), 0.0, layout.NEED_SCHEDULE),
        (1, (1.0, 1.0), -1.01 * bound, layout.NEED_GOVERNOR),
        (1, (1.0, 1.0), 0.99 * bound, 0),
        (1, (1.0, 1.0), np.inf, 0),  # not finite: for the guard, not the governor
        (1, (1.0, 1.0), np.nan, 0),
        (c.steps_per_schedule, (1.0, 1.0), 2.0, layout.NEED_SCHEDULE | layout.NEED_GOVERNOR),
    ):
        v, s = u.copy(), state.copy()
        s[lay.counter] = counter
        v[lay.omega] = omega
        v[lay.T_ff.start] = T_ff_0
        need, flags = step.step(c._constants, c._legs, v, s, c._bounds)
        assert need == due, (counter, omega, T_ff_0)
        assert s[lay.counter][0] == (1.0 if due & layout.NEED_SCHEDULE else counter + 1)
        if need:
            assert flags == 0 and np.array_equal(s[lay.T], state[lay.T])  # act has not run


def test_without_pose_scheduling_only_the_weights_make_a_re_solve_due():
    c = _controller()
    _with(c, schedule_pose=0.0)
    lay = c.layout
    u, state = _case(c, 10)
    state[lay.counter] = 10 * c.steps_per_schedule
    need, _ = step.step(c._constants, c._legs, u, state, c._bounds)
    assert need == 0


def _estimator_case(seed, zero_errors=None):
    """(estimator, pose x, legs, the encoders' angles at x, the last estimate, J^-1 at x): the
    last estimate a period behind, moving at its rate to within 1e-7; with ``zero_errors`` (6,)
    the encoders read the angles plus them, and the legs' constants say so."""
    est = PoseEstimator(GEOMETRY, H, 2 * np.pi / 2**17)
    rng = np.random.default_rng(seed)
    x = X_HOME + rng.uniform(-1, 1, 6) * [0.1, 0.1, 0.1, 0.01, 0.01, 0.01]
    v = rng.uniform(-1, 1, 6) * [0.3, 0.3, 0.3, 0.05, 0.05, 0.05]
    x_hat = np.concatenate([x - H * v + rng.normal(0, 1e-7, 6), v])
    legs, theta = est.legs, kinematics.ik(GEOMETRY, x)
    if zero_errors is not None:
        legs = est.legs.copy()
        legs[:, 16] = zero_errors
        legs.setflags(write=False)  # as the estimator keeps them
        theta = theta + zero_errors
    return est, x, legs, theta, x_hat, np.linalg.inv(kinematics.jacobian(GEOMETRY, x))


def _estimate(est, legs, theta, x_hat, J_inv):
    out = x_hat.copy()
    ok = step.estimate(legs, est.h, est.alpha, est.chord_step_max, theta, out, J_inv)
    return ok, out


def test_the_chord_step_lands_on_the_pose_and_filters_its_rate():
    """From the last estimate advanced by its rate, one chord step lands within 1e-10 of the
    pose whose angles the encoders read, less their zero errors (any turn of them alike; from
    a start 0.3 mm off it would miss by 1e-8), and the rate is low-passed:
    v+ = v + alpha ((x - x_prev) / h - v)."""
    for seed in range(6):
        zero_errors = None if seed < 3 else np.linspace(-2e-3, 3e-3, 6)
        est, x, legs, theta, x_hat, J_inv = _estimator_case(seed, zero_errors)
        ok, out = _estimate(est, legs, theta, x_hat, J_inv)
        assert ok
        assert np.abs(out[:6] - x).max() < 1e-10
        v = x_hat[6:] + est.alpha * ((out[:6] - x_hat[:6]) / H - x_hat[6:])
        _close(out[6:], v)
        turned = theta + 2 * np.pi * np.array([1, -1, 0, 2, 0, -3])
        ok, again = _estimate(est, legs, turned, x_hat, J_inv)
        assert ok and np.abs(again[:6] - out[:6]).max() < 1e-9


def test_the_chord_step_refuses_a_jump_or_a_correction_that_is_not_finite():
    """A correction larger than the estimator's largest (a jump), or any of them not finite:
    False, x_hat untouched; observe says NEED_NEWTON (with NEED_SCHEDULE when that is due
    too)."""
    est, x, legs, theta, x_hat, J_inv = _estimator_case(11)
    jump = x_hat.copy()
    jump[2] += 5 * est.chord_step_max  # 5 steps away in z
    ok, out = _estimate(est, legs, theta, jump, J_inv)
    assert not ok and np.array_equal(out, jump)
    nan = theta.copy()
    nan[4] = np.nan
    ok, out = _estimate(est, legs, nan, x_hat, J_inv)
    assert not ok and np.array_equal(out, x_hat)
    c = _controller(estimator=True)
    lay = c.layout
    for counter, due in ((3, 0), (c.steps_per_schedule, layout.NEED_SCHEDULE)):
        u, state = _case(c, 12)
        state[lay.counter] = counter
        state[lay.x_hat.start + 2] += 5 * est.chord_step_max
        s = state.copy()
        need, _ = step.step(c._constants, c._legs, u, s, c._bounds)
        assert need == layout.NEED_NEWTON | due
        np.testing.assert_array_equal(s[lay.x_hat], state[lay.x_hat])
    u, state = _case(c, 12)
    need, _ = step.step(c._constants, c._legs, u, state, c._bounds)
    assert need == 0


def test_filter_rate_sets_the_pose_and_low_passes_the_rate():
    rng = np.random.default_rng(13)
    x, x_hat, alpha = rng.normal(size=6), rng.normal(size=12), 0.3
    out = x_hat.copy()
    step.filter_rate(H, alpha, x, out)
    np.testing.assert_array_equal(out[:6], x)
    _close(out[6:], x_hat[6:] + alpha * ((x - x_hat[:6]) / H - x_hat[6:]))
