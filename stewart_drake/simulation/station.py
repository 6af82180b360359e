"""The station: the robot as a Diagram with documented ports, what a controller talks to.

:func:`make_stewart_station` (the shape of the manipulation course's ``MakeHardwareStation``)
builds the discrete SAP ``MultibodyPlant`` of the scenario's robot with everything that belongs to
the robot, and exports the ports a controller and a study use. Nothing of the controller, the
reference or the loggers is in it: :func:`~stewart_drake.simulation.diagram.make_stewart_diagram`
composes station + reference + controller (+ features + tuner) + loggers.
"""

from __future__ import annotations

import numpy as np
from pydrake.common.value import AbstractValue
from pydrake.multibody.math import SpatialForce
from pydrake.multibody.plant import ExternallyAppliedSpatialForce
from pydrake.systems.framework import Diagram, DiagramBuilder, LeafSystem
from pydrake.systems.primitives import MatrixGain, PassThrough, Saturation

from ..model.kinematics import X_HOME
from ..model.plant import add_stewart_plant, assemble
from .sensors import PlatformPoseSensor

#: The tool tip in the platform frame E, m: the end of the tool drawn on the platform (8 cm up).
p_ETool = np.array([0.0, 0.0, 0.08])


class ToolWrench(LeafSystem):
    """A wrench on the tool tip, as the plant's externally applied spatial force.

    Input port:  ``tool_wrench`` (6,) [torque (3) N m, force (3) N], world frame, applied at the
    tool tip (:data:`p_ETool` on the platform).
    Output port: ``spatial_forces``: ``list[ExternallyAppliedSpatialForce]`` for the plant's
    ``applied_spatial_force`` input. Drake caches it while the input does not change, so a
    constant wrench costs one evaluation per run.
    """

    def __init__(self, platform_body):
        super().__init__()
        self._body = platform_body.index()
        self._wrench = self.DeclareVectorInputPort("tool_wrench", 6)
        self.DeclareAbstractOutputPort(
            "spatial_forces", lambda: AbstractValue.Make([ExternallyAppliedSpatialForce()]),
            self._Calc, prerequisites_of_calc={self.all_input_ports_ticket()})

    def _Calc(self, context, output):
        w = self._wrench.Eval(context)
        force = ExternallyAppliedSpatialForce()
        force.body_index = self._body
        force.p_BoBq_B = p_ETool
        force.F_Bq_W = SpatialForce(w[:3], w[3:])
        output.set_value([force])


class StewartStation(Diagram):
    """The robot as built by :func:`make_stewart_station`; a Drake ``Diagram`` named "station".

    Input ports:
        ``motor_torque`` (6,): motor torque commands, N m (leg order of reference_geometry.md).
        ``tool_wrench`` (6,): [torque, force] on the tool tip in the world frame (N m, N); fix it
            to zeros (:func:`~stewart_drake.simulation.diagram.make_stewart_diagram` does) when
            there is no disturbance.
    Output ports:
        ``motor_angle`` (6,): the motor shaft angles the robot measures, rad.
        ``motor_rate`` (6,): their rates, rad/s.
        ``platform_state`` (12,): ground truth [phi, theta, psi, X, Y, Z] (rad, m) and rates
            (rad/s, m/s): for metrics and for an ideal pose sensor.
        ``motor_torque_applied`` (6,): the torques the motors apply, N m (after the torque
            limit), what the metrics count as effort.
        ``plant_state`` (nq + nv,): the MultibodyPlant's state (logging, replays).
    Attributes:
        plant, scene_graph, handles (:class:`~stewart_drake.model.plant.StewartPlantHandles`),
        sensor (the ground-truth :class:`~.sensors.PlatformPoseSensor`), scenario.
    """

    def __init__(self, scenario, meshcat=None):
        super().__init__()
        builder = DiagramBuilder()
        geometry = scenario.plant_geometry()
        plant, scene_graph, handles = add_stewart_plant(builder, geometry,
                                                        plant_config=scenario.plant)
        plant.set_name("plant")
        self.plant, self.scene_graph, self.handles, self.scenario = (plant, scene_graph, handles,
                                                                     scenario)
        # Motor torques: command -> [saturation] -> plant; the applied torques are exported.
        command = builder.AddNamedSystem("motor_torque", PassThrough(6))
        builder.ExportInput(command.get_input_port(), "motor_torque")
        applied = command.get_output_port()
        if scenario.torque_limit_Nm is not None:
            limit = scenario.torque_limit_Nm * np.ones(6)
            saturation = builder.AddNamedSystem("torque_limit", Saturation(-limit, limit))
            builder.Connect(applied, saturation.get_input_port())
            applied = saturation.get_output_port()
        builder.Connect(applied, handles.actuation_port)
        builder.ExportOutput(applied, "motor_torque_applied")
        # Tool wrench -> plant.
        wrench = builder.AddNamedSystem("tool_wrench", ToolWrench(handles.platform))
        builder.ExportInput(wrench.get_input_port(), "tool_wrench")
        builder.Connect(wrench.get_output_port(), plant.get_applied_spatial_force_input_port())
        # Motor angles and rates, selected from the plant state (C++ systems: no Python per step).
        n_q, n = plant.num_positions(), plant.num_positions() + plant.num_velocities()
        select_q, select_v = np.zeros((6, n)), np.zeros((6, n))
        for i, joint in enumerate(handles.motors):
            select_q[i, joint.position_start()] = 1.0
            select_v[i, n_q + joint.velocity_start()] = 1.0
        for name, matrix in (("motor_angle", select_q), ("motor_rate", select_v)):
            gain = builder.AddNamedSystem(name, MatrixGain(matrix))
            builder.Connect(plant.get_state_output_port(), gain.get_input_port())
            builder.ExportOutput(gain.get_output_port(), name)
        self.sensor = builder.AddNamedSystem("platform_sensor", PlatformPoseSensor(plant, handles))
        builder.Connect(plant.get_state_output_port(), self.sensor.get_input_port())
        builder.ExportOutput(self.sensor.get_output_port(), "platform_state")
        builder.ExportOutput(plant.get_state_output_port(), "plant_state")
        if meshcat is not None:
            from pydrake.visualization import ApplyVisualizationConfig

            ApplyVisualizationConfig(scenario.visualization, builder, meshcat=meshcat)
        builder.BuildInto(self)
        self.set_name("station")

    def assemble(self, root_context, x=X_HOME, x_dot=None) -> np.ndarray:
        """Write the robot assembled at pose x (6,) [rad, m], moving at x_dot (6,) (default at
        rest), into the station's plant inside ``root_context``; returns the (6,) motor angles.

        Raises:
            UnreachablePoseError: x cannot be reached (names the leg).
        """
        return assemble(self.plant, self.plant.GetMyMutableContextFromRoot(root_context),
                        self.handles, x, x_dot)


def make_stewart_station(scenario=None, meshcat=None) -> StewartStation:
    """The robot of ``scenario`` as a Diagram with exported ports (:class:`StewartStation`).

    Args:
        scenario: a :class:`~stewart_drake.simulation.scenario.Scenario` (default: the paper's);
            its robot, plant, payload and torque limit are used here.
        meshcat: optional pydrake Meshcat; adds Drake's visualization (``scenario.visualization``).
    Returns:
        the :class:`StewartStation` (a Diagram): ports ``motor_torque``, ``tool_wrench`` in;
        ``motor_angle``, ``motor_rate``, ``platform_state``, ``motor_torque_applied``,
        ``plant_state`` out.
    Raises:
        InvalidConfigError, InvalidGeometryError: the scenario does not validate.
    """
    from .scenario import Scenario

    scenario = (scenario or Scenario()).validate()
    return StewartStation(scenario, meshcat)
