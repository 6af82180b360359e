"""The pose sensor reads the plant state as Drake's roll-pitch-yaw."""

import numpy as np

from stewart_drake.run.diagram import make_stewart_diagram
from stewart_drake.run.scenario import (
    Scenario,
)


def test_the_pose_sensor_reads_the_state_as_drakes_roll_pitch_yaw():
    """The vectorized quaternion -> roll-pitch-yaw and angular velocity -> rpy rates agree with
    Drake's RollPitchYaw on arbitrary states (near gimbal lock included)."""
    from pydrake.common.eigen_geometry import Quaternion
    from pydrake.math import RollPitchYaw

    sd = make_stewart_diagram(Scenario(duration_s=0.1))
    sensor, plant = sd.sensor, sd.plant
    states = np.random.default_rng(0).normal(
        size=(300, plant.num_positions() + plant.num_velocities())
    )

    def drake(s):
        q = s[sensor._iq : sensor._iq + 4]
        rpy = RollPitchYaw(Quaternion(q / np.linalg.norm(q)))
        rates = rpy.CalcRpyDtFromAngularVelocityInParent(s[sensor._iv : sensor._iv + 3])
        return np.concatenate(
            [
                rpy.vector(),
                s[sensor._iq + 4 : sensor._iq + 7],
                rates,
                s[sensor._iv + 3 : sensor._iv + 6],
            ]
        )

    expected = np.array([drake(s) for s in states])
    np.testing.assert_allclose(sensor.poses_from_states(states), expected, rtol=0, atol=1e-12)
    np.testing.assert_allclose(sensor.pose_from_state(states[7]), expected[7], rtol=0, atol=1e-12)
