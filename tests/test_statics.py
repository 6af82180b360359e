"""Statics (model/statics.py): holding torques by virtual work against an independent potential,
the torques of a tool wrench against its virtual work, the task inertia against Drake's kinetic
energy, the crank rates of motor_effort, the gravity feed-forward."""

import numpy as np
import pytest

from stewart_drake.base.errors import InvalidConfigError
from stewart_drake.plant.closed_chain import assemble
from stewart_drake.plant.plant import make_plant
from stewart_drake.robot import kinematics, statics
from stewart_drake.robot.geometry import X_HOME
from stewart_drake.robot.servo import ServoModel


def test_holding_torques_do_no_net_virtual_work(geometry, random_poses):
    """Energy balance: T . d theta = dV for a small motion, from an independent potential."""
    rng = np.random.default_rng(2)
    g = geometry

    def potential(x):
        th = kinematics.ik(g, x)
        q_B, _ = kinematics.platform_joints(g, x)
        tip = g.crank_tips(th)
        z_crank = g.pivot_z + 0.5 * g.crank_length * np.sin(th)
        return g.gravity * (
            g.platform_mass * x[5]
            + g.crank_mass * z_crank.sum()
            + g.rod_mass * 0.5 * (tip[:, 2] + q_B[:, 2]).sum()
        )

    for x in random_poses[:20]:
        T = statics.holding_torques(g, x)
        dx = 1e-6 * rng.normal(size=6)
        d_theta = kinematics.ik(g, x + dx) - kinematics.ik(g, x - dx)
        dV = potential(x + dx) - potential(x - dx)
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
