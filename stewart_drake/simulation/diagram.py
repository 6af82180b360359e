"""The one Diagram: plant, reference, sensor, LQI (and, optionally, features + ANN tuner), loggers."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np
from pydrake.common import RandomDistribution
from pydrake.systems.framework import DiagramBuilder
from pydrake.systems.primitives import (Adder, ConstantVectorSource, Gain, LogVectorOutput,
                                        RandomSource, Saturation)

from ..control.pd import CrankPdController
from ..control.lqi import LqiController, LqiScales
from ..model.geometry import StewartGeometry
from .guard import GuardConfig
from ..model.plant import add_stewart_plant
from .reference import ReferenceSources, add_reference_sources
from .sensors import PlatformPoseSensor
from .trajectories import make_trajectory
from pathlib import Path
from ..checks import as_number, check_multiple
from ..control.lqi import OMEGA_MAX, OMEGA_MIN
from ..errors import InvalidConfigError, MissingFileError
from ..model.statics import FEEDFORWARD_MODES

#: Controllers :func:`make_stewart_diagram` can put behind the same ports.
CONTROLLERS = ("lqi", "pd")


def check_config(config) -> None:
    """Validate a StewartConfig before anything is built or simulated.

    Checks (each raising :class:`InvalidConfigError` that names the field):
        - every period and the duration are finite numbers > 0 (also refuses strings, bools);
        - control_period_s is a whole multiple of plant_time_step_s, schedule_period_s and
          tuner_period_s of control_period_s (the controller and the tuner run on its clock),
          log_period_s and the guard's check_period_s of plant_time_step_s (a log between plant
          steps would compare a held state with a later reference);
        - omega_Q, omega_R in [1e-3, 1e3]; feedforward, tuner names; feature_window >= 1;
        - a trajectory name that exists, or an object with ``evaluate``;
        - tuner_weights, when given, names an existing file (:class:`MissingFileError`);
        - the guard settings (:class:`~stewart_drake.guard.GuardConfig`).
    """
    for name in ("duration_s", "plant_time_step_s", "control_period_s", "schedule_period_s",
                 "tuner_period_s", "log_period_s"):
        as_number(name, getattr(config, name), lo=0.0, lo_open=True)
    for name in ("omega_Q", "omega_R"):
        as_number(name, getattr(config, name), OMEGA_MIN, OMEGA_MAX)
    h = config.plant_time_step_s
    check_multiple("control_period_s", config.control_period_s, "plant_time_step_s", h)
    check_multiple("schedule_period_s", config.schedule_period_s, "control_period_s",
                   config.control_period_s)
    if config.tuner is not None:
        check_multiple("tuner_period_s", config.tuner_period_s, "control_period_s",
                       config.control_period_s)
    check_multiple("log_period_s", config.log_period_s, "plant_time_step_s", h)
    if config.feedforward not in FEEDFORWARD_MODES:
        raise InvalidConfigError(f"feedforward must be 'gravity', 'inverse_dynamics' or 'none', "
                                 f"got {config.feedforward!r}")
    if config.tuner not in (None, "ann"):
        raise InvalidConfigError(f"tuner must be None or 'ann', got {config.tuner!r}")
    if config.controller not in CONTROLLERS:
        raise InvalidConfigError(f"controller must be 'lqi' or 'pd', got {config.controller!r}")
    if config.tuner and config.controller != "lqi":
        raise InvalidConfigError("the ANN tuner drives the LQI's weights: use controller='lqi' "
                                 "with tuner='ann'")
    if config.riccati not in ("warm", "cold"):
        raise InvalidConfigError(f"riccati must be 'warm' or 'cold', got {config.riccati!r}")
    as_number("pd_bandwidth_hz", config.pd_bandwidth_hz, lo=0.0, lo_open=True)
    as_number("payload_scale", config.payload_scale, 0.1, 10.0)
    if config.torque_limit_Nm is not None:
        as_number("torque_limit_Nm", config.torque_limit_Nm, lo=0.0, lo_open=True)
    if config.sensor_noise_std is not None:
        try:
            std = np.broadcast_to(np.asarray(config.sensor_noise_std, dtype=float), (12,))
        except (TypeError, ValueError):
            std = np.array([np.nan])
        if not (np.all(np.isfinite(std)) and np.all(std >= 0)):
            raise InvalidConfigError(f"sensor_noise_std needs 12 finite values >= 0 (rad, m, "
                                     f"rad/s, m/s), got {config.sensor_noise_std}")
    seed = config.noise_seed
    if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)) or seed < 0:
        raise InvalidConfigError(f"noise_seed must be an integer >= 0, got {seed!r}")
    window = config.feature_window
    if isinstance(window, bool) or not isinstance(window, (int, np.integer)) or window < 1:
        raise InvalidConfigError(f"feature_window must be an integer >= 1, got {window!r}")
    if isinstance(config.trajectory, str):
        make_trajectory(config.trajectory)          # unknown name: lists the known ones
    elif not callable(getattr(config.trajectory, "evaluate", None)):
        raise InvalidConfigError(f"trajectory must be a name or an object with evaluate(t), got "
                                 f"{type(config.trajectory).__name__}")
    if config.tuner_weights is not None and not Path(config.tuner_weights).is_file():
        raise MissingFileError(f"no ANN tuner weights at {config.tuner_weights}: check the path, "
                               f"or leave tuner_weights unset for the shipped weights")
    guard = getattr(config, "guard", None)
    if guard is not None:
        if not isinstance(guard, GuardConfig):
            raise InvalidConfigError(f"guard must be a GuardConfig, got {type(guard).__name__}")
        check_multiple("guard.check_period_s", guard.check_period_s, "plant_time_step_s", h)


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
        feedforward: "gravity", "inverse_dynamics" or "none" (reference.feedforward_torques).
        controller: "lqi" (paper section III) or "pd" (baselines.CrankPdController).
        riccati: "warm" (Newton refinement of the last gain) or "cold" (DARE each re-schedule).
        pd_bandwidth_hz: closed-loop bandwidth of the "pd" baseline, Hz.
        tuner: None for fixed weights, or "ann" for the density-feature ANN tuner.
        tuner_period_s: ANN tuner period, s.
        tuner_weights: path of the tuner's .npz (None: the shipped weights).
        feature_window: samples m + 1 of the density features (eqs. 35-36).
        log_period_s: logging period, s.
        sensor_noise_std: optional (12,) standard deviation of white Gaussian noise added to
            the measured pose and rate (rad, m, rad/s, m/s), drawn every control period.
        noise_seed: seed of that noise (Drake RandomSource).
        payload_scale: the plant's platform mass and inertia are this multiple of the
            geometry's; the controller still uses ``geometry`` (an unknown payload).
        torque_limit_Nm: motor torque saturation, N m, or None.
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
    noise_seed: int = 0
    controller: str = "lqi"
    riccati: str = "warm"
    pd_bandwidth_hz: float = 20.0
    payload_scale: float = 1.0
    torque_limit_Nm: float | None = None
    guard: GuardConfig = field(default_factory=GuardConfig)

    def __post_init__(self):
        check_config(self)

    def plant_geometry(self) -> StewartGeometry:
        """The robot that is simulated: ``geometry`` with the payload scale on the platform."""
        if self.payload_scale == 1.0:
            return self.geometry
        return self.geometry.replace(
            platform_mass=self.geometry.platform_mass * self.payload_scale,
            platform_inertia=tuple(self.payload_scale * v for v in self.geometry.platform_inertia))

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
    controller: Any
    reference: ReferenceSources
    sensor: PlatformPoseSensor
    loggers: dict
    config: StewartConfig
    features: Any = None
    tuner: Any = None
    noise: Any = None
    guard: Any = None          # guard.DivergenceGuard, attached by experiments.build_simulator

    def seed_noise(self, root_context) -> None:
        """Seed the sensor noise (if any) in ``root_context`` from ``config.noise_seed``: Drake
        gives every RandomSource a fresh seed otherwise, and two runs would differ."""
        if self.noise is not None:
            from pydrake.common import RandomGenerator

            self.noise.SetRandomContext(self.noise.GetMyMutableContextFromRoot(root_context),
                                        RandomGenerator(self.config.noise_seed))


def make_stewart_diagram(config: StewartConfig | None = None, meshcat=None) -> StewartDiagram:
    """Build the closed-loop Diagram of the rotary Stewart platform.

    Wiring: reference and feed-forward sources (precomputed, :mod:`~stewart_drake.reference`) ->
    controller.x_d, controller.T_ff; MultibodyPlant state -> PlatformPoseSensor [+ noise] ->
    controller.x; controller.T [-> Saturation] -> plant actuation; [omega_Q, omega_R] from a
    constant source, or from DensityFeatures(controller.e_bar, T) -> AnnTuner when
    ``config.tuner == "ann"``. The controller is the LQI or the crank-space PD baseline.

    Args:
        config: the run's settings (default: the paper's experiment).
        meshcat: optional pydrake Meshcat; adds the default visualization.
    Returns:
        :class:`StewartDiagram`; loggers (``LogVectorOutput``) are keyed "T" (applied torques, 6),
        "status" (controller, 5), "state" (plant), and with the tuner "rho" (12, every
        tuner period). The platform
        pose is recovered from "state" (``sensor.poses_from_states``), so no logger evaluates the
        sensor.
    Raises:
        InvalidConfigError: inconsistent periods or names. UnreachablePoseError: the reference
            leaves the workspace (first time and leg).
    """
    config = config or StewartConfig()
    builder = DiagramBuilder()
    plant, scene_graph, handles = add_stewart_plant(builder, config.plant_geometry(),
                                                    config.plant_time_step_s)
    plant.set_name("plant")
    trajectory = config.resolved_trajectory()
    x_d0 = trajectory.evaluate(0.0)[0]
    h_plant, h = config.plant_time_step_s, config.control_period_s
    # The controller samples half a plant step after each plant update, when the plant already
    # holds the configuration of the next step's time: its reference leads by the same half step.
    offset = 0.5 * h_plant
    reference = add_reference_sources(builder, trajectory, config.geometry, config.duration_s,
                                      period_s=h, offset_s=offset, lead_s=0.5 * h_plant,
                                      feedforward=config.feedforward)
    sensor = builder.AddNamedSystem("sensor", PlatformPoseSensor(plant, handles))
    if config.controller == "lqi":
        controller = builder.AddNamedSystem("lqi", LqiController(
            config.geometry, period_s=h, schedule_period_s=config.schedule_period_s,
            scales=config.scales, offset_s=offset, x_initial=x_d0, riccati=config.riccati))
    else:
        controller = builder.AddNamedSystem("crank_pd", CrankPdController(
            config.geometry, period_s=h, offset_s=offset, bandwidth_hz=config.pd_bandwidth_hz,
            x_initial=x_d0))
    builder.Connect(plant.get_state_output_port(), sensor.get_input_port())
    measured = sensor.get_output_port()
    noise = None
    if config.sensor_noise_std is not None:
        std = np.broadcast_to(np.asarray(config.sensor_noise_std, dtype=float), (12,)).copy()
        noise = builder.AddNamedSystem("sensor_noise", RandomSource(
            RandomDistribution.kGaussian, 12, sampling_interval_sec=h))
        scale = builder.AddNamedSystem("noise_std", Gain(std))
        add = builder.AddNamedSystem("noisy_x", Adder(2, 12))
        builder.Connect(noise.get_output_port(), scale.get_input_port())
        builder.Connect(measured, add.get_input_port(0))
        builder.Connect(scale.get_output_port(), add.get_input_port(1))
        measured = add.get_output_port()
    builder.Connect(measured, controller.get_x_input_port())
    builder.Connect(reference.x_d.get_output_port(), controller.get_x_d_input_port())
    builder.Connect(reference.T_ff.get_output_port(), controller.get_T_ff_input_port())
    applied = controller.GetOutputPort("T")
    if config.torque_limit_Nm is not None:
        limit = config.torque_limit_Nm * np.ones(6)
        saturation = builder.AddNamedSystem("saturation", Saturation(-limit, limit))
        builder.Connect(applied, saturation.get_input_port())
        applied = saturation.get_output_port()
    builder.Connect(applied, handles.actuation_port)

    features = tuner = None
    loggers = {}
    if config.tuner == "ann":
        from ..control.features import DensityFeatures
        from ..control.tuner import AnnTuner, load_tuner

        features = builder.AddNamedSystem("features", DensityFeatures(
            window=config.feature_window, period_s=h))
        tuner = builder.AddNamedSystem("ann_tuner", AnnTuner(
            load_tuner(config.tuner_weights), period_s=config.tuner_period_s))
        builder.Connect(controller.GetOutputPort("e_bar"), features.GetInputPort("e_bar"))
        builder.Connect(applied, features.GetInputPort("T"))
        builder.Connect(features.GetOutputPort("rho"), tuner.GetInputPort("rho"))
        builder.Connect(tuner.GetOutputPort("omega"), controller.get_omega_input_port())
        # rho is computed when read: log it where the tuner reads it, not every millisecond.
        loggers["rho"] = LogVectorOutput(features.GetOutputPort("rho"), builder,
                                         config.tuner_period_s)
    else:
        omega = builder.AddNamedSystem("omega", ConstantVectorSource(
            np.array([config.omega_Q, config.omega_R])))
        builder.Connect(omega.get_output_port(), controller.get_omega_input_port())

    period = config.log_period_s
    loggers["T"] = LogVectorOutput(applied, builder, period)
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
                          loggers=loggers, config=config, features=features, tuner=tuner,
                          noise=noise)
