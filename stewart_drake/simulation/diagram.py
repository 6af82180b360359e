"""The one closed-loop Diagram: station + reference + controller (+ features + tuner) + loggers."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Callable

import numpy as np
from pydrake.common import RandomDistribution
from pydrake.systems.framework import DiagramBuilder
from pydrake.systems.primitives import (Adder, ConstantVectorSource, Gain, LogVectorOutput,
                                        RandomSource, TrajectorySource)
from pydrake.trajectories import PiecewisePolynomial

from ..control.contract import ControllerContext, check_controller, resolve_controller
from ..control.estimator import FkEstimator, PoseEstimator
from ..control.lqi import LqiController
from ..control.pd import CrankPdController
from ..errors import InvalidConfigError
from .reference import ReferenceSources, add_reference_sources
from .scenario import (LqiDriver, PdDriver, RatioTunerDriver, Scenario, UserController,
                       WeightSchedule)
from .station import StewartStation
from .trajectories import as_trajectory


def lqi_factory(driver: LqiDriver) -> Callable[[ControllerContext], LqiController]:
    """The factory of the LQI a scenario's :class:`~.scenario.LqiDriver` describes."""
    def make(context: ControllerContext) -> LqiController:
        return LqiController(context.geometry, period_s=context.period_s,
                             schedule_period_s=driver.schedule_period_s,
                             scales=driver.scales.build(), offset_s=context.offset_s,
                             x_initial=context.x_initial, riccati=driver.riccati,
                             torque_limit_Nm=context.torque_limit_Nm,
                             anti_windup=driver.anti_windup,
                             delay_periods=context.delay_periods if driver.delay_compensation
                             else 0, estimator=context.pose_estimator,
                             x_dot_initial=context.x_dot_initial,
                             reference_governor=driver.reference_governor,
                             schedule_pose=driver.schedule_pose,
                             gain_transfer=driver.gain_transfer)
    return make


def pd_factory(driver: PdDriver) -> Callable[[ControllerContext], CrankPdController]:
    """The factory of the crank PD a scenario's :class:`~.scenario.PdDriver` describes."""
    def make(context: ControllerContext) -> CrankPdController:
        return CrankPdController(context.geometry, period_s=context.period_s,
                                 offset_s=context.offset_s, bandwidth_hz=driver.bandwidth_hz,
                                 damping=driver.damping, x_initial=context.x_initial,
                                 schedule_period_s=driver.schedule_period_s)
    return make


def controller_factory(scenario: Scenario, controller=None) -> Callable:
    """The factory ``f(ControllerContext) -> LeafSystem`` of a run.

    Args:
        scenario: its ``controller`` is used when ``controller`` is None.
        controller: a factory callable or a registered name (overrides the scenario).
    """
    if controller is not None:
        return resolve_controller(controller) if isinstance(controller, str) else controller
    driver = scenario.controller
    if isinstance(driver, LqiDriver):
        return lqi_factory(driver)
    if isinstance(driver, PdDriver):
        return pd_factory(driver)
    if isinstance(driver, UserController):
        factory = resolve_controller(driver.factory)
        return lambda context: factory(context, **driver.parameters)
    raise InvalidConfigError(f"unknown controller choice {type(driver).__name__}")


@dataclass
class StewartDiagram:
    """Handles to the built Diagram and its pieces (see :func:`make_stewart_diagram`).

    Attributes:
        diagram: the Diagram. station: the :class:`~.station.StewartStation` in it.
        controller: the controller system. reference: its :class:`~.reference.ReferenceSources`.
        trajectory: the reference object (``evaluate(t)``). loggers: name -> LogVectorOutput.
        scenario: the scenario built. features, tuner, noise: the systems, or None.
        learner: the :class:`~stewart_drake.control.ilc.IterativeLearningController` when the
            scenario learns (``learning``), or None.
        guard: the :class:`~.guard.DivergenceGuard`, attached by ``build_simulator``.
    """

    diagram: Any
    station: StewartStation
    controller: Any
    reference: ReferenceSources
    trajectory: Any
    loggers: dict
    scenario: Scenario
    features: Any = None
    tuner: Any = None
    noise: Any = None
    estimator: Any = None
    guard: Any = None
    learner: Any = None

    @property
    def plant(self):
        return self.station.plant

    @property
    def handles(self):
        return self.station.handles

    @property
    def sensor(self):
        return self.station.sensor

    def initialize(self, root_context) -> None:
        """Set what a Context needs before a run: the tool wrench fixed to zero when the scenario
        has no disturbance; the sensor and encoder noise seeded from the scenario (Drake gives
        every RandomSource a fresh seed otherwise, and two runs would differ); the station's
        torque pipes (delay, current loop) holding the first feed-forward torque."""
        from pydrake.common import RandomGenerator

        if self.scenario.disturbance is None:
            self.diagram.GetInputPort("tool_wrench").FixValue(root_context, np.zeros(6))
        if self.noise is not None:
            self.noise.SetRandomContext(self.noise.GetMyMutableContextFromRoot(root_context),
                                        RandomGenerator(self.scenario.sensor_noise.seed))
        hw = self.scenario.hardware
        self.station.initialize(root_context, self.reference.T_ff_table[0],
                                seed=hw.encoders.seed if hw is not None else 0)


def make_stewart_diagram(scenario: Scenario | None = None, meshcat=None, *, reference=None,
                         controller=None) -> StewartDiagram:
    """Build the closed-loop Diagram of the rotary Stewart platform.

    Wiring: the station (:func:`~.station.make_stewart_station`); the reference and its
    feed-forward (precomputed ``TrajectorySource``s, :mod:`~.reference`); the controller, whose
    ports are connected by name as the controller contract says
    (:mod:`~stewart_drake.control.contract`): ``x_d``, ``T_ff``, ``x`` (the station's
    ``platform_state`` [+ sensor noise]), ``motor_angle``, ``motor_rate``, ``omega`` (constant
    weights, or DensityFeatures(e_bar, T) -> AnnTuner when the scenario has a tuner); its ``T``
    drives the station's ``motor_torque``; ``tool_wrench`` is fixed to zero.

    Args:
        scenario: the run (default: the paper's experiment on the ideal robot).
        meshcat: optional pydrake Meshcat (Drake's visualization of the station).
        reference: optional reference object overriding ``scenario.reference``: anything
            :func:`~.trajectories.as_trajectory` accepts (an object with ``evaluate(t)``, a Drake
            ``Trajectory``, a CSV path or a name).
        controller: optional factory ``f(ControllerContext) -> LeafSystem`` or registered name,
            overriding ``scenario.controller``.
    Returns:
        :class:`StewartDiagram`; loggers (``LogVectorOutput``) keyed "state" (plant state),
        "T" (applied torques, 6), and when the controller has them "status", "integral",
        "e_bar" (the error the controller acted on: its estimate, on the hardware), and with the
        tuner "rho" (12, every tuner period).
    Raises:
        InvalidConfigError: a scenario field out of range, a controller that breaks the contract
            (names the port), a tuner without a controller that has ``omega`` and ``e_bar``.
        UnreachablePoseError: the reference leaves the workspace (first time and leg).
    """
    scenario = (scenario or Scenario()).validate()
    trajectory = as_trajectory(reference if reference is not None else scenario.make_reference())
    geometry = scenario.geometry()
    builder = DiagramBuilder()
    station = builder.AddSystem(StewartStation(scenario, meshcat))
    h_plant, h = scenario.plant_time_step_s, scenario.control_period_s
    # The controller samples half a plant step after each plant update, when the plant already
    # holds the configuration of the next step's time: its reference leads by the same half step.
    offset = 0.5 * h_plant
    delay = scenario.hardware.computation_delay_periods if scenario.hardware else 0
    ref = add_reference_sources(builder, trajectory, geometry, scenario.duration_s,
                                period_s=h, offset_s=offset, lead_s=0.5 * h_plant,
                                feedforward=scenario.feedforward, feedforward_lead_s=delay * h)
    x0, x_dot0, _ = (np.asarray(v, dtype=float) for v in trajectory.evaluate(0.0))
    hw = scenario.hardware
    pose_estimator = None if hw is None else PoseEstimator(
        geometry, h, hw.encoders.quantum_rad, x0, rate_cutoff_hz=hw.estimator.rate_cutoff_hz,
        tolerance_counts=hw.estimator.fk_tolerance_counts)
    context = ControllerContext(geometry=geometry, period_s=h, offset_s=offset,
                                plant_time_step_s=h_plant, x_initial=x0, x_dot_initial=x_dot0,
                                torque_limit_Nm=scenario.torque_limit(), delay_periods=delay,
                                pose_estimator=pose_estimator)
    system = controller_factory(scenario, controller)(context)
    check_controller(system)
    if not system.get_name():
        system.set_name("controller")
    system = builder.AddSystem(system)
    inputs = {system.get_input_port(i).get_name() for i in range(system.num_input_ports())}
    outputs = {system.get_output_port(i).get_name() for i in range(system.num_output_ports())}

    noise = estimator = None
    measured = station.GetOutputPort("platform_state")
    if pose_estimator is not None and "x" in inputs:       # the pose from the encoders
        estimator = builder.AddNamedSystem("estimator", FkEstimator(pose_estimator, offset, x0,
                                                                    x_dot0))
        builder.Connect(station.GetOutputPort("motor_angle"), estimator.get_input_port())
        measured = estimator.get_output_port()
    if scenario.sensor_noise is not None and "x" in inputs:
        std = np.broadcast_to(np.asarray(scenario.sensor_noise.std, dtype=float), (12,)).copy()
        noise = builder.AddNamedSystem("sensor_noise", RandomSource(
            RandomDistribution.kGaussian, 12, sampling_interval_sec=h))
        scale = builder.AddNamedSystem("noise_std", Gain(std))
        add = builder.AddNamedSystem("noisy_x", Adder(2, 12))
        builder.Connect(noise.get_output_port(), scale.get_input_port())
        builder.Connect(measured, add.get_input_port(0))
        builder.Connect(scale.get_output_port(), add.get_input_port(1))
        measured = add.get_output_port()
    x_d, learner = ref.x_d.get_output_port(), None
    if scenario.learning is not None:             # a learned correction on the reference
        from .learning import add_learning

        learner, x_d = add_learning(builder, scenario, trajectory, x_d,
                                    station.GetOutputPort("motor_angle"), offset)
    sources = {"x_d": x_d, "T_ff": ref.T_ff.get_output_port(),
               "x": measured, "motor_angle": station.GetOutputPort("motor_angle"),
               "motor_rate": station.GetOutputPort("motor_rate")}
    for name in inputs - {"omega"}:
        builder.Connect(sources[name], system.GetInputPort(name))
    builder.Connect(system.GetOutputPort("T"), station.GetInputPort("motor_torque"))
    if scenario.disturbance is not None:
        t = np.arange(0.0, scenario.duration_s + 2 * h_plant, h_plant)
        wrench = builder.AddNamedSystem("tool_disturbance", TrajectorySource(
            PiecewisePolynomial.FirstOrderHold(t, scenario.disturbance.wrench(t).T)))
        builder.Connect(wrench.get_output_port(), station.GetInputPort("tool_wrench"))
    else:
        # Exported and fixed to zero in the Context (build_simulator): a fixed input is computed
        # once, where a constant source would be re-evaluated at every plant step.
        builder.ExportInput(station.GetInputPort("tool_wrench"), "tool_wrench")
    applied = station.GetOutputPort("motor_torque_applied")

    features = tuner = None
    loggers = {}
    tuner_driver = scenario.tuner
    if isinstance(tuner_driver, WeightSchedule):
        if "omega" not in inputs:
            raise InvalidConfigError(f"a weight schedule drives the omega input; "
                                     f"{system.get_name()} has none")
        t_s = np.append(np.asarray(tuner_driver.t, dtype=float), scenario.duration_s + 1.0)
        values = np.array([tuner_driver.omega_Q, tuner_driver.omega_R], dtype=float)
        tuner = builder.AddNamedSystem("weight_schedule", TrajectorySource(
            PiecewisePolynomial.ZeroOrderHold(t_s, np.hstack([values, values[:, -1:]]))))
        builder.Connect(tuner.get_output_port(), system.GetInputPort("omega"))
    elif tuner_driver is not None:
        from ..control.features import DensityFeatures
        from ..control.tuner import AnnTuner, RatioTuner, load_ratio_tuner, load_tuner

        missing = [p for p, have in (("omega input", "omega" in inputs),
                                     ("e_bar output", "e_bar" in outputs)) if not have]
        if missing:
            raise InvalidConfigError(f"the ANN tuner needs a controller with an {' and an '.join(missing)} "
                                     f"(the LQI has both); {system.get_name()} has not")
        t = tuner_driver
        features = builder.AddNamedSystem("features", DensityFeatures(
            window=t.feature_window, period_s=h, offset_s=offset))
        if isinstance(t, RatioTunerDriver):
            tuner = builder.AddNamedSystem("ratio_tuner", RatioTuner(
                load_ratio_tuner(t.weights), period_s=t.period_s, smoothing_s=t.smoothing_s))
            builder.Connect(ref.x_d.get_output_port(), tuner.GetInputPort("x_d"))
        else:
            tuner = builder.AddNamedSystem("ann_tuner", AnnTuner(
                load_tuner(t.weights or None), period_s=t.period_s))
        builder.Connect(system.GetOutputPort("e_bar"), features.GetInputPort("e_bar"))
        builder.Connect(applied, features.GetInputPort("T"))
        builder.Connect(features.GetOutputPort("rho"), tuner.GetInputPort("rho"))
        builder.Connect(tuner.GetOutputPort("omega"), system.GetInputPort("omega"))
        # rho is computed when read: log it where the tuner reads it, not every millisecond.
        loggers["rho"] = LogVectorOutput(features.GetOutputPort("rho"), builder, t.period_s)
    elif "omega" in inputs:
        driver = scenario.controller
        weights = ([driver.omega_Q, driver.omega_R] if isinstance(driver, LqiDriver)
                   else [1.0, 1.0])
        omega = builder.AddNamedSystem("omega", ConstantVectorSource(np.array(weights)))
        builder.Connect(omega.get_output_port(), system.GetInputPort("omega"))

    period = scenario.log_period_s
    loggers["T"] = LogVectorOutput(applied, builder, period)
    loggers["state"] = LogVectorOutput(station.GetOutputPort("plant_state"), builder, period)
    for name in ("status", "integral", "e_bar"):
        if name in outputs:
            loggers[name] = LogVectorOutput(system.GetOutputPort(name), builder, period)
    if learner is not None:
        for name in ("ilc_status", "x_d_correction"):
            loggers[name] = LogVectorOutput(learner.GetOutputPort(name), builder, period)
    for name, logger in loggers.items():
        logger.set_name(f"log_{name}")
    diagram = builder.Build()
    diagram.set_name("rotary_stewart")
    return StewartDiagram(diagram=diagram, station=station, controller=system, reference=ref,
                          trajectory=trajectory, loggers=loggers, scenario=scenario,
                          features=features, tuner=tuner, noise=noise, estimator=estimator,
                          learner=learner)
