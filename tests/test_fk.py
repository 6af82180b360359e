"""Forward kinematics: round trips through the closed-form IK, and Drake's InverseKinematics."""

import numpy as np
import pytest
from conftest import random_reachable_poses
from pydrake.math import RollPitchYaw
from pydrake.multibody.inverse_kinematics import InverseKinematics
from pydrake.solvers import IpoptSolver, SolverOptions

from stewart_drake.base.errors import ForwardKinematicsError, InvalidConfigError
from stewart_drake.plant.plant import make_plant
from stewart_drake.robot import forward_kinematics, kinematics, limits
from stewart_drake.robot.geometry import X_HOME


@pytest.fixture(scope="module")
def poses_1000(geometry):
    return random_reachable_poses(geometry, 1000, seed=5)


def test_fk_inverts_ik_at_1000_random_poses_from_home(geometry, poses_1000):
    theta = kinematics.ik(geometry, poses_1000)
    x, converged, iterations, residual = forward_kinematics.fk_unchecked(geometry, theta)
    assert converged.all()
    assert np.abs(x - poses_1000).max() < 1e-9
    assert residual.max() <= 1e-12
    assert iterations.max() <= 8  # Newton: quadratic, few steps from home


def test_fk_batch_keeps_shape_and_reports_worst_case(geometry, poses_1000):
    x_in = poses_1000[:60].reshape(3, 20, 6)
    x, status = forward_kinematics.fk(geometry, kinematics.ik(geometry, x_in))
    assert x.shape == (3, 20, 6)
    np.testing.assert_allclose(x, x_in, atol=1e-9)
    assert status.converged and 1 <= status.iterations <= 8 and status.residual <= 1e-12
    _, converged, iterations, residual = forward_kinematics.fk_unchecked(
        geometry, kinematics.ik(geometry, x_in)
    )
    assert converged.shape == iterations.shape == residual.shape == (3, 20)
    assert iterations.dtype.kind == "i" and iterations.max() == status.iterations


def test_fk_single_pose_at_home_and_modulo_two_pi(geometry):
    theta = kinematics.ik(geometry, X_HOME)
    x, status = forward_kinematics.fk(geometry, theta + 2 * np.pi)
    np.testing.assert_allclose(x, X_HOME, atol=1e-14)
    assert status.iterations == 0 and status.converged


def test_fk_raises_for_angles_no_pose_has(geometry):
    theta = np.array([1.4, -1.4, 1.4, -1.4, 1.4, -1.4])
    with pytest.raises(ForwardKinematicsError, match="did not converge"):
        forward_kinematics.fk(geometry, theta)
    x, converged, steps, residual = forward_kinematics.fk_unchecked(geometry, theta)
    assert not converged and residual > 1e-3
    # it stops where no step descends, not at max_iter
    _, _, more_steps, _ = forward_kinematics.fk_unchecked(geometry, theta, max_iter=60)
    assert more_steps == steps < 50


def test_fk_raises_from_an_unreachable_initial_pose(geometry):
    theta = kinematics.ik(geometry, X_HOME)
    with pytest.raises(ForwardKinematicsError, match="x0 is unreachable"):
        forward_kinematics.fk(geometry, theta, x0=[0, 0, 0, 0, 0, 0.9])


def test_fk_steps_back_into_the_workspace(geometry):
    """From a far initial guess full Newton steps leave the workspace; halving keeps it inside."""
    x_goal = np.array([0.3, -0.2, 0.4, 0.03, -0.04, 0.33])
    x, status = forward_kinematics.fk(
        geometry, kinematics.ik(geometry, x_goal), x0=[-0.3, 0.2, -0.4, -0.05, 0.05, 0.26]
    )
    np.testing.assert_allclose(x, x_goal, atol=1e-9)


def _drake_fk(plant, context, handles, q_start, theta):
    """Platform pose with the motor joints bounded to theta: Drake IK with the ball constraints."""
    ik = InverseKinematics(plant, with_joint_limits=False)
    prog, q = ik.get_mutable_prog(), ik.q()
    assert len(prog.GetAllConstraints()) == 7  # 6 ball constraints + unit quaternion
    for joint, angle in zip(handles.motors, theta):
        prog.AddBoundingBoxConstraint(angle, angle, q[joint.position_start()])
    options = SolverOptions()
    options.SetOption(IpoptSolver.id(), "tol", 1e-12)
    result = IpoptSolver().Solve(prog, q_start, options)
    assert result.is_success()
    plant.SetPositions(context, result.GetSolution(q))
    X_WE = plant.EvalBodyPoseInWorld(context, handles.platform)
    return np.concatenate([RollPitchYaw(X_WE.rotation()).vector(), X_WE.translation()])


def test_fk_agrees_with_drake_inverse_kinematics(geometry):
    plant, context, handles, _, _ = make_plant()
    q_home = plant.GetPositions(context)  # assembled at home
    for x_true in random_reachable_poses(geometry, 12, seed=7):
        theta = kinematics.ik(geometry, x_true)
        x_drake = _drake_fk(plant, context, handles, q_home, theta)
        x_ours, _ = forward_kinematics.fk(geometry, theta)
        assert np.abs(x_ours - x_drake).max() < 1e-6  # measured: < 1e-11
        assert np.abs(x_ours - x_true).max() < 1e-9


def test_fk_over_the_whole_workspace_is_right_or_reports_failure(geometry):
    """Far from home Newton could land in another assembly mode; it must fail loudly instead."""
    rng = np.random.default_rng(0)
    x = X_HOME + rng.uniform(-1, 1, (40_000, 6)) * [0.5, 0.5, 0.8, 0.15, 0.15, 0.12]
    x = x[limits.is_reachable(geometry, x).reachable]
    assert len(x) > 2500
    x_fk, converged, _, _ = forward_kinematics.fk_unchecked(geometry, kinematics.ik(geometry, x))
    assert converged.mean() > 0.99
    assert np.abs(x_fk - x)[converged].max() < 1e-9


def test_encoder_pose_noise_agrees_with_rounding_the_angles(geometry):
    """The first-order figure of the encoders' resolution in the pose against rounding the
    angles of 2,000 poses to whole counts (17 bits) and solving the forward kinematics: within
    5 % (measured: 0.7 % in translation, 1.3 % in rotation)."""
    q = 2 * np.pi / 2**17
    rng = np.random.default_rng(0)
    x = X_HOME + np.concatenate([rng.normal(0, 2e-3, (2000, 3)), rng.normal(0, 1e-3, (2000, 3))], 1)
    theta = kinematics.ik(geometry, x)
    x_fk, _ = forward_kinematics.fk(geometry, np.round(theta / q) * q, x)
    e = x_fk - x
    measured = (
        np.sqrt(np.mean(np.sum(e[:, 3:] ** 2, axis=1))),
        np.sqrt(np.mean(np.sum(e[:, :3] ** 2, axis=1))),
    )
    figure = forward_kinematics.encoder_pose_noise(geometry, x, q)
    assert figure == pytest.approx(measured, rel=0.05)
    assert 5e-6 < figure[0] < 7e-6 and 30e-6 < figure[1] < 37e-6  # 5.9 um, 33.8 urad
    # halving the count halves both
    half = forward_kinematics.encoder_pose_noise(geometry, x, q / 2)
    assert half == pytest.approx((figure[0] / 2, figure[1] / 2), rel=1e-12)
    # a cap on the poses evaluates every k-th one: the same figure as those poses give
    capped = forward_kinematics.encoder_pose_noise(geometry, x, q, max_poses=300)
    assert capped == forward_kinematics.encoder_pose_noise(geometry, x[::6], q)
    assert capped == pytest.approx(figure, rel=0.05)


def _first_step(geometry, theta, x0):
    """The first Newton step of fk as its docstring states it, from the kinematics alone:
    dx = J(x0)^-1 wrap(ik(x0) - theta), then x0 - 2^-j dx for the first j whose pose is
    reachable, has a smaller residual and the sign of det J of x0. Returns j, that pose and
    why each larger step was refused."""
    th0 = kinematics.ik(geometry, x0)
    residual = np.linalg.norm(kinematics.wrap_angle(th0 - theta))
    dx = np.linalg.solve(kinematics.jacobian(geometry, x0, th0), kinematics.wrap_angle(th0 - theta))
    mode = np.sign(np.linalg.det(kinematics.jacobian(geometry, x0, th0)))
    refused = []
    for j in range(31):
        x = x0 - 0.5**j * dx
        th, _ = kinematics.ik_unchecked(geometry, x)
        if not np.isfinite(th).all():
            refused.append("unreachable")
        elif np.linalg.norm(kinematics.wrap_angle(th - theta)) >= residual:
            refused.append("no descent")
        elif np.sign(np.linalg.det(kinematics.jacobian(geometry, x, th))) != mode:
            refused.append("other assembly mode")
        else:
            return j, x, refused
    raise AssertionError("no step")


@pytest.mark.parametrize(
    "x_goal, x0, refused",
    [
        (
            [-0.3, 0.61, 0.11, -0.05, -0.08, 0.29],
            [-0.47, 0.6, 0.05, -0.08, -0.1, 0.3],
            ["other assembly mode"] * 3,
        ),
        (
            [0.44, 0.07, 0.17, 0.05, 0.01, 0.29],
            [0.54, 0.31, -0.1, -0.09, 0.1, 0.27],
            ["unreachable", "no descent"],
        ),
    ],
)
def test_a_newton_step_halves_until_reachable_descending_and_in_the_same_mode(
    geometry, x_goal, x0, refused
):
    """Far from the solution the full step is refused (into the other assembly mode, out of
    the workspace, up the residual) and halved; fk takes the step the docstring's rule gives,
    and none when max_halvings stops short of it."""
    x0 = np.array(x0)
    theta = kinematics.ik(geometry, np.array(x_goal))
    j, x_step, why = _first_step(geometry, theta, x0)
    assert why == refused  # the case this test is about
    for halvings in (j, 30):
        x, converged, iterations, _ = forward_kinematics.fk_unchecked(
            geometry, theta, x0, max_iter=1, max_halvings=halvings
        )
        np.testing.assert_allclose(x, x_step, rtol=0, atol=1e-15)
        assert iterations == 1 and not converged
    x, _, iterations, _ = forward_kinematics.fk_unchecked(
        geometry, theta, x0, max_iter=1, max_halvings=j - 1
    )
    np.testing.assert_array_equal(x, x0)
    x, status = forward_kinematics.fk(geometry, theta, x0)
    np.testing.assert_allclose(x, x_goal, rtol=0, atol=1e-9)


def test_each_pose_of_a_batch_is_solved_as_alone(geometry):
    """A batch mixing a start that needs halvings, easy poses, angles no pose has and an
    unreachable start gives each pose what it gives alone: the poses do not share a residual,
    a convergence test or a failure."""
    near = np.array([0.2, -0.1, 0.3, 0.02, -0.03, 0.32])
    theta = np.stack(
        [
            kinematics.ik(geometry, np.array([0.44, 0.07, 0.17, 0.05, 0.01, 0.29])),
            kinematics.ik(geometry, near),
            np.array([1.4, -1.4, 1.4, -1.4, 1.4, -1.4]),
            kinematics.ik(geometry, X_HOME),
        ]
    )
    x0 = np.stack([[0.54, 0.31, -0.1, -0.09, 0.1, 0.27], X_HOME, X_HOME, [0, 0, 0, 0, 0, 0.9]])
    batch = forward_kinematics.fk_unchecked(geometry, theta, x0)
    for k in range(4):
        alone = forward_kinematics.fk_unchecked(geometry, theta[k], x0[k])
        for b, a in zip(batch, alone):
            np.testing.assert_array_equal(b[k], a)
    assert batch[1].tolist() == [True, True, False, False]
    assert batch[2][3] == 0 and batch[3][3] == np.inf  # an unreachable start takes no step
    np.testing.assert_array_equal(batch[0][3], x0[3])


def test_max_iter_bounds_the_newton_steps_it_reports(geometry):
    """A solve reported as n Newton steps converges with max_iter = n to the same pose and
    fails with n - 1, naming n - 1 steps."""
    x_goal = np.array([0.25, -0.2, 0.3, 0.03, -0.03, 0.32])
    theta = kinematics.ik(geometry, x_goal)
    x, status = forward_kinematics.fk(geometry, theta)
    n = status.iterations
    assert n >= 3  # Newton from home: not one step
    x_n, status_n = forward_kinematics.fk(geometry, theta, max_iter=n)
    np.testing.assert_array_equal(x_n, x)
    assert status_n == status
    with pytest.raises(ForwardKinematicsError, match=f"after {n - 1} Newton steps"):
        forward_kinematics.fk(geometry, theta, max_iter=n - 1)


def test_fk_refuses_arguments_out_of_their_domain(geometry):
    theta = kinematics.ik(geometry, X_HOME)
    for kwargs in ({"tol": 0.0}, {"tol": -1e-9}, {"max_iter": 0}, {"max_iter": 2.5}):
        with pytest.raises(InvalidConfigError):
            forward_kinematics.fk(geometry, theta, **kwargs)
    with pytest.raises(InvalidConfigError):
        forward_kinematics.fk(geometry, theta, max_iter=True)
    with pytest.raises(InvalidConfigError):
        forward_kinematics.fk(geometry, theta[:5])
    x, status = forward_kinematics.fk(geometry, theta, max_iter=1)  # 1 is allowed
    np.testing.assert_allclose(x, X_HOME, atol=1e-14)
    x, status = forward_kinematics.fk(geometry, np.zeros((0, 6)))  # nothing to solve
    assert x.shape == (0, 6) and status == forward_kinematics.FkStatus(True, 0, 0.0)


def test_fk_names_the_first_pose_of_a_batch_it_cannot_solve(geometry):
    no_pose = np.array([1.4, -1.4, 1.4, -1.4, 1.4, -1.4])
    home = kinematics.ik(geometry, X_HOME)
    theta = np.stack([home, no_pose, home, no_pose])
    with pytest.raises(ForwardKinematicsError, match=r"\[1\.4, -1\.4, .*batch index 1\)"):
        forward_kinematics.fk(geometry, theta)
    with pytest.raises(ForwardKinematicsError, match=r"cannot start \(batch index 2\)"):
        forward_kinematics.fk(geometry, np.stack([home] * 3), x0=[X_HOME, X_HOME, [0] * 5 + [0.9]])


def test_the_newton_step_falls_back_to_the_pseudo_inverse_and_marks_what_is_not_finite(
    monkeypatch,
):
    """A J exactly singular in the batch: every pose's step by the pseudo-inverse (for a
    regular J, J^-1 r; for diag(1, 2, 4, 5, 8, 0), the least-squares step with 0 on the null
    axis); a J not finite is replaced by the identity and its step marked not ok, as is a step
    not finite."""
    J = np.stack(
        [
            np.diag([1.0, 2, 4, 5, 8, 10]),
            np.diag([1.0, 2, 4, 5, 8, 0]),
            np.full((6, 6), np.inf),
            np.eye(6),
        ]
    )
    monkeypatch.setattr(forward_kinematics, "jacobian_unchecked", lambda geometry, x, theta: J)
    r = np.array([[1.0] * 6, [2.0] * 6, [1, 2, 3, 4, 5, 6], [np.nan] + [1.0] * 5])
    dx, ok = forward_kinematics._newton_step(None, np.zeros((4, 6)), np.zeros((4, 6)), r)
    np.testing.assert_allclose(dx[0], [1, 0.5, 0.25, 0.2, 0.125, 0.1], rtol=1e-14)
    np.testing.assert_allclose(dx[1], [2, 1, 0.5, 0.4, 0.25, 0], rtol=1e-14, atol=1e-15)
    np.testing.assert_allclose(dx[2], r[2], rtol=1e-14)
    assert ok.tolist() == [True, True, False, False]


def test_encoder_pose_noise_is_the_first_order_spread_of_the_forward_kinematics(geometry):
    """The figure from its definition, without the Jacobian's inverse: dx/dtheta by central
    differences of the forward kinematics, the variance of one count's rounding error as the
    mean square of a fine uniform grid over [-q/2, q/2] (q^2 / 12 to 1e-6); the translation's
    and the rotation's RMS standard deviation over the poses. A cap of max_poses >= n evaluates
    every pose, a cap of 1 the first alone; a count must be > 0."""
    q = 2 * np.pi / 2**17
    grid = (np.arange(1000) + 0.5) / 1000 - 0.5
    variance = np.mean((grid * q) ** 2)
    x = random_reachable_poses(geometry, 3, seed=9)
    h = 1e-6
    spread = []
    for pose in x:
        theta = kinematics.ik(geometry, pose)
        columns = [
            forward_kinematics.fk(geometry, theta + h * e, pose)[0]
            - forward_kinematics.fk(geometry, theta - h * e, pose)[0]
            for e in np.eye(6)
        ]
        dx_dtheta = np.column_stack(columns) / (2 * h)
        spread.append(variance * np.sum(dx_dtheta**2, axis=1))  # each axis' variance
    spread = np.array(spread)
    expected = (
        np.sqrt(np.mean(np.sum(spread[:, 3:], axis=1))),
        np.sqrt(np.mean(np.sum(spread[:, :3], axis=1))),
    )
    figure = forward_kinematics.encoder_pose_noise(geometry, x, q)
    assert figure == pytest.approx(expected, rel=1e-5)
    assert forward_kinematics.encoder_pose_noise(geometry, x, q, max_poses=3) == figure
    assert forward_kinematics.encoder_pose_noise(geometry, x, q, max_poses=1) == (
        forward_kinematics.encoder_pose_noise(geometry, x[0], q)
    )
    for bad in (0.0, -q):
        with pytest.raises(InvalidConfigError):
            forward_kinematics.encoder_pose_noise(geometry, x, bad)
