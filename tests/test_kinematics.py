"""Kinematics: IK against the loop equation, Jacobian against finite differences, the per-step
kernels against the batched functions (statics: test_statics.py)."""

import warnings
from types import SimpleNamespace

import numpy as np
import pytest
from conftest import random_reachable_poses
from pydrake.math import RollPitchYaw

from stewart_drake.base.errors import InvalidConfigError, SingularPoseError, UnreachablePoseError
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
        J_ik = kinematics.jacobian_unchecked(geometry, x)  # its own IK when theta is not given
        assert np.abs(J_ik - J_fd).max() / np.abs(J).max() < 1e-6


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


def _rod_crank_cosines(geometry, x):
    """e_l . e_N per leg from the joints alone: the rod's direction, and the crank tip's
    direction of motion by a central difference of the tips in theta."""
    theta = kinematics.ik(geometry, x)
    q_B, _ = kinematics.platform_joints(geometry, x)
    tip = geometry.crank_tips(theta)
    e_l = (q_B - tip) / np.linalg.norm(q_B - tip, axis=1, keepdims=True)
    h = 1e-7
    e_N = (geometry.crank_tips(theta + h) - geometry.crank_tips(theta - h)) / (2 * h)
    e_N /= geometry.crank_lengths[:, None]
    return np.sum(e_l * e_N, axis=1)


def test_paper_eq18_as_printed_is_the_wrench_map_times_the_squared_cosine(either_robot):
    """Column i of the printed map is the statics' column times (e_l . e_N)^2, the cosine found
    from the joints (not from the map): eq. 15 multiplies by the cosine over a_i where statics
    divides by it times a_i."""
    geometry = either_robot
    for x in random_reachable_poses(geometry, 4, seed=5, margin=0.9):
        d = _rod_crank_cosines(geometry, x)
        np.testing.assert_allclose(
            kinematics.wrench_map_paper_eq18(geometry, x),
            kinematics.wrench_map(geometry, x) * d**2,
            rtol=1e-7,
            atol=1e-9,
        )


def test_a_stack_of_poses_gives_each_pose_s_own_maps(geometry, random_poses):
    """The batched maps of a (2, n, 6) stack are those of each pose alone: wrench map (both
    forms), tau, Jacobian, singular values and the singularity measures."""
    x = random_poses[:3]
    stacked = np.stack([x, x[::-1]])
    for f in (
        kinematics.wrench_map,
        kinematics.wrench_map_paper_eq18,
        kinematics.tau,
        kinematics.jacobian,
        kinematics.singular_values,
    ):
        batch = f(geometry, stacked)
        for k, p in enumerate(x[::-1]):
            np.testing.assert_allclose(batch[1, k], f(geometry, p), rtol=1e-12, atol=1e-12)
    cond, inv = kinematics.singularity_measures(geometry, stacked)
    for k, p in enumerate(x):
        sv = np.linalg.svd(kinematics.jacobian(geometry, p), compute_uv=False)
        assert cond[0, k] == pytest.approx(sv[0] / sv[-1], rel=1e-12)
        assert inv[0, k] == pytest.approx(1 / sv[0], rel=1e-12)


def test_singular_values_mark_unreachable_and_unbounded_rows(geometry):
    """NaN rows where J has NaN, [inf, NaN...] where J has inf, numpy's SVD elsewhere; the
    measures give cond inf and sigma_min_inv 0 at an unbounded J, NaN where unreachable."""
    J = np.stack([kinematics.jacobian(geometry, X_HOME)] * 3)
    J[1, 2, 3] = np.nan
    J[2, 4, 0] = np.inf
    sv = kinematics.singular_values_of(J)
    np.testing.assert_allclose(sv[0], np.linalg.svd(J[0], compute_uv=False), rtol=1e-14)
    assert np.all(np.isnan(sv[1]))
    assert sv[2, 0] == np.inf and np.all(np.isnan(sv[2, 1:]))
    cond, inv = kinematics.singularity_measures_of(sv)
    assert cond[0] == pytest.approx(sv[0, 0] / sv[0, 5], rel=1e-14)
    assert inv[0] == pytest.approx(1 / sv[0, 0], rel=1e-14)
    assert np.isnan(cond[1]) and np.isnan(inv[1])
    assert cond[2] == np.inf and inv[2] == 0.0
    beyond = X_HOME.copy()
    beyond[5] = 0.5
    cond, inv = kinematics.singularity_measures_unchecked(geometry, np.stack([X_HOME, beyond]))
    assert np.isfinite(cond[0]) and np.isnan(cond[1]) and np.isnan(inv[1])
    theta = kinematics.ik(geometry, X_HOME)
    np.testing.assert_array_equal(
        kinematics.singularity_measures(geometry, X_HOME, theta),
        kinematics.singularity_measures(geometry, X_HOME),
    )


def test_the_first_unreachable_pose_is_named_with_its_time_and_leg(geometry):
    """In a batch, the error names the first unreachable pose, its time and its first leg out of
    reach, with that leg's |ratio|."""
    x = np.stack([X_HOME] * 4)
    x[2, 5] = 0.5
    x[3, 5] = 0.6
    t = np.array([0.0, 0.1, 0.2, 0.3])
    with pytest.raises(UnreachablePoseError) as err:
        kinematics.ik(geometry, x, t)
    ratio = kinematics.leg_reach_ratio(geometry, x[2])
    leg = int(np.argmax(np.abs(ratio) > 1))
    assert err.value.leg == leg
    assert err.value.ratio == pytest.approx(abs(ratio[leg]), rel=1e-14)
    assert err.value.t == pytest.approx(0.2)
    np.testing.assert_array_equal(err.value.pose, x[2])
    with pytest.raises(UnreachablePoseError) as err:  # a (2, 2) stack with its (2, 2) times
        kinematics.ik(geometry, x.reshape(2, 2, 6), t.reshape(2, 2))
    assert err.value.t == pytest.approx(0.2)
    np.testing.assert_array_equal(err.value.pose, x[2])


def test_a_quantity_not_finite_is_named_at_its_first_pose(geometry):
    """finite_or_singular: the value back when finite; else SingularPoseError with the first
    pose whose rows are not all finite."""
    x = np.stack([X_HOME + 0.01 * k for k in range(3)])
    value = np.ones((3, 6, 6))
    assert kinematics.finite_or_singular("J", value, x) is value
    value[1, 4, 2] = np.inf
    value[2, 0, 0] = np.nan
    with pytest.raises(SingularPoseError) as err:
        kinematics.finite_or_singular("J", value, x)
    np.testing.assert_array_equal(err.value.pose, x[1])
    assert err.value.measure == "J" and err.value.value == np.inf


def _stand_in_robot(joints):
    """A stand-in for the robot with the attributes the closed-form IK reads: six legs with
    their pivots at the origin, the crank turning in the x-z plane (d = x, w = z), a = 3 and
    s = 5, and the platform joints at ``joints`` (6, 3), where the zero pose leaves them. Each
    leg's L = |l|^2 - (s^2 - a^2), M = 2 a l_z and N = 2 a l_x are small integers."""
    return SimpleNamespace(
        P_B=np.zeros((6, 3)),
        p_E=np.asarray(joints, dtype=float),
        d_B=np.tile([1.0, 0.0, 0.0], (6, 1)),
        w_B=np.tile([0.0, 0.0, 1.0], (6, 1)),
        crank_lengths=np.full(6, 3.0),
        rod_lengths=np.full(6, 5.0),
    )


def test_the_reach_ratio_of_joints_on_the_shaft_axis_and_at_the_dead_points():
    """L / sqrt(M^2 + N^2) by hand: (3, 0, 4) gives 9 / 30; a joint on its motor's shaft axis
    (M = N = 0) nearer than the rod's reach gives -inf, farther +inf, at it (L = 0) 0; (0, 5, 3)
    gives 18 / 18 and (0, 3, 1) -6 / 6, the two dead points. The IK without checks gives NaN
    for the legs on the shaft axis, without a floating-point warning; the IK names the first
    leg that cannot close."""
    robot = _stand_in_robot([[3, 0, 4], [0, 2, 0], [0, 6, 0], [0, 4, 0], [0, 5, 3], [0, 3, 1]])
    x = np.zeros(6)
    np.testing.assert_array_equal(
        kinematics.leg_reach_ratio(robot, x), [0.3, -np.inf, np.inf, 0.0, 1.0, -1.0]
    )
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # a sweep of the workspace stays quiet
        theta, _ = kinematics.ik_unchecked(robot, x)
    assert np.isnan(theta[1:4]).all() and np.isfinite(theta[[0, 4, 5]]).all()
    with pytest.raises(UnreachablePoseError) as err:
        kinematics.ik(robot, x)
    assert err.value.leg == 1 and err.value.ratio == np.inf and err.value.t is None
    np.testing.assert_array_equal(err.value.pose, x)


def test_a_leg_at_its_dead_point_closes():
    """|ratio| = 1 exactly (the crank along +-w, the rod orthogonal to it) is reachable: the IK
    gives angles whose crank tips, P + a (cos theta d + sin theta w), are a rod's length from
    the joints."""
    joints = np.array([[0, 5, 3], [0, 3, 1], [0, -5, -3], [0, -3, -1], [3, 0, 4], [4, 0, 0]], float)
    robot = _stand_in_robot(joints)
    theta = kinematics.ik(robot, np.zeros(6))
    tips = 3.0 * np.column_stack([np.cos(theta), np.zeros(6), np.sin(theta)])
    np.testing.assert_allclose(np.linalg.norm(joints - tips, axis=1), 5.0, rtol=1e-15)
    np.testing.assert_allclose(np.abs(theta[:4]), np.pi / 2 * np.array([1, 1, 1, 3]), rtol=1e-15)


def test_the_maps_name_the_pose_where_a_rod_is_orthogonal_to_its_crank_tip_s_motion(geometry):
    """Motor angles 0 (the cranks horizontal, their tips moving straight up) and the platform
    joints at the pivots' height (the rods horizontal): every rod is orthogonal to its tip's
    motion, J and W are unbounded, and the error names that pose, not the first of the batch."""
    at_pivots = np.array([0, 0, 0, 0, 0, geometry.P_B[0, 2]])
    assert np.all(geometry.P_B[:, 2] == at_pivots[5]) and np.all(geometry.p_E[:, 2] == 0)
    x = np.stack([X_HOME, at_pivots])
    theta = np.stack([kinematics.ik(geometry, X_HOME), np.zeros(6)])
    for f, name in ((kinematics.jacobian, "J"), (kinematics.wrench_map, "W")):
        with pytest.raises(SingularPoseError) as err:
            f(geometry, x, theta)
        assert err.value.measure == name
        np.testing.assert_array_equal(err.value.pose, at_pivots)


def test_motor_angles_given_are_used_and_checked(geometry, random_poses):
    """theta given (the IK's) gives the maps of theta computed; theta of another shape than x,
    with a last axis not 6 or not finite is refused."""
    x = random_poses[:3]
    theta = kinematics.ik(geometry, x)
    np.testing.assert_array_equal(
        kinematics.jacobian(geometry, x, theta), kinematics.jacobian(geometry, x)
    )
    np.testing.assert_array_equal(
        kinematics.wrench_map(geometry, x, theta), kinematics.wrench_map(geometry, x)
    )
    nan = theta.copy()
    nan[1, 2] = np.nan
    for bad in (theta[:2], theta[0], np.zeros((3, 7)), nan):
        with pytest.raises(InvalidConfigError):
            kinematics.jacobian(geometry, x, bad)
    with pytest.raises(InvalidConfigError):
        kinematics.singularity_measures(geometry, x[0], theta[0, :5])
    beyond = X_HOME + np.array([0, 0, 0, 0, 0, 0.2])
    with pytest.raises(UnreachablePoseError):
        kinematics.singularity_measures(geometry, beyond)
    with pytest.raises(UnreachablePoseError):
        kinematics.jacobian_unchecked(geometry, beyond)


def test_leg_terms_against_drake_s_rotation_and_finite_differences(geometry, random_poses):
    """Each term of leg_terms from an independent source: q_i = R p_i + p with Drake's R, the
    tips a rod's length from them, e_N the tips' derivative in theta over a_i, and Gq = dq_i/dx
    by central differences of q_i in the pose (rpy and position)."""

    def joints(x):
        R = RollPitchYaw(x[:3]).ToRotationMatrix().matrix()
        return geometry.p_E @ R.T + x[3:]

    h = 1e-6
    for x in random_poses[:3]:
        theta = kinematics.ik(geometry, x)
        terms = kinematics.leg_terms(geometry, x, theta)
        assert terms.theta is theta
        np.testing.assert_allclose(terms.q_B, joints(x), rtol=0, atol=1e-15)
        np.testing.assert_allclose(terms.r_B, joints(x) - x[3:], rtol=0, atol=1e-15)
        np.testing.assert_allclose(np.linalg.norm(terms.q_B - terms.tip, axis=1), 0.404, rtol=1e-13)
        np.testing.assert_array_equal(terms.ell, terms.q_B - terms.tip)
        tip_rate = (geometry.crank_tips(theta + h) - geometry.crank_tips(theta - h)) / (2 * h)
        np.testing.assert_allclose(terms.e_N * 0.11, tip_rate, rtol=0, atol=1e-10)
        Gq = np.stack(
            [(joints(x + h * e) - joints(x - h * e)) / (2 * h) for e in np.eye(6)], axis=-1
        )
        np.testing.assert_allclose(terms.Gq, Gq, rtol=0, atol=1e-9)


def test_wrap_angle_is_the_angle_of_the_unit_phasor():
    """(a + pi) mod 2 pi - pi against the argument of exp(i a), in [-pi, pi)."""
    a = np.array([0.5, 3.5, -3.5, 7.0, -7.0, 20.0, -np.pi, 3 * np.pi / 2])
    wrapped = kinematics.wrap_angle(a)
    np.testing.assert_allclose(wrapped[:6], np.angle(np.exp(1j * a[:6])), rtol=0, atol=1e-14)
    assert wrapped[6] == -np.pi and wrapped[7] == pytest.approx(-np.pi / 2, abs=1e-15)
