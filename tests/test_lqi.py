"""LQI: error model, Hautus checks, Riccati gains, re-scheduling."""

import numpy as np
import pytest
from scipy.linalg import expm, solve_discrete_are

from stewart_drake.base.errors import InvalidConfigError, RiccatiSolveError
from stewart_drake.control.lqi.controller import LqiController, LqiDiagram
from stewart_drake.control.lqi.driver import LqiDriver, LqiScales, LqiScalesConfig
from stewart_drake.control.lqi.gain import (
    error_model,
    hautus_checks,
    input_matrix,
    lqi_gain,
    project_onto_torque_bound,
)
from stewart_drake.robot import statics
from stewart_drake.robot.geometry import X_HOME, StewartGeometry

H = 1e-3


def test_closed_form_zoh_equals_matrix_exponential(geometry):
    """The double-integrator ZOH in closed form agrees with expm of the continuous model."""
    B_c = input_matrix(geometry, X_HOME)
    A, B = error_model(B_c, H)
    Ac = np.zeros((12, 12))
    Ac[:6, 6:] = np.eye(6)
    Bc = np.vstack([np.zeros((6, 6)), B_c])
    big = np.zeros((18, 18))
    big[:12, :12], big[:12, 12:] = Ac, Bc
    Phi = expm(big * H)
    np.testing.assert_allclose(A[:12, :12], Phi[:12, :12], atol=1e-14)
    np.testing.assert_allclose(B[:12], Phi[:12, 12:], rtol=1e-12, atol=1e-16)
    np.testing.assert_allclose(A[12:, :6], H * np.eye(6))  # the controller's integrator


def test_input_matrix_is_inverse_inertia_times_tau(geometry, random_poses):
    from stewart_drake.robot import kinematics

    for x in random_poses[:5]:
        B_c = input_matrix(geometry, x)
        np.testing.assert_allclose(
            statics.task_inertia(geometry, x) @ B_c, kinematics.tau(geometry, x), atol=1e-10
        )


def test_hautus_checks_pass_and_detect_a_missing_input(geometry):
    A, B = error_model(input_matrix(geometry, X_HOME), H)
    C = np.eye(18)
    assert hautus_checks(A, B, C)["stabilizable"]
    assert hautus_checks(A, B, C)["detectable"]
    B_bad = B.copy()
    B_bad[:, 5] = 0
    B_bad[:, 4] = 0  # two motors off: rank drops, (A, B) not stabilizable
    assert not hautus_checks(A, B_bad, C)["stabilizable"]
    C_bad = np.zeros((6, 18))
    C_bad[:, 6:12] = np.eye(6)  # rates only: the pose integral modes are not detectable
    assert not hautus_checks(A, B, C_bad)["detectable"]


def test_gain_matches_scipy_riccati(geometry):
    c = LqiController(geometry, LqiDriver())
    A, B = error_model(input_matrix(geometry, X_HOME), H)
    Q, R = 3.0 * c.scales.Q_unit(), 0.5 * c.scales.R_unit()
    P = solve_discrete_are(A, B, Q, R)
    K_ref = np.linalg.solve(R + B.T @ P @ B, B.T @ P @ A)
    np.testing.assert_allclose(c.gain(X_HOME, 3.0, 0.5), K_ref, rtol=1e-6, atol=1e-6)


def test_only_the_weight_ratio_matters(geometry):
    """LQR gains are invariant to scaling Q and R together: the 9 paper pairs give 5 gains."""
    c = LqiController(geometry, LqiDriver())
    np.testing.assert_allclose(c.gain(X_HOME, 0.1, 0.1), c.gain(X_HOME, 10, 10), rtol=1e-6)
    assert not np.allclose(c.gain(X_HOME, 1, 0.1), c.gain(X_HOME, 0.1, 1), rtol=1e-3)


@pytest.mark.parametrize("omega_Q,omega_R", [(q, r) for q in (0.1, 1, 10) for r in (0.1, 1, 10)])
def test_every_paper_weight_pair_stabilizes_the_model(geometry, omega_Q, omega_R):
    c = LqiController(geometry, LqiDriver())
    A, B = error_model(input_matrix(geometry, X_HOME), H)
    K = c.gain(X_HOME, omega_Q, omega_R)
    rho = np.abs(np.linalg.eigvals(A - B @ K)).max()
    assert rho < 0.999


def test_stiffer_weights_give_larger_position_gains(geometry):
    c = LqiController(geometry, LqiDriver())
    soft, stiff = c.gain(X_HOME, 0.1, 10), c.gain(X_HOME, 10, 0.1)
    assert np.linalg.norm(stiff[:, :6]) > 5 * np.linalg.norm(soft[:, :6])


def test_failed_riccati_raises_typed_error(geometry):
    A, B = error_model(input_matrix(geometry, X_HOME), H)
    with pytest.raises(RiccatiSolveError):
        lqi_gain(A, np.zeros_like(B), np.eye(18), np.eye(6))


def test_bad_settings_are_refused(geometry):
    with pytest.raises(InvalidConfigError, match="multiple"):
        LqiController(geometry, LqiDriver(schedule_period_s=2.5e-3), period_s=1e-3)
    with pytest.raises(InvalidConfigError, match="driver.riccati must be one of"):
        LqiController(geometry, LqiDriver(riccati="magic"))
    with pytest.raises(InvalidConfigError, match="omega_Q"):
        LqiController(geometry, LqiDriver()).gain(X_HOME, 0.0, 1.0)
    with pytest.raises(InvalidConfigError):
        LqiScales(torque=-1)


def _switch(mode):
    """A constant 1 mrad / 1 mm error held 50 ms at ratio 10, then the weights drop to ratio 0.01:
    (z, K, T) just before the switch and (z, K, T) at the switch's update."""
    from pydrake.systems.analysis import Simulator

    geometry = StewartGeometry()
    controller = LqiDiagram(
        geometry, LqiDriver(schedule_period_s=1e-2, gain_transfer=mode), period_s=H
    )
    simulator = Simulator(controller)
    context = simulator.get_mutable_context()
    x = X_HOME + np.array([1e-3, 0, 0, 0, 0, 1e-3])
    controller.get_x_input_port().FixValue(context, np.concatenate([x, np.zeros(6)]))
    controller.get_x_d_input_port().FixValue(context, np.concatenate([X_HOME, np.zeros(12)]))
    controller.get_T_ff_input_port().FixValue(context, statics.holding_torques(geometry, X_HOME))
    controller.get_omega_input_port().FixValue(context, [10.0, 1.0])

    def read():
        z = controller.GetOutputPort("integral").Eval(context).copy()
        T = controller.GetOutputPort("T").Eval(context).copy()
        return z, controller.gain_in_use(context).copy(), T

    simulator.AdvanceTo(0.0505)
    before = read()
    controller.get_omega_input_port().FixValue(context, [0.1, 10.0])
    simulator.AdvanceTo(0.0515)
    return before, read(), x - X_HOME


@pytest.mark.parametrize("mode", ["integral", "feedback", "none"])
def test_a_gain_switch_carries_over_what_its_mode_says(mode):
    (z0, K0, T0), (z1, K1, T1), e = _switch(mode)
    assert np.abs(K1[:, :6]).max() < 0.2 * np.abs(K0[:, :6]).max()  # a real switch
    z_before_update = z1 - H * e  # this step's integration
    if mode == "integral":  # the integral torque is kept, z rescaled
        np.testing.assert_allclose(
            K1[:, 12:18] @ z_before_update, K0[:, 12:18] @ z0, rtol=1e-9, atol=1e-12
        )
        assert np.abs(z_before_update - z0).max() > 0.5 * np.abs(z0).max()
    elif mode == "feedback":  # no torque step: only this step's integration moves T
        assert (
            np.abs(T1 - T0).max()
            < 0.02 * np.abs(T0 - statics.holding_torques(StewartGeometry(), X_HOME)).max()
        )
    else:  # the paper: z kept, the torque steps
        np.testing.assert_allclose(z_before_update, z0, rtol=1e-12, atol=1e-15)
        assert (
            np.abs(T1 - T0).max()
            > 0.1 * np.abs(T0 - statics.holding_torques(StewartGeometry(), X_HOME)).max()
        )


def test_an_unknown_gain_transfer_is_refused():
    with pytest.raises(InvalidConfigError, match="gain_transfer must be one of"):
        LqiController(StewartGeometry(), LqiDriver(gain_transfer="smooth"))


def test_a_model_that_fails_the_hautus_test_at_home_is_a_typed_error():
    """An integral scale of 1e100 leaves the integral modes out of the cost: not detectable
    (eq. 29), refused with the typed error, which names the pose and pickles."""
    import pickle

    from stewart_drake.base.errors import NotStabilizableError

    with pytest.raises(NotStabilizableError, match=r"not detectable .* LqiScales") as info:
        LqiController(StewartGeometry(), LqiDriver(scales=LqiScalesConfig(integral=[1e100] * 6)))
    err = info.value
    assert err.detectable is False and err.stabilizable is True and err.rank_AC < err.n == 18
    assert err.pose == pytest.approx(list(X_HOME))
    assert str(pickle.loads(pickle.dumps(err))) == str(err)


def test_the_governor_projection_is_the_nearest_point_within_the_bound():
    """Independent agreement: the active-set projection equals SciPy's SLSQP on the same QP
    (min |s - d| s.t. |T + G s| <= bound) on random instances, 0 to 3 motors active."""
    from scipy.optimize import minimize

    rng = np.random.default_rng(3)
    actives = set()
    for _ in range(40):
        G = rng.normal(size=(6, 6)) + 3 * np.eye(6)
        T, d, bound = rng.uniform(0.2, 0.3, 6), rng.normal(scale=0.02, size=6), 0.315
        s, C = project_onto_torque_bound(d, T, G, bound)
        # Each lambda is used by this iteration's minimize only: bound the values it reads.
        below = {
            "type": "ineq",
            "fun": lambda v, T=T, G=G, b=bound: b - (T + G @ v),
            "jac": lambda v, G=G: -G,
        }
        above = {
            "type": "ineq",
            "fun": lambda v, T=T, G=G, b=bound: b + (T + G @ v),
            "jac": lambda v, G=G: G,
        }
        ref = minimize(
            lambda v, d=d: 0.5 * np.sum((v - d) ** 2),
            np.zeros(6),
            jac=lambda v, d=d: v - d,
            method="SLSQP",
            constraints=[below, above],
            options={"ftol": 1e-14, "maxiter": 200},
        )
        assert ref.success
        np.testing.assert_allclose(s, ref.x, atol=1e-7)
        assert np.abs(T + G @ s).max() <= bound * (1 + 1e-9)
        # C: the rows of the motors at the bound, with the side each is on (its null space is
        # the tangent the governor moves the reference's rate along); none when none is.
        at = np.abs(np.abs(T + G @ s) - bound) < 1e-9 * bound
        np.testing.assert_array_equal(C, np.sign(T + G @ s)[at, None] * G[at])
        actives.add(len(C))
    assert {0, 1, 2, 3} <= actives  # the bound binds, on several motors, or not at all
