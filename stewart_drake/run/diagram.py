"""The one closed-loop Diagram: station + reference + controller (+ features + tuner) + loggers.

:func:`build_diagram` builds it from a :class:`~.plan.RunPlan` in stages, one function each:
the station, the reference and its feed-forward (:func:`~.reference.add_run_reference`), the
controller (built by its scenario choice), the measurement it reads, the learner, the tool
disturbance (:func:`~stewart_drake.station.station.add_tool_disturbance`), what drives the
controller's weights (a tuner choice, or a constant), the logs (:func:`~.run_logs.add_run_logs`),
the guard (:func:`~stewart_drake.station.guard.add_divergence_guard`) and LCM. Every derived
value is read from the plan; each scenario choice builds itself (the controller's ``make``, the
tuner's ``add_to``, the reference's ``make``, beside what they build); a stage that adds a
thing lives beside it, and the stages here only wire by port name. :func:`make_stewart_diagram`
plans a scenario first.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
from pydrake.systems.framework import Diagram, DiagramBuilder, OutputPort, System
from pydrake.systems.primitives import (
    Adder,
    ConstantVectorSource,
    RandomSource,
)

from ..base.errors import InvalidConfigError
from ..control.contract import ControllerContext, LearnerContext, check_controller
from ..control.estimator import FkEstimator, PoseEstimator
from ..control.tuning import TunerPorts
from ..references.motion import Reference, learning_cycles
from ..robot.kinematics import X_HOME
from ..station.bus.station import HardwareStation
from ..station.guard import DivergenceGuard, add_divergence_guard
from ..station.station import (
    PlatformPoseSensor,
    StewartStation,
    add_tool_disturbance,
    add_white_noise,
)
from ..station.surrogate.axis import ExternalSignal
from ..station.surrogate.stage import SurrogatePorts
from .plan import RunPlan, make_plan
from .reference import ReferenceSources, add_run_reference
from .run_logs import SignalLog, add_run_logs
from .scenario import Scenario, dump_scenario
from .surrogate_wiring import add_surrogate

#: What the Diagram's station is: the simulated robot, or the real one on its servo bus.
Station = StewartStation | HardwareStation


@dataclass
class StewartDiagram:
    """Handles to the built Diagram and its pieces (see :func:`make_stewart_diagram`).

    Attributes:
        diagram: the Diagram. station: the :class:`~.station.StewartStation` in it, or with
            the scenario's ``bus`` the :class:`~.bus.station.HardwareStation`.
        controller: the controller system. reference: its :class:`~.reference.ReferenceSources`
            (or the live reference system). trajectory: the reference object (``evaluate(t)``;
            None with a live reference). loggers: name -> :class:`~.run_logs.SignalLogger`
            (``FindLog(root_context)``).
        plan: the :class:`~.plan.RunPlan` built (``scenario`` is its scenario). features,
            tuner: the tuner's systems, or None.
        noise: the sensor noise's ``RandomSource``, or None. estimator: the
            :class:`~stewart_drake.control.estimator.FkEstimator` on the encoders, or None.
        guard: the :class:`~.guard.DivergenceGuard` system checking the run.
        T_ff_initial: (6,) the feed-forward at t = 0, N m (the torque pipes start there).
        learner: the :class:`~stewart_drake.control.ilc.IterativeLearningController` when the
            scenario learns (``learning``), or None.
        lcm: the ``DrakeLcm`` the status and commands are published on (the scenario's
            ``lcm``; subscribe to it to receive them in process), or None.
        x_initial, x_dot_initial: (6,) where the run starts, the reference's pose and rate at
            t = 0 [rad, m; rad/s, m/s] (a live reference's start pose, at rest).
        surrogate: the surrogate's stage
            (:class:`~stewart_drake.station.surrogate.stage.SurrogatePorts`) with the
            scenario's ``surrogate``, or None; surrogate_signal: the
            :class:`~stewart_drake.station.surrogate.axis.ExternalSignal` it follows, or None.
    """

    diagram: Diagram
    station: Station
    controller: System
    reference: ReferenceSources | System
    trajectory: Reference | None  # None with a live reference
    loggers: dict
    plan: RunPlan
    features: System | None = None
    tuner: System | None = None
    noise: RandomSource | None = None
    estimator: FkEstimator | None = None
    guard: DivergenceGuard | None = None
    T_ff_initial: np.ndarray | None = None
    learner: System | None = None
    lcm: Any = None  # the DrakeLcm of the scenario's ``lcm``, or None
    x_initial: np.ndarray | None = None
    x_dot_initial: np.ndarray | None = None
    surrogate: SurrogatePorts | None = None
    surrogate_signal: ExternalSignal | None = None

    @property
    def scenario(self) -> Scenario:
        """The validated scenario the Diagram was built from (``plan.scenario``)."""
        return self.plan.scenario

    def scenario_yaml(self) -> str:
        """The scenario as YAML (:func:`~.scenario.dump_scenario`), e.g. for a saved run."""
        return dump_scenario(self.plan.scenario)

    @property
    def plant(self):
        return self.station.plant

    @property
    def handles(self):
        return self.station.handles

    @property
    def sensor(self) -> PlatformPoseSensor:
        return self.station.sensor

    def initialize(self, root_context) -> None:
        """Set what a Context needs before a run: the tool wrench fixed to zero when the scenario
        has no disturbance; the sensor and encoder noise seeded from the scenario (Drake gives
        every RandomSource a fresh seed otherwise, and two runs would differ); the station's
        torque pipes (delay, current loop) holding the first feed-forward torque."""
        from pydrake.common import RandomGenerator

        if self.diagram.HasInputPort("tool_wrench"):
            self.diagram.GetInputPort("tool_wrench").FixValue(
                _own_context(self.diagram, root_context), np.zeros(6)
            )
        noise = self.scenario.sensor_noise
        if self.noise is not None and noise is not None:  # the source exists for the noise
            self.noise.SetRandomContext(
                self.noise.GetMyMutableContextFromRoot(root_context),
                RandomGenerator(noise.seed),
            )
        for logger in self.loggers.values():  # the logs drain from this run's Context
            logger.log.bind(root_context)
        if self.surrogate is not None:
            self.surrogate.initialize(root_context)
        hw = self.scenario.hardware
        self.station.initialize(
            root_context, self.T_ff_initial, seed=hw.encoders.seed if hw is not None else 0
        )


def _own_context(system: System, root_context):
    """``system``'s Context inside ``root_context``: ``root_context`` itself when ``system`` is
    the root. pydrake's ``GetMyMutableContextFromRoot`` returns the root's own Context with a
    keep-alive on itself, a reference cycle Python cannot see: the Context (0.6 MB of the
    closed loop's) would never be freed (measured on drake 1.58, docs/performance.md)."""
    try:
        system.ValidateContext(root_context)
    except RuntimeError:  # a subsystem's: the root belongs to a Diagram around it (teleop)
        return system.GetMyMutableContextFromRoot(root_context)
    return root_context


def make_stewart_diagram(
    scenario: Scenario | RunPlan | None = None,
    meshcat=None,
    *,
    reference=None,
    controller=None,
    reference_system=None,
    controller_logs: bool = True,
) -> StewartDiagram:
    """Build the closed-loop Diagram of the rotary Stewart platform.

    The station (:func:`~make_stewart_station`), the reference and its feed-forward
    (:mod:`~.reference`), the controller connected by port name
    (:mod:`~stewart_drake.control.contract`; its ``T`` drives ``motor_torque``), the tuner's
    ``omega`` or constant weights, the disturbance on ``tool_wrench`` (else zero) and a
    :class:`~.guard.DivergenceGuard` every ``scenario.guard.check_period_s``.

    Args:
        scenario: the run: a :class:`~.plan.RunPlan`, or a scenario planned here
            (:func:`~.plan.make_plan`; default: the paper's experiment on the ideal robot).
        meshcat: optional pydrake Meshcat (Drake's visualization of the station).
        reference: optional reference object overriding ``scenario.reference``: anything
            :func:`~.trajectories.as_trajectory` accepts (an object with ``evaluate(t)``, a Drake
            ``Trajectory``, a CSV path or a name).
        controller: optional factory ``f(ControllerContext) -> LeafSystem`` or registered name,
            overriding ``scenario.controller``.
        reference_system: a live reference instead of the precomputed one (e.g.
            :class:`~.reference.TeleopReference`): output ports ``x_d`` (18) and ``T_ff`` (6),
            attributes ``x_initial`` (6,) and ``T_ff_initial`` (6,); its inputs are exported,
            with ``platform_state`` (12), ``x_d`` (18) and its ``limited`` port if any
            (``scenario.reference`` and ``duration_s`` unused, ``trajectory`` None).
        controller_logs: log the controller's "integral" and "e_bar" (False saves 48 B a sample).
    Returns:
        :class:`StewartDiagram`; loggers (each with Drake's ``FindLog(context)``) keyed "x"
        (the true platform pose and rate, 12), "T" (applied torques, 6), and when the controller
        has them "status", "integral", "e_bar" (the error the controller acted on: its
        estimate, on the hardware), every ``log_period_s`` in float32
        (:class:`~.run_logs.SignalLog`); "state" (the plant state, float64) every
        ``state_log_period_s``, with a learner's status under its ``status_port`` name; with
        the tuner "rho" (12, every tuner period).
    Raises:
        InvalidConfigError: a scenario field out of range, a controller that breaks the contract
            (names the port), a tuner without a controller that has ``omega`` and ``e_bar``.
        UnreachablePoseError: the reference leaves the workspace (first time and leg).
    """
    # Long for its docstring (every port and choice documented); the stages are functions below.
    plan = make_plan(
        scenario,
        reference=reference,
        controller=controller,
        with_reference=reference_system is None,
    )
    return build_diagram(
        plan, meshcat, reference_system=reference_system, controller_logs=controller_logs
    )


def build_diagram(
    plan: RunPlan,
    meshcat=None,
    *,
    reference_system=None,
    controller_logs: bool = True,
    lcm=None,
) -> StewartDiagram:
    """The closed-loop Diagram of a plan: :func:`make_stewart_diagram` without planning (a run
    built from a checked plan, :func:`~.simulate.build_simulator`).

    Args:
        plan: the :class:`~.plan.RunPlan` (with its reference object, unless
            ``reference_system`` is given). meshcat, reference_system, controller_logs: as
            :func:`make_stewart_diagram`.
        lcm: the ``DrakeLcm`` of the scenario's ``lcm`` when the caller has made it (and so
            checked its URL: :func:`~stewart_drake.station.lcm_publish.make_lcm`); made here
            otherwise.
    Returns:
        :class:`StewartDiagram`.
    """
    scenario = plan.scenario
    trajectory = None if reference_system is not None else plan.reference
    builder = DiagramBuilder()
    station = _station(plan, meshcat)
    builder.AddSystem(station)
    ref = add_run_reference(builder, plan, trajectory, station, reference_system)
    context = controller_context(plan, ref.x0, ref.x_dot0)
    system = plan.controller_factory(context)
    check_controller(system)  # the contract: its ports, by name and size
    if not system.get_name():
        system.set_name("controller")
    system = builder.AddSystem(system)
    inputs = {system.get_input_port(i).get_name() for i in range(system.num_input_ports())}
    outputs = {system.get_output_port(i).get_name() for i in range(system.num_output_ports())}
    measured, estimator, noise = _add_measurement(builder, station, scenario, context, inputs)
    applied = station.GetOutputPort("motor_torque_applied")
    x_d, learner = _add_learning(builder, station, plan, trajectory, ref.x_d, context)
    _connect_controller(builder, system, station, inputs, x_d, ref.T_ff, measured)
    add_tool_disturbance(builder, station, plan, live=reference_system is not None)
    features, tuner, loggers = _add_weights(
        builder, scenario, context, system, inputs, outputs, ref.x_d, applied
    )
    logged = outputs if controller_logs else outputs - {"integral", "e_bar"}
    loggers.update(add_run_logs(builder, station, system, logged, plan, learner))
    for name, logger in loggers.items():
        logger.set_name(f"log_{name}")
    surrogate, signal = add_surrogate(
        builder, plan, trajectory, meshcat, loggers, station.GetOutputPort("platform_state")
    )
    guard = add_divergence_guard(builder, station, system.GetOutputPort("T"), ref.x_d, plan)
    if scenario.lcm is not None:
        from ..station.lcm_publish import add_run_publishers

        T, config = system.GetOutputPort("T"), scenario.lcm
        lcm = add_run_publishers(builder, config, station, T, measured, ref.x_d, lcm)
    diagram = builder.Build()
    diagram.set_name("rotary_stewart")
    return StewartDiagram(
        diagram=diagram,
        station=station,
        controller=system,
        reference=ref.system,
        trajectory=trajectory,
        loggers=loggers,
        plan=plan,
        features=features,
        tuner=tuner,
        noise=noise,
        estimator=estimator,
        guard=guard,
        T_ff_initial=ref.T_ff_initial,
        learner=learner,
        lcm=lcm,
        x_initial=ref.x0,
        x_dot_initial=ref.x_dot0,
        surrogate=surrogate,
        surrogate_signal=signal,
    )


def controller_context(plan: RunPlan, x0, x_dot0) -> ControllerContext:
    """What the run of ``plan`` tells its controller's factory, starting at pose x0 (6,)
    [rad, m] moving at x_dot0 (6,) [rad/s, m/s]: on the robot as built a new encoders' pose
    estimator, with a network tuner its features' window. A new context (and estimator) each
    call."""
    hw, h = plan.scenario.hardware, plan.control_period_s
    pose_estimator = (
        None
        if hw is None
        else PoseEstimator(
            plan.geometry,
            h,
            hw.encoders.quantum_rad,
            x0,
            rate_cutoff_hz=hw.estimator.rate_cutoff_hz,
            tolerance_counts=hw.estimator.fk_tolerance_counts,
        )
    )
    tuner = plan.scenario.tuner
    return ControllerContext(
        geometry=plan.geometry,
        period_s=h,
        offset_s=plan.sample_offset_s,
        plant_time_step_s=plan.plant_time_step_s,
        x_initial=x0,
        x_dot_initial=x_dot0,
        torque_limit_Nm=plan.torque_limit_Nm,
        delay_periods=plan.delay_periods,
        pose_estimator=pose_estimator,
        feature_window=None if tuner is None else tuner.density_window(),
        servo=plan.servo,
    )


def _connect_controller(builder, system, station, inputs: set, x_d, T_ff, measured) -> None:
    """The controller's inputs, connected by name as the controller contract says (``omega`` is
    the weights' stage), its ``T`` to the station's ``motor_torque`` and its ``crank_goal`` to
    the station's (a bus in Position Control Mode has that input; the scenario pairs them).

    Raises:
        InvalidConfigError: a ``crank_goal`` on one side only.
    """
    sources = {
        "x_d": x_d,
        "T_ff": T_ff,
        "x": measured,
        "motor_angle": station.GetOutputPort("motor_angle"),
        "motor_rate": station.GetOutputPort("motor_rate"),
        "motor_torque_applied": station.GetOutputPort("motor_torque_applied"),
    }
    for name in inputs - {"omega"}:
        builder.Connect(sources[name], system.GetInputPort(name))
    builder.Connect(system.GetOutputPort("T"), station.GetInputPort("motor_torque"))
    goal = system.HasOutputPort("crank_goal"), station.HasInputPort("crank_goal")
    if goal == (True, True):
        builder.Connect(system.GetOutputPort("crank_goal"), station.GetInputPort("crank_goal"))
    elif any(goal):
        raise InvalidConfigError(
            "the controller streams crank goals but the station runs no position loop"
            if goal[0]
            else "the servos run their own position loop: the controller must stream crank_goal"
        )


def _add_measurement(
    builder, station: Station, scenario: Scenario, context: ControllerContext, inputs: set
):
    """The pose and rate a controller with an ``x`` input reads: the station's ground truth, or
    on the robot as built the FK estimate from the encoders, plus the scenario's sensor noise.
    Returns (port, estimator or None, noise source or None)."""
    measured = station.GetOutputPort("platform_state")
    estimator = noise = None
    if "x" not in inputs:
        return measured, estimator, noise
    if context.pose_estimator is not None:  # the pose from the encoders
        estimator = builder.AddNamedSystem(
            "estimator",
            FkEstimator(
                context.pose_estimator, context.offset_s, context.x_initial, context.x_dot_initial
            ),
        )
        builder.Connect(station.GetOutputPort("motor_angle"), estimator.get_input_port())
        measured = estimator.get_output_port()
    if scenario.sensor_noise is not None:
        noise, measured = add_white_noise(
            builder,
            measured,
            scenario.sensor_noise.std_vector(),
            context.period_s,
            ("sensor_noise", "noise_std", "noisy_x"),
        )
    return measured, estimator, noise


def _add_learning(
    builder,
    station: Station,
    plan: RunPlan,
    trajectory,
    x_d: OutputPort,
    context: ControllerContext,
):
    """With the scenario's ``learning``, its learner between the reference and the controller:
    the learning choice builds it from a :class:`~.contract.LearnerContext` (the reference's
    cycles asked for through :func:`~.motion.learning_cycles`), and it is wired by port name: it
    reads the reference source's ``x_d`` and the station's ``motor_angle`` (what the robot
    measures), and an ``Adder`` puts its ``x_d_correction`` on the reference. The controller
    tracks that sum; the guard and the tuner keep the reference itself. Returns (the x_d port
    the controller reads, the learner or None).

    Raises:
        InvalidConfigError: learning on a live reference (it has no cycles to learn from); a
            reference without cycles and no ``learning.period_s``, or not one whole cycle in
            the run.
    """
    if plan.scenario.learning is None:
        return x_d, None
    if trajectory is None:
        raise InvalidConfigError(
            "learning needs a reference known in advance, with cycles; a "
            "live reference has none: set learning: null"
        )
    learner_context = LearnerContext(
        geometry=plan.geometry,
        reference=trajectory,
        period_s=plan.control_period_s,
        offset_s=context.offset_s,
        duration_s=plan.duration_s,
        floor=plan.encoder_count_at_tip,
        cycles=lambda period_s: learning_cycles(period_s, trajectory, plan.duration_s),
        encoder_quantum_rad=0.0
        if plan.scenario.hardware is None
        else plan.scenario.hardware.encoders.quantum_rad,
    )
    learner = builder.AddNamedSystem(
        "learner", plan.scenario.learning.make_learner(learner_context)
    )
    builder.Connect(x_d, learner.GetInputPort("x_d"))
    builder.Connect(station.GetOutputPort("motor_angle"), learner.GetInputPort("motor_angle"))
    add = builder.AddNamedSystem("learned_x_d", Adder(2, 18))
    builder.Connect(x_d, add.get_input_port(0))
    builder.Connect(learner.GetOutputPort("x_d_correction"), add.get_input_port(1))
    return add.get_output_port(), learner


def _add_weights(builder, scenario: Scenario, context, system, inputs, outputs, x_d, applied):
    """What drives the controller's ``omega`` input: the scenario's tuner
    (:meth:`~stewart_drake.control.tuning.TunerConfig.add_to`, wired to the controller
    ``system`` with its input and output port names, the reference ``x_d`` and the ``applied``
    torques, at the period and offset of the controller's ``context``), or the controller
    choice's constant weights. Returns (features or None, tuner or None, loggers: "rho" when
    the tuner has features)."""
    ports = TunerPorts(
        controller=system,
        inputs=frozenset(inputs),
        outputs=frozenset(outputs),
        x_d=x_d,
        T_applied=applied,
        period_s=context.period_s,
        offset_s=context.offset_s,
        duration_s=scenario.duration_s,
    )
    if scenario.tuner is not None:
        added = scenario.tuner.add_to(builder, ports)
        loggers = {}
        if added.rho_period_s is not None and added.features is not None:
            rho = {"rho": (added.features.GetOutputPort("rho"), np.float64)}
            log = SignalLog.add(builder, "log_rho", rho, added.rho_period_s, ports.duration_s)
            loggers["rho"] = log.logger("rho")
        return added.features, added.tuner, loggers
    if "omega" in ports.inputs:
        omega = builder.AddNamedSystem(
            "omega", ConstantVectorSource(np.array(scenario.controller.omega()))
        )
        builder.Connect(omega.get_output_port(), ports.controller.GetInputPort("omega"))
    return None, None, {}


def make_stewart_station(scenario=None, meshcat=None):
    """The robot of ``scenario`` as a Diagram with exported ports: the simulated robot
    (:class:`StewartStation`) or, with the scenario's ``bus``, the real one on its servo bus
    (:class:`~.bus.station.HardwareStation`, same ports; the bus is opened by the caller).

    Args:
        scenario: a :class:`~.plan.RunPlan`, or a :class:`~.scenario.Scenario`
            planned here without its reference (default: the paper's); its robot, plant,
            payload, motors and torque limit are used.
        meshcat: optional pydrake Meshcat; adds Drake's visualization (``scenario.visualization``).
    Returns:
        the :class:`StewartStation` or ``HardwareStation`` (a Diagram): ports ``motor_torque``,
        ``tool_wrench`` in; ``motor_angle``, ``motor_rate``, ``platform_state``,
        ``motor_torque_applied``, ``plant_state`` out.
    Raises:
        InvalidConfigError, InvalidGeometryError: the scenario does not validate.
        MissingExtraError: a scenario with ``bus`` without dynamixel-sdk installed.
    """
    return _station(make_plan(scenario, with_reference=False), meshcat)


def _station(plan: RunPlan, meshcat=None) -> Station:
    """The station of a plan: the backend its ``station_factory`` names
    (:class:`StewartStation`, or with the scenario's ``bus`` the
    :class:`~.bus.station.HardwareStation`)."""
    return plan.station_factory(plan, meshcat)


def held_station(scenario=None, x=X_HOME, T=None, wrench=None):
    """The station alone under constant inputs, ready to simulate: the robot assembled at pose x,
    ``motor_torque`` fixed to T (default the holding torques of x) and ``tool_wrench`` to wrench
    (default none); the torque pipes start at T.

    For experiments on the plant itself (drift under friction, statics against Drake's
    dynamics, the plant-alone speed benchmark).

    Args:
        scenario: the robot, a scenario or a plan (default the paper's). x: (6,) pose [rad, m].
            T: (6,) N m.
            wrench: (6,) [torque N m, force N] at the tool tip, world frame.
    Returns:
        (station, simulator, station_context): simulator.AdvanceTo(t) runs it; read the ports
        with station_context.
    Raises:
        UnreachablePoseError: x cannot be assembled; InvalidConfigError: a bad scenario.
    """
    from pydrake.systems.analysis import Simulator

    from ..robot.statics import holding_torques

    builder = DiagramBuilder()
    station = builder.AddSystem(make_stewart_station(scenario))
    builder.ExportInput(station.GetInputPort("motor_torque"), "motor_torque")
    builder.ExportInput(station.GetInputPort("tool_wrench"), "tool_wrench")
    diagram = builder.Build()
    simulator = Simulator(diagram)
    context = simulator.get_mutable_context()
    station.assemble(context, x)
    T = holding_torques(station.plan.plant_geometry, x) if T is None else np.asarray(T, float)
    station.initialize(context, T)
    diagram.get_input_port(0).FixValue(context, T)
    diagram.get_input_port(1).FixValue(context, np.zeros(6) if wrench is None else wrench)
    return station, simulator, station.GetMyContextFromRoot(context)
