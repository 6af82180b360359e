"""Measurement: the platform pose from the plant state (a Drake LeafSystem), and white noise on
a measured signal (the encoders' in the station, the ideal pose sensor's in the Diagram)."""

from __future__ import annotations

import math

import numpy as np
from pydrake.common import RandomDistribution
from pydrake.systems.framework import BasicVector, LeafSystem
from pydrake.systems.primitives import Adder, Gain, RandomSource

from ..plant.plant import StewartPlantHandles


def add_white_noise(builder, port, std, period_s: float, names: tuple):
    """Add white Gaussian noise of standard deviations ``std`` to the output ``port``, drawn
    every ``period_s``: RandomSource -> Gain(std) -> Adder(port, noise), C++ systems only.

    Args:
        builder: the DiagramBuilder. port: the output port measured (size n).
        std: (n,) standard deviations, the port's units. period_s: s.
        names: the names of the (source, gain, adder) systems.
    Returns:
        (source, noisy output port). The source's Context must be seeded
        (``SetRandomContext``): Drake gives every RandomSource a fresh seed otherwise.
    """
    std = np.asarray(std, dtype=float)
    source = builder.AddNamedSystem(
        names[0],
        RandomSource(RandomDistribution.kGaussian, std.size, sampling_interval_sec=period_s),
    )
    scale = builder.AddNamedSystem(names[1], Gain(std))
    add = builder.AddNamedSystem(names[2], Adder(2, std.size))
    builder.Connect(source.get_output_port(), scale.get_input_port())
    builder.Connect(port, add.get_input_port(0))
    builder.Connect(scale.get_output_port(), add.get_input_port(1))
    return source, add.get_output_port()


class PlatformPoseSensor(LeafSystem):
    """Platform pose and rate from the plant's state vector.

    Input port:  ``plant_state`` (nq + nv,) the MultibodyPlant state.
    Output port: ``x`` (12,) [phi, theta, psi, X, Y, Z] (rad, m) and their time derivatives
    (rad/s, m/s); roll-pitch-yaw as Drake's RollPitchYaw, rates from the angular velocity.

    Args:
        plant: the finalized MultibodyPlant; handles: from ``add_stewart_plant``.

    Measurement noise is not added here: the Diagram adds a seeded Drake ``RandomSource``
    (``Scenario.sensor_noise``), so a run repeats however often ``x`` is evaluated.
    """

    def __init__(self, plant, handles: StewartPlantHandles):
        super().__init__()
        body = handles.platform
        nq = plant.num_positions()
        self._iq = body.floating_positions_start()
        self._iv = nq + body.floating_velocities_start_in_v()
        self._state = self.DeclareVectorInputPort("plant_state", nq + plant.num_velocities())
        self.DeclareVectorOutputPort("x", 12, self._Calc)

    def pose_from_state(self, state) -> np.ndarray:
        """True (noise-free) pose and rate x (12,) from one plant state vector (nq + nv,), in
        Python floats (a few microseconds: the guard and an ideal sensor read it at run time)."""
        s = np.asarray(state, dtype=float)[self._iq : self._iv + 6].tolist()
        iv = self._iv - self._iq
        return np.array(
            _pose_and_rate(
                s[0:4], s[4:7], s[iv : iv + 3], s[iv + 3 : iv + 6], math.atan2, math.sqrt
            )
        )

    def poses_from_states(self, states) -> np.ndarray:
        """(N, 12) true poses and rates of plant states (N, nq + nv), vectorized: metrics use
        these, not the noisy measurement, and the Diagram need not log the sensor at all."""
        s = np.atleast_2d(np.asarray(states, dtype=float)).T
        iq, iv = self._iq, self._iv
        return np.array(
            _pose_and_rate(
                s[iq : iq + 4],
                s[iq + 4 : iq + 7],
                s[iv : iv + 3],
                s[iv + 3 : iv + 6],
                np.arctan2,
                np.sqrt,
            )
        ).T

    def _Calc(self, context, output: BasicVector):
        output.SetFromVector(self.pose_from_state(self._state.Eval(context)))


def _pose_and_rate(q, p, w_WE, v_WE, atan2, sqrt) -> list:
    """[roll, pitch, yaw, X, Y, Z, their rates] of the platform from its unit quaternion q
    (w, x, y, z; normalized here), position p, angular velocity w_WE and velocity v_WE (world),
    as Drake's ``RollPitchYaw`` gives them (R = Rz(yaw) Ry(pitch) Rx(roll); the same to 1e-15,
    a test). One code for floats (``math``) and arrays (``numpy``): pass atan2 and sqrt.
    The rates solve w_WE = E(rpy) rpy_dot (:func:`~stewart_drake.robot.kinematics.
    angular_velocity_map`) in closed form (singular at pitch = +-pi/2, gimbal lock)."""
    qw, qx, qy, qz = q
    norm = sqrt(qw * qw + qx * qx + qy * qy + qz * qz)
    qw, qx, qy, qz = qw / norm, qx / norm, qy / norm, qz / norm
    R20, R21, R22 = 2 * (qx * qz - qw * qy), 2 * (qy * qz + qw * qx), 1 - 2 * (qx * qx + qy * qy)
    R00, R10 = 1 - 2 * (qy * qy + qz * qz), 2 * (qx * qy + qw * qz)
    roll, pitch, yaw = atan2(R21, R22), atan2(-R20, sqrt(R21 * R21 + R22 * R22)), atan2(R10, R00)
    cy, sy = R00 / sqrt(R00 * R00 + R10 * R10), R10 / sqrt(R00 * R00 + R10 * R10)
    cp, sp = sqrt(R21 * R21 + R22 * R22), -R20
    wx, wy, wz = w_WE
    roll_dot = (cy * wx + sy * wy) / cp
    return [roll, pitch, yaw, *p, roll_dot, -sy * wx + cy * wy, wz + sp * roll_dot, *v_WE]
