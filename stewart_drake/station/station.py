"""The station: the robot as a Diagram with documented ports, what a controller talks to.

:func:`~.diagram.make_stewart_station` (the shape of the manipulation course's
``MakeHardwareStation``) builds the discrete SAP ``MultibodyPlant`` of the scenario's robot with
everything that belongs to the robot, and exports the ports a controller and a study use.
Nothing of the controller, the reference or the loggers is in it:
:func:`~stewart_drake.run.diagram.make_stewart_diagram` composes station + reference +
controller (+ features + tuner) + loggers.
"""

from __future__ import annotations

import weakref

import numpy as np
from pydrake.common.value import AbstractValue
from pydrake.multibody.math import SpatialForce
from pydrake.multibody.plant import ExternallyAppliedSpatialForce
from pydrake.symbolic import Variable, floor
from pydrake.systems.framework import Diagram, DiagramBuilder, LeafSystem
from pydrake.systems.primitives import (
    ConstantVectorSource,
    DiscreteTimeDelay,
    LinearSystem,
    MatrixGain,
    PassThrough,
    Saturation,
    SymbolicVectorSystem,
)

from ..plant.closed_chain import assemble
from ..robot.kinematics import X_HOME
from ..robot.statics import p_ETool
from .sensors import PlatformPoseSensor, add_white_noise


def _weak(method):
    """``method`` (a bound method of a system) as a callback that does not keep its system
    alive. pydrake stores a system's callbacks in C++, where Python's garbage collector cannot
    see the cycle system -> callback -> system; drake 1.58 breaks it for events and vector
    outputs, not for abstract outputs (drake#24162), so a Diagram with this system would
    otherwise live as long as the process."""
    ref = weakref.WeakMethod(method)

    def callback(*args):
        return ref()(*args)

    return callback


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
            "spatial_forces",
            lambda: AbstractValue.Make([ExternallyAppliedSpatialForce()]),
            _weak(self._Calc),
            prerequisites_of_calc={self.all_input_ports_ticket()},
        )

    def _Calc(self, context, output):
        w = self._wrench.Eval(context)
        force = ExternallyAppliedSpatialForce()
        force.body_index = self._body
        force.p_BoBq_B = p_ETool
        force.F_Bq_W = SpatialForce(w[:3], w[3:])
        output.set_value([force])


def quantizer(quantum: float, size: int = 6) -> SymbolicVectorSystem:
    """A memoryless mid-tread quantizer y = q round(u / q), as a C++ ``SymbolicVectorSystem``
    (no Python per evaluation): the error is within +-q/2."""
    u = [Variable(f"u{i}") for i in range(size)]
    y = [quantum * floor(ui / quantum + 0.5) for ui in u]
    # The stubs list only numpy-array overloads; Drake takes lists of Variable and Expression.
    return SymbolicVectorSystem(input=u, output=y)  # type: ignore[call-overload]


def current_loop(time_constant_s: float, period_s: float, size: int = 6) -> LinearSystem:
    """The drive's first-order current (torque) loop as a discrete ``LinearSystem``.

    The state is the torque at the plant's update instants, x+ = a x + (1 - a) u with
    a = exp(-h / tau) (exact for a command held over the step); the output is the torque
    *averaged over the coming step*, y = c x + (1 - c) u with c = (tau / h)(1 - a), the impulse
    the plant integrates, so the lag adds no extra step of delay.
    """
    a = float(np.exp(-period_s / time_constant_s))
    c = time_constant_s / period_s * (1 - a)
    I = np.eye(size)
    return LinearSystem(A=a * I, B=(1 - a) * I, C=c * I, D=(1 - c) * I, time_period=period_s)


def _connect_actuators(builder, applied, handles) -> None:
    """The applied torques to the plant's actuation input; with the servo's dry-friction
    actuators (12 in all), those take no command and their desired state is zero."""
    if handles.n_actuators > 6:
        to_actuators = builder.AddNamedSystem(
            "actuators", MatrixGain(np.vstack([np.eye(6), np.zeros((handles.n_actuators - 6, 6))]))
        )
        builder.Connect(applied, to_actuators.get_input_port())
        builder.Connect(to_actuators.get_output_port(), handles.actuation_port)
        zero = builder.AddNamedSystem(
            "friction_target", ConstantVectorSource(np.zeros(handles.desired_state_port.size()))
        )
        builder.Connect(zero.get_output_port(), handles.desired_state_port)
    else:
        builder.Connect(applied, handles.actuation_port)


class StewartStation(Diagram):
    """The robot as built by :func:`~.diagram.make_stewart_station`; a Drake ``Diagram`` named
    "station".

    With the scenario's ``hardware``, the station is the robot as built (docs/hardware.md): the
    command passes the computation delay (``DiscreteTimeDelay``, whole control periods), the
    drive's current limit (``Saturation`` at the servo's peak torque) and its current loop
    (:func:`current_loop`); the plant carries the motors' reflected inertia, viscous and Coulomb
    friction (:func:`~stewart_drake.plant.plant.add_stewart_plant`); ``motor_angle`` is what the
    absolute encoders read: the crank angles plus optional white noise, quantized
    (:func:`quantizer`). Without it, the ideal robot: torques applied as commanded (up to
    ``torque_limit_Nm``), exact angles.

    Input ports:
        ``motor_torque`` (6,): motor torque commands, N m (leg order of reference_geometry.md).
        ``tool_wrench`` (6,): [torque, force] on the tool tip in the world frame (N m, N); fix it
            to zeros (:func:`~stewart_drake.run.diagram.make_stewart_diagram` does) when
            there is no disturbance.
    Output ports:
        ``motor_angle`` (6,): the motor shaft angles the robot measures, rad.
        ``motor_rate`` (6,): their rates, rad/s.
        ``platform_state`` (12,): ground truth [phi, theta, psi, X, Y, Z] (rad, m) and rates
            (rad/s, m/s): for metrics and for an ideal pose sensor.
        ``motor_torque_applied`` (6,): the torques the motors apply, N m (after the torque
            limit), what the metrics count as effort.
        ``plant_state`` (nq + nv,): the MultibodyPlant's state (logging, replays).
        ``contact_results`` (abstract ``ContactResults``), only with the scenario's ``contact``:
            the contacts between the robot's parts.
    Attributes:
        plant, scene_graph, handles (:class:`~stewart_drake.plant.plant.StewartPlantHandles`),
        sensor (the ground-truth :class:`~.sensors.PlatformPoseSensor`), plan (the
        :class:`~.plan.RunPlan` it was built from).
    Args:
        plan: the :class:`~.plan.RunPlan` (:func:`~.diagram.make_stewart_station` makes one from a
            scenario). meshcat: optional pydrake Meshcat.
    """

    def __init__(self, plan, meshcat=None):
        super().__init__()
        builder = DiagramBuilder()
        scenario = plan.scenario
        plant, scene_graph, handles = plan.add_plant(builder)
        self.plant, self.scene_graph, self.handles, self.plan = (plant, scene_graph, handles, plan)
        command = builder.AddNamedSystem("motor_torque", PassThrough(6))
        builder.ExportInput(command.get_input_port(), "motor_torque")
        applied = self._add_torque_pipe(builder, command.get_output_port())
        _connect_actuators(builder, applied, handles)
        builder.ExportOutput(applied, "motor_torque_applied")
        # Tool wrench -> plant.
        wrench = builder.AddNamedSystem("tool_wrench", ToolWrench(handles.platform))
        builder.ExportInput(wrench.get_input_port(), "tool_wrench")
        builder.Connect(wrench.get_output_port(), plant.get_applied_spatial_force_input_port())
        outputs = self._add_motor_sensors(builder)
        for name, port in outputs.items():
            builder.ExportOutput(port, name)
        self.sensor = builder.AddNamedSystem("platform_sensor", PlatformPoseSensor(plant, handles))
        builder.Connect(plant.get_state_output_port(), self.sensor.get_input_port())
        builder.ExportOutput(self.sensor.get_output_port(), "platform_state")
        builder.ExportOutput(plant.get_state_output_port(), "plant_state")
        if scenario.contact:
            builder.ExportOutput(plant.get_contact_results_output_port(), "contact_results")
        if meshcat is not None:
            from pydrake.visualization import ApplyVisualizationConfig

            ApplyVisualizationConfig(scenario.visualization, builder, meshcat=meshcat)
        builder.BuildInto(self)
        self.set_name("station")

    def _add_torque_pipe(self, builder, command):
        """Motor torques: command -> [computation delay] -> [current limit] -> [current loop];
        returns the applied torques' port (the delay and the loop are kept: their state starts at
        the first feed-forward, :meth:`initialize`)."""
        plan, servo, applied = self.plan, self.plan.servo, command
        self.delay = self.lag = None
        if plan.delay_periods > 0:
            # Sampled at k h, half a plant step after the controller wrote it: the sample itself
            # is one period late, so d periods of delay take d - 1 more (measured in a test).
            self.delay = builder.AddNamedSystem(
                "computation_delay",
                DiscreteTimeDelay(plan.control_period_s, plan.delay_periods - 1, 6),
            )
            builder.Connect(applied, self.delay.get_input_port())
            applied = self.delay.get_output_port()
        limit = plan.torque_limit_Nm
        if limit is not None:
            saturation = builder.AddNamedSystem(
                "torque_limit", Saturation(-limit * np.ones(6), limit * np.ones(6))
            )
            builder.Connect(applied, saturation.get_input_port())
            applied = saturation.get_output_port()
        if servo is not None and servo.current_time_constant_s > 0:
            self.lag = builder.AddNamedSystem(
                "current_loop", current_loop(servo.current_time_constant_s, plan.plant_time_step_s)
            )
            builder.Connect(applied, self.lag.get_input_port())
            applied = self.lag.get_output_port()
        return applied

    def _add_motor_sensors(self, builder) -> dict:
        """{"motor_angle", "motor_rate": port}: the crank angles and rates selected from the
        plant state (C++ systems: no Python per step); on the robot as built the angles pass
        the encoders (white noise, if any, then the quantizer)."""
        plant, hardware = self.plant, self.plan.scenario.hardware
        n_q, n = plant.num_positions(), plant.num_positions() + plant.num_velocities()
        select_q, select_v = np.zeros((6, n)), np.zeros((6, n))
        for i, joint in enumerate(self.handles.motors):
            select_q[i, joint.position_start()] = 1.0
            select_v[i, n_q + joint.velocity_start()] = 1.0
        outputs = {}
        for name, matrix in (("motor_angle", select_q), ("motor_rate", select_v)):
            gain = builder.AddNamedSystem(name, MatrixGain(matrix))
            builder.Connect(plant.get_state_output_port(), gain.get_input_port())
            outputs[name] = gain.get_output_port()
        self.encoder_noise = None
        if hardware is not None:  # encoders: angle [+ noise] -> quantizer
            q = hardware.encoders.quantum_rad
            if hardware.encoders.noise_counts > 0:
                self.encoder_noise, outputs["motor_angle"] = add_white_noise(
                    builder,
                    outputs["motor_angle"],
                    np.full(6, hardware.encoders.noise_counts * q),
                    self.plan.control_period_s,
                    ("encoder_noise", "encoder_noise_std", "noisy_angle"),
                )
            encoders = builder.AddNamedSystem("encoders", quantizer(q))
            builder.Connect(outputs["motor_angle"], encoders.get_input_port())
            outputs["motor_angle"] = encoders.get_output_port()
        return outputs

    def initialize(self, root_context, T0, seed: int = 0) -> None:
        """Start the pipes at rest: the pending commands (delay) and the current loop hold T0
        (6,) N m, and the encoder noise, if any, is seeded with ``seed``."""
        for system in (self.delay, self.lag):
            if system is not None:
                ctx = system.GetMyMutableContextFromRoot(root_context)
                size = ctx.get_discrete_state_vector().size()
                ctx.SetDiscreteState(np.tile(np.asarray(T0, dtype=float), size // 6))
        if self.encoder_noise is not None:
            from pydrake.common import RandomGenerator

            self.encoder_noise.SetRandomContext(
                self.encoder_noise.GetMyMutableContextFromRoot(root_context), RandomGenerator(seed)
            )

    def assemble(self, root_context, x=X_HOME, x_dot=None) -> np.ndarray:
        """Write the robot assembled at pose x (6,) [rad, m], moving at x_dot (6,) (default at
        rest), into the station's plant inside ``root_context``; returns the (6,) motor angles.

        Raises:
            UnreachablePoseError: x cannot be reached (names the leg).
        """
        return assemble(
            self.plant, self.plant.GetMyMutableContextFromRoot(root_context), self.handles, x, x_dot
        )
