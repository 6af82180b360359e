"""Forward kinematics: round trips through the closed-form IK, and Drake's InverseKinematics."""

import numpy as np
import pytest
from conftest import random_reachable_poses
from pydrake.math import RollPitchYaw
from pydrake.multibody.inverse_kinematics import InverseKinematics
from pydrake.solvers import IpoptSolver, SolverOptions

from stewart_drake.base.errors import ForwardKinematicsError
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


def test_fk_single_pose_at_home_and_modulo_two_pi(geometry):
    theta = kinematics.ik(geometry, X_HOME)
    x, status = forward_kinematics.fk(geometry, theta + 2 * np.pi)
    np.testing.assert_allclose(x, X_HOME, atol=1e-14)
    assert status.iterations == 0 and status.converged


def test_fk_raises_for_angles_no_pose_has(geometry):
    theta = np.array([1.4, -1.4, 1.4, -1.4, 1.4, -1.4])
    with pytest.raises(ForwardKinematicsError, match="did not converge"):
        forward_kinematics.fk(geometry, theta)
    x, converged, _, residual = forward_kinematics.fk_unchecked(geometry, theta)
    assert not converged and residual > 1e-3


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
