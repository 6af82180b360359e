"""The station: the robot as a Diagram with documented ports, what a controller talks to.

:func:`~.diagram.make_stewart_station` (the shape of the manipulation course's
``MakeHardwareStation``) builds the discrete SAP ``MultibodyPlant`` of the scenario's robot with
everything that belongs to the robot, and exports the ports a controller and a study use.
Nothing of the controller, the reference or the loggers is in it:
:func:`~stewart_drake.run.diagram.make_stewart_diagram` composes station + reference +
controller (+ features + tuner) + loggers.

Beside it, what measures it and the scenario's sections it reads besides the robot as built
(:mod:`~.hardware`): the platform pose from the plant state (:class:`PlatformPoseSensor`),
white noise on a measured signal (:func:`add_white_noise`: the encoders' in the station, the
ideal pose sensor's in the Diagram, :class:`SensorNoise`) and the wrench on the tool
(:class:`ToolDisturbance`, through :class:`ToolWrench`).
"""

import math
import weakref
from dataclasses import dataclass, field

import numpy as np
from pydrake.common import RandomDistribution
from pydrake.common.value import AbstractValue
from pydrake.multibody.math import SpatialForce
from pydrake.multibody.plant import ExternallyAppliedSpatialForce
from pydrake.symbolic import Variable, floor
from pydrake.systems.framework import BasicVector, Diagram, DiagramBuilder, LeafSystem
from pydrake.systems.primitives import (
    Adder,
    ConstantVectorSource,
    DiscreteTimeDelay,
    Gain,
    LinearSystem,
    MatrixGain,
    PassThrough,
    RandomSource,
    Saturation,
    SymbolicVectorSystem,
    TrajectorySource,
)
from pydrake.trajectories import PiecewisePolynomial

from ..base.checks import MAX_SEED, as_number
from ..base.checks import check_int as _check_int
from ..base.errors import InvalidConfigError
from ..plant.backlash import crank_state_selectors, take_up_play
from ..plant.closed_chain import LoopClosure, assemble
from ..plant.plant import StewartPlantHandles, add_stewart_plant
from ..robot.kinematics import X_HOME
from ..robot.statics import holding_torques, p_ETool

# Drake's YAML loader reads the sections' field annotations (a Scenario's ``sensor_noise`` and
# ``disturbance``): this module must not use ``from __future__ import annotations``.


@dataclass
class SensorNoise:
    """White Gaussian noise on the measured pose and rate, drawn every control period.

    Attributes:
        std: 12 standard deviations [rad x3, m x3, rad/s x3, m/s x3] (or one for all).
        seed: seed of Drake's RandomSource, 0 .. 2^32 - 1.
    """

    std: list[float] = field(default_factory=lambda: [0.0] * 12)
    seed: int = 0

    def std_vector(self) -> np.ndarray:
        """(12,) the standard deviations, one broadcast to all."""
        return np.broadcast_to(np.asarray(self.std, dtype=float), (12,)).copy()

    def validate(self) -> None:
        """Check the fields (``sensor_noise.<name>``).

        Raises:
            InvalidConfigError: names the field.
        """
        try:
            std = self.std_vector()
        except (TypeError, ValueError):
            std = np.array([np.nan])
        if not (np.all(np.isfinite(std)) and np.all(std >= 0)):
            raise InvalidConfigError(
                f"sensor_noise.std needs 12 finite values >= 0 (rad, m, rad/s, m/s), got {self.std}"
            )
        _check_int("sensor_noise.seed", self.seed, 0, MAX_SEED)


#: Largest tool disturbance, N (push, contact) or N m (twist).
MAX_DISTURBANCE = 1e4


@dataclass
class ToolDisturbance:
    """A wrench on the tool tip (world frame) during the run, through the station's
    ``tool_wrench`` input.

    Attributes:
        kind: "push" (a force step), "twist" (a torque step) or "contact" (a force
            oscillating between 0 and ``magnitude`` at ``frequency_hz``, (1 - cos) shaped).
        magnitude: N (push, contact) or N m (twist), at most :data:`MAX_DISTURBANCE`.
        direction: 3 numbers, the force's or the torque's axis in the world frame (normalized).
        start_s: when it begins, s. duration_s: how long it lasts, s (0: to the end).
        frequency_hz: of the contact force, Hz.
    """

    kind: str = "push"
    magnitude: float = 5.0
    direction: list[float] = field(default_factory=lambda: [1.0, 0.0, 0.0])
    start_s: float = 1.0
    duration_s: float = 0.0
    frequency_hz: float = 2.0

    def validate(self) -> None:
        """Check every field (``disturbance.<name>``).

        Raises:
            InvalidConfigError: names the field.
        """
        if self.kind not in ("push", "twist", "contact"):
            raise InvalidConfigError(
                f"disturbance.kind must be 'push', 'twist' or 'contact', got {self.kind!r}"
            )
        for name in ("magnitude", "start_s", "duration_s", "frequency_hz"):
            as_number(f"disturbance.{name}", getattr(self, name), 0.0)
        # A tabletop platform of a kilogram: 10 kN (or 10 kN m) is far past anything it holds,
        # and a much larger number overflows the contact solver instead of failing the run.
        as_number("disturbance.magnitude", self.magnitude, 0.0, MAX_DISTURBANCE)
        axis = np.asarray(self.direction, dtype=float) if np.ndim(self.direction) == 1 else None
        if (
            axis is None
            or axis.shape != (3,)
            or not np.isfinite(axis).all()
            or np.linalg.norm(axis) == 0
        ):
            raise InvalidConfigError(
                f"disturbance.direction must be 3 finite numbers, not all "
                f"zero, got {self.direction!r}"
            )

    def wrench(self, t) -> np.ndarray:
        """(n, 6) [torque, force] at times t (s), world frame, on the tool tip."""
        t = np.atleast_1d(np.asarray(t, dtype=float))
        on = (t >= self.start_s) & ((self.duration_s <= 0) | (t < self.start_s + self.duration_s))
        axis = np.asarray(self.direction, dtype=float)
        axis = axis / np.linalg.norm(axis)
        level = np.where(on, self.magnitude, 0.0)
        if self.kind == "contact":
            level = level * 0.5 * (1 - np.cos(2 * np.pi * self.frequency_hz * (t - self.start_s)))
        out = np.zeros((t.size, 6))
        columns = slice(0, 3) if self.kind == "twist" else slice(3, 6)
        out[:, columns] = level[:, None] * axis
        return out


# -- the station ---------------------------------------------------------------------------


def add_tool_disturbance(builder, station, plan, live: bool) -> None:
    """The scenario's tool disturbance (:class:`ToolDisturbance`) on the station's
    ``tool_wrench``, in the run's Diagram (``builder``; ``plan`` its
    :class:`~stewart_drake.run.plan.RunPlan`); without one (or with a ``live`` reference, which
    has no end), the input is exported and fixed to zero in the Context
    (:meth:`~stewart_drake.run.diagram.StewartDiagram.initialize`): a fixed input is computed
    once, where a constant source would be re-evaluated at every plant step."""
    disturbance = plan.scenario.disturbance
    if disturbance is not None and not live:
        # The wrench sampled every plant step over the run and joined linearly.
        h = plan.plant_time_step_s
        t = np.arange(0.0, plan.duration_s + 2 * h, h)
        samples = PiecewisePolynomial.FirstOrderHold(t, disturbance.wrench(t).T)  # type: ignore[call-overload]  # stub shapes
        source = TrajectorySource(samples)
        wrench = builder.AddNamedSystem("tool_disturbance", source)
        builder.Connect(wrench.get_output_port(), station.GetInputPort("tool_wrench"))
    else:
        builder.ExportInput(station.GetInputPort("tool_wrench"), "tool_wrench")


def weak_callback(method):
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
            weak_callback(self._Calc),
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


def add_station_plant(builder, plan):
    """The robot as simulated, a MultibodyPlant named "plant" with its SceneGraph, added to
    ``builder``: :func:`~stewart_drake.plant.plant.add_stewart_plant` with the plan's
    ``plant_geometry`` and ``servo`` and its scenario's plant settings, contact and rod model
    (``plan`` a :class:`~stewart_drake.run.plan.RunPlan`). Returns (plant, scene_graph,
    handles)."""
    scenario = plan.scenario
    plant, scene_graph, handles = add_stewart_plant(
        builder,
        plan.plant_geometry,
        plant_config=scenario.plant,
        servo=plan.servo,
        contact=scenario.contact,
        rod_model=scenario.rod_model,
    )
    plant.set_name("plant")
    return plant, scene_graph, handles


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

    With the scenario's ``hardware``, the robot as built: the command passes the computation
    delay, the current limit and the current loop (:func:`current_loop`); the plant carries the
    motors' inertia, friction and play (:func:`~stewart_drake.plant.plant.add_stewart_plant`,
    :mod:`~stewart_drake.plant.backlash`); ``motor_angle`` is the encoders' reading, zero errors
    and noise included, quantized (:func:`quantizer`); docs/station.md, "The robot as built".
    Without it, the ideal robot: torques applied as commanded (up to ``torque_limit_Nm``),
    exact angles.

    Input ports:
        ``motor_torque`` (6,): motor torque commands, N m (leg order of reference_geometry.md).
        ``tool_wrench`` (6,): [torque, force] on the tool tip in the world frame (N m, N); fix it
            to zeros (:func:`~stewart_drake.run.diagram.make_stewart_diagram` does) when
            there is no disturbance.
    Output ports:
        ``motor_angle`` (6,): the crank (output shaft) angles the robot measures, rad; with
            gear play the crank's, not the rotor's.
        ``motor_rate`` (6,): the cranks' rates, rad/s.
        ``platform_state`` (12,): ground truth [phi, theta, psi, X, Y, Z] (rad, m) and rates
            (rad/s, m/s): for metrics and for an ideal pose sensor.
        ``motor_torque_applied`` (6,): the torques the motors apply, N m (after the torque
            limit), what the metrics count as effort.
        ``plant_state`` (nq + nv,): the MultibodyPlant's state (logging, replays).
        ``contact_results`` (abstract ``ContactResults``), only with the scenario's ``contact``:
            the contacts between the robot's parts.
    Attributes:
        plant, scene_graph, handles (:class:`~stewart_drake.plant.plant.StewartPlantHandles`),
        loop_closure (:class:`~stewart_drake.plant.closed_chain.LoopClosure`: each rod's gap to
        its platform joint from the plant's positions, made once for the guard and the run's
        result), sensor (the ground-truth :class:`PlatformPoseSensor`), plan (the
        :class:`~.plan.RunPlan` it was built from).
    Args:
        plan: the :class:`~.plan.RunPlan` (:func:`~.diagram.make_stewart_station` makes one from a
            scenario). meshcat: optional pydrake Meshcat.
    """

    def __init__(self, plan, meshcat=None):
        super().__init__()
        builder = DiagramBuilder()
        scenario = plan.scenario
        plant, scene_graph, handles = add_station_plant(builder, plan)
        self.plant, self.scene_graph, self.handles, self.plan = (plant, scene_graph, handles, plan)
        self.loop_closure = LoopClosure(handles)
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
        the encoders (their zero errors, white noise, if any, then the quantizer)."""
        plant, hardware = self.plant, self.plan.scenario.hardware
        select_q, select_v = crank_state_selectors(plant, self.handles)
        outputs = {}
        for name, matrix in (("motor_angle", select_q), ("motor_rate", select_v)):
            gain = builder.AddNamedSystem(name, MatrixGain(matrix))
            builder.Connect(plant.get_state_output_port(), gain.get_input_port())
            outputs[name] = gain.get_output_port()
        self.encoder_noise = None
        if hardware is not None:  # encoders: angle [+ zero error] [+ noise] -> quantizer
            q = hardware.encoders.quantum_rad
            offsets = self.plan.plant_geometry.encoder_offsets
            if np.any(offsets != 0.0):
                zero = builder.AddNamedSystem("encoder_zero_error", ConstantVectorSource(offsets))
                read = builder.AddNamedSystem("encoder_reading", Adder(2, 6))
                builder.Connect(outputs["motor_angle"], read.get_input_port(0))
                builder.Connect(zero.get_output_port(), read.get_input_port(1))
                outputs["motor_angle"] = read.get_output_port()
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

    def logged_pose(self):
        """What a run logs to give the true platform pose and rate: (``plant_state`` port,
        ``sensor.poses_from_states``), the plant's state converted a drained second at a time
        (:class:`~stewart_drake.run.run_logs.SignalLog`), so no Python runs per logged sample."""
        return self.GetOutputPort("plant_state"), self.sensor.poses_from_states

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
        With gear play, each crank rests on the flank that carries its holding torque at x
        (:func:`~stewart_drake.plant.backlash.take_up_play`), as on a robot that has held the
        pose: the run does not start with the cranks falling through the play.

        Raises:
            UnreachablePoseError: x cannot be reached (names the leg).
        """
        context = self.plant.GetMyMutableContextFromRoot(root_context)
        theta = assemble(self.plant, context, self.handles, x, x_dot)
        if self.handles.plays:
            T = holding_torques(self.plan.plant_geometry, np.asarray(x, dtype=float))
            take_up_play(self.plant, context, self.handles, T)
        return theta
