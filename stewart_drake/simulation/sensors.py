"""Measurement of the platform pose from the plant state, as a Drake LeafSystem."""

from __future__ import annotations

import numpy as np
from pydrake.common.eigen_geometry import Quaternion
from pydrake.math import RollPitchYaw
from pydrake.systems.framework import BasicVector, LeafSystem

from ..model.plant import StewartPlantHandles


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
        """True (noise-free) pose and rate x (12,) from one plant state vector (nq + nv,)."""
        s = np.asarray(state, dtype=float)
        q = s[self._iq:self._iq + 4]
        rpy = RollPitchYaw(Quaternion(q / np.linalg.norm(q)))
        rpy_dot = rpy.CalcRpyDtFromAngularVelocityInParent(s[self._iv:self._iv + 3])
        return np.concatenate([rpy.vector(), s[self._iq + 4:self._iq + 7], rpy_dot,
                               s[self._iv + 3:self._iv + 6]])

    def poses_from_states(self, states) -> np.ndarray:
        """(N, 12) true poses and rates of logged plant states (N, nq + nv): metrics use these,
        not the noisy measurement, and the Diagram need not log the sensor at all."""
        return np.array([self.pose_from_state(s) for s in np.atleast_2d(states)]).reshape(-1, 12)

    def _Calc(self, context, output: BasicVector):
        output.SetFromVector(self.pose_from_state(self._state.Eval(context)))
