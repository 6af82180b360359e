"""control/servo: the crank servo's design (the DARE's gain against scipy's own Riccati solver,
the estimator's poles where the design puts them, the loop with its estimator stable by
separation), its compiled step against its Python form and against the law written out here
with the package's batched kinematics, its refusals, and the driver as a scenario's choice."""

import dataclasses
import math

import numpy as np
import pytest
from scipy.linalg import solve_discrete_are

from stewart_drake.base.errors import InvalidConfigError, RiccatiSolveError
from stewart_drake.control.contract import ControllerContext
from stewart_drake.control.servo import design
from stewart_drake.control.servo.controller import SERVO_STATUS_NAMES, CrankServoController
from stewart_drake.control.servo.driver import CrankServoDriver
from stewart_drake.robot import kinematics, statics
from stewart_drake.robot.geometry import X_HOME
from stewart_drake.robot.motor_catalogue import catalogue_motor

# -- the design --------------------------------------------------------------------------------


@pytest.mark.parametrize(
    "h, d, f_c, ratio", [(0.01, 1, 3.0, 10.0), (0.005, 0, 8.0, 3.0), (0.002, 2, 20.0, 5.0)]
)
def test_the_feedback_gain_is_the_lqr_of_the_written_out_model(h, d, f_c, ratio):
    """The gain against scipy's Riccati solver on the model and weights written out here: the
    double integrator's zero-order hold, the integral by the rectangle rule, the pending
    commands shifting in."""
    w = 2 * math.pi * f_c
    n = 3 + d
    A = np.zeros((n, n))
    A[0, :2] = [1.0, h]
    A[1, 1:3] = [1.0, h]
    A[2, 2] = 1.0
    B = np.zeros((n, 1))
    if d == 0:
        B[1:3, 0] = [h * h / 2, h]
    else:
        A[1:3, 3] = [h * h / 2, h]
        for j in range(d - 1):
            A[3 + j, 4 + j] = 1.0
        B[-1, 0] = 1.0
    Q = np.diag([(w / ratio) ** 2, 1.0, 1 / w**2] + [1e-9] * d)
    R = np.array([[1 / w**4]])
    P = solve_discrete_are(A, B, Q, R)
    K = np.linalg.solve(R + B.T @ P @ B, B.T @ P @ A)[0]
    np.testing.assert_allclose(design.feedback_gain(h, d, f_c, ratio), K, rtol=1e-7)
    # and the regulator it gives is stable, its slowest pole near the integral's corner
    poles = np.linalg.eigvals(A - B @ K[None, :])
    assert np.max(np.abs(poles)) < 1.0


def test_the_estimator_poles_are_the_butterworth_pattern_mapped_by_the_period():
    h, f_o = 0.01, 12.0
    L = design.estimator_gain(h, f_o)
    Phi, _ = design.crank_model(h)
    C = np.array([[1.0, 0.0, 0.0]])
    got = np.sort_complex(np.linalg.eigvals(Phi @ (np.eye(3) - np.outer(L, C))))
    w = 2 * math.pi * f_o
    s = w * np.exp(1j * np.pi * np.array([1.0, 2 / 3, 4 / 3]))  # -1, -1/2 +- j sqrt(3)/2
    want = np.sort_complex(np.exp(s * h))
    np.testing.assert_allclose(got, want, atol=1e-9)


def test_ackermanns_gain_is_scipys_pole_placement():
    from scipy.signal import place_poles

    h = 0.005
    Phi, _ = design.crank_model(h)
    poles = np.exp(h * 2 * math.pi * 20.0 * np.array([-1.0, -0.5 + 0.866j, -0.5 - 0.866j]))
    G = design.ackermann_observer(Phi, np.array([1.0, 0.0, 0.0]), poles)
    want = place_poles(Phi.T, np.array([[1.0], [0.0], [0.0]]), poles).gain_matrix[0]
    np.testing.assert_allclose(G, want, rtol=1e-8)


def test_an_unobservable_model_is_refused():
    with pytest.raises(InvalidConfigError, match="does not observe"):
        design.ackermann_observer(np.eye(3), np.array([1.0, 0.0, 0.0]), [0.1, 0.2, 0.3])


def test_the_crank_model_is_the_double_integrators_hold_over_a_period():
    """Phi and Gamma against the matrix exponential of the continuous model."""
    from scipy.linalg import expm

    h = 0.007
    A = np.array([[0, 1, 0], [0, 0, 1], [0, 0, 0]], dtype=float)  # delta as an acceleration
    Bc = np.array([[0.0], [1.0], [0.0]])
    M = np.zeros((4, 4))
    M[:3, :3], M[:3, 3:] = A, Bc
    E = expm(M * h)
    Phi, Gamma = design.crank_model(h)
    np.testing.assert_allclose(Phi, E[:3, :3], atol=1e-15)
    np.testing.assert_allclose(Gamma, E[:3, 3], atol=1e-15)


@pytest.mark.parametrize("d", [0, 1, 3])
def test_the_loop_with_its_estimator_has_the_regulators_and_the_estimators_poles(d):
    """Separation: the closed loop (plant, integral, pending commands, estimator) has the
    eigenvalues of A - B K and of Phi (I - L C), and no others: the closed-loop matrix is
    assembled right."""
    loop = design.design_loop(0.01, d, 3.0, 15.0, 10.0)
    A, B = design.error_model(0.01, d)
    regulator = np.linalg.eigvals(A - B @ loop.K[None, :])
    C = np.array([[1.0, 0.0, 0.0]])
    estimator = np.linalg.eigvals(loop.Phi @ (np.eye(3) - np.outer(loop.L, C)))
    got = np.sort_complex(design.closed_loop_poles(loop))
    want = np.sort_complex(np.concatenate([regulator, estimator]))
    # 2e-5: with d = 3 the pending commands are a triple pole near 0, which rounding splits by
    # about the cube root of the machine epsilon (6e-6)
    np.testing.assert_allclose(got, want, atol=2e-5)
    assert np.max(np.abs(got)) < 1.0


@pytest.mark.parametrize(
    "call, named",
    [
        (lambda: design.feedback_gain(0.01, 1, 20.0, 10.0), "bandwidth_hz"),
        (lambda: design.estimator_gain(0.01, 16.0), "observer_bandwidth_hz"),
        (lambda: design.feedback_gain(0.01, 1, 3.0, 0.0), "integral_ratio"),
        (lambda: design.error_model(0.01, 21), "delay_periods"),
        (lambda: design.feedback_gain(0.01, 1, float("nan"), 10.0), "bandwidth_hz"),
    ],
)
def test_a_design_the_sampling_cannot_carry_is_refused_naming_the_setting(call, named):
    with pytest.raises(InvalidConfigError, match=named):
        call()


def test_a_failed_riccati_solve_is_a_riccati_error(monkeypatch):
    def fail(*args):
        raise RuntimeError("no stabilizing solution")

    monkeypatch.setattr(design, "DiscreteAlgebraicRiccatiEquation", fail)
    with pytest.raises(RiccatiSolveError, match="crank servo"):
        design.feedback_gain(0.01, 1, 3.0, 10.0)


# -- the step ----------------------------------------------------------------------------------


def _controller(geometry, d=1, compiled=True, **kw):
    loop = design.design_loop(0.01, d, 3.0, 15.0, 10.0)
    args = dict(
        offset_s=0.0005,
        lead_s=0.014,
        torque_limit_Nm=3.0,
        friction_Nm=np.full(6, 0.2),
        viscous=0.04,
        friction_max_Nm=1.0,
    )
    args.update(kw)
    return CrankServoController(geometry, loop, compiled=compiled, **args)


def _inputs(geometry, rng):
    x = X_HOME + rng.uniform(-1, 1, 6) * [0.05, 0.05, 0.05, 0.01, 0.01, 0.01]
    x_d = np.concatenate([x, rng.normal(size=6) * 0.02, rng.normal(size=6) * 0.1])
    theta = kinematics.ik(geometry, x) + rng.normal(size=6) * 2e-3
    T_ff = statics.holding_torques(geometry, x)
    return x_d, theta, T_ff


def _update(controller, context, x_d, theta, T_ff):
    controller.GetInputPort("x_d").FixValue(context, x_d)
    controller.GetInputPort("motor_angle").FixValue(context, theta)
    controller.GetInputPort("T_ff").FixValue(context, T_ff)
    update = controller.EvalUniquePeriodicDiscreteUpdate(context)
    context.SetDiscreteState(update)
    return context


@pytest.mark.parametrize("d", [0, 1, 2])
def test_the_compiled_step_is_its_python_form(geometry, d):
    rng = np.random.default_rng(d)
    pair = [_controller(geometry, d, compiled=c) for c in (True, False)]
    contexts = [c.CreateDefaultContext() for c in pair]
    for _ in range(25):
        inputs = _inputs(geometry, rng)
        for c, ctx in zip(pair, contexts):
            _update(c, ctx, *inputs)
    a, b = (ctx.get_discrete_state(0).get_value() for ctx in contexts)
    np.testing.assert_allclose(a, b, rtol=1e-12, atol=1e-14)


KT = np.array([0.7, 0.9, 1.0, 1.1, 1.3, 1.5])


@pytest.mark.parametrize(
    "share, load, kt", [(1.0, 0.0, None), (0.5, 0.0, None), (0.0, 0.0, None), (0.5, 0.29, KT)]
)
def test_one_update_applies_the_law_written_out_with_the_batched_kinematics(
    geometry, share, load, kt
):
    """The torque of a first update from the state at t = 0, computed here with the batched
    IK and Jacobian (not the compiled kernels), the estimator's correction, the gain and the
    friction's smoothed sign: ``share`` of it the way the angle error closes, the rest the
    reference's rate's; the friction ``load`` N m a newton metre of the feed-forward's torque
    over the Coulomb's 0.2 N m, and the whole divided by each servo's torque per command
    ``kt``; and the estimator's prediction for the next period with the command that acts
    then, the one pending (none at t = 0), not the one just computed."""
    rng = np.random.default_rng(7)
    ctrl = _controller(
        geometry,
        d=1,
        torque_limit_Nm=None,
        friction_direction_share=share,
        friction_load_share=load,
        torque_constant_scale=kt,
    )
    context = ctrl.CreateDefaultContext()
    x_d, theta_read, T_ff = _inputs(geometry, rng)
    x0 = X_HOME
    loop = ctrl.loop
    # the state at t = 0: the estimator at home, at rest
    theta0 = kinematics.ik(geometry, x0)
    x_bar = np.column_stack([theta0, np.zeros(6), np.zeros(6)])
    th_d = kinematics.ik(geometry, x_d[:6])
    w_d = kinematics.jacobian(geometry, x_d[:6], th_d) @ x_d[6:12]
    lead = 0.014
    x_l = x_d[:6] + x_d[6:12] * lead + 0.5 * x_d[12:] * lead**2
    v_l = x_d[6:12] + x_d[12:] * lead
    w_l = kinematics.jacobian(geometry, x_l) @ v_l
    # half the cranks read well ahead of their reference the way it turns: the way their error
    # closes is against the reference's rate there, so the two senses part
    ahead = np.array([1.0, 0.0, 1.0, 0.0, 1.0, 0.0]) * 0.03 * np.sign(w_l)
    theta_read = theta_read + (th_d - theta_read) * (ahead != 0) + ahead
    x_hat = x_bar + np.outer(theta_read - theta0, loop.L)
    e_th, e_w = x_hat[:, 0] - th_d, x_hat[:, 1] - w_d
    a = -(loop.K[1] * e_th + loop.K[2] * e_w)  # z = 0 and nothing pending at t = 0
    J = kinematics.jacobian(geometry, X_HOME)
    J_inv = np.linalg.inv(J)
    M = J_inv.T @ statics.task_inertia(geometry, X_HOME) @ J_inv
    k_c = 2 * math.pi * 3.0
    v = w_l - k_c * e_th
    sense = (1 - share) * np.tanh(w_l / 2e-3) + share * np.tanh(v / 2e-3)
    want = (T_ff + (0.2 + load * np.abs(T_ff)) * sense + 0.04 * w_l + M @ a) / (
        np.ones(6) if kt is None else kt
    )
    assert np.max(np.abs(np.tanh(w_l / 2e-3) - np.tanh(v / 2e-3))) > 0.1  # the share shows
    _update(ctrl, context, x_d, theta_read, T_ff)
    T = ctrl.GetOutputPort("T").Eval(context)
    np.testing.assert_allclose(T, want, rtol=1e-9, atol=1e-10)
    # the estimator predicts the next period with the command that acts in it: the pending one,
    # zero at the start (d = 1), not a
    x_bar_next = x_hat @ loop.Phi.T
    state = context.get_discrete_state(0).get_value()
    np.testing.assert_allclose(state[:18].reshape(6, 3), x_bar_next, rtol=1e-9, atol=1e-12)
    # the integral took the rectangle rule's step of the estimated angle error
    np.testing.assert_allclose(ctrl.GetOutputPort("integral").Eval(context), 0.01 * e_th, rtol=1e-9)
    # the pose error is J^-1 of the read error, at the start's inertia schedule
    np.testing.assert_allclose(
        ctrl.GetOutputPort("e_bar").Eval(context), J_inv @ (theta_read - th_d), rtol=1e-9
    )


def test_a_clipped_torque_is_the_limit_and_its_crank_stops_integrating(geometry):
    ctrl = _controller(geometry, d=1, torque_limit_Nm=0.3)
    context = ctrl.CreateDefaultContext()
    x_d = np.concatenate([X_HOME, np.zeros(12)])
    theta = kinematics.ik(geometry, X_HOME)
    theta[0] -= 0.05  # crank 0 far below: its feedback asks for much more than 0.3 N m
    T_ff = statics.holding_torques(geometry, X_HOME)
    _update(ctrl, context, x_d, theta, T_ff)
    T = ctrl.GetOutputPort("T").Eval(context)
    assert T[0] == pytest.approx(0.3, abs=0.0)
    z = ctrl.GetOutputPort("integral").Eval(context)
    assert z[0] == 0.0
    status = dict(zip(SERVO_STATUS_NAMES, ctrl.GetOutputPort("status").Eval(context)))
    assert status["saturated_steps"] == 1


def test_the_friction_error_is_the_weighted_least_squares_fit_of_sign_and_offset():
    """The running fit tau = dF sign(omega) + b, each sample weighted by memory^age, against
    numpy's least squares on the same samples; a steady torque with one sense only is no
    friction (0); a steady torque with both senses is the offset, not dF."""
    from stewart_drake.control.servo.kernels import reference

    rng = np.random.default_rng(5)
    memory, n = 0.99, 300
    omega = np.where(np.sin(np.arange(n) / 30.0) > 0, 0.05, -0.05)
    tau = 0.03 * np.sign(omega) + 0.11 + rng.normal(size=n) * 0.01
    sums = np.zeros(4)
    for w, t in zip(omega, tau):
        got = reference.friction_error(sums, 0, memory, t, w)
    weights = np.sqrt(memory ** np.arange(n)[::-1])
    A = np.column_stack([np.sign(omega), np.ones(n)]) * weights[:, None]
    want = np.linalg.lstsq(A, tau * weights, rcond=None)[0][0]
    assert got == pytest.approx(want, rel=1e-9)
    assert got == pytest.approx(0.03, abs=0.005)
    one_sense = np.zeros(4)
    for _ in range(50):
        assert reference.friction_error(one_sense, 0, memory, 0.2, 0.05) == 0.0


def test_the_friction_believed_moves_by_its_fit_and_stays_bounded(geometry):
    """Along a moving reference each moving crank's friction believed moves by h / tau_F times
    the fitted friction error of its feedback torque (read back from the command: T - T_ff -
    the friction and viscous terms); a crank below the rate keeps it; it never leaves [0,
    friction_max_Nm] nor a factor of 2 of what it started from."""
    from stewart_drake.control.servo.kernels import MEMORY, reference

    ctrl = _controller(geometry, d=0, friction_adaptation_s=0.5, friction_max_Nm=0.25, lead_s=0.0)
    context = ctrl.CreateDefaultContext()
    # X at 10 mm/s: cranks 0, 1, 3, 4 turn at 28 to 33 mrad/s, 2 and 5 at 4.8 (below the rate
    # the estimate adapts above, ten times the smoothed sign's 2 mrad/s)
    v = np.array([0.0, 0.0, 0.0, 0.01, 0.0, 0.0])
    w = kinematics.jacobian(geometry, X_HOME) @ v
    moving = np.abs(w) > 2e-2
    np.testing.assert_array_equal(moving, [True, True, False, True, True, False])
    T_ff = statics.holding_torques(geometry, X_HOME)
    th_d = kinematics.ik(geometry, X_HOME)
    loop = ctrl.loop
    k_c = 2 * math.pi * 3.0
    sums = np.zeros((6, 4))
    for sense in [1.0] * 5 + [-1.0] * 5:  # both senses: the fit separates sign and offset
        F0 = ctrl.friction_estimate(context)
        x_d = np.concatenate([X_HOME, sense * v, np.zeros(6)])
        state = context.get_discrete_state(0).get_value()
        theta = th_d.copy()
        theta[0] -= 1e-3 * sense * np.sign(w[0])  # crank 0 behind its reference
        x_bar = state[:18].reshape(6, 3).copy()
        _update(ctrl, context, x_d, theta, T_ff)
        F1 = ctrl.friction_estimate(context)
        T = ctrl.GetOutputPort("T").Eval(context)
        e_th = x_bar[:, 0] + loop.L[0] * (theta - x_bar[:, 0]) - th_d
        tau_fb = T - T_ff - F0 * np.tanh((sense * w - k_c * e_th) / 2e-3) - 0.04 * sense * w
        for i in np.flatnonzero(moving):
            dF = reference.friction_error(sums[i], 0, ctrl._c[MEMORY], tau_fb[i], sense * w[i])
            assert F1[i] - F0[i] == pytest.approx(0.01 / 0.5 * dF, rel=1e-6, abs=1e-15)
        np.testing.assert_array_equal(F1[~moving], F0[~moving])
    for _ in range(400):
        _update(ctrl, context, np.concatenate([X_HOME, v, np.zeros(6)]), theta, T_ff)
    F = ctrl.friction_estimate(context)
    assert np.all((F >= 0.1) & (F <= 0.25))  # [0.2 / 2, min(2 x 0.2, friction_max_Nm)]


def test_an_unreachable_reference_keeps_the_torque_and_counts_the_failure(geometry):
    ctrl = _controller(geometry, d=1)
    context = ctrl.CreateDefaultContext()
    T0 = ctrl.GetOutputPort("T").Eval(context).copy()
    x_d = np.concatenate([X_HOME + [0, 0, 0, 0, 0, 0.5], np.zeros(12)])
    _update(ctrl, context, x_d, kinematics.ik(geometry, X_HOME), np.zeros(6))
    np.testing.assert_array_equal(ctrl.GetOutputPort("T").Eval(context), T0)
    status = dict(zip(SERVO_STATUS_NAMES, ctrl.GetOutputPort("status").Eval(context)))
    assert status["reference_failures"] == 1


def test_the_start_holds_the_start_pose(geometry):
    x0 = X_HOME + np.array([0.02, 0.0, -0.01, 0.003, 0.0, -0.01])
    ctrl = _controller(geometry, x_initial=x0)
    context = ctrl.CreateDefaultContext()
    np.testing.assert_allclose(
        ctrl.GetOutputPort("T").Eval(context), statics.holding_torques(geometry, x0), rtol=1e-12
    )


@pytest.mark.parametrize(
    "kw, named",
    [
        (dict(offset_s=0.01), "offset_s"),
        (dict(friction_Nm=np.full(6, 2.0)), "friction_Nm"),
        (dict(friction_rate_rad_s=0.0), "friction_rate_rad_s"),
        (dict(torque_limit_Nm=-1.0), "torque_limit_Nm"),
        (dict(disturbance_feedback=2.0), "disturbance_feedback"),
        (dict(friction_load_share=-0.1), "friction_load_share"),
        (dict(friction_load_share=0.95), "friction_load_share"),
        (dict(torque_constant_scale=np.full(6, 0.49)), "torque_constant_scale"),
        (dict(torque_constant_scale=np.full(6, 2.01)), "torque_constant_scale"),
        (dict(torque_constant_scale=np.ones(5)), "torque_constant_scale"),
    ],
)
def test_a_bad_setting_of_the_controller_is_refused_naming_it(geometry, kw, named):
    with pytest.raises(InvalidConfigError, match=named):
        _controller(geometry, **kw)


def test_the_kernels_cache_digest_is_path_kernels_current_source():
    from stewart_drake.control.servo import kernels
    from stewart_drake.robot import path_kernels

    assert path_kernels.source_digest() == kernels.PATH_KERNELS_DIGEST


def test_the_state_layout_holds_every_part_once():
    from stewart_drake.control.servo import kernels

    for d in (0, 1, 4):
        parts = kernels.layout(d)
        sizes = {k: v.stop - v.start for k, v in parts.items() if k != "size"}
        assert sum(sizes.values()) == parts["size"].stop == 18 + 6 + 6 * d + 6 + 24 + 12 + 3
        assert sizes["pending"] == 6 * d and sizes["friction_sums"] == 24


# -- the driver --------------------------------------------------------------------------------


def _context(geometry, servo=None, d=1, limit=None):
    return ControllerContext(
        geometry=geometry,
        period_s=0.01,
        offset_s=0.0005,
        plant_time_step_s=0.001,
        x_initial=X_HOME,
        torque_limit_Nm=limit,
        delay_periods=d,
        servo=servo,
    )


def test_the_driver_believes_the_servos_catalogue_friction_at_its_scale(geometry):
    servo = catalogue_motor("XM430-W350-T").servo
    ctrl = CrankServoDriver(friction_scale=0.5).make(_context(geometry, servo, limit=3.2))
    np.testing.assert_allclose(
        ctrl.friction_estimate(ctrl.CreateDefaultContext()), 0.5 * servo.coulomb_friction_Nm
    )
    # the torque acts over the period after next's start: its middle, 1.5 periods less half a
    # plant step after the sample, less the half step the reference is led by
    from stewart_drake.control.servo import kernels

    assert ctrl._c[kernels.LEAD] == pytest.approx(1.5 * 0.01 - 0.001)
    assert ctrl._c[kernels.VISCOUS] == servo.viscous_damping
    assert ctrl._c[kernels.LIMIT] == 3.2


def test_the_driver_takes_each_servos_commissioning(geometry):
    """Each crank's friction and torque constant as commissioning gave them reach the step as
    given (the friction within its bound, half the limit), the load share as a constant."""
    servo = catalogue_motor("XM430-W350-T").servo
    friction = [0.05, 0.06, 0.07, 0.08, 0.09, 2.0]
    driver = CrankServoDriver(
        friction_Nm=friction, torque_constant_scale=list(KT), friction_load_share=0.29
    )
    ctrl = driver.validate(0.01, 1).make(_context(geometry, servo, limit=3.2))
    np.testing.assert_allclose(
        ctrl.friction_estimate(ctrl.CreateDefaultContext()), [*friction[:5], 0.5 * 3.2]
    )
    np.testing.assert_array_equal(ctrl._kt, KT)
    assert ctrl.constants["load_share"] == 0.29


def test_on_the_ideal_robot_the_driver_believes_no_friction(geometry):
    ctrl = CrankServoDriver().make(_context(geometry, None, d=0))
    np.testing.assert_array_equal(ctrl.friction_estimate(ctrl.CreateDefaultContext()), 0.0)


def test_the_commissionings_edges_are_accepted():
    """A friction of 0 and of 5 N m, torque constants at 0.5 and 2, and load shares of 0 and
    0.9 are each within what the driver takes (the refusals above are just beyond them)."""
    for changes in (
        dict(friction_Nm=[0.0] * 3 + [5.0] * 3, friction_load_share=0.9),
        dict(torque_constant_scale=[0.5] * 3 + [2.0] * 3, friction_load_share=0.0),
    ):
        dataclasses.replace(CrankServoDriver(), **changes).validate(0.01, 1)


def test_robot_says_when_the_crank_servo_has_no_commissioning(capsys):
    """``robot`` names the missing commissioning on the catalogue's figures alone, and on
    nothing else: any one of the three settings given, or another controller, says nothing."""
    from types import SimpleNamespace

    from stewart_drake.control.lqi.driver import LqiDriver
    from stewart_drake.live.command import _note_commissioning

    def said(controller) -> str:
        _note_commissioning(SimpleNamespace(controller=controller))
        return capsys.readouterr().err

    assert not CrankServoDriver().commissioned
    assert "no commissioning" in said(CrankServoDriver())
    assert "servo identify" in said(CrankServoDriver(friction_scale=0.5))
    for changes in (
        dict(friction_Nm=[0.1] * 6),
        dict(torque_constant_scale=[1.0] * 6),
        dict(friction_load_share=0.01),
    ):
        driver = dataclasses.replace(CrankServoDriver(), **changes)
        assert driver.commissioned, changes
        assert said(driver) == "", changes
    assert said(LqiDriver()) == ""


@pytest.mark.parametrize(
    "changes, named",
    [
        (dict(bandwidth_hz=30.0), "controller.bandwidth_hz"),
        (dict(observer_bandwidth_hz=0.0), "controller.observer_bandwidth_hz"),
        (dict(friction_scale=6.0), "controller.friction_scale"),
        (dict(friction_adaptation_s=-1.0), "controller.friction_adaptation_s"),
        (dict(schedule_period_s=0.015), "controller.schedule_period_s"),
        (dict(integral_ratio=float("inf")), "controller.integral_ratio"),
        (dict(friction_load_share=1.0), "controller.friction_load_share"),
        (dict(friction_load_share=-0.01), "controller.friction_load_share"),
        (dict(friction_Nm=[0.1] * 5 + [5.01]), "controller.friction_Nm"),
        (dict(friction_Nm=[0.1] * 5), "controller.friction_Nm"),
        (dict(friction_Nm=[0.1] * 5 + [-0.1]), "controller.friction_Nm"),
        (dict(torque_constant_scale=[1.0] * 5 + [2.5]), "controller.torque_constant_scale"),
        (dict(torque_constant_scale=[1.0] * 7), "controller.torque_constant_scale"),
    ],
)
def test_a_bad_option_of_the_driver_is_refused_naming_it(changes, named):
    driver = dataclasses.replace(CrankServoDriver(), **changes)
    with pytest.raises(InvalidConfigError, match=named.replace(".", r"\.")):
        driver.validate(0.01, 1)


def test_the_scenario_reads_the_driver_by_its_tag(tmp_path):
    from stewart_drake.run.scenario import dump_scenario
    from stewart_drake.run.scenario_io import load_scenario

    scenario = load_scenario("paper_bus", [])
    assert isinstance(scenario.controller, CrankServoDriver)
    assert scenario.feedforward == "inverse_dynamics"
    path = tmp_path / "again.yaml"
    dump_scenario(scenario, path)
    assert "!CrankServoDriver" in path.read_text()
    again = load_scenario(str(path), ["controller.bandwidth_hz=2.5"])
    assert again.controller == dataclasses.replace(scenario.controller, bandwidth_hz=2.5)


@pytest.mark.parametrize("share", [0.0, 0.5, 1.0])
def test_a_crank_at_rest_is_pushed_with_its_share_of_the_friction(geometry, share):
    """At rest (omega_d = 0) a crank behind its reference gets share x F of friction pushed the
    way that closes its error, the rest of the friction term (the reference's sense) being 0:
    the torque with a share, less the one without, is share x F x tanh(-k_c e / r)."""
    x_d = np.concatenate([X_HOME, np.zeros(12)])
    T_ff = statics.holding_torques(geometry, X_HOME)
    theta = kinematics.ik(geometry, X_HOME)
    theta[0] -= 3e-4  # crank 0 behind: e < 0
    torques = {}
    for s in (0.0, share):
        ctrl = _controller(geometry, d=1, friction_direction_share=s, torque_limit_Nm=None)
        context = _update(ctrl, ctrl.CreateDefaultContext(), x_d, theta, T_ff)
        torques[s] = ctrl.GetOutputPort("T").Eval(context)
    e = ctrl.loop.L[0] * (theta[0] - kinematics.ik(geometry, X_HOME)[0])  # the estimate's error
    push = share * 0.2 * np.tanh(-2 * np.pi * 3.0 * e / 2e-3)
    assert torques[share][0] - torques[0.0][0] == pytest.approx(push, rel=1e-9, abs=1e-15)
    if share:
        assert push > 0.9 * share * 0.2  # the push is saturated: the share of F, no more


def test_the_settings_are_what_the_step_runs_with(geometry):
    """The defaults and given settings read back as the step's constants, each worked out here
    from the docstring's meaning (the friction held when tau_F = 0; the estimate's bounds a
    factor of 2 either side of a friction given, within friction_max_Nm)."""
    loop = design.design_loop(0.01, 1, 3.0, 15.0, 10.0)
    ctrl = CrankServoController(geometry, loop)
    c = ctrl.constants
    assert ctrl.status_names == SERVO_STATUS_NAMES and len(SERVO_STATUS_NAMES) == 4
    assert ctrl.steps_per_schedule == 10  # 0.1 s at 10 ms
    expected = {
        "h": 0.01, "lead": 0.0, "friction_rate": 2e-3, "k_c": 2 * math.pi * 3.0,
        "adapt": 1 / 2.0, "adapt_min_rate": 10 * 2e-3, "friction_min": 0.0,
        "friction_max": 1.0, "viscous": 0.0, "limit": math.inf, "delay": 1.0, "dob": 0.0,
        "memory": math.exp(-0.01 / 4.0), "share": 1.0, "load_share": 0.0,
    }  # fmt: skip
    assert c == pytest.approx(expected, rel=1e-12)
    given = CrankServoController(
        geometry,
        loop,
        offset_s=0.0099,
        lead_s=1.0,
        friction_direction_hz=5.0,
        friction_adaptation_s=0.0,
        friction_Nm=np.full(6, 0.2),
        friction_max_Nm=0.3,
        viscous=0.04,
        torque_limit_Nm=2.5,
        friction_direction_share=0.25,
        disturbance_feedback=1.0,
        schedule_period_s=0.026,
        friction_load_share=0.29,
    )
    c = given.constants
    assert c["load_share"] == 0.29
    assert given.steps_per_schedule == 3  # 26 ms rounds to 3 periods
    assert (c["lead"], c["k_c"], c["adapt"], c["viscous"]) == pytest.approx(
        (1.0, 2 * math.pi * 5.0, 0.0, 0.04)
    )
    assert (c["friction_min"], c["friction_max"]) == pytest.approx(
        (0.1, 0.3)
    )  # 0.2 / 2, min(0.3, 0.4)
    assert (c["limit"], c["share"], c["dob"]) == (2.5, 0.25, 1.0)


@pytest.mark.parametrize(
    "name, good, bad",
    [
        ("offset_s", 0.0, -1e-9),
        ("offset_s", 0.01 - 1e-9, 0.01),
        ("lead_s", 0.0, -1e-9),
        ("lead_s", 1.0, 1.0 + 1e-9),
        ("friction_rate_rad_s", 1e-9, 0.0),
        ("friction_direction_hz", 0.0, -1e-9),
        ("friction_adaptation_s", 0.0, -1e-9),
        ("friction_max_Nm", 0.0, -1e-9),
        ("viscous", 0.0, -1e-9),
        ("torque_limit_Nm", 1e-9, 0.0),
        ("friction_direction_share", 0.0, -1e-9),
        ("friction_direction_share", 1.0, 1.0 + 1e-9),
        ("disturbance_feedback", 0.0, -1e-9),
        ("disturbance_feedback", 1.0, 1.0 + 1e-9),
        ("schedule_period_s", 1e-9, 0.0),
    ],
)
def test_each_setting_is_taken_at_its_bound_and_refused_past_it_by_name(geometry, name, good, bad):
    loop = design.design_loop(0.01, 1, 3.0, 15.0, 10.0)
    CrankServoController(geometry, loop, **{name: good})
    with pytest.raises(InvalidConfigError, match=f"^{name} must be"):
        CrankServoController(geometry, loop, **{name: bad})


def test_the_driver_passes_each_option_to_the_controller(geometry):
    """Every option of the driver read back from the controller it makes: the loop designed for
    the context's period and delay at its bandwidths, the friction's settings, the bound of the
    friction believed (half the lesser of the servo's peak and the torque limit), the torque
    limit, the sample's offset."""
    servo = catalogue_motor("XM430-W350-T").servo
    driver = CrankServoDriver(
        bandwidth_hz=2.5,
        observer_bandwidth_hz=12.0,
        integral_ratio=4.0,
        friction_scale=2.0,
        friction_rate_rad_s=3e-3,
        friction_adaptation_s=1.5,
        disturbance_feedback=0.5,
        schedule_period_s=0.05,
        friction_direction_hz=2.0,
        friction_direction_share=0.5,
    )
    ctrl = driver.make(_context(geometry, servo, d=2, limit=servo.peak_torque_Nm + 1.0))
    loop = design.design_loop(0.01, 2, 2.5, 12.0, 4.0)
    np.testing.assert_array_equal(ctrl.loop.K, loop.K)
    np.testing.assert_array_equal(ctrl.loop.L, loop.L)
    c = ctrl.constants
    bound = 0.5 * servo.peak_torque_Nm  # the peak is the lesser
    assert c["friction_max"] == pytest.approx(min(bound, 2.0 * 2.0 * servo.coulomb_friction_Nm))
    believed = min(2.0 * servo.coulomb_friction_Nm, bound)
    np.testing.assert_allclose(ctrl.friction_estimate(ctrl.CreateDefaultContext()), believed)
    assert c["lead"] == pytest.approx(2.5 * 0.01 - 0.001)
    assert (c["friction_rate"], c["adapt"], c["dob"]) == pytest.approx((3e-3, 1 / 1.5, 0.5))
    assert (c["k_c"], c["share"], c["delay"]) == pytest.approx((2 * math.pi * 2.0, 0.5, 2.0))
    assert c["limit"] == servo.peak_torque_Nm + 1.0 and ctrl.steps_per_schedule == 5
    assert driver.summary() == {
        "bandwidth_hz": 2.5,
        "observer_bandwidth_hz": 12.0,
        "friction_scale": 2.0,
    }
    # without a delay the torque acts over the next period: its middle, half a period on
    assert CrankServoDriver().make(_context(geometry, servo, d=0)).constants["lead"] == 0.005


@pytest.mark.parametrize(
    "name, good, bad",
    [
        ("bandwidth_hz", 1e-6, 0.0),
        ("observer_bandwidth_hz", 1e-6, 0.0),
        ("integral_ratio", 1e-6, 0.0),
        ("friction_scale", 0.0, -1e-9),
        ("friction_scale", 5.0, 5.0 + 1e-9),
        ("friction_rate_rad_s", 10.0, 10.0 + 1e-9),
        ("friction_rate_rad_s", 1e-9, 0.0),
        ("friction_direction_hz", 0.0, -1e-9),
        ("friction_direction_hz", 1e3, 1e3 + 1e-6),
        ("friction_direction_share", 0.0, -1e-9),
        ("friction_direction_share", 1.0, 1.0 + 1e-9),
        ("friction_adaptation_s", 1e4, 1e4 + 1e-6),
        ("disturbance_feedback", 1.0, 1.0 + 1e-9),
        ("disturbance_feedback", 0.0, -1e-9),
    ],
)
def test_each_option_of_the_driver_is_taken_at_its_bound_and_refused_past_it(name, good, bad):
    """Each bound of :meth:`CrankServoDriver.validate`, at the bound (taken: the design then
    refuses a bandwidth the sampling cannot carry on its own terms, so those take a value
    well within) and just past it (refused, named with the prefix)."""
    if name.endswith("_hz") and name != "friction_direction_hz":
        good = 1.0  # the design's own limit is tested apart
    dataclasses.replace(CrankServoDriver(), **{name: good}).validate(0.01, 1)
    driver = dataclasses.replace(CrankServoDriver(), **{name: bad})
    with pytest.raises(InvalidConfigError, match=rf"^ctl\.{name} must be"):
        driver.validate(0.01, 1, prefix="ctl.")


def test_a_delay_the_servo_cannot_carry_is_refused_and_a_design_error_is_prefixed():
    from stewart_drake.control.servo.driver import MAX_DELAY_PERIODS

    CrankServoDriver().validate(0.01, MAX_DELAY_PERIODS)
    with pytest.raises(InvalidConfigError, match=f"of {MAX_DELAY_PERIODS + 1} periods is more"):
        CrankServoDriver().validate(0.01, MAX_DELAY_PERIODS + 1)
    with pytest.raises(InvalidConfigError, match=r"^ctl\.\S"):
        CrankServoDriver(bandwidth_hz=30.0).validate(0.01, 1, prefix="ctl.")


def test_the_warm_up_passes_each_kernel_the_types_the_controller_and_the_streamer_pass(
    geometry, monkeypatch
):
    """numba compiles one version of a kernel per argument types (read-only or not, the
    dimensions, the scalars' kinds), so the warm-up must pass each kernel what the running loop
    passes, or a control period compiles one with the torque on. The types (``numba.typeof``)
    of each kernel's arguments are recorded from :func:`kernels.warm_up`, then from a
    controller's updates (to its first inertia re-schedule) and a goal streamer's first goals,
    and are equal kernel by kernel."""
    import numba

    from stewart_drake.control.servo import goal_stream, kernels
    from stewart_drake.control.servo.goal_stream import CrankGoalStreamer
    from stewart_drake.robot import path_kernels

    phase, calls = ["warm_up"], {}

    def recording(name, fn):
        def record(*args):
            calls.setdefault((phase[0], name), tuple(str(numba.typeof(a)) for a in args))
            return fn(*args)

        return record

    for module, name in (
        (kernels, "step"),
        (kernels, "crank_reference"),
        (goal_stream, "crank_reference"),
        (path_kernels, "joint_inertia"),
    ):
        monkeypatch.setattr(module, name, recording(name, getattr(module, name)))
    kernels.warm_up()
    phase[0] = "run"
    controller = _controller(geometry)
    context = controller.CreateDefaultContext()
    rng = np.random.default_rng(3)
    for _ in range(controller.steps_per_schedule + 1):
        _update(controller, context, *_inputs(geometry, rng))
    CrankGoalStreamer(geometry, 0.01, 0.0005, 0.014, X_HOME)
    names = ("step", "crank_reference", "joint_inertia")
    assert sorted(calls) == sorted((p, n) for p in ("warm_up", "run") for n in names)
    for name in names:
        assert calls["warm_up", name] == calls["run", name], name
    assert calls["run", "step"][0] == "readonly array(float64, 1d, C)"  # the constants


@pytest.mark.parametrize("d", [1, 2])
def test_six_periods_apply_the_law_written_out_with_encoder_zero_errors(geometry, d):
    """Six periods of the law written out here (vectorised, with the batched kinematics) on a
    calibrated robot whose encoders read each crank plus its zero error (up to 5 mrad), with
    the disturbance estimate fed back (0.3): from the second period on the integral, the
    pending commands (one or two) and the estimator's prediction all enter the torque, so each
    is held to its own term, period by period; the pose error is J^-1 of the corrected reading's
    error. The robot's readings subtract the zero errors: adding them instead leaves the
    platform 2 x 5 mrad off at rest."""
    offsets = np.array([5e-3, -4e-3, 3e-3, -5e-3, 2e-3, -1e-3])
    robot = dataclasses.replace(geometry, encoder_offsets_rad=tuple(offsets))
    ctrl = _controller(
        robot, d=d, torque_limit_Nm=None, friction_adaptation_s=0.0, disturbance_feedback=0.3,
        friction_direction_share=0.5,
    )  # fmt: skip
    context = ctrl.CreateDefaultContext()
    loop, h, lead, k_c, rate = ctrl.loop, 0.01, 0.014, 2 * math.pi * 3.0, 2e-3
    J_inv = np.linalg.inv(kinematics.jacobian(geometry, X_HOME))
    M = J_inv.T @ statics.task_inertia(geometry, X_HOME) @ J_inv
    x_bar = np.column_stack([kinematics.ik(geometry, X_HOME), np.zeros((6, 2))])
    z, pending = np.zeros(6), np.zeros((6, d))
    rng = np.random.default_rng(11)
    for period in range(6):
        x_d, theta, T_ff = _inputs(geometry, rng)
        reading = theta + offsets
        th_d = kinematics.ik(geometry, x_d[:6])
        w_d = kinematics.jacobian(geometry, x_d[:6], th_d) @ x_d[6:12]
        x_l = x_d[:6] + x_d[6:12] * lead + 0.5 * x_d[12:] * lead**2
        w_l = kinematics.jacobian(geometry, x_l) @ (x_d[6:12] + x_d[12:] * lead)
        x_hat = x_bar + np.outer(theta - x_bar[:, 0], loop.L)
        e_th, e_w = x_hat[:, 0] - th_d, x_hat[:, 1] - w_d
        a = -(loop.K[0] * z + loop.K[1] * e_th + loop.K[2] * e_w + pending @ loop.K[3:])
        acc = a - 0.3 * x_hat[:, 2]
        sense = 0.5 * np.tanh(w_l / rate) + 0.5 * np.tanh((w_l - k_c * e_th) / rate)
        want = T_ff + 0.2 * sense + 0.04 * w_l + M @ acc
        _update(ctrl, context, x_d, reading, T_ff)
        np.testing.assert_allclose(
            ctrl.GetOutputPort("T").Eval(context), want, rtol=1e-9, atol=1e-9
        )
        z = z + h * e_th
        x_bar = x_hat @ loop.Phi.T + np.outer(pending[:, 0], loop.Gamma)
        pending = np.column_stack([pending[:, 1:], acc])
        state = context.get_discrete_state(0).get_value()
        np.testing.assert_allclose(state[:18].reshape(6, 3), x_bar, rtol=1e-9, atol=1e-12)
        np.testing.assert_allclose(ctrl.GetOutputPort("integral").Eval(context), z, atol=1e-14)
        np.testing.assert_allclose(
            ctrl.GetOutputPort("e_bar").Eval(context), J_inv @ (theta - th_d), rtol=1e-9, atol=1e-14
        )
        if period >= d:  # the commands now pending were computed here
            assert np.max(np.abs(pending)) > 1.0
    assert np.max(np.abs(z)) > 1e-4 and np.max(np.abs(x_bar[:, 2])) > 1.0


def test_the_inertia_is_rescheduled_every_schedule_period(geometry):
    """steps_per_schedule 10 (0.1 s at 10 ms): re-scheduled at the 11th and the 21st update,
    not before (the status's last figure counts them)."""
    ctrl = _controller(geometry, torque_limit_Nm=None)
    assert ctrl.steps_per_schedule == 10
    context = ctrl.CreateDefaultContext()
    rng = np.random.default_rng(5)
    counts = []
    for _ in range(21):
        _update(ctrl, context, *_inputs(geometry, rng))
        counts.append(ctrl.GetOutputPort("status").Eval(context)[3])
    assert counts == [0.0] * 10 + [1.0] * 10 + [2.0]
