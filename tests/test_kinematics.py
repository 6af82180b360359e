"""Kinematics: IK against the loop equation, Jacobian against finite differences, the per-step
kernels against the batched functions (statics: test_statics.py)."""

import numpy as np
import pytest
from conftest import random_reachable_poses
from pydrake.math import RollPitchYaw

from stewart_drake.base.errors import UnreachablePoseError
from stewart_drake.robot import kinematics, single_pose, statics
from stewart_drake.robot.geometry import X_HOME


def test_rotation_matches_drake_rollpitchyaw(random_poses):
    for x in random_poses[:20]:
        R_drake = RollPitchYaw(x[:3]).ToRotationMatrix().matrix()
        np.testing.assert_allclose(kinematics.rotation_rpy(x[:3]), R_drake, atol=1e-14)


def test_angular_velocity_map_matches_drake(random_poses):
    rng = np.random.default_rng(1)
    for x in random_poses[:20]:
        rpy_dot = rng.normal(size=3)
        w = RollPitchYaw(x[:3]).CalcAngularVelocityInParentFromRpyDt(rpy_dot)
        np.testing.assert_allclose(kinematics.angular_velocity_map(x[:3]) @ rpy_dot, w, atol=1e-14)


def test_ik_closes_every_rod(geometry, random_poses):
    theta = kinematics.ik(geometry, random_poses)
    q_B, _ = kinematics.platform_joints(geometry, random_poses)
    rod = np.linalg.norm(q_B - geometry.crank_tips(theta), axis=-1)
    np.testing.assert_allclose(rod, geometry.rod_length, atol=1e-12)


def test_reference_manoeuvre_peak_ratio_is_as_documented(geometry):
    t = np.linspace(0, np.pi, 4001)
    x = np.zeros((t.size, 6))
    x[:, 0] = np.pi / 6 * np.sin(2 * t)
    x[:, 5] = 0.05 * np.sin(2 * t) + 0.30
    peak = np.abs(kinematics.leg_reach_ratio(geometry, x)).max()
    assert 0.90 < peak < 0.92  # reference_geometry.md: "about 0.91"


def test_unreachable_pose_names_leg_and_ratio(geometry):
    x = X_HOME.copy()
    x[5] = 0.5
    with pytest.raises(UnreachablePoseError) as err:
        kinematics.ik(geometry, x)
    assert err.value.ratio > 1 and 0 <= err.value.leg < 6
    assert f"leg {err.value.leg}" in str(err.value)


def test_jacobian_agrees_with_finite_differences(either_robot):
    geometry = either_robot
    h = 1e-6
    for x in random_reachable_poses(geometry, 50, seed=3, margin=0.9):
        J = kinematics.jacobian(geometry, x)
        J_fd = np.column_stack(
            [
                (kinematics.ik(geometry, x + h * e) - kinematics.ik(geometry, x - h * e)) / (2 * h)
                for e in np.eye(6)
            ]
        )
        assert np.abs(J - J_fd).max() / np.abs(J).max() < 1e-6


def test_tau_is_jacobian_transpose_and_corrected_eq18(either_robot):
    geometry = either_robot
    for x in random_reachable_poses(geometry, 20, seed=3, margin=0.9):
        tau = kinematics.tau(geometry, x)
        np.testing.assert_allclose(tau, kinematics.jacobian(geometry, x).T, atol=1e-12)
        E = kinematics.angular_velocity_map(x[:3])
        to_rpy = np.block([[E.T, np.zeros((3, 3))], [np.zeros((3, 3)), np.eye(3)]])
        np.testing.assert_allclose(to_rpy @ kinematics.wrench_map(geometry, x), tau, atol=1e-10)


def test_paper_eq18_as_printed_differs_from_virtual_work(geometry):
    """Eq. 15 multiplies by e_l . e_N where statics divides: the printed map is wrong."""
    W = kinematics.wrench_map(geometry, X_HOME)
    W_paper = kinematics.wrench_map_paper_eq18(geometry, X_HOME)
    ratio = W_paper[5] / W[5]  # column scale = (e_l . e_N)^2 per leg
    assert np.all(ratio < 0.9)  # the printed map is > 10 % off at home
    np.testing.assert_allclose(W_paper / ratio, W, atol=1e-12)


def test_batch_and_single_agree(geometry, random_poses):
    J_batch = kinematics.jacobian(geometry, random_poses[:10])
    for k in range(10):
        np.testing.assert_array_equal(J_batch[k], kinematics.jacobian(geometry, random_poses[k]))


def test_per_step_kernels_agree_with_the_batched_functions(geometry, random_poses):
    """The controller's per-step kernels (single-pose numpy, plain-Python floats, the compiled
    B(x)) give the numbers of the batched, validated functions; an unreachable leg is NaN in
    all of them."""
    from stewart_drake.control.lqi.gain import body_constants, input_matrix
    from stewart_drake.control.lqi.reschedule import input_matrix as input_matrix_per_step

    constants = single_pose.leg_constants(geometry)
    legs, body = statics.kernel_constants(geometry)[0], body_constants(geometry)
    for x in random_poses[:50]:
        theta = kinematics.ik(geometry, x)
        th_single, cache = single_pose.ik_single(geometry, x)
        np.testing.assert_allclose(th_single, theta, rtol=0, atol=1e-12)
        np.testing.assert_allclose(
            single_pose.ik_scalar(constants, x.tolist()), theta, rtol=0, atol=1e-12
        )
        J = kinematics.jacobian(geometry, x)
        np.testing.assert_allclose(
            single_pose.jacobian_single(geometry, cache),
            J,
            rtol=1e-12,
            atol=1e-12 * np.abs(J).max(),
        )
        M = statics.task_inertia(geometry, x)
        np.testing.assert_allclose(
            statics.task_inertia_single(geometry, cache, J),
            M,
            rtol=1e-11,
            atol=1e-12 * np.abs(M).max(),
        )
        B = input_matrix(geometry, x)
        np.testing.assert_allclose(
            input_matrix_per_step(legs, body, x)[0], B, rtol=1e-10, atol=1e-12 * np.abs(B).max()
        )
    far = X_HOME + np.array([0, 0, 0, 0, 0, 0.5])  # every rod too short
    assert np.isnan(single_pose.ik_single(geometry, far)[0]).all()
    assert np.isnan(single_pose.ik_scalar(constants, far.tolist())).all()
