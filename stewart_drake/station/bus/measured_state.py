"""The plant state at the pose the servos measured, for what reads the simulated plant's state
(the loggers, replays and the guard) on the bus (:class:`MeasuredPlantState`), and a Meshcat
view of it."""

from __future__ import annotations

import numpy as np
from pydrake.systems.framework import LeafSystem

from ...plant.sdf import rod_zero_rotations
from ...robot.single_pose import leg_constants


def bus_kernels():
    """:mod:`.kernels`, compiled (or loaded from numba's cache) when a station on the bus is
    first built, not when a module is imported."""
    from . import kernels

    return kernels


class MeasuredPlantState(LeafSystem):
    """A plant state for the measured pose, for the loggers, replays and the guard, which read
    ``plant_state``: the positions of the robot assembled at the pose of ``platform_state``
    (:func:`~stewart_drake.plant.closed_chain.assembled_positions`: cranks from the IK, rods aimed,
    platform at the pose; its loop closure is exact, so the guard's closure check passes and
    its tracking and clearance checks read the measured pose), the platform's velocity from the
    measured rates (w_WP = E(rpy) rpy_dot, v_WP = p_dot) and the cranks' from the IK Jacobian;
    the rods' spin and swing rates are left at zero (nothing measures them; nothing downstream
    reads them).

    Input port: ``platform_state`` (12,). Output port: ``plant_state`` (nq + nv,).
    """

    def __init__(self, plant, handles):
        super().__init__()
        self._plant, self._handles = plant, handles
        nq = plant.num_positions()
        geometry = handles.geometry
        self._kernels = bus_kernels()
        self._legs = np.array(leg_constants(geometry))
        self._legs.setflags(write=False)  # as the kernels were compiled for
        self._u_B = np.array(geometry.u_B, dtype=float)  # writable, as compiled
        self._R0 = np.array(rod_zero_rotations(geometry), dtype=float)
        rods = handles.rod_balls
        self._layout = np.array(
            [j.position_start() for j in handles.motors]
            + [rods[i].position_start() if rods else -1 for i in range(6)]
            + [handles.platform.floating_positions_start()]
            + [nq + handles.platform.floating_velocities_start_in_v()]
            + [nq + j.velocity_start() for j in handles.motors],
            dtype=np.int64,
        )
        self._x = self.DeclareVectorInputPort("platform_state", 12)
        self._x_in = np.zeros(12)
        self.DeclareVectorOutputPort(
            "plant_state", plant.num_positions() + plant.num_velocities(), self._Calc
        )

    def _Calc(self, context, output):
        x = self._x_in
        x[:] = self._x.Eval(context)
        self._kernels.plant_state(
            self._legs, self._u_B, self._R0, self._layout, x, output.get_mutable_value()
        )


class ShowMeasured(LeafSystem):
    """Draws the robot at the measured plant state in a Diagram of its own (the model's plant,
    SceneGraph and Drake's Meshcat visualizer, never simulated): every ``period_s`` a publish
    event sets the model plant's positions and force-publishes the visualizer."""

    def __init__(self, model, plant, period_s: float):
        super().__init__()
        self._model, self._plant = model, plant
        self._model_context = model.CreateDefaultContext()
        self._plant_context = plant.GetMyMutableContextFromRoot(self._model_context)
        n = plant.num_positions() + plant.num_velocities()
        self._state = self.DeclareVectorInputPort("plant_state", n)
        self.DeclarePeriodicPublishEvent(period_s, 0.0, self._Show)
        self.DeclareForcedPublishEvent(self._Show)

    def _Show(self, context):
        self._model_context.SetTime(context.get_time())
        self._plant.SetPositionsAndVelocities(self._plant_context, self._state.Eval(context))
        self._model.ForcedPublish(self._model_context)


__all__ = [
    "bus_kernels",
    "MeasuredPlantState",
    "ShowMeasured",
]
