"""The fast paths agree with the slow ones: warm Riccati vs cold DARE, precomputed
reference and feed-forward vs evaluating them on the spot."""

import numpy as np
from pydrake.systems.framework import DiagramBuilder

from stewart_drake.control.lqi.controller import LqiController
from stewart_drake.control.lqi.driver import LqiDriver, LqiScales
from stewart_drake.control.lqi.gain import STEIN_TOL, error_model, input_matrix, lqi_gain
from stewart_drake.references.trajectories import paper_manoeuvre
from stewart_drake.robot import kinematics, statics
from stewart_drake.robot.geometry import X_HOME
from stewart_drake.robot.statics import feedforward_torques
from stewart_drake.run.reference import add_reference_sources

H = 1e-3


def _rel(K, K_ref):
    return np.abs(K - K_ref).max() / np.abs(K_ref).max()


def _warm(A, B, Q, R, K_start):
    """(K, iterations): the warm re-solve as the controller runs it ("warm": Newton's method
    from K_start to a relative step of 1e-4, 8 iterations at most), compiled
    (:func:`~stewart_drake.control.lqi.reschedule.newton_gain`); iterations < 0 where it gives
    up and the controller solves cold."""
    from stewart_drake.control.lqi.reschedule import newton_gain

    arrays = (np.ascontiguousarray(M, dtype=float) for M in (A, B, Q, R, K_start))
    return newton_gain(*arrays, 1e-4, 8, STEIN_TOL)


def test_warm_gain_equals_cold_solve_along_the_paper_manoeuvre(geometry):
    """Re-scheduled every 10 ms along 2 s of eqs. 37-38, Newton from the last gain gives the
    cold DARE's gain to 1e-8 relative, in at most 3 Stein solves per re-schedule."""
    scales = LqiScales()
    Q, R = scales.Q_unit(), scales.R_unit()
    x = paper_manoeuvre().evaluate(np.arange(0.0, 2.0, 0.01))[0]
    A, B = error_model(input_matrix(geometry, x[0]), H)
    K = lqi_gain(A, B, Q, R)
    worst, iterations = 0.0, []
    for pose in x[1:]:
        A, B = error_model(input_matrix(geometry, pose), H)
        K, n = _warm(A, B, Q, R, K)
        assert n > 0
        worst = max(worst, _rel(K, lqi_gain(A, B, Q, R)))
        iterations.append(n)
    assert worst < 1e-8
    assert max(iterations) <= 3


def test_warm_gain_follows_a_change_of_weights(geometry):
    """The ANN tuner changes omega every 20 ms: Newton from the old weights' gain converges to
    the new weights' gain (a 10x jump of omega_Q / omega_R included)."""
    scales = LqiScales()
    A, B = error_model(input_matrix(geometry, X_HOME), H)
    K_old = lqi_gain(A, B, scales.Q_unit(), scales.R_unit())
    for q, r in ((2.0, 0.5), (10.0, 1.0), (0.1, 1.0)):
        Q, R = q * scales.Q_unit(), r * scales.R_unit()
        K, n = _warm(A, B, Q, R, K_old)
        assert n > 0 and _rel(K, lqi_gain(A, B, Q, R)) < 1e-8


def test_warm_gain_refuses_a_start_that_does_not_stabilize(geometry):
    scales = LqiScales()
    A, B = error_model(input_matrix(geometry, X_HOME), H)
    # No gain: the Stein series of the double integrators diverges (-1); the controller solves
    # cold.
    assert _warm(A, B, scales.Q_unit(), scales.R_unit(), np.zeros((6, 18)))[1] == -1
    assert _warm(A, B, scales.Q_unit(), scales.R_unit(), np.full((6, 18), np.nan))[1] < 0


def test_controller_falls_back_to_the_cold_solve(geometry):
    c = LqiController(geometry, LqiDriver())
    K = c.gain(X_HOME, 1.0, 1.0, K_start=np.zeros((6, 18)))  # warm start refused
    assert c.solve_stats["cold"] == 1 and c.solve_stats["warm"] == 0
    np.testing.assert_allclose(K, c.K_initial, rtol=1e-9, atol=1e-12)


def test_precomputed_reference_is_read_at_the_right_step(geometry):
    """Sampled mid-interval at t_k = k h + h/2, the sources give x_d(t_k + lead) and the gravity
    feed-forward at that pose, exactly (no neighbour's value at any k)."""
    from pydrake.systems.framework import Diagram  # noqa: F401  (pydrake import order)

    builder = DiagramBuilder()
    traj = paper_manoeuvre()
    src = add_reference_sources(
        builder, traj, geometry, duration_s=0.5, period_s=H, offset_s=0.5 * H, lead_s=0.5 * H
    )
    diagram = builder.Build()
    context = diagram.CreateDefaultContext()
    ref_ctx = src.x_d.GetMyContextFromRoot(context)
    ff_ctx = src.T_ff.GetMyContextFromRoot(context)
    for k in (0, 1, 7, 250, 499, 500):
        t_k = k * H + 0.5 * H
        context.SetTime(t_k)
        x, xd, xdd = traj.evaluate(t_k + 0.5 * H)
        np.testing.assert_allclose(
            src.x_d.get_output_port().Eval(ref_ctx),
            np.concatenate([x, xd, xdd]),
            rtol=0,
            atol=1e-15,
        )
        np.testing.assert_allclose(
            src.T_ff.get_output_port().Eval(ff_ctx),
            statics.holding_torques(geometry, x),
            rtol=1e-12,
        )


def test_inverse_dynamics_feedforward_adds_the_inertial_torque(geometry, random_poses):
    x = random_poses[:10]
    a = np.random.default_rng(1).normal(size=(10, 6))
    theta = kinematics.ik(geometry, x)
    J = kinematics.jacobian(geometry, x, theta)
    M = statics.task_inertia(geometry, x, theta)
    extra = np.linalg.solve(np.swapaxes(J, -1, -2), (M @ a[..., None]))[..., 0]
    np.testing.assert_allclose(
        feedforward_torques(geometry, x, a, "inverse_dynamics"),
        feedforward_torques(geometry, x) + extra,
        rtol=1e-10,
        atol=1e-12,
    )
    assert np.all(feedforward_torques(geometry, x, mode="none") == 0)
