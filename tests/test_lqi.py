"""LQI: error model, Hautus checks, Riccati gains, re-scheduling."""

import numpy as np
import pytest
from scipy.linalg import expm, solve_discrete_are

from stewart_drake.base.errors import InvalidConfigError, RiccatiSolveError
from stewart_drake.control.lqi.controller import LqiController, LqiDiagram
from stewart_drake.control.lqi.driver import LqiDriver, LqiScales, LqiScalesConfig
from stewart_drake.control.lqi.gain import (
    balance,
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


def test_the_delay_augmented_model_is_the_model_with_its_input_d_periods_late(geometry):
    """e+ = A e + B u with the d pending torques in the state: the error part follows the
    undelayed model driven by u_{k-d} (the pending torques first, newest first, then the new
    ones), and the pending part holds the last d torques, newest first."""
    A0, B0 = error_model(input_matrix(geometry, X_HOME), H)
    rng = np.random.default_rng(0)
    for d in (1, 2, 3):
        A, B = error_model(input_matrix(geometry, X_HOME), H, d)
        assert A.shape == (18 + 6 * d, 18 + 6 * d) and B.shape == (18 + 6 * d, 6)
        e0, pending = rng.normal(size=18), list(rng.normal(size=(d, 6)))  # u_{-1}, ..., u_{-d}
        inputs = rng.normal(size=(5, 6))
        e, x = np.concatenate([e0, *pending]), e0
        acting = pending[::-1] + list(inputs)  # oldest first: the torque each period applies
        for k, u in enumerate(inputs):
            e = A @ e + B @ u
            x = A0 @ x + B0 @ acting[k]
            np.testing.assert_allclose(e[:18], x, rtol=1e-12, atol=1e-15)
            newest = (list(inputs[: k + 1][::-1]) + pending)[:d]
            np.testing.assert_array_equal(e[18:], np.concatenate(newest))


def test_the_error_model_refuses_what_it_cannot_model():
    with pytest.raises(InvalidConfigError, match="B_c"):
        error_model(np.eye(5), H)
    for h in (0.0, -1e-3, 1.5, np.inf):
        with pytest.raises(InvalidConfigError, match="sample time"):
            error_model(np.eye(6), h)
    assert error_model(np.eye(6), 1.0)[0][0, 6] == 1.0  # h = 1 s is the bound, allowed
    for d in (-1, 1.5, True, "1"):
        with pytest.raises(InvalidConfigError, match="delay_periods"):
            error_model(np.eye(6), H, d)
    assert error_model(np.eye(6), H, np.int64(2))[0].shape == (30, 30)


def test_a_pose_whose_inertia_cannot_be_inverted_is_a_singular_pose(geometry, monkeypatch):
    """B_c = M_x^-1 tau: a singular task inertia (or one that gives no finite B_c) is the typed
    error naming B_c and the pose."""
    from stewart_drake.base.errors import SingularPoseError

    x = X_HOME + np.array([0.01, 0, 0, 0, 0, 0.002])
    for inertia in (np.zeros((6, 6)), np.full((6, 6), np.inf)):
        monkeypatch.setattr(statics, "task_inertia", lambda *a, M=inertia: M)
        with pytest.raises(SingularPoseError) as info:
            input_matrix(geometry, x)
        err = info.value
        assert (err.measure, err.value, err.threshold) == ("B_c", np.inf, np.inf)
        np.testing.assert_array_equal(err.pose, x)


def test_the_hautus_test_checks_the_modes_on_or_outside_the_unit_circle_only():
    """(A, B) stabilizable iff rank [lambda I - A, B] = n for every |lambda| >= 1: an
    uncontrollable mode at 0.5 (stable) is fine, one at 1.3 is not; the same for (A, C)
    detectable. A 1-state system is a system too."""
    B, C = np.array([[1.0], [0.0]]), np.array([[1.0, 0.0]])
    stable_hidden = hautus_checks(np.diag([1.0, 0.5]), B, C)
    assert stable_hidden["stabilizable"] and stable_hidden["detectable"]
    assert (stable_hidden["rank_AB"], stable_hidden["rank_AC"], stable_hidden["n"]) == (2, 2, 2)
    unstable_hidden = hautus_checks(np.diag([0.5, 1.3]), B, C)
    assert not unstable_hidden["stabilizable"] and not unstable_hidden["detectable"]
    assert unstable_hidden["rank_AB"] == unstable_hidden["rank_AC"] == 1
    one = hautus_checks([[1.0]], [[1.0]], [[1.0]])
    assert one["stabilizable"] and one["detectable"] and one["n"] == 1


def test_the_hautus_rank_tolerance_is_the_callers():
    """An input of 1e-12 moves the integrator: stabilizable with a rank tolerance below it,
    not with the default 1e-9; the same for an output."""
    A, tiny = np.array([[1.0]]), np.array([[1e-12]])
    assert not hautus_checks(A, tiny, tiny)["stabilizable"]
    assert not hautus_checks(A, tiny, tiny)["detectable"]
    assert hautus_checks(A, tiny, tiny, tol=1e-14)["stabilizable"]
    assert hautus_checks(A, tiny, tiny, tol=1e-14)["detectable"]


def test_the_hautus_test_refuses_what_is_not_a_system():
    A, B, C = np.eye(3), np.ones((3, 1)), np.ones((1, 3))
    for bad in (np.ones((3, 4)), np.ones(3), 1.0):
        with pytest.raises(InvalidConfigError, match="A must be square"):
            hautus_checks(bad, B, C)
    for b, c in ((np.ones((2, 1)), C), (np.ones(3), C), (B, np.ones((1, 2))), (B, np.ones(3))):
        with pytest.raises(InvalidConfigError, match=r"B must be \(3, m\) and C \(p, 3\)"):
            hautus_checks(A, b, c)
    with pytest.raises(InvalidConfigError, match="tol"):
        hautus_checks(A, B, C, tol=-1e-9)


def _random_problem(n, m, seed):
    """A random controllable (A, B) and symmetric positive definite, not diagonal, Q and R."""
    rng = np.random.default_rng(seed)
    A = np.eye(n) + 0.1 * rng.normal(size=(n, n))
    B = rng.normal(size=(n, m))
    M, N = rng.normal(size=(n, n)), rng.normal(size=(m, m))
    Q = M @ M.T + np.diag(rng.uniform(0.1, 10, n))
    R = N @ N.T + np.diag(rng.uniform(0.1, 10, m))
    return A, B, Q, R


def _scipy_gain(A, B, Q, R):
    P = solve_discrete_are(A, B, Q, R)
    return np.linalg.solve(R + B.T @ P @ B, B.T @ P @ A)


@pytest.mark.parametrize("n,m", [(2, 1), (4, 2), (5, 3)])
def test_the_gain_is_scipys_for_any_weights(n, m):
    """Weights not diagonal, a single input: the balanced solve gives scipy's gain, and A - B K
    is stable."""
    A, B, Q, R = _random_problem(n, m, n)
    K = lqi_gain(A, B, Q, R)
    np.testing.assert_allclose(K, _scipy_gain(A, B, Q, R), rtol=1e-9, atol=1e-12)
    assert np.abs(np.linalg.eigvals(A - B @ K)).max() < 1.0


def test_balance_scales_the_problem_to_unit_weight_diagonals():
    """D_x = diag(Q)^-1/2, D_u = diag(R)^-1/2: A~ = D_x^-1 A D_x, B~ = D_x^-1 B D_u,
    Q~ = D_x Q D_x, R~ = D_u R D_u (unit diagonals), whose gain scaled back is the gain; a
    weight matrix with a zero on its diagonal is left unscaled."""
    A, B, Q, R = _random_problem(4, 2, 7)
    Q, R = 0.01 * Q, 0.01 * R  # weights below 1 (the LQI's span 1 to 2.5e9)
    assert np.diag(Q).max() < 1 and np.diag(R).max() < 1
    Ab, Bb, Qb, Rb, d_x, d_u = balance(A, B, Q, R)
    np.testing.assert_allclose(d_x, np.diag(Q) ** -0.5, rtol=1e-15)
    np.testing.assert_allclose(d_u, np.diag(R) ** -0.5, rtol=1e-15)
    Dx, Du = np.diag(d_x), np.diag(d_u)
    for got, want in (
        (Ab, np.linalg.inv(Dx) @ A @ Dx),
        (Bb, np.linalg.inv(Dx) @ B @ Du),
        (Qb, Dx @ Q @ Dx),
        (Rb, Du @ R @ Du),
    ):
        np.testing.assert_allclose(got, want, rtol=1e-13, atol=1e-15)
    np.testing.assert_allclose(np.diag(Qb), 1.0, rtol=1e-14)
    K = Du @ _scipy_gain(Ab, Bb, Qb, Rb) @ np.linalg.inv(Dx)
    np.testing.assert_allclose(K, _scipy_gain(A, B, Q, R), rtol=1e-9)
    Q0, R0 = Q.copy(), R.copy()
    Q0[1, 1] = R0[0, 0] = 0.0
    Ab, Bb, Qb, Rb, d_x, d_u = balance(A, B, Q0, R0)
    np.testing.assert_array_equal(d_x, np.ones(4))
    np.testing.assert_array_equal(d_u, np.ones(2))
    np.testing.assert_array_equal(Qb, Q0)


def test_lqi_gain_refuses_what_it_cannot_solve_and_names_it():
    A, B, Q, R = _random_problem(3, 2, 1)
    for name in ("A", "B", "Q", "R"):
        args = dict(A=A, B=B, Q=Q, R=R)
        args[name] = args[name].copy()
        args[name][0, 0] = np.nan
        with pytest.raises(RiccatiSolveError, match=f"^{name} has non-finite entries"):
            lqi_gain(**args)
    message = r"got \(3, 3\), \(3, 2\), \(3, 3\), \(3, 3\)$"
    with pytest.raises(InvalidConfigError, match=message):
        lqi_gain(A, B, Q, np.eye(3))
    with pytest.raises(InvalidConfigError, match=r"got \(3, 3\), \(3,\), \(3, 3\), \(2, 2\)$"):
        lqi_gain(A, B[:, 0], Q, R)
    with pytest.raises(InvalidConfigError):
        lqi_gain(np.eye(2), B, Q, R)


def test_a_gain_that_cannot_move_a_marginal_mode_is_refused():
    """x+ = x + u with the weight 1e-40 on x: the Riccati gain (about 1e-20) is lost against 1
    in floating point, so A - B K has the eigenvalue 1 exactly: not a stabilizing gain, refused.
    With the weight 1e-20 the gain 1e-10 moves it (1 - 1e-10)."""
    one = np.array([[1.0]])
    with pytest.raises(RiccatiSolveError, match=r"spectral radius 1\)"):
        lqi_gain(one, one, np.array([[1e-40]]), one)
    q = 1e-20
    K = lqi_gain(one, one, np.array([[q]]), one)
    P = (q + np.sqrt(q * q + 4 * q)) / 2  # the scalar Riccati equation's positive root
    np.testing.assert_allclose(K, [[P / (1 + P)]], rtol=1e-7)
    assert 1.0 - K[0, 0] < 1.0
