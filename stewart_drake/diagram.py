"""The one Diagram: plant, reference, sensor, LQI (and, optionally, features + ANN tuner), loggers."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np
from pydrake.systems.framework import BasicVector, DiagramBuilder, LeafSystem
from pydrake.systems.primitives import ConstantVectorSource, LogVectorOutput

from .controller import LqiController, LqiScales
from .errors import InvalidConfigError
from .geometry import StewartGeometry
from .guard import GuardConfig
from .plant import add_stewart_plant
from .sensors import PlatformPoseSensor
from .trajectories import ReferenceSource, make_trajectory
from .validation import check_config


@dataclass(frozen=True)
class StewartConfig:
    """Everything that defines one closed-loop run; SI units.

    Attributes:
        geometry: the robot (default reference_geometry.md).
        trajectory: a trajectory object (``evaluate(t)``) or a registered name ("paper").
        duration_s: simulated time, s.
        plant_time_step_s: MultibodyPlant period (SAP), s.
        control_period_s: LQI period h, s; a whole multiple of the plant step.
        schedule_period_s: gain re-scheduling period, s; a whole multiple of control_period_s.
        omega_Q, omega_R: fixed LQI weights (paper eq. 27), used when ``tuner`` is None.
        scales: normalization of Q and R (controller.LqiScales).
        feedforward: "gravity", "inverse_dynamics" or "none" (controller.LqiController).
        tuner: None for fixed weights, or "ann" for the density-feature ANN tuner.
        tuner_period_s: ANN tuner period, s.
        tuner_weights: path of the tuner's .npz (None: the shipped weights).
        feature_window: samples m + 1 of the density features (eqs. 35-36).
        log_period_s: logging period, s.
        sensor_noise_std: optional (12,) noise on the measured pose and rate.
        guard: checks before and during the run: singularity thresholds of the reference,
            bounds on loop closure and tracking error, where a diverged run is saved
            (:class:`~stewart_drake.guard.GuardConfig`).
    Raises:
        InvalidConfigError: a field out of range, a period that is not a whole multiple of the
            one it runs on, an unknown name (``validation.check_config``).
        MissingFileError: tuner_weights names no file.
    """

    geometry: StewartGeometry = field(default_factory=StewartGeometry)
    trajectory: Any = "paper"
    duration_s: float = 10.0
    plant_time_step_s: float = 1e-3
    control_period_s: float = 1e-3
    schedule_period_s: float = 1e-2
    omega_Q: float = 1.0
    omega_R: float = 1.0
    scales: LqiScales = field(default_factory=LqiScales)
    feedforward: str = "gravity"
    tuner: str | None = None
    tuner_period_s: float = 0.02
    tuner_weights: str | None = None
    feature_window: int = 50
    log_period_s: float = 1e-3
    sensor_noise_std: Any = None
    guard: GuardConfig = field(default_factory=GuardConfig)

    def __post_init__(self):
        check_config(self)
        for name in ("duration_s", "plant_time_step_s", "control_period_s", "schedule_period_s",
                     "tuner_period_s", "log_period_s"):
            value = getattr(self, name)
            if not (np.isfinite(value) and value > 0):
                raise InvalidConfigError(f"{name} must be a finite number > 0, got {value}")
        ratio = self.control_period_s / self.plant_time_step_s
        if abs(ratio - round(ratio)) > 1e-6 or round(ratio) < 1:
            raise InvalidConfigError(
                f"control_period_s ({self.control_period_s}) must be a whole multiple of "
                f"plant_time_step_s ({self.plant_time_step_s})")
        for name in ("omega_Q", "omega_R"):
            value = getattr(self, name)
            if not (np.isfinite(value) and 1e-3 <= value <= 1e3):
                raise InvalidConfigError(f"{name} must be in [1e-3, 1e3], got {value}")
        if self.tuner not in (None, "ann"):
            raise InvalidConfigError(f"tuner must be None or 'ann', got {self.tuner!r}")

    def resolved_trajectory(self):
        """The trajectory object (names are looked up in trajectories.TRAJECTORIES)."""
        if isinstance(self.trajectory, str):
            return make_trajectory(self.trajectory)
        return self.trajectory


@dataclass
class StewartDiagram:
    """Handles to the built Diagram and its pieces (see :func:`make_stewart_diagram`)."""

    diagram: Any
    plant: Any
    scene_graph: Any
    handles: Any
    controller: LqiController
    reference: ReferenceSource
    sensor: PlatformPoseSensor
    loggers: dict
    config: StewartConfig
    features: Any = None
    tuner: Any = None
    guard: Any = None          # guard.DivergenceGuard, attached by experiments.build_simulator


def make_stewart_diagram(config: StewartConfig | None = None, meshcat=None) -> StewartDiagram:
    """Build the closed-loop Diagram of the rotary Stewart platform.

    Wiring: ReferenceSource -> LqiController.x_d; MultibodyPlant state -> PlatformPoseSensor ->
    LqiController.x; LqiController.T -> plant actuation; [omega_Q, omega_R] from a constant
    source, or from DensityFeatures -> AnnTuner when ``config.tuner == "ann"``.

    Args:
        config: the run's settings (default: the paper's experiment).
        meshcat: optional pydrake Meshcat; adds the default visualization.
    Returns:
        :class:`StewartDiagram`; loggers (``LogVectorOutput``) are keyed "x" (measured, 12),
        "T" (torques, 6), "status" (controller, 5), "state" (plant),
        and with the tuner "omega" (2) and "rho" (12).
    Raises:
        InvalidConfigError: inconsistent periods or names.
    """
    config = config or StewartConfig()
    builder = DiagramBuilder()
    plant, scene_graph, handles = add_stewart_plant(builder, config.geometry,
                                                    config.plant_time_step_s)
    plant.set_name("plant")
    trajectory = config.resolved_trajectory()
    x_d0 = trajectory.evaluate(0.0)[0]
    # The LQI samples half a plant step after each plant update, when the plant already holds
    # the configuration of the next step's time: its reference leads by the same half step.
    reference = builder.AddNamedSystem("reference", ReferenceSource(
        trajectory, lead_s=0.5 * config.plant_time_step_s))
    sensor = builder.AddNamedSystem("sensor", PlatformPoseSensor(
        plant, handles, noise_std=config.sensor_noise_std))
    controller = builder.AddNamedSystem("lqi", LqiController(
        config.geometry, period_s=config.control_period_s,
        schedule_period_s=config.schedule_period_s, scales=config.scales,
        feedforward=config.feedforward, offset_s=0.5 * config.plant_time_step_s,
        x_initial=x_d0))
    builder.Connect(plant.get_state_output_port(), sensor.get_input_port())
    builder.Connect(sensor.get_output_port(), controller.get_x_input_port())
    builder.Connect(reference.get_output_port(), controller.get_x_d_input_port())
    builder.Connect(controller.GetOutputPort("T"), handles.actuation_port)

    features = tuner = None
    loggers = {}
    if config.tuner == "ann":
        from .features import DensityFeatures
        from .tuner import AnnTuner, load_tuner

        features = builder.AddNamedSystem("features", DensityFeatures(
            window=config.feature_window, period_s=config.control_period_s))
        tuner = builder.AddNamedSystem("ann_tuner", AnnTuner(
            load_tuner(config.tuner_weights), period_s=config.tuner_period_s))
        error = builder.AddNamedSystem("pose_error", _PoseError())
        builder.Connect(sensor.get_output_port(), error.GetInputPort("x"))
        builder.Connect(reference.get_output_port(), error.GetInputPort("x_d"))
        builder.Connect(error.get_output_port(), features.GetInputPort("e_bar"))
        builder.Connect(controller.GetOutputPort("T"), features.GetInputPort("T"))
        builder.Connect(features.GetOutputPort("rho"), tuner.GetInputPort("rho"))
        builder.Connect(tuner.GetOutputPort("omega"), controller.get_omega_input_port())
        loggers["omega"] = LogVectorOutput(tuner.GetOutputPort("omega"), builder,
                                           config.log_period_s)
        loggers["rho"] = LogVectorOutput(features.GetOutputPort("rho"), builder,
                                         config.log_period_s)
    else:
        omega = builder.AddNamedSystem("omega", ConstantVectorSource(
            np.array([config.omega_Q, config.omega_R])))
        builder.Connect(omega.get_output_port(), controller.get_omega_input_port())

    period = config.log_period_s
    loggers["x"] = LogVectorOutput(sensor.get_output_port(), builder, period)
    loggers["T"] = LogVectorOutput(controller.GetOutputPort("T"), builder, period)
    loggers["status"] = LogVectorOutput(controller.GetOutputPort("status"), builder, period)
    loggers["state"] = LogVectorOutput(plant.get_state_output_port(), builder, period)
    for name, logger in loggers.items():
        logger.set_name(f"log_{name}")
    if meshcat is not None:
        from pydrake.visualization import AddDefaultVisualization

        AddDefaultVisualization(builder, meshcat)
    diagram = builder.Build()
    diagram.set_name("rotary_stewart_lqi")
    return StewartDiagram(diagram=diagram, plant=plant, scene_graph=scene_graph, handles=handles,
                          controller=controller, reference=reference, sensor=sensor,
                          loggers=loggers, config=config, features=features, tuner=tuner)


class _PoseError(LeafSystem):
    """e_bar = x - x_d on the pose (6,), from the sensor's x (12,) and the reference (18,)."""

    def __init__(self):
        super().__init__()
        self._x = self.DeclareVectorInputPort("x", 12)
        self._x_d = self.DeclareVectorInputPort("x_d", 18)
        self.DeclareVectorOutputPort("e_bar", 6, self._Calc)

    def _Calc(self, context, output: BasicVector):
        output.SetFromVector(self._x.Eval(context)[:6] - self._x_d.Eval(context)[:6])
