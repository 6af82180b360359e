"""Scenarios: everything that defines a run, as typed dataclasses that load from YAML.

A :class:`Scenario` is read with ``pydrake.common.yaml.yaml_load_typed`` (:func:`load_scenario`)
and written with ``yaml_dump_typed`` (:func:`dump_scenario`), like the manipulation course's
``Scenario`` for ``MakeHardwareStation``. Choices are tagged unions: in YAML,
``controller: !PdDriver {bandwidth_hz: 20}`` or ``reference: !CsvReference {path: run.csv}``.
Shipped scenarios live in ``scenarios/`` (``paper_ideal.yaml``: the paper's experiment on the
ideal robot); :func:`load_scenario` takes their names too.

Every choice is one class that checks its own fields and builds what it stands for, the one
place it does: the controllers (:class:`~stewart_drake.control.lqi.LqiDriver`,
:class:`~stewart_drake.control.pd.PdDriver`,
:class:`~stewart_drake.control.contract.UserController`: ``validate`` and ``make``, beside the
controllers they configure), the references
(:class:`ReferenceConfig`: ``validate`` and ``make``), the tuners (:class:`TunerConfig`:
``validate`` and ``add_to``, which wires it into the Diagram) and the tool disturbance. A new
choice is one such class added to its union (:data:`ControllerChoice`, :data:`ReferenceChoice`,
:data:`TunerChoice`).

Drake's YAML loader builds each class with its defaults and then sets fields, so the classes are
plain mutable dataclasses with concrete field types (this module must not use
``from __future__ import annotations``), and validation is a separate step:
:meth:`Scenario.validate` (run by every builder) names the field to fix. The robot's geometry, the
servo and the LQI's scales are frozen value types of the lower layers; :class:`Robot`,
:class:`Motors` and :class:`~stewart_drake.control.lqi.LqiScalesConfig` are their YAML forms
(same names, units and defaults; lists where they have tuples), with ``build()`` to get the value
type back (:class:`~stewart_drake.mirrors.ValueMirror`).
"""

import dataclasses
import functools
import importlib.resources
import typing
from dataclasses import dataclass, field
from pathlib import Path
from typing import ClassVar, List, Optional, Union

import numpy as np
from pydrake.common.yaml import yaml_dump_typed, yaml_load, yaml_load_typed
from pydrake.multibody.plant import MultibodyPlantConfig
from pydrake.systems.analysis import SimulatorConfig
from pydrake.visualization import VisualizationConfig

from ..checks import MAX_SEED, as_array, as_number, check_multiple
from ..checks import check_int as _check_int
from ..control.contract import UserController
from ..control.lqi import LQI_OMEGA_MAX, LQI_OMEGA_MIN, LqiDriver
from ..control.lqi import LqiScalesConfig as LqiScalesConfig  # re-exported: controller.scales
from ..control.pd import PdDriver
from ..errors import (
    CorruptFileError,
    InvalidConfigError,
    InvalidGeometryError,
    MissingFileError,
    StewartError,
)
from ..mirrors import ValueMirror
from ..model.geometry import StewartGeometry
from ..model.limits import (
    DEFAULT_COND_THRESHOLD,
    DEFAULT_EFFORT_MARGIN,
    DEFAULT_MIN_CLEARANCE_M,
    DEFAULT_MIN_SIGMA_MIN_INV,
    MotorLimits,
)
from ..model.servo import ServoModel
from ..model.statics import FEEDFORWARD_MODES
from .motion import ReferenceConfig as ReferenceConfig  # re-exported: the choices' base
from .organ_motion import OrganMotionReference
from .traces import TraceReference
from .trajectories import CsvReference, DataCollectionReference, NamedReference, SineReference

#: The scenario `run`, `collect`, `evaluate`, `workspace` and the diagram pictures use unless told:
#: the robot as built.
DEFAULT_SCENARIO = "paper_hardware"

_GEOMETRY, _SERVO = StewartGeometry(), ServoModel()


@dataclass
class Robot(ValueMirror):
    """The robot: every field of :class:`~stewart_drake.model.geometry.StewartGeometry`, same
    names, units and defaults (docs/reference_geometry.md, Table I; meanings there), lists for
    its tuples, but the motors' reflected inertia, which the scenario's ``hardware.motors`` sets;
    ``build()`` gives the geometry (validated there)."""

    value_class = StewartGeometry

    base_radius: float = _GEOMETRY.base_radius
    pivot_z: float = _GEOMETRY.pivot_z
    pivot_angles_deg: List[float] = field(
        default_factory=lambda: list(_GEOMETRY.pivot_angles_deg))
    platform_radius: float = _GEOMETRY.platform_radius
    platform_angles_deg: List[float] = field(
        default_factory=lambda: list(_GEOMETRY.platform_angles_deg))
    crank_angles_deg: List[float] = field(
        default_factory=lambda: list(_GEOMETRY.crank_angles_deg))
    crank_length: float = _GEOMETRY.crank_length
    rod_length: float = _GEOMETRY.rod_length
    rod_mass: float = _GEOMETRY.rod_mass
    rod_inertia: List[float] = field(default_factory=lambda: list(_GEOMETRY.rod_inertia))
    crank_mass: float = _GEOMETRY.crank_mass
    crank_inertia: List[float] = field(default_factory=lambda: list(_GEOMETRY.crank_inertia))
    platform_mass: float = _GEOMETRY.platform_mass
    platform_inertia: List[float] = field(
        default_factory=lambda: list(_GEOMETRY.platform_inertia))
    base_mass: float = _GEOMETRY.base_mass
    base_inertia: List[float] = field(default_factory=lambda: list(_GEOMETRY.base_inertia))
    base_plate_radius: float = _GEOMETRY.base_plate_radius
    rod_radius: float = _GEOMETRY.rod_radius
    rod_end_radius: float = _GEOMETRY.rod_end_radius
    platform_plate_radius: float = _GEOMETRY.platform_plate_radius
    gravity: float = _GEOMETRY.gravity
    motor_angle_min_deg: float = _GEOMETRY.motor_angle_min_deg
    motor_angle_max_deg: float = _GEOMETRY.motor_angle_max_deg
    crank_joint_cone_deg: float = _GEOMETRY.crank_joint_cone_deg
    platform_joint_cone_deg: float = _GEOMETRY.platform_joint_cone_deg


@dataclass
class Motors(ValueMirror):
    """The servo at each crank: every field of :class:`~stewart_drake.model.servo.ServoModel`, same
    names, units and defaults (at the output shaft: gear ratio, rotor inertia kg m^2, peak torque
    N m, current-loop time constant s, viscous N m s/rad and Coulomb N m friction, friction
    regularization N m s/rad, no-load speed rad/s); defaults: maxon EC 45 flat 50 W + a 4.3:1
    planetary gearhead (docs/hardware.md). ``build()`` gives the servo."""

    value_class = ServoModel

    name: str = _SERVO.name
    gear_ratio: float = _SERVO.gear_ratio
    rotor_inertia: float = _SERVO.rotor_inertia
    peak_torque_Nm: float = _SERVO.peak_torque_Nm
    current_time_constant_s: float = _SERVO.current_time_constant_s
    viscous_damping: float = _SERVO.viscous_damping
    coulomb_friction_Nm: float = _SERVO.coulomb_friction_Nm
    friction_damping: float = _SERVO.friction_damping
    no_load_speed_rad_s: float = _SERVO.no_load_speed_rad_s


# -- tuners ----------------------------------------------------------------------------------------

@dataclass(frozen=True)
class TunerPorts:
    """What a tuner is wired to in the Diagram (:meth:`TunerConfig.add_to`): the controller
    system with its port names, the reference's ``x_d`` (18) and the applied torques (6), and the
    control period and sample offset (s)."""

    controller: object
    inputs: frozenset
    outputs: frozenset
    x_d: object
    T_applied: object
    period_s: float
    offset_s: float
    duration_s: float


@dataclass(frozen=True)
class TunerSystems:
    """The systems a tuner added: ``features`` (or None), ``tuner`` (what drives ``omega``), and
    ``rho_period_s``, the period to log the features at (None: nothing to log)."""

    tuner: object
    features: object = None
    rho_period_s: Optional[float] = None


class TunerConfig:
    """Base of a scenario's tuner choices (:class:`AnnTunerDriver`, :class:`RatioTunerDriver`,
    :class:`WeightSchedule`): each checks its fields (:meth:`validate`) and wires what drives the
    controller's ``omega`` input into the Diagram (:meth:`add_to`), the one place it does."""

    #: How a run's result files mark the tuner (``run_<reference><suffix>``).
    run_suffix: ClassVar[str] = "_tuned"

    def validate(self, scenario: "Scenario") -> None:
        """Check the fields against the scenario's controller and periods.

        Raises:
            InvalidConfigError, MissingFileError: names the field (``tuner.<name>``).
        """
        if scenario.controller.takes_omega is False:
            raise InvalidConfigError("a tuner drives the LQI's weights (its omega input): use an "
                                     "LqiDriver controller with a tuner")

    def density_window(self) -> Optional[int]:
        """The samples of the density features' window a controller may buffer for the tuner
        (None: the tuner reads no features)."""
        return None

    def weights_path(self) -> Optional[Path]:
        """The network's weights file the run uses (None: no network)."""
        return None

    def add_to(self, builder, ports: TunerPorts) -> TunerSystems:
        """Add the systems that drive ``ports.controller``'s ``omega`` input, connected.

        Raises:
            InvalidConfigError: the controller lacks a port the tuner needs (named).
        """
        raise NotImplementedError


class _NetworkTuner(TunerConfig):
    """A network on the density features of the controller's error and torques (eqs. 35-36)
    that sets omega every ``period_s``: a subclass has the fields ``weights``, ``period_s`` and
    ``feature_window``, and makes the network's system (:meth:`make_tuner`)."""

    #: What the messages call it.
    kind: ClassVar[str] = "tuner"
    #: The name of its system in the Diagram.
    system_name: ClassVar[str] = "tuner"

    def validate(self, scenario: "Scenario") -> None:
        super().validate(scenario)
        as_number("tuner.period_s", self.period_s, lo=0.0, lo_open=True)
        check_multiple("tuner.period_s", self.period_s, "control_period_s",
                       scenario.control_period_s)
        _check_int("tuner.feature_window", self.feature_window, 1, 100_000)
        if self.weights and not Path(self.weights).exists():
            raise MissingFileError(f"no {self.kind} weights at {self.weights} (tuner.weights): "
                                   f"check the path, or leave it empty for the shipped weights")

    def density_window(self) -> Optional[int]:
        return self.feature_window

    def make_tuner(self):
        """The tuner system: input ``rho`` (12) (and ``x_d`` for ours), output ``omega`` (2)."""
        raise NotImplementedError

    def add_to(self, builder, ports: TunerPorts) -> TunerSystems:
        from ..control.features import N_FEATURES, DensityFeatures

        missing = [p for p, have in (("omega input", "omega" in ports.inputs),
                                     ("e_bar output", "e_bar" in ports.outputs)) if not have]
        name = ports.controller.get_name()
        if missing:
            raise InvalidConfigError(f"the {self.kind} needs a controller with an "
                                     f"{' and an '.join(missing)} (the LQI has both); {name} "
                                     f"has not")
        window = self.feature_window
        # A controller that buffers the samples spares the features a callback per period.
        buffered = "feature_window" in ports.outputs
        size = N_FEATURES * window + 2
        if buffered and ports.controller.GetOutputPort("feature_window").size() != size:
            raise InvalidConfigError(
                f"{name}: output port 'feature_window' has size "
                f"{ports.controller.GetOutputPort('feature_window').size()}; the tuner's window "
                f"of {window} samples needs {size} (contract, control/contract.py)")
        features = builder.AddNamedSystem("features", DensityFeatures(
            window=window, period_s=ports.period_s, offset_s=ports.offset_s, buffered=buffered))
        tuner = self._add_tuner(builder, ports)
        if buffered:
            builder.Connect(ports.controller.GetOutputPort("feature_window"),
                            features.GetInputPort("feature_window"))
        else:
            builder.Connect(ports.controller.GetOutputPort("e_bar"),
                            features.GetInputPort("e_bar"))
            builder.Connect(ports.T_applied, features.GetInputPort("T"))
        builder.Connect(features.GetOutputPort("rho"), tuner.GetInputPort("rho"))
        builder.Connect(tuner.GetOutputPort("omega"), ports.controller.GetInputPort("omega"))
        # rho is computed when read: log it where the tuner reads it, not every millisecond.
        return TunerSystems(tuner=tuner, features=features, rho_period_s=self.period_s)

    def _add_tuner(self, builder, ports: TunerPorts):
        return builder.AddNamedSystem(self.system_name, self.make_tuner())


@dataclass
class AnnTunerDriver(_NetworkTuner):
    """The ANN tuner of omega_Q, omega_R (paper section III.D) on density features
    (:class:`~stewart_drake.control.tuner.AnnTuner`).

    It moves the weights every period, as fast as the gains can follow: run it with the paper's
    gain switching, ``controller.gain_transfer: none``, as :func:`use_paper_tuner` does
    (``run --tuner ann``, ``evaluate``, the tuner study). Our ``integral`` transfer re-maps the
    integral states at every switch, and switched that fast the re-maps pile up and the loop
    chatters at the torque limit (docs/paper_notes.md).

    Attributes:
        weights: the tuner's ``.npz`` (``stewart-drake train``); empty for the shipped weights.
        period_s: tuner period, s (a whole multiple of the control period).
        feature_window: samples m + 1 of the density features (eqs. 35-36).
    """

    weights: str = ""
    period_s: float = 0.02
    feature_window: int = 50

    run_suffix: ClassVar[str] = "_ann"
    kind: ClassVar[str] = "ANN tuner"
    system_name: ClassVar[str] = "ann_tuner"

    def weights_path(self) -> Path:
        from ..control.tuner import DEFAULT_TUNER_PATH

        return Path(self.weights) if self.weights else DEFAULT_TUNER_PATH

    def make_tuner(self):
        from ..control.tuner import AnnTuner, load_tuner

        return AnnTuner(load_tuner(self.weights or None), period_s=self.period_s)


@dataclass
class RatioTunerDriver(_NetworkTuner):
    """Our tuner (:class:`~stewart_drake.control.tuner.RatioTuner`): the density features and the
    reference's speed and acceleration -> the ratio omega_Q / omega_R (the tuner study).

    Attributes:
        weights: its ``.npz`` (:func:`~stewart_drake.control.tuner.save_ratio_tuner`); empty
            for the shipped weights trained for the cost at lambda = 0.1
            (:data:`~stewart_drake.control.tuner.DEFAULT_RATIO_TUNER_PATH`; the ones for
            lambda = 0.01 and 1 ship beside them:
            :func:`~stewart_drake.control.tuner.ratio_tuner_path`).
        period_s: tuner period, s (a whole multiple of the control period).
        feature_window: samples m + 1 of the density features.
        smoothing_s: time constant of the low-pass on its log10 ratio, s (0: none).
    """

    weights: str = ""
    period_s: float = 0.02
    feature_window: int = 50
    smoothing_s: float = 0.0

    run_suffix: ClassVar[str] = "_ratio"
    kind: ClassVar[str] = "ratio tuner"
    system_name: ClassVar[str] = "ratio_tuner"

    def weights_path(self) -> Path:
        from ..control.tuner import DEFAULT_RATIO_TUNER_PATH

        return Path(self.weights) if self.weights else DEFAULT_RATIO_TUNER_PATH

    def make_tuner(self):
        from ..control.tuner import RatioTuner, load_ratio_tuner

        return RatioTuner(load_ratio_tuner(self.weights or None), period_s=self.period_s,
                          smoothing_s=self.smoothing_s)

    def _add_tuner(self, builder, ports: TunerPorts):
        tuner = super()._add_tuner(builder, ports)
        builder.Connect(ports.x_d, tuner.GetInputPort("x_d"))
        return tuner


@dataclass
class WeightSchedule(TunerConfig):
    """omega_Q and omega_R known in advance, held from each time to the next: the hindsight
    schedule and the hand-made ones of the tuner study.

    Attributes:
        t: increasing times, s (the first is 0).  omega_Q, omega_R: the weights from each time
            on, in [1e-3, 1e3].
    """

    t: List[float] = field(default_factory=lambda: [0.0])
    omega_Q: List[float] = field(default_factory=lambda: [1.0])
    omega_R: List[float] = field(default_factory=lambda: [1.0])

    def validate(self, scenario: "Scenario") -> None:
        super().validate(scenario)
        times = as_array("tuner.t", self.t)
        if times.ndim != 1 or times.size < 1 or times[0] != 0.0 or np.any(np.diff(times) <= 0):
            raise InvalidConfigError(f"tuner.t must be increasing times starting at 0 s, got "
                                     f"{self.t!r:.80}")
        for name in ("omega_Q", "omega_R"):
            values = as_array(f"tuner.{name}", getattr(self, name))
            if values.shape != times.shape:
                raise InvalidConfigError(f"tuner.{name} needs one value per time "
                                         f"({times.size}), got {values.size}")
            if np.any(values < LQI_OMEGA_MIN) or np.any(values > LQI_OMEGA_MAX):
                raise InvalidConfigError(f"tuner.{name} must be in [{LQI_OMEGA_MIN:g}, "
                                         f"{LQI_OMEGA_MAX:g}]")

    def add_to(self, builder, ports: TunerPorts) -> TunerSystems:
        from pydrake.systems.primitives import TrajectorySource
        from pydrake.trajectories import PiecewisePolynomial

        if "omega" not in ports.inputs:
            raise InvalidConfigError(f"a weight schedule drives the omega input; "
                                     f"{ports.controller.get_name()} has none")
        t_s = np.append(np.asarray(self.t, dtype=float), ports.duration_s + 1.0)
        values = np.array([self.omega_Q, self.omega_R], dtype=float)
        tuner = builder.AddNamedSystem("weight_schedule", TrajectorySource(
            PiecewisePolynomial.ZeroOrderHold(t_s, np.hstack([values, values[:, -1:]]))))
        builder.Connect(tuner.get_output_port(), ports.controller.GetInputPort("omega"))
        return TunerSystems(tuner=tuner)


TunerChoice = Union[AnnTunerDriver, RatioTunerDriver, WeightSchedule]


# -- references ------------------------------------------------------------------------------------

ReferenceChoice = Union[NamedReference, CsvReference, SineReference, DataCollectionReference,
                        OrganMotionReference, TraceReference]
ControllerChoice = Union[LqiDriver, PdDriver, UserController]


def _choices(union) -> tuple:
    """The classes of a tagged union (``typing.Union[A, B]`` -> (A, B))."""
    return typing.get_args(union)


@dataclass
class IlcDriver:
    """Learning from every cycle: a correction of the reference learned from the previous
    cycles' error (:class:`~stewart_drake.control.ilc.IterativeLearningController`), added to
    the ``x_d`` the controller tracks; needs a reference with cycles (the organ-motion library,
    a trace that repeats) or ``period_s``.

    Attributes:
        gain: learning gain gamma, in (0, 2).
        q_cutoff_hz: corner of the zero-phase Q-filter, Hz.
        lead_s: phase lead, s (the loop's delay and lag).
        error: "pose" (forward kinematics of the encoders) or "motor_angle" (the motor-angle
            error, mapped to the pose by J^-1).
        sample_period_s: the learner's record period, s (a whole multiple of control_period_s).
        bound_ratio: no cycle's measured RMS error may exceed this times that of the cycle its
            correction learned from, plus one encoder count at the crank tip; over it, the
            correction is rolled back to the best one and the gain halved.
        max_rollbacks: rollbacks before learning stops and the best correction is held.
        learn_cycles: learn from the first this many cycles, then hold (0: every cycle).
        gain_decay_cycles: n: the j-th update uses gain n / (n + j) (0: a constant gain); the
            correction then averages the cycles' noise out instead of following it.
        period_s: cycles of this period from t = 0 for a reference that has none of its own
            (0: the reference's).
    """

    gain: float = 0.8
    q_cutoff_hz: float = 25.0
    lead_s: float = 0.008
    error: str = "pose"
    sample_period_s: float = 0.004
    bound_ratio: float = 1.2
    max_rollbacks: int = 2
    learn_cycles: int = 0
    gain_decay_cycles: float = 4.0
    period_s: float = 0.0

    def validate(self, control_period_s: float, prefix: str = "learning.") -> None:
        """Check every field; raises InvalidConfigError naming it."""
        from ..control.ilc import ERROR_MODES

        as_number(f"{prefix}gain", self.gain, 0.0, 2.0, lo_open=True)
        if self.gain >= 2.0:
            raise InvalidConfigError(f"{prefix}gain must be below 2, got {self.gain}")
        as_number(f"{prefix}q_cutoff_hz", self.q_cutoff_hz, 0.0, lo_open=True)
        as_number(f"{prefix}lead_s", self.lead_s, 0.0, 1.0)
        if self.error not in ERROR_MODES:
            raise InvalidConfigError(f"{prefix}error must be one of {ERROR_MODES}, got "
                                     f"{self.error!r}")
        as_number(f"{prefix}sample_period_s", self.sample_period_s, 0.0, 1.0, lo_open=True)
        check_multiple(f"{prefix}sample_period_s", self.sample_period_s, "control_period_s",
                       control_period_s)
        as_number(f"{prefix}bound_ratio", self.bound_ratio, 1.0, 100.0)
        _check_int(f"{prefix}max_rollbacks", self.max_rollbacks, 0, 1000)
        _check_int(f"{prefix}learn_cycles", self.learn_cycles, 0, 10**6)
        as_number(f"{prefix}gain_decay_cycles", self.gain_decay_cycles, 0.0, 1e6)
        as_number(f"{prefix}period_s", self.period_s, 0.0, 3600.0)


# -- hardware ------------------------------------------------------------------------------------

@dataclass
class Encoders:
    """Absolute encoders on the six crank shafts, read at the control period.

    Attributes:
        counts_per_rev: counts per crank revolution (default 2^17, a 17-bit absolute encoder on
            the output shaft, RLS AksIM-2 class); the quantum is 2 pi / counts_per_rev rad.
        noise_counts: standard deviation of white Gaussian noise added before quantization,
            counts (0: quantization only).
        seed: seed of that noise (Drake RandomSource), 0 .. 2^32 - 1.
    """

    counts_per_rev: int = 2**17
    noise_counts: float = 0.0
    seed: int = 0

    @property
    def quantum_rad(self) -> float:
        """One count, rad."""
        return 2 * np.pi / self.counts_per_rev


@dataclass
class Estimator:
    """Pose and rate from the encoders (:class:`~stewart_drake.control.estimator.FkEstimator`).

    Attributes:
        rate_cutoff_hz: corner of the first-order low-pass on the differentiated FK pose, Hz.
        fk_tolerance_counts: Newton stops when every motor angle of the estimate is within this
            many counts of the measurement.
    """

    rate_cutoff_hz: float = 100.0
    fk_tolerance_counts: float = 0.01


@dataclass
class Hardware:
    """The robot as built: encoders, servos, the controller computer's delay.

    Attributes:
        encoders: the only position measurement (:class:`Encoders`).
        motors: the servo at each crank (:class:`Motors`).
        estimator: FK pose and rate estimation from the encoders (:class:`Estimator`).
        computation_delay_periods: control periods between the measurement and the torque it
            produces (0: none).
    """

    encoders: Encoders = field(default_factory=Encoders)
    motors: Motors = field(default_factory=Motors)
    estimator: Estimator = field(default_factory=Estimator)
    computation_delay_periods: int = 1

    def validate(self, control_period_s: float) -> None:
        """Check every field (``hardware.<path>``) for a controller of period
        ``control_period_s``.

        Raises:
            InvalidConfigError: names the field.
        """
        for name, kind in (("encoders", Encoders), ("motors", Motors), ("estimator", Estimator)):
            if not isinstance(getattr(self, name), kind):
                raise InvalidConfigError(f"hardware.{name} must be a {kind.__name__}, got "
                                         f"{type(getattr(self, name)).__name__}")
        _check_int("hardware.encoders.counts_per_rev", self.encoders.counts_per_rev, 16, 2**40)
        as_number("hardware.encoders.noise_counts", self.encoders.noise_counts, 0.0, 1e6)
        _check_int("hardware.encoders.seed", self.encoders.seed, 0, MAX_SEED)
        try:
            self.motors.build()
        except (StewartError, TypeError) as err:
            raise InvalidConfigError(f"hardware.motors: {err}") from None
        as_number("hardware.estimator.rate_cutoff_hz", self.estimator.rate_cutoff_hz, 0.0,
                  0.5 / control_period_s, lo_open=True)
        as_number("hardware.estimator.fk_tolerance_counts", self.estimator.fk_tolerance_counts,
                  0.0, 1.0, lo_open=True)
        _check_int("hardware.computation_delay_periods", self.computation_delay_periods, 0, 100)


# -- disturbance, sensor noise, guard --------------------------------------------------------------

@dataclass
class ToolDisturbance:
    """A wrench on the tool tip (world frame) during the run, through the station's
    ``tool_wrench`` input.

    Attributes:
        kind: "push" (a force step), "twist" (a torque step) or "contact" (a force
            oscillating between 0 and ``magnitude`` at ``frequency_hz``, (1 - cos) shaped).
        magnitude: N (push, contact) or N m (twist).
        direction: 3 numbers, the force's or the torque's axis in the world frame (normalized).
        start_s: when it begins, s. duration_s: how long it lasts, s (0: to the end).
        frequency_hz: of the contact force, Hz.
    """

    kind: str = "push"
    magnitude: float = 5.0
    direction: List[float] = field(default_factory=lambda: [1.0, 0.0, 0.0])
    start_s: float = 1.0
    duration_s: float = 0.0
    frequency_hz: float = 2.0

    def validate(self) -> None:
        """Check every field (``disturbance.<name>``).

        Raises:
            InvalidConfigError: names the field.
        """
        if self.kind not in ("push", "twist", "contact"):
            raise InvalidConfigError(f"disturbance.kind must be 'push', 'twist' or 'contact', "
                                     f"got {self.kind!r}")
        for name in ("magnitude", "start_s", "duration_s", "frequency_hz"):
            as_number(f"disturbance.{name}", getattr(self, name), 0.0)
        axis = np.asarray(self.direction, dtype=float) if np.ndim(self.direction) == 1 else None
        if axis is None or axis.shape != (3,) or not np.isfinite(axis).all() \
                or np.linalg.norm(axis) == 0:
            raise InvalidConfigError(f"disturbance.direction must be 3 finite numbers, not all "
                                     f"zero, got {self.direction!r}")

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

    def make_source(self, duration_s: float, step_s: float):
        """A ``TrajectorySource`` of the wrench (6,) over [0, duration_s], sampled every plant
        step ``step_s`` and joined linearly, for the station's ``tool_wrench`` input."""
        from pydrake.systems.primitives import TrajectorySource
        from pydrake.trajectories import PiecewisePolynomial

        t = np.arange(0.0, duration_s + 2 * step_s, step_s)
        return TrajectorySource(PiecewisePolynomial.FirstOrderHold(t, self.wrench(t).T))


@dataclass
class SensorNoise:
    """White Gaussian noise on the measured pose and rate, drawn every control period.

    Attributes:
        std: 12 standard deviations [rad x3, m x3, rad/s x3, m/s x3] (or one for all).
        seed: seed of Drake's RandomSource, 0 .. 2^32 - 1.
    """

    std: List[float] = field(default_factory=lambda: [0.0] * 12)
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
            raise InvalidConfigError(f"sensor_noise.std needs 12 finite values >= 0 (rad, m, "
                                     f"rad/s, m/s), got {self.std}")
        _check_int("sensor_noise.seed", self.seed, 0, MAX_SEED)


@dataclass
class GuardConfig:
    """Bounds of a guarded run (:mod:`~stewart_drake.simulation.guard`); SI units.

    Attributes:
        max_closure_error_m: largest distance between a rod's top end and its platform joint, m
            (the paper run stays below 1e-6 m); None disables the check.
        max_tracking_error: [rad, m]: largest |x - x_d| over the three angles and over the three
            positions. Loose by default (0.2 rad, 0.05 m): it catches a lost platform, not a
            poorly tuned one. None disables the check.
        check_period_s: the state's and torques' finiteness, closure and tracking are checked
            this often, s (a whole multiple of the plant step; Drake itself refuses a NaN
            actuation at the plant step that would use it).
        divergence_dir: folder of the saved ``.npz`` when a run diverges.
        cond_threshold: largest cond(J) along the reference (limits.DEFAULT_COND_THRESHOLD).
        min_sigma_min_inv: smallest 1/sigma_max(J) along the reference, (rad or m) per rad.
        min_clearance_m: smallest distance two parts of the robot may come to along the
            reference, m (collision geometry, :mod:`~stewart_drake.model.clearance`).
        effort_margin: the share of the motors' peak torque and no-load speed the reference may
            need (inverse dynamics with the reflected inertia and friction), in (0, 1]; the
            rest is the feedback's.
        allow_infeasible: run a reference that needs more than that anyway, with a warning (the
            motors saturate), instead of refusing it.
    Raises:
        InvalidConfigError: a bound that is not a finite positive number (or None), at
            construction and in :meth:`validate`.
    """

    max_closure_error_m: Optional[float] = 1e-3
    max_tracking_error: Optional[List[float]] = field(default_factory=lambda: [0.2, 0.05])
    check_period_s: float = 0.01
    divergence_dir: str = "results/diverged"
    cond_threshold: float = DEFAULT_COND_THRESHOLD
    min_sigma_min_inv: float = DEFAULT_MIN_SIGMA_MIN_INV
    min_clearance_m: float = DEFAULT_MIN_CLEARANCE_M
    effort_margin: float = DEFAULT_EFFORT_MARGIN
    allow_infeasible: bool = False

    def __post_init__(self):
        self.validate()

    def validate(self, prefix: str = "guard.") -> None:
        """Check every field; raises InvalidConfigError naming it."""
        if self.max_closure_error_m is not None:
            as_number(f"{prefix}max_closure_error_m", self.max_closure_error_m, 0.0, lo_open=True)
        if self.max_tracking_error is not None:
            bounds = self.max_tracking_error
            if isinstance(bounds, (str, bytes)) or np.ndim(bounds) != 1 or len(bounds) != 2:
                raise InvalidConfigError(f"{prefix}max_tracking_error must be [rad, m], got "
                                         f"{bounds!r}")
            self.max_tracking_error = [
                as_number(f"{prefix}max_tracking_error[{k}]", v, 0.0, lo_open=True)
                for k, v in enumerate(bounds)]
        as_number(f"{prefix}check_period_s", self.check_period_s, 0.0, lo_open=True)
        as_number(f"{prefix}cond_threshold", self.cond_threshold, 1.0, lo_open=True)
        as_number(f"{prefix}min_sigma_min_inv", self.min_sigma_min_inv, 0.0)
        as_number(f"{prefix}min_clearance_m", self.min_clearance_m, 0.0, 0.05)
        as_number(f"{prefix}effort_margin", self.effort_margin, 0.0, 1.0, lo_open=True)
        if not isinstance(self.allow_infeasible, bool):
            raise InvalidConfigError(f"{prefix}allow_infeasible must be true or false, got "
                                     f"{self.allow_infeasible!r}")
        if isinstance(self.divergence_dir, Path):
            self.divergence_dir = str(self.divergence_dir)
        if not isinstance(self.divergence_dir, str) or not self.divergence_dir:
            raise InvalidConfigError(f"{prefix}divergence_dir must be a folder path, got "
                                     f"{self.divergence_dir!r}")


def _default_plant() -> MultibodyPlantConfig:
    return MultibodyPlantConfig(time_step=1e-3, discrete_contact_approximation="sap")


@dataclass
class Scenario:
    """Everything that defines one closed-loop run; SI units. Defaults: the paper's experiment
    (eqs. 37-38, 10 s) on the ideal robot, LQI with omega_Q = omega_R = 1.

    Attributes:
        robot: the geometry and inertias (:class:`Robot`).
        plant: Drake's ``MultibodyPlantConfig``; ``time_step`` > 0 and a SAP approximation
            ("sap", "lagged", "similar"): ball constraints need a discrete SAP plant.
        simulator: Drake's ``SimulatorConfig`` (``target_realtime_rate`` etc.).
        visualization: Drake's ``VisualizationConfig``, applied when a Meshcat is given.
        reference: the path x_d(t) (a tagged choice: :class:`NamedReference`,
            :class:`CsvReference`, :class:`SineReference`, :class:`DataCollectionReference`,
            :class:`OrganMotionReference`, :class:`TraceReference`).
        feedforward: "gravity" (virtual work), "inverse_dynamics" or "none".
        controller: :class:`LqiDriver`, :class:`PdDriver` or :class:`UserController`.
        tuner: None (fixed weights), :class:`AnnTunerDriver` (the paper's network),
            :class:`RatioTunerDriver` (ours) or :class:`WeightSchedule` (weights known in
            advance); the tuners need a controller with the ``omega`` input and the ``e_bar``
            output (the LQI), a schedule only the ``omega`` input.
        duration_s: simulated time, s.
        control_period_s: controller period h, s (a whole multiple of the plant step).
        log_period_s: logging period, s (a whole multiple of the plant step).
        sensor_noise: None, or noise on the measured pose and rate (:class:`SensorNoise`).
        payload_scale: the simulated platform's mass and inertia are this multiple of the
            robot's; the controller still believes in ``robot`` (an unknown payload).
        torque_limit_Nm: motor torque saturation, N m, or None (with hardware, the lower of this
            and the motors' peak torque applies).
        guard: checks before and during the run (:class:`GuardConfig`).
        hardware: None for the ideal robot (the controller reads the exact pose, ideal torque
            sources, no friction, no delay), or :class:`Hardware` (encoders, FK estimation,
            servos with friction, delay).
        disturbance: None, or a wrench on the tool tip (:class:`ToolDisturbance`).
        contact: simulate contact between the robot's parts (SAP point contact on their
            collision geometry, :mod:`~stewart_drake.model.parts`): a collision becomes contact
            forces and the guard reports the first one with the parts' names. False (default,
            cheaper per step): parts would pass through each other, and the guard stops a run
            the moment two of them overlap.
        learning: None, or learning from every cycle (:class:`IlcDriver`): a correction of
            the reference the controller tracks, learned from the encoders.
    Raises:
        InvalidConfigError: (``validate``, run by every builder and at construction) a field
            out of range, a period that is not a whole multiple of the one it runs on, a wrong
            type; the message names the field path (e.g. ``controller.omega_Q``).
        InvalidGeometryError: the robot cannot be built (names the field).
        MissingFileError: a tuner weights file or a CSV reference that does not exist.
    """

    robot: Robot = field(default_factory=Robot)
    plant: MultibodyPlantConfig = field(default_factory=_default_plant)
    simulator: SimulatorConfig = field(default_factory=SimulatorConfig)
    visualization: VisualizationConfig = field(default_factory=VisualizationConfig)
    reference: ReferenceChoice = field(default_factory=NamedReference)
    feedforward: str = "gravity"
    controller: ControllerChoice = field(default_factory=LqiDriver)
    tuner: Optional[TunerChoice] = None
    duration_s: float = 10.0
    control_period_s: float = 1e-3
    log_period_s: float = 1e-3
    sensor_noise: Optional[SensorNoise] = None
    payload_scale: float = 1.0
    torque_limit_Nm: Optional[float] = None
    guard: GuardConfig = field(default_factory=GuardConfig)
    hardware: Optional[Hardware] = None
    disturbance: Optional[ToolDisturbance] = None
    contact: bool = False
    learning: Optional[IlcDriver] = None

    def __post_init__(self):
        self.validate()

    # -- derived values ----------------------------------------------------------------------
    def geometry(self) -> StewartGeometry:
        """The robot the controller believes in: ``robot.build()`` with, on the built robot, the
        motors' reflected inertia (rotor inertia x gear ratio^2)."""
        g = self.robot.build()
        if self.hardware is None:
            return g
        return g.replace(motor_reflected_inertia=self.servo().reflected_inertia)

    def servo(self) -> ServoModel | None:
        """The servo of ``hardware.motors`` (None on the ideal robot)."""
        return None if self.hardware is None else self.hardware.motors.build()

    def torque_limit(self) -> float | None:
        """The motors' torque saturation in force, N m: ``torque_limit_Nm`` and, with hardware,
        the servo's peak torque, whichever is lower (None: unlimited)."""
        limits = [v for v in (self.torque_limit_Nm,
                              None if self.hardware is None else self.servo().peak_torque_Nm)
                  if v is not None]
        return min(limits) if limits else None

    def motor_limits(self) -> MotorLimits:
        """What a reference may ask of the motors: the torque limit in force
        (:meth:`torque_limit`), the servo's no-load speed at the crank and its friction, and
        ``guard.effort_margin`` (all unlimited on the ideal robot without a torque limit)."""
        servo = self.servo()
        return MotorLimits(self.torque_limit(),
                           None if servo is None else servo.no_load_speed_rad_s,
                           self.guard.effort_margin, servo)

    def plant_geometry(self) -> StewartGeometry:
        """The robot that is simulated: ``geometry()`` with the payload scale on the platform."""
        g = self.geometry()
        if self.payload_scale == 1.0:
            return g
        return g.replace(platform_mass=g.platform_mass * self.payload_scale,
                         platform_inertia=tuple(self.payload_scale * v for v in g.platform_inertia))

    def make_reference(self):
        """The reference object (``evaluate(t)``) the scenario names
        (:meth:`ReferenceConfig.make`)."""
        return self.reference.make(self.geometry(), self.duration_s, self.torque_limit())

    @property
    def plant_time_step_s(self) -> float:
        """The plant's step, s (``plant.time_step``)."""
        return self.plant.time_step

    @property
    def computation_delay_periods(self) -> int:
        """Control periods between a measurement and its torque (0 on the ideal robot)."""
        return self.hardware.computation_delay_periods if self.hardware is not None else 0

    def use_controller(self, controller: ControllerChoice,
                       tuner: Optional[TunerChoice] = None) -> "Scenario":
        """Run this scenario with ``controller`` and ``tuner`` (None: fixed weights; the
        paper's ANN tuner comes with its gain switching, :func:`use_paper_tuner`): the one way
        the studies put a controller on a base scenario. Changes the scenario in place and
        returns it (not validated)."""
        self.controller, self.tuner = controller, None
        if isinstance(tuner, AnnTunerDriver):
            return use_paper_tuner(self, tuner)
        self.tuner = tuner
        return self

    def lqi(self, **changes) -> LqiDriver:
        """This scenario's LQI with ``changes`` (e.g. ``omega_Q=10``): its own options when its
        controller is an LqiDriver, the defaults otherwise. The scenario is not changed."""
        base = self.controller if isinstance(self.controller, LqiDriver) else LqiDriver()
        return dataclasses.replace(base, **changes)

    # -- validation --------------------------------------------------------------------------
    def validate(self) -> "Scenario":
        """Check every field before anything is built; returns self.

        Raises:
            InvalidConfigError, InvalidGeometryError, MissingFileError: see the class docstring.
        """
        self._validate_types()
        try:
            self.robot.build()
        except InvalidGeometryError as err:
            raise InvalidGeometryError(f"robot: {err}") from None
        except TypeError as err:
            raise InvalidConfigError(f"robot: {err}") from None
        self._validate_periods()
        if self.hardware is not None:
            self.hardware.validate(self.control_period_s)
            if self.sensor_noise is not None:
                raise InvalidConfigError("sensor_noise is the ideal pose sensor's; on the robot "
                                         "as built the encoders are noisy: set "
                                         "hardware.encoders.noise_counts instead")
        self.controller.validate(self.control_period_s, self.computation_delay_periods)
        self.reference.validate()
        if self.feedforward not in FEEDFORWARD_MODES:
            raise InvalidConfigError(f"feedforward must be one of {FEEDFORWARD_MODES}, got "
                                     f"{self.feedforward!r}")
        if self.tuner is not None:
            self.tuner.validate(self)
        if self.sensor_noise is not None:
            self.sensor_noise.validate()
        as_number("payload_scale", self.payload_scale, 0.1, 10.0)
        if not isinstance(self.contact, bool):
            raise InvalidConfigError(f"contact must be true or false, got {self.contact!r}")
        if self.torque_limit_Nm is not None:
            as_number("torque_limit_Nm", self.torque_limit_Nm, lo=0.0, lo_open=True)
        self.guard.validate()
        check_multiple("guard.check_period_s", self.guard.check_period_s, "plant.time_step",
                       self.plant.time_step)
        if self.disturbance is not None:
            self.disturbance.validate()
        if self.learning is not None:
            self.learning.validate(self.control_period_s)
        return self

    #: The fields that hold a choice or a section, and the classes each may hold.
    _FIELD_TYPES = {"robot": (Robot,), "plant": (MultibodyPlantConfig,),
                    "simulator": (SimulatorConfig,), "visualization": (VisualizationConfig,),
                    "guard": (GuardConfig,), "controller": _choices(ControllerChoice),
                    "reference": _choices(ReferenceChoice),
                    "tuner": (type(None),) + _choices(TunerChoice),
                    "sensor_noise": (type(None), SensorNoise),
                    "hardware": (type(None), Hardware),
                    "disturbance": (type(None), ToolDisturbance),
                    "learning": (type(None), IlcDriver)}

    def _validate_types(self) -> None:
        """Each section and choice is of a class its field takes (a dict, say, is not)."""
        for name, kinds in self._FIELD_TYPES.items():
            value = getattr(self, name)
            if isinstance(value, kinds):
                continue
            names = [k.__name__ for k in kinds if k is not type(None)]
            listed = ", ".join(names[:-1]) + (" or " if len(names) > 1 else "") + names[-1]
            article = "an" if listed[0] in "AEIOU" or listed.startswith("Lqi") else "a"
            raise InvalidConfigError(
                f"{name} must be {'None or ' if type(None) in kinds else ''}{article} {listed}, "
                f"got {type(value).__name__}"
                + (" (a dict: load it with load_scenario, or build the dataclass with "
                   f"{names[0]}(**d))" if isinstance(value, dict) else ""))

    def _validate_periods(self) -> None:
        """The run's durations and periods, and Drake's plant and simulator settings."""
        for name in ("duration_s", "control_period_s", "log_period_s"):
            as_number(name, getattr(self, name), lo=0.0, lo_open=True)
        h = as_number("plant.time_step", self.plant.time_step, lo=0.0, lo_open=True)
        if self.plant.discrete_contact_approximation not in ("sap", "lagged", "similar"):
            raise InvalidConfigError(
                f"plant.discrete_contact_approximation "
                f"{self.plant.discrete_contact_approximation!r} does not enforce the ball "
                f"constraints that close the loops; use 'sap', 'lagged' or 'similar'")
        _validate_plant_config(self.plant)
        _validate_simulator_config(self.simulator)
        check_multiple("control_period_s", self.control_period_s, "plant.time_step", h)
        check_multiple("log_period_s", self.log_period_s, "plant.time_step", h)
        if self.duration_s < 2 * self.log_period_s:
            raise InvalidConfigError(
                f"duration_s ({self.duration_s:g} s) must cover at least two log periods "
                f"({2 * self.log_period_s:g} s): a shorter run has no second sample to measure")

    # -- pickling through YAML (Drake's config structs do not pickle) -------------------------
    def __reduce__(self):
        return (_scenario_from_yaml, (dump_scenario(self),))


def use_paper_tuner(scenario: Scenario, tuner: AnnTunerDriver) -> Scenario:
    """Give ``scenario`` the paper's ANN ``tuner`` and, for an LQI, the paper's gain switching
    (``gain_transfer = "none"``; see :class:`AnnTunerDriver`). Returns the scenario (changed in
    place)."""
    scenario.tuner = tuner
    if isinstance(scenario.controller, LqiDriver):
        scenario.controller = dataclasses.replace(scenario.controller, gain_transfer="none")
    return scenario


#: Slowest real-time pacing accepted (besides 0, as fast as possible): the Simulator sleeps
#: between steps in C++, where no signal is handled, so a plant step must not wait more than a
#: fraction of a second (1 ms at 0.01: 0.1 s).
MIN_REALTIME_RATE = 0.01


def _validate_plant_config(plant: MultibodyPlantConfig) -> None:
    """The fields of Drake's ``MultibodyPlantConfig`` besides the step and the approximation:
    numbers here (Drake aborts the process on some), names by Drake's own parser."""
    as_number("plant.penetration_allowance", plant.penetration_allowance, 0.0, lo_open=True)
    as_number("plant.stiction_tolerance", plant.stiction_tolerance, 0.0, lo_open=True)
    as_number("plant.sap_near_rigid_threshold", plant.sap_near_rigid_threshold, 0.0)
    for name in ("use_sampled_output_ports", "adjacent_bodies_collision_filters"):
        if not isinstance(getattr(plant, name, False), bool):
            raise InvalidConfigError(f"plant.{name} must be true or false, got "
                                     f"{getattr(plant, name)!r}")
    names = []
    for name in ("contact_model", "contact_surface_representation"):
        value = getattr(plant, name)
        if not isinstance(value, str):
            raise InvalidConfigError(f"plant.{name} must be a name, got {value!r}")
        names.append(value)
    problem = _drake_plant_names_problem(*names)
    if problem:
        raise InvalidConfigError(f"plant: {problem} (see Drake's MultibodyPlantConfig for the "
                                 f"names)")


@functools.lru_cache(maxsize=32)
def _drake_plant_names_problem(contact_model: str, contact_surface_representation: str) -> str:
    """Drake's own refusal of these names ("Unknown contact_model: 'bogus'"), "" if none: the
    names a Drake version knows are its own to say."""
    from pydrake.multibody.plant import AddMultibodyPlant
    from pydrake.systems.framework import DiagramBuilder

    config = MultibodyPlantConfig(time_step=1e-3, discrete_contact_approximation="sap",
                                  contact_model=contact_model,
                                  contact_surface_representation=contact_surface_representation)
    try:
        AddMultibodyPlant(config, DiagramBuilder())
    except RuntimeError as err:
        return " ".join(str(err).split())
    return ""


def _validate_simulator_config(config: SimulatorConfig) -> None:
    """The fields of Drake's ``SimulatorConfig``: the scheme among Drake's, a start at 0 s, and a
    real-time rate of 0 or at least :data:`MIN_REALTIME_RATE` (a slower one hangs the run)."""
    from pydrake.systems.analysis import GetIntegrationSchemes

    schemes = GetIntegrationSchemes()
    if config.integration_scheme not in schemes:
        raise InvalidConfigError(f"simulator.integration_scheme must be one of "
                                 f"{', '.join(schemes)}, got {config.integration_scheme!r}")
    as_number("simulator.max_step_size", config.max_step_size, 0.0, lo_open=True)
    as_number("simulator.accuracy", config.accuracy, 0.0, 1.0, lo_open=True)
    if as_number("simulator.start_time", config.start_time) != 0.0:
        raise InvalidConfigError(f"simulator.start_time must be 0 (the reference and duration_s "
                                 f"count from t = 0), got {config.start_time!r}")
    rate = as_number("simulator.target_realtime_rate", config.target_realtime_rate, 0.0)
    if 0.0 < rate < MIN_REALTIME_RATE:
        raise InvalidConfigError(f"simulator.target_realtime_rate must be 0 (as fast as "
                                 f"possible) or at least {MIN_REALTIME_RATE:g} (100 times slower "
                                 f"than real time), got {config.target_realtime_rate!r}")
    for name in ("use_error_control", "publish_every_time_step"):
        if not isinstance(getattr(config, name, False), bool):
            raise InvalidConfigError(f"simulator.{name} must be true or false, got "
                                     f"{getattr(config, name)!r}")


def _scenario_from_yaml(text: str) -> Scenario:
    return yaml_load_typed(schema=Scenario, data=text, allow_schema_with_no_yaml=True)


#: Drake's config structs in a Scenario, and the fields of each that a dump always writes (the
#: ones the robot needs whatever Drake's defaults are).
_DRAKE_SECTIONS = {"plant": (MultibodyPlantConfig, ("time_step", "discrete_contact_approximation")),
                   "simulator": (SimulatorConfig, ()),
                   "visualization": (VisualizationConfig, ())}


def _top_level_blocks(text: str) -> dict:
    """{key: its lines} of a YAML mapping as ``yaml_dump_typed`` writes it (a key at column 0,
    its nested lines indented below it), in order."""
    blocks: dict = {}
    key = None
    for line in text.splitlines(keepends=True):
        if line[:1] not in (" ", "") and ":" in line:
            key = line.split(":", 1)[0]
            blocks[key] = ""
        blocks[key] += line
    return blocks


def _drake_section(name: str, value) -> str:
    """The ``name:`` block of a Drake config struct: the fields that differ from this Drake's
    defaults, plus the ones the robot needs (:data:`_DRAKE_SECTIONS`); "" when none."""
    kind, always = _DRAKE_SECTIONS[name]
    changed = yaml_load(data=yaml_dump_typed(value, defaults=kind())) or {}
    keep = set(changed) | set(always)
    lines = [block for key, block in _top_level_blocks(yaml_dump_typed(value)).items()
             if key in keep]
    return (f"{name}:\n" + "".join("  " + line if line.strip() else line
                                   for block in lines for line in block.splitlines(True))
            if lines else "")


def dump_scenario(scenario: Scenario, path=None) -> str:
    """The scenario as YAML text (``yaml_dump_typed``); also written to ``path`` if given.

    Every field of ours is written; of Drake's config structs (``plant``, ``simulator``,
    ``visualization``) only the fields that differ from the running Drake's defaults, and the
    plant's ``time_step`` and ``discrete_contact_approximation``. Drake adds, renames and removes
    fields of these structs between releases (``SimulatorConfig.publish_every_time_step`` is
    gone in 1.58), so a full dump would load only on the Drake that wrote it; this one loads on
    every supported Drake unless the user changed a field that one of them lacks.
    """
    blocks = _top_level_blocks(yaml_dump_typed(scenario))
    for name in _DRAKE_SECTIONS:
        blocks[name] = _drake_section(name, getattr(scenario, name))
    text = "".join(blocks.values())
    if path is not None:
        from ..fileio import atomic_write

        atomic_write(Path(path), lambda f: f.write(text.encode()))
    return text


#: Where the shipped scenarios are (``scenarios/`` of the repository, installed as package data).
def shipped_scenarios() -> dict:
    """{name: path} of the scenarios shipped with the package (``scenarios/*.yaml``)."""
    folder = importlib.resources.files("stewart_drake.scenarios")
    return {Path(p.name).stem: Path(str(p)) for p in folder.iterdir() if p.name.endswith(".yaml")}


def load_scenario(source="paper_ideal", overrides: typing.Sequence[str] = ()) -> Scenario:
    """Load a scenario from a YAML file or a shipped name, apply ``key=value`` overrides, validate.

    Args:
        source: a path to a ``.yaml`` file, or the name of a shipped scenario
            (:func:`shipped_scenarios`, e.g. "paper_ideal").
        overrides: ``"key.sub=value"`` strings (YAML values: ``controller.omega_Q=10``,
            ``controller=!PdDriver {}``, ``guard.max_closure_error_m=null``), applied in order.
    Returns:
        the validated :class:`Scenario`.
    Raises:
        MissingFileError: no such file or name.
        CorruptFileError (an InvalidConfigError): the file is empty, not UTF-8, not YAML, or
            YAML that does not fit the schema (unknown or mistyped field, named).
        InvalidConfigError, InvalidGeometryError, MissingFileError: a bad override, or a value
            out of range (named by file and field path).
    """
    from ..fileio import read_checked

    shipped = shipped_scenarios()
    path = Path(source)
    if not path.exists():
        if str(source) in shipped:
            path = shipped[str(source)]
        else:
            raise MissingFileError(f"no scenario file {source} and no shipped scenario of that "
                                   f"name (shipped: {', '.join(sorted(shipped))})")
    remedy = "fix it, or start from `stewart-drake scenario paper_hardware --out FILE.yaml`"
    raw = read_checked(path, "scenario file", MAX_SCENARIO_BYTES,
                       remedy + "; long data (a reference) belongs in a CSV file")
    if not raw.strip():
        raise CorruptFileError(path, "scenario file", "it is empty", remedy)
    try:
        text = raw.decode("utf-8")
    except UnicodeDecodeError as err:
        raise CorruptFileError(path, "scenario file", f"not UTF-8 text ({err.reason} at byte "
                                                      f"{err.start})", remedy) from None
    try:
        _refuse_duplicate_keys(text)
        scenario = yaml_load_typed(schema=Scenario, data=text, allow_schema_with_no_yaml=True)
    except StewartError as err:
        raise _in_file(err, path) from None
    except Exception as err:      # noqa: BLE001 - yaml and Drake's loader raise several types
        problem = _one_line(err)
        if not problem.startswith("not YAML"):
            problem = f"it does not fit the Scenario schema: {problem}"
        raise CorruptFileError(path, "scenario file", problem, remedy) from None
    for override in overrides:
        apply_override(scenario, override)
    try:
        return scenario.validate()
    except StewartError as err:
        raise _in_file(err, f"{path} with --set {', '.join(overrides)}" if overrides
                       else path) from None


#: Largest scenario file read, bytes: a scenario is a few kB; parsing is about 5 s per MB.
MAX_SCENARIO_BYTES = 256 * 1024


def _refuse_duplicate_keys(text: str) -> None:
    """Refuse a mapping that names a key twice (YAML loaders keep the last silently).

    The document is composed, not constructed (PyYAML's node graph: tags are not resolved,
    nothing is built), and each node is visited once, so aliases cannot multiply the work.
    Raises:
        InvalidConfigError: names the key and its two lines.
    """
    import yaml

    root = yaml.compose(text, Loader=yaml.SafeLoader)
    seen, stack = set(), [root] if root is not None else []
    while stack:
        node = stack.pop()
        if id(node) in seen:
            continue
        seen.add(id(node))
        if isinstance(node, yaml.MappingNode):
            first = {}
            for key, value in node.value:
                if isinstance(key, yaml.ScalarNode) and key.value != "<<":
                    if key.value in first:
                        raise InvalidConfigError(
                            f"the key {key.value!r} appears twice in one mapping (lines "
                            f"{first[key.value] + 1} and {key.start_mark.line + 1}); keep one")
                    first[key.value] = key.start_mark.line
                stack += [key, value]
        elif isinstance(node, yaml.SequenceNode):
            stack += node.value


def _in_file(err: StewartError, where) -> StewartError:
    """``err`` with "<where>: " in front of its message, when its class takes just a message
    (InvalidConfigError, InvalidGeometryError, MissingFileError); other errors as they are."""
    if type(err) not in (InvalidConfigError, InvalidGeometryError, MissingFileError):
        return err
    return type(err)(f"{where}: {err}")


def apply_override(scenario: Scenario, override: str) -> None:
    """Set one ``key.sub=value`` (value in YAML) on ``scenario`` in place, typed by the schema.

    Raises:
        InvalidConfigError: no ``=``, a key that is not a field (names it), or a value the field's
            type does not accept.
    """
    key, sep, value = override.partition("=")
    key = key.strip()
    if not sep or not key:
        raise InvalidConfigError(f"an override must be key=value (e.g. controller.omega_Q=10), "
                                 f"got {override!r}")
    *parents, leaf = key.split(".")
    target = scenario
    for name in parents:
        if name not in _field_names(target):
            raise InvalidConfigError(f"--set {key}: {name!r} is not a field of "
                                     f"{type(target).__name__}")
        target = getattr(target, name)
    fields = _field_names(target)
    if leaf not in fields:
        raise InvalidConfigError(f"--set {key}: {leaf!r} is not a field of "
                                 f"{type(target).__name__} (fields: {', '.join(sorted(fields))})")
    try:
        updated = yaml_load_typed(schema=type(target), data=f"{leaf}: {value}\n",
                                  defaults=target, allow_schema_with_no_yaml=True)
    except Exception as err:       # noqa: BLE001 - yaml and Drake's loader raise several types
        raise InvalidConfigError(f"--set {key}={value}: {_one_line(err)}") from None
    setattr(target, leaf, getattr(updated, leaf))


def _field_names(value) -> list[str]:
    """The fields of a scenario dataclass or of a Drake config struct (``__fields__``, what
    ``yaml_load_typed`` reads: ``plant.time_step``, ``simulator.target_realtime_rate``)."""
    if dataclasses.is_dataclass(value):
        return [f.name for f in dataclasses.fields(value)]
    return [f.name for f in getattr(type(value), "__fields__", ())]


def _one_line(err: BaseException) -> str:
    """An exception's text on one line, at most 300 characters; for a YAML syntax error its
    problem and where (PyYAML's message spans several lines with the text it quotes)."""
    import yaml

    if isinstance(err, yaml.MarkedYAMLError) and err.problem:
        mark = err.problem_mark
        where = f" at line {mark.line + 1}, column {mark.column + 1}" if mark else ""
        text = f"not YAML ({' '.join(filter(None, (err.context, err.problem)))}{where})"
    else:
        text = " ".join(str(err).split()) or type(err).__name__
    return text if len(text) <= 300 else text[:297] + "..."
