"""Statics (model/statics.py): holding torques by virtual work against an independent potential,
the torques of a tool wrench against its virtual work, the task inertia against Drake's kinetic
energy, the crank rates of motor_effort, the gravity feed-forward."""

import numpy as np
import pytest
from conftest import drawn_robot

from stewart_drake.base.errors import InvalidConfigError, SingularPoseError, UnreachablePoseError
from stewart_drake.plant.closed_chain import assemble
from stewart_drake.plant.plant import make_plant
from stewart_drake.robot import kinematics, statics
from stewart_drake.robot.geometry import X_HOME
from stewart_drake.robot.servo import ServoModel


def potential_energy(g, x):
    """V of platform, cranks and rods at pose x (6,), from the joints alone (COMs at the
    geometric centres), in J: independent of statics' virtual-work formulas."""
    th = kinematics.ik(g, x)
    q_B, _ = kinematics.platform_joints(g, x)
    tip = g.crank_tips(th)
    z_crank = g.pivot_z + 0.5 * g.crank_length * np.sin(th)
    return g.gravity * (
        g.platform_mass * x[5]
        + g.crank_mass * z_crank.sum()
        + g.rod_mass * 0.5 * (tip[:, 2] + q_B[:, 2]).sum()
    )


def test_holding_torques_do_no_net_virtual_work(geometry, random_poses):
    """Energy balance: T . d theta = dV for a small motion, from an independent potential."""
    rng = np.random.default_rng(2)
    g = geometry

    for x in random_poses[:20]:
        T = statics.holding_torques(g, x)
        dx = 1e-6 * rng.normal(size=6)
        d_theta = kinematics.ik(g, x + dx) - kinematics.ik(g, x - dx)
        dV = potential_energy(g, x + dx) - potential_energy(g, x - dx)
        assert abs(T @ d_theta - dV) < 1e-6 * abs(dV) + 1e-12


def test_platform_only_model_is_tens_of_percent_off_at_home(geometry):
    T_full = statics.holding_torques(geometry, X_HOME)
    W = kinematics.wrench_map(geometry, X_HOME)
    T_platform = np.linalg.solve(W, [0, 0, 0, 0, 0, geometry.platform_mass * geometry.gravity])
    assert np.all(T_full / T_platform > 1.2)


def test_gravity_feedforward_is_the_holding_torque(geometry, random_poses):
    from stewart_drake.robot.statics import feedforward_torques

    np.testing.assert_allclose(
        feedforward_torques(geometry, random_poses[:20]),
        statics.holding_torques(geometry, random_poses[:20]),
        atol=1e-12,
    )
    with pytest.raises(InvalidConfigError, match="feedforward"):
        feedforward_torques(geometry, random_poses[:2], mode="magic")


def test_task_inertia_matches_drake_kinetic_energy(geometry, random_poses):
    plant, context, handles, _, _ = make_plant()
    rng = np.random.default_rng(4)
    for x in random_poses[:25]:
        x_dot = rng.normal(size=6) * [0.5, 0.5, 0.5, 0.05, 0.05, 0.05]
        assemble(plant, context, handles, x, x_dot)
        M_x = statics.task_inertia(geometry, x)
        # The rods' free spin is set to zero by assemble, so energies must match exactly.
        assert plant.CalcKineticEnergy(context) == pytest.approx(
            0.5 * x_dot @ M_x @ x_dot, rel=1e-9
        )


def test_tool_load_torques_balance_the_wrench_s_virtual_work(geometry, random_poses):
    """The motors' share of a tool wrench [torque, force] at the tool tip does, over a small
    motion, the opposite of the wrench's work: T_ext . d theta + f . dp_tool + tau . d phi = 0
    (d theta from the IK, dp_tool from the tool tip's position, d phi from the rotations: no
    wrench map involved)."""
    rng = np.random.default_rng(5)
    p_EP = statics.p_ETool
    assert np.array_equal(
        statics.tool_load_torques(geometry, X_HOME, np.zeros(6)),
        statics.holding_torques(geometry, X_HOME),
    )
    for x in random_poses[:10]:
        wrench = rng.normal(size=6) * [0.5, 0.5, 0.5, 5.0, 5.0, 5.0]
        T_ext = statics.tool_load_torques(geometry, x, wrench) - statics.holding_torques(
            geometry, x
        )
        dx = 1e-6 * rng.normal(size=6)
        d_theta = kinematics.ik(geometry, x + dx) - kinematics.ik(geometry, x - dx)
        R_plus, R_minus = (kinematics.rotation_rpy(y[:3]) for y in (x + dx, x - dx))
        dp_tool = (x + dx)[3:] + R_plus @ p_EP - (x - dx)[3:] - R_minus @ p_EP
        dR = R_plus @ R_minus.T  # I + skew(d phi) to first order
        d_phi = 0.5 * np.array([dR[2, 1] - dR[1, 2], dR[0, 2] - dR[2, 0], dR[1, 0] - dR[0, 1]])
        work = wrench[3:] @ dp_tool + wrench[:3] @ d_phi
        assert abs(T_ext @ d_theta + work) < 1e-6 * np.abs(T_ext).max() * np.abs(d_theta).max()


def test_motor_effort_rates_are_the_ik_s_derivative_and_friction_adds_on_top(
    geometry, random_poses
):
    """theta_dot = J x_dot agrees with a central difference of the IK along x_dot; a servo adds
    exactly b theta_dot + F_c sign(theta_dot) to the inverse-dynamics torques."""
    rng = np.random.default_rng(6)
    servo = ServoModel()
    for x in random_poses[:10]:
        x_dot = rng.normal(size=6) * [0.5, 0.5, 0.5, 0.05, 0.05, 0.05]
        x_ddot = rng.normal(size=6) * [2.0, 2.0, 2.0, 0.2, 0.2, 0.2]
        T, theta_dot = statics.motor_effort(geometry, x, x_dot, x_ddot)
        h = 1e-6
        fd = (kinematics.ik(geometry, x + h * x_dot) - kinematics.ik(geometry, x - h * x_dot)) / (
            2 * h
        )
        np.testing.assert_allclose(theta_dot, fd, rtol=1e-6, atol=1e-8)
        np.testing.assert_allclose(
            T, statics.inverse_dynamics_torques(geometry, x, x_dot, x_ddot), rtol=1e-12
        )
        T_servo, _ = statics.motor_effort(geometry, x, x_dot, x_ddot, servo)
        np.testing.assert_allclose(
            T_servo - T,
            servo.viscous_damping * theta_dot + servo.coulomb_friction_Nm * np.sign(theta_dot),
            atol=1e-12,
        )


def _energy_along(geometry, path, t):
    """Kinetic + potential energy of the closed chain at time t of ``path`` (t -> x), the rates
    by central differences: E = 1/2 x_dot^T M_x x_dot + V, V from the poses alone."""
    h = 1e-5
    x = path(t)
    x_dot = (path(t + h) - path(t - h)) / (2 * h)
    V = potential_energy(geometry, x)
    return 0.5 * x_dot @ statics.task_inertia(geometry, x) @ x_dot + V


def test_inverse_dynamics_torques_deliver_the_power_the_energy_takes(geometry):
    """Power balance along a smooth motion: T . theta_dot = dE/dt, E the kinetic (task inertia)
    plus potential energy, dE/dt by a central difference in time: every term of
    T = J^-T (M_x x_ddot + c + dV/dx) counts, the Coriolis term's 1/2 included."""
    amplitude = np.array([0.2, -0.15, 0.25, 0.02, -0.015, 0.02])
    omega = np.array([2.0, 3.0, 1.5, 2.5, 1.0, 3.5])

    def path(t):
        return X_HOME + amplitude * np.sin(omega * t + 0.3)

    for t in (0.1, 0.7, 1.3):
        x = path(t)
        x_dot = amplitude * omega * np.cos(omega * t + 0.3)
        x_ddot = -amplitude * omega**2 * np.sin(omega * t + 0.3)
        T = statics.inverse_dynamics_torques(geometry, x, x_dot, x_ddot)
        theta_dot = kinematics.jacobian(geometry, x) @ x_dot
        dt = 1e-4
        dE = (_energy_along(geometry, path, t + dt) - _energy_along(geometry, path, t - dt)) / (
            2 * dt
        )
        assert T @ theta_dot == pytest.approx(dE, rel=2e-5, abs=1e-7)


def test_coriolis_forces_are_quadratic_and_do_half_the_inertia_s_rate_of_work(
    geometry, random_poses
):
    """x_dot . c = 1/2 x_dot^T (dM_x/dt) x_dot (the velocity-product forces of a Lagrangian), with
    dM_x/dt by a central difference along x_dot, and c(x, 2 x_dot) = 4 c(x, x_dot)."""
    rng = np.random.default_rng(8)
    for x in random_poses[:6]:
        x_dot = rng.normal(size=6) * [0.5, 0.5, 0.5, 0.05, 0.05, 0.05]
        c = statics.coriolis_forces(geometry, x, x_dot)
        h = 1e-6
        M_dot = (
            statics.task_inertia(geometry, x + h * x_dot)
            - statics.task_inertia(geometry, x - h * x_dot)
        ) / (2 * h)
        assert x_dot @ c == pytest.approx(0.5 * x_dot @ M_dot @ x_dot, rel=1e-4)
        np.testing.assert_allclose(
            statics.coriolis_forces(geometry, x, 2 * x_dot), 4 * c, rtol=1e-9, atol=1e-12
        )
    # the poses and the rates broadcast: one pose at two rates, two poses at one rate
    x, x_dot = random_poses[:2], rng.normal(size=(2, 6)) * [0.5, 0.5, 0.5, 0.05, 0.05, 0.05]
    for poses, rates in ((x[0], x_dot), (x, x_dot[0])):
        pairs = np.broadcast_arrays(poses, rates)
        np.testing.assert_allclose(
            statics.coriolis_forces(geometry, poses, rates),
            [statics.coriolis_forces(geometry, p, r) for p, r in zip(*pairs)],
            rtol=1e-9,
            atol=1e-12,
        )


def test_gravity_gradient_is_the_potential_s_gradient_and_the_holding_wrench(
    geometry, random_poses
):
    """dV/dx against central differences of an independent potential, axis by axis, and
    J^T T_hold = dV/dx; passing theta and J changes nothing."""
    g = geometry

    for x in random_poses[:5]:
        grad = statics.gravity_gradient(g, x)
        h = 1e-6
        fd = [
            (potential_energy(g, x + h * e) - potential_energy(g, x - h * e)) / (2 * h)
            for e in np.eye(6)
        ]
        np.testing.assert_allclose(grad, fd, rtol=1e-6, atol=1e-7)
        theta = kinematics.ik(g, x)
        J = kinematics.jacobian(g, x, theta)
        assert np.array_equal(statics.gravity_gradient(g, x, theta, J), grad)
        np.testing.assert_allclose(J.T @ statics.holding_torques(g, x), grad, atol=1e-10)


def test_crank_inertia_gives_the_kinetic_energy_in_crank_rates(geometry, random_poses):
    """1/2 theta_dot^T M_theta theta_dot = 1/2 x_dot^T M_x x_dot for theta_dot = J x_dot, at home
    (the default pose) and elsewhere; M_theta symmetric positive definite."""
    rng = np.random.default_rng(9)
    for x in (X_HOME, *random_poses[:4]):
        M_theta = (
            statics.crank_inertia_matrix(geometry)
            if x is X_HOME
            else statics.crank_inertia_matrix(geometry, x)
        )
        x_dot = rng.normal(size=6) * [0.5, 0.5, 0.5, 0.05, 0.05, 0.05]
        theta_dot = kinematics.jacobian(geometry, x) @ x_dot
        M_x = statics.task_inertia(geometry, x)
        assert theta_dot @ M_theta @ theta_dot == pytest.approx(x_dot @ M_x @ x_dot, rel=1e-10)
        np.testing.assert_allclose(M_theta, M_theta.T, rtol=1e-10, atol=1e-14)
        assert np.all(np.linalg.eigvalsh(M_theta) > 0)


def test_task_inertia_of_legs_with_their_own_shaft_inertias_adds_each_shaft_s_energy():
    """On a robot whose shaft inertias differ leg by leg, a rotor inertia dI reflected at every
    shaft adds exactly dI J^T J to M_x: the per-leg sum J^T diag(I_shaft) J, not another
    product."""
    robot = drawn_robot()
    assert np.ptp(robot.shaft_inertias) > 0
    x = X_HOME + np.array([[0.1, -0.05, 0.08, 0.01, -0.01, 0.005], [-0.05, 0.1, 0.0, 0, 0.01, 0]])
    d_I = 3e-4
    J = kinematics.jacobian(robot, x)  # a batch of two poses, and each alone
    heavier = robot.replace(motor_reflected_inertia=d_I)
    for poses, jacobians in ((x, J), (x[0], J[0])):
        np.testing.assert_allclose(
            statics.task_inertia(heavier, poses) - statics.task_inertia(robot, poses),
            d_I * np.swapaxes(jacobians, -1, -2) @ jacobians,
            rtol=1e-9,
            atol=1e-15,
        )


def test_a_batch_of_poses_gives_each_pose_s_own_statics_and_dynamics(geometry, random_poses):
    """The batched forms, (n, 6) poses and (2, n, 6) stacks, give each pose what the pose alone
    gives: holding torques, task inertia, the feed-forward of every mode (the unchecked form
    with the motor angles given too) and the inverse dynamics."""
    rng = np.random.default_rng(11)
    x = random_poses[:4]
    x_dot = rng.normal(size=(4, 6)) * [0.5, 0.5, 0.5, 0.05, 0.05, 0.05]
    x_ddot = rng.normal(size=(4, 6)) * [2.0, 2.0, 2.0, 0.2, 0.2, 0.2]
    theta = kinematics.ik(geometry, x)
    stacked = np.stack([x, x[::-1]])
    np.testing.assert_allclose(
        statics.holding_torques(geometry, stacked)[1],
        [statics.holding_torques(geometry, p) for p in x[::-1]],
        rtol=1e-12,
    )
    np.testing.assert_allclose(
        statics.task_inertia(geometry, stacked)[0],
        [statics.task_inertia(geometry, p) for p in x],
        rtol=1e-12,
        atol=1e-15,
    )
    one_by_one = [statics.inverse_dynamics_torques(geometry, *a) for a in zip(x, x_dot, x_ddot)]
    np.testing.assert_allclose(
        statics.inverse_dynamics_torques(geometry, x, x_dot, x_ddot), one_by_one, rtol=1e-9
    )
    np.testing.assert_allclose(
        statics.feedforward_torques(geometry, x, x_ddot, "inverse_dynamics", xd_d=x_dot),
        one_by_one,
        rtol=1e-9,
    )
    without_rates = [
        statics.inverse_dynamics_torques(geometry, p, np.zeros(6), a) for p, a in zip(x, x_ddot)
    ]
    np.testing.assert_allclose(
        statics.feedforward_unchecked(geometry, x, theta, x_ddot, "inverse_dynamics"),
        without_rates,
        rtol=1e-9,
    )
    np.testing.assert_allclose(
        statics.feedforward_unchecked(geometry, x, theta),
        statics.holding_torques(geometry, x),
        rtol=1e-12,
    )
    assert np.array_equal(statics.feedforward_torques(geometry, x, mode="none"), np.zeros((4, 6)))
    beyond = X_HOME + np.array([0, 0, 0, 0, 0, 0.2])  # "none" needs no kinematics
    assert np.array_equal(statics.feedforward_torques(geometry, beyond, mode="none"), np.zeros(6))
    assert np.array_equal(
        statics.feedforward_unchecked(geometry, x, theta, mode="none"), np.zeros((4, 6))
    )
    with pytest.raises(InvalidConfigError, match="xdd_d"):
        statics.feedforward_unchecked(geometry, x, theta, None, "inverse_dynamics")


def test_the_compiled_effort_is_the_numpy_effort(geometry, random_poses):
    """motor_effort_compiled (pose by pose, compiled) against motor_effort_of, with and
    without a servo's friction."""
    rng = np.random.default_rng(12)
    x = random_poses[:7]
    x_dot = rng.normal(size=(7, 6)) * [0.5, 0.5, 0.5, 0.05, 0.05, 0.05]
    x_ddot = rng.normal(size=(7, 6)) * [2.0, 2.0, 2.0, 0.2, 0.2, 0.2]
    theta = kinematics.ik(geometry, x)
    J = kinematics.jacobian(geometry, x, theta)
    terms = kinematics.leg_terms(geometry, x, theta)
    for servo in (None, ServoModel()):
        T_c, rate_c = statics.motor_effort_compiled(geometry, x, x_dot, x_ddot, servo, theta, J)
        T, rate = statics.motor_effort_of(geometry, x, x_dot, x_ddot, servo, terms, J)
        np.testing.assert_allclose(rate_c, rate, rtol=1e-13, atol=1e-15)
        np.testing.assert_allclose(T_c, T, rtol=0, atol=1e-8 * np.abs(T).max())


def test_task_inertia_of_one_pose_from_the_single_pose_cache_is_the_batched_one(
    geometry, random_poses
):
    from stewart_drake.robot.single_pose import ik_single, jacobian_single

    for x in random_poses[:3]:
        _, cache = ik_single(geometry, x)
        J = jacobian_single(geometry, cache)
        np.testing.assert_allclose(
            statics.task_inertia_single(geometry, cache, J),
            statics.task_inertia(geometry, x),
            rtol=1e-12,
            atol=1e-15,
        )


def test_a_pose_whose_jacobian_is_exactly_singular_is_named_when_no_torques_hold_it(
    geometry, random_poses, monkeypatch
):
    """J^T singular at one pose of a batch (one leg's row zeroed, as if the leg gave no
    motion): SingularPoseError on cond, infinite, at the pose whose J is singular."""
    x = random_poses[:3]
    jacobian_of = statics.jacobian_of

    def one_singular(geometry, terms):
        J = jacobian_of(geometry, terms).copy()
        J[1, 2, :] = 0.0
        return J

    monkeypatch.setattr(statics, "jacobian_of", one_singular)
    with pytest.raises(SingularPoseError) as err:
        statics.holding_torques(geometry, x)
    assert err.value.measure == "cond" and err.value.value == np.inf
    assert err.value.threshold == kinematics.DEFAULT_COND_THRESHOLD
    np.testing.assert_array_equal(err.value.pose, x[1])


def test_the_pose_whose_jacobian_gives_no_torques_is_named(geometry, random_poses, monkeypatch):
    """J at the second pose of a batch unbounded (SingularPoseError on J), with one leg's row
    so small that the torques overflow (on T), or zero, no leg moving (cond(J) is NaN, counted
    as infinite): the error names that pose, from the holding torques, the inverse dynamics
    and motor_effort (the zero J: the holding torques)."""
    x = random_poses[:3]
    zeros = np.zeros((3, 6))
    jacobian_of = statics.jacobian_of
    every = (
        lambda: statics.holding_torques(geometry, x),
        lambda: statics.inverse_dynamics_torques(geometry, x, zeros, zeros),
        lambda: statics.motor_effort(geometry, x, zeros, zeros),
    )
    for change, measure, torques in (
        (lambda J: J.__setitem__((1, 2, 0), np.inf), "J", every),
        (lambda J: J.__setitem__((1, 2), J[1, 2] * 1e-310), "T", every),
        (lambda J: J.__setitem__(1, 0.0), "cond", every[:1]),
    ):

        def changed(geometry, terms, change=change):
            J = jacobian_of(geometry, terms).copy()
            change(J)
            return J

        monkeypatch.setattr(statics, "jacobian_of", changed)
        for f in torques:
            with pytest.raises(SingularPoseError) as err:
                f()
            assert err.value.measure == measure
            np.testing.assert_array_equal(err.value.pose, x[1])


def test_a_servo_at_rest_adds_no_friction(geometry, random_poses):
    """At rest (x_dot = 0, so theta_dot = 0 exactly) b theta_dot + F_c sign(theta_dot) is 0: the
    servo's torques are the ideal motors', in the numpy form and the compiled one."""
    x = random_poses[:2]
    rest = np.zeros((2, 6))
    x_ddot = np.array([[1.0, -1.0, 0.5, 0.1, 0.1, -0.2], [0, 0, 0, 0, 0, 0]])
    theta = kinematics.ik(geometry, x)
    J = kinematics.jacobian(geometry, x, theta)
    terms = kinematics.leg_terms(geometry, x, theta)
    servo = ServoModel()
    assert servo.coulomb_friction_Nm > 0
    T, rate = statics.motor_effort_of(geometry, x, rest, x_ddot, None, terms, J)
    assert np.array_equal(rate, np.zeros((2, 6)))
    T_servo, _ = statics.motor_effort_of(geometry, x, rest, x_ddot, servo, terms, J)
    np.testing.assert_array_equal(T_servo, T)
    T_c, _ = statics.motor_effort_compiled(geometry, x, rest, x_ddot, None, theta, J)
    T_c_servo, _ = statics.motor_effort_compiled(geometry, x, rest, x_ddot, servo, theta, J)
    np.testing.assert_array_equal(T_c_servo, T_c)


def test_the_compiled_effort_leaves_a_pose_it_cannot_finish_to_the_numpy_form(geometry):
    """A pose 50 nm below the top of pure heave (found by bisection on the reach ratio): a
    forward-difference step up leaves the workspace, so the compiled form hands the batch to
    the numpy form, which names the error: UnreachablePoseError from both."""
    lo, hi = X_HOME[5], X_HOME[5] + 0.2
    for _ in range(60):
        mid = 0.5 * (lo + hi)
        top = X_HOME + np.array([0, 0, 0, 0, 0, mid - X_HOME[5]])
        lo, hi = (
            (mid, hi) if np.abs(kinematics.leg_reach_ratio(geometry, top)).max() <= 1 else (lo, mid)
        )
    x = np.stack([X_HOME, X_HOME + np.array([0, 0, 0, 0, 0, lo - 5e-8 - X_HOME[5]])])
    x_dot = np.zeros((2, 6))
    theta = kinematics.ik(geometry, x)
    J = kinematics.jacobian(geometry, x, theta)
    with pytest.raises(UnreachablePoseError):
        statics.motor_effort_compiled(geometry, x, x_dot, x_dot, ServoModel(), theta, J)
    terms = kinematics.leg_terms(geometry, x, theta)
    with pytest.raises(UnreachablePoseError):
        statics.motor_effort_of(geometry, x, x_dot, x_dot, ServoModel(), terms, J)


def test_the_statics_name_the_pose_where_a_rod_is_orthogonal_to_its_crank_tip_s_motion(geometry):
    """Motor angles 0 (the cranks horizontal, their tips moving straight up) with the platform
    joints at the pivots' height (the rods horizontal): J is unbounded, and the holding torques,
    the inverse dynamics and the feed-forward name that pose, not the batch's first."""
    at_pivots = np.array([0, 0, 0, 0, 0, geometry.P_B[0, 2]])
    x = np.stack([X_HOME, at_pivots])
    theta = np.stack([kinematics.ik(geometry, X_HOME), np.zeros(6)])
    zeros = np.zeros((2, 6))
    for torques in (
        lambda: statics.holding_torques(geometry, x, theta),
        lambda: statics.inverse_dynamics_torques(geometry, x, zeros, zeros, theta),
        lambda: statics.feedforward_unchecked(geometry, x, theta),
    ):
        with pytest.raises(SingularPoseError) as err:
            torques()
        assert err.value.measure == "J"
        np.testing.assert_array_equal(err.value.pose, at_pivots)
