"""Scenarios: everything that defines a run, as typed dataclasses that load from YAML.

A :class:`Scenario` is read with ``pydrake.common.yaml.yaml_load_typed`` (:func:`load_scenario`)
and written with ``yaml_dump_typed`` (:func:`dump_scenario`), like the manipulation course's
``Scenario`` for ``MakeHardwareStation``. Choices are tagged unions: in YAML,
``controller: !PdDriver {bandwidth_hz: 20}`` or ``reference: !CsvReference {path: run.csv}``.
Shipped scenarios live in ``scenarios/`` (``paper_ideal.yaml``: the paper's experiment on the
ideal robot); :func:`load_scenario` takes their names too.

Drake's YAML loader builds each class with its defaults and then sets fields, so the classes are
plain mutable dataclasses with concrete field types (this module must not use
``from __future__ import annotations``), and validation is a separate step:
:meth:`Scenario.validate` (run by every builder) names the field to fix. The robot's geometry and
the LQI's scales are frozen value types of the lower layers; :class:`Robot` and
:class:`LqiScalesConfig` are their YAML mirrors, generated from their fields (same names, units
and defaults; lists where they have tuples), with ``build()`` to get the value type back.
"""

import dataclasses
import functools
import importlib.resources
import typing
from dataclasses import dataclass, field
from pathlib import Path
from typing import Dict, List, Optional, Union

import numpy as np
from pydrake.common.yaml import yaml_dump_typed, yaml_load_typed
from pydrake.multibody.plant import MultibodyPlantConfig
from pydrake.systems.analysis import SimulatorConfig
from pydrake.visualization import VisualizationConfig

from ..checks import as_array, as_number, check_multiple
from ..errors import (CorruptFileError, InvalidConfigError, InvalidGeometryError, MissingFileError,
                      StewartError)
from ..control.lqi import GAIN_TRANSFER_MODES, OMEGA_MAX, OMEGA_MIN, RICCATI_MODES, LqiScales
from ..model.geometry import StewartGeometry
from ..model.servo import ServoModel
from ..model.limits import (DEFAULT_COND_THRESHOLD, DEFAULT_EFFORT_MARGIN,
                            DEFAULT_MIN_CLEARANCE_M, DEFAULT_MIN_SIGMA_MIN_INV, MotorLimits)
from ..model.statics import FEEDFORWARD_MODES

#: Largest RandomSource seed Drake accepts (a 32-bit unsigned integer).
MAX_SEED = 2**32 - 1


class _Mirror:
    """Base of the YAML mirrors of frozen value types (see the module docstring)."""

    _value_class: type = object

    def build(self):
        """The value type with these fields (lists become tuples); validated by its constructor."""
        return self._value_class(**{
            f.name: tuple(v) if isinstance(v, list) else v
            for f in dataclasses.fields(self) for v in [getattr(self, f.name)]})

    @classmethod
    def from_value(cls, value):
        """The mirror of a value-type instance (e.g. ``Robot.from_value(StewartGeometry())``)."""
        return cls(**{f.name: list(v) if isinstance(v, tuple) else v
                      for f in dataclasses.fields(cls) for v in [getattr(value, f.name)]})


def _mirror(value_class: type, name: str, doc: str, exclude: tuple = ()) -> type:
    hints = typing.get_type_hints(value_class)
    prototype = value_class()
    fields = []
    for f in dataclasses.fields(value_class):
        if f.name in exclude:
            continue
        default = getattr(prototype, f.name)
        kind = hints[f.name]
        if kind is tuple or typing.get_origin(kind) is tuple:
            fields.append((f.name, List[float],
                           field(default_factory=lambda d=tuple(default): list(d))))
        else:
            fields.append((f.name, kind, field(default=default)))
    cls = dataclasses.make_dataclass(name, fields, bases=(_Mirror,))
    cls.__module__, cls.__qualname__, cls.__doc__ = __name__, name, doc
    cls._value_class = value_class
    return cls


Robot = _mirror(StewartGeometry, "Robot", """The robot: every field of
:class:`~stewart_drake.model.geometry.StewartGeometry`, same names, units and defaults
(docs/reference_geometry.md, Table I), but the motors' reflected inertia, which the scenario's
``hardware.motors`` sets; ``build()`` gives the geometry (validated there).""",
                exclude=("motor_reflected_inertia",))

Motors = _mirror(ServoModel, "Motors", """The servo at each crank: every field of
:class:`~stewart_drake.model.servo.ServoModel` (at the output shaft: gear ratio, rotor inertia
kg m^2, peak torque N m, current-loop time constant s, viscous N m s/rad and Coulomb N m
friction, friction regularization N m s/rad); defaults: maxon EC 45 flat 50 W + a 4.3:1
planetary gearhead (docs/hardware.md).""")

LqiScalesConfig = _mirror(LqiScales, "LqiScalesConfig", """Normalization of the LQI's Q and R
(Bryson's rule): every field of :class:`~stewart_drake.control.lqi.LqiScales` (pose, rate,
integral: 6 each, SI; torque: N m).""")


# -- controllers ---------------------------------------------------------------------------------

@dataclass
class LqiDriver:
    """The LQI of paper section III (:class:`~stewart_drake.control.lqi.LqiController`).

    Attributes:
        omega_Q, omega_R: weights of eq. 27 on normalized errors and torques, in [1e-3, 1e3]
            (only their ratio matters); the ANN tuner replaces them when the scenario has one.
        schedule_period_s: re-solve the Riccati gain from the measured pose this often, s (a
            whole multiple of the control period); ours, not the paper's.
        riccati: "warm" (Newton refinement of the last gain to convergence), "track" (one
            Newton step per re-schedule) or "cold" (DARE each time).
        scales: normalization of Q and R.
        anti_windup: stop integrating while the torque is clipped at the motors' limit
            (clamping); only acts when the scenario has a limit.
        delay_compensation: augment the error model with the torques still in the pipe when
            the hardware has a computation delay; false ignores the delay.
        reference_governor: with a torque limit, follow the nearest pose whose holding torques
            are within 90 % of the limit while the reference's own feed-forward exceeds it
            (:meth:`~stewart_drake.control.lqi.LqiController.govern`).
        schedule_pose: re-schedule the input matrix B(x) from the measured pose (ours); false
            keeps the start pose's, as a plain LQI (the gain then changes only with omega).
        gain_transfer: what a gain change carries over: ``integral`` (the integral torque,
            default), ``feedback`` (the whole feedback, no torque step) or ``none`` (as the
            paper); see :class:`~stewart_drake.control.lqi.LqiController` (ours).
    """

    omega_Q: float = 1.0
    omega_R: float = 1.0
    schedule_period_s: float = 0.01
    riccati: str = "warm"
    scales: LqiScalesConfig = field(default_factory=LqiScalesConfig)
    anti_windup: bool = True
    delay_compensation: bool = True
    reference_governor: bool = True
    schedule_pose: bool = True
    gain_transfer: str = "integral"


@dataclass
class PdDriver:
    """The crank-space PD baseline with gravity feed-forward
    (:class:`~stewart_drake.control.pd.CrankPdController`).

    Attributes:
        bandwidth_hz: closed-loop natural frequency, Hz. damping: damping ratio.
        schedule_period_s: re-schedule the inertia-shaped gains this often, s.
    """

    bandwidth_hz: float = 20.0
    damping: float = 1.0
    schedule_period_s: float = 0.01


@dataclass
class UserController:
    """A controller of the user's: ``factory`` names a callable ``factory(context,
    **parameters) -> LeafSystem`` following the controller contract
    (:mod:`~stewart_drake.control.contract`) that Python code the user ran registered
    (:func:`~stewart_drake.control.contract.register_controller`), or an installed entry point
    the user opted into (``--plugin NAME``). Loading the scenario imports and calls nothing: an
    unknown name is refused when the run is built, listing the registered ones.

    Attributes:
        factory: the registered name. parameters: keyword arguments of the factory (numbers).
    """

    factory: str = ""
    parameters: Dict[str, float] = field(default_factory=dict)


@dataclass
class AnnTunerDriver:
    """The ANN tuner of omega_Q, omega_R (paper section III.D) on density features.

    It moves the weights every period (on a dash-and-hold task its ratio went from 1.8 to 100 to
    0.45 within 0.2 s):
    run it with the paper's gain switching, ``controller.gain_transfer: none``, as
    :func:`use_paper_tuner` does (``run --tuner ann``, ``evaluate``, the tuner study). Our
    ``integral`` transfer re-maps the integral states at every switch; switched that fast the
    re-maps pile up and the loop chatters at the torque limit (a dash-and-hold task: error
    0.616 against 0.0121 with ``none``; docs/paper_notes.md).

    Attributes:
        weights: the tuner's ``.npz`` (``stewart-drake train``); empty for the shipped weights.
        period_s: tuner period, s (a whole multiple of the control period).
        feature_window: samples m + 1 of the density features (eqs. 35-36).
    """

    weights: str = ""
    period_s: float = 0.02
    feature_window: int = 50


@dataclass
class RatioTunerDriver:
    """Our tuner (:class:`~stewart_drake.control.tuner.RatioTuner`): the density features and the
    reference's speed and acceleration -> the ratio omega_Q / omega_R (the tuner study).

    Attributes:
        weights: its ``.npz`` (:func:`~stewart_drake.control.tuner.save_ratio_tuner`), required.
        period_s: tuner period, s (a whole multiple of the control period).
        feature_window: samples m + 1 of the density features.
        smoothing_s: time constant of the low-pass on its log10 ratio, s (0: none).
    """

    weights: str = ""
    period_s: float = 0.02
    feature_window: int = 50
    smoothing_s: float = 0.0


@dataclass
class WeightSchedule:
    """omega_Q and omega_R known in advance, held from each time to the next: the hindsight
    schedule and the hand-made ones of the tuner study.

    Attributes:
        t: increasing times, s (the first is 0).  omega_Q, omega_R: the weights from each time
            on, in [1e-3, 1e3].
    """

    t: List[float] = field(default_factory=lambda: [0.0])
    omega_Q: List[float] = field(default_factory=lambda: [1.0])
    omega_R: List[float] = field(default_factory=lambda: [1.0])


TunerChoice = Union[AnnTunerDriver, RatioTunerDriver, WeightSchedule]


# -- references ----------------------------------------------------------------------------------

@dataclass
class NamedReference:
    """A reference of :data:`~stewart_drake.simulation.trajectories.TRAJECTORIES`: "paper"
    (eqs. 37-38), "home", "helix", "step_<axis>", "sweep_<axis>"."""

    name: str = "paper"


@dataclass
class CsvReference:
    """A reference from a CSV file ``t,phi,theta,psi,X,Y,Z`` (s, rad, m), joined by a C2 cubic
    spline (:func:`~stewart_drake.simulation.trajectories.load_csv_trajectory`). A relative path
    is relative to the working folder."""

    path: str = ""


@dataclass
class SineReference:
    """x_d(t) = offset + amplitude sin(2 pi f t + phase), axis by axis (6 values each: rad, m,
    Hz, rad); see :class:`~stewart_drake.simulation.trajectories.SineTrajectory`."""

    amplitude: List[float] = field(default_factory=lambda: [0.0] * 6)
    frequency_hz: List[float] = field(default_factory=lambda: [0.0] * 6)
    phase: List[float] = field(default_factory=lambda: [0.0] * 6)
    offset: List[float] = field(default_factory=lambda: [0.0, 0.0, 0.0, 0.0, 0.0, 0.30])
    name: str = "sine"


@dataclass
class DataCollectionReference:
    """The seeded excitation of the tuner's data collection (every axis at 1-5 Hz inside the
    workspace; :func:`~stewart_drake.simulation.trajectories.data_collection_trajectory`), as long
    as the scenario's duration."""

    seed: int = 0


@dataclass
class OrganMotionReference:
    """A motion of the organ-motion library (:mod:`~.organ_motion`: breathing, heartbeat,
    breathing_heartbeat, irregular_breathing, hysteresis) with parameters carrying units, e.g.
    ``{amplitude: 15mm, period: 4s, direction: SI}`` (:func:`~.organ_motion.make_motion`).

    Attributes:
        motion: the library's name. parameters: name -> value (a number in the field's SI unit,
            or text with a unit). scale: the motion shrunk about its centre, in (0, 1]
            (``reproduce --scale-to-fit`` finds it).
    """

    motion: str = "breathing"
    parameters: Dict[str, str] = field(default_factory=dict)
    scale: float = 1.0


@dataclass
class TraceReference:
    """A recorded trace of 1 to 6 axes: a CSV whose header names each column and its unit
    (:func:`~.organ_motion.load_trace`); the project's own ``t,phi,theta,psi,X,Y,Z`` CSV too.

    Attributes:
        path: the file (relative to the working folder).
        axis_map: trace column -> platform axis with an optional sign ({SI: -Z}).
        centre: (6,) the pose the trace is centred on, rad and m.
        centre_on: "mean", "first" or "none" (which pose of the trace goes to ``centre``).
        lowpass_hz: corner of the zero-phase low-pass, Hz (0: none).
        max_gap_s: longest interval without data an axis may have, s.
        scale: the trace shrunk about its centre, in (0, 1].
    """

    path: str = ""
    axis_map: Dict[str, str] = field(default_factory=dict)
    centre: List[float] = field(default_factory=lambda: [0.0, 0.0, 0.0, 0.0, 0.0, 0.30])
    centre_on: str = "mean"
    lowpass_hz: float = 0.0
    max_gap_s: float = 1.0
    scale: float = 1.0


ReferenceChoice = Union[NamedReference, CsvReference, SineReference, DataCollectionReference,
                        OrganMotionReference, TraceReference]
ControllerChoice = Union[LqiDriver, PdDriver, UserController]


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


# -- the rest ------------------------------------------------------------------------------------

@dataclass
class SensorNoise:
    """White Gaussian noise on the measured pose and rate, drawn every control period.

    Attributes:
        std: 12 standard deviations [rad x3, m x3, rad/s x3, m/s x3] (or one for all).
        seed: seed of Drake's RandomSource, 0 .. 2^32 - 1.
    """

    std: List[float] = field(default_factory=lambda: [0.0] * 12)
    seed: int = 0


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
        """The reference object (``evaluate(t)``) the scenario names."""
        from . import trajectories

        ref = self.reference
        if isinstance(ref, NamedReference):
            return trajectories.make_trajectory(ref.name)
        if isinstance(ref, CsvReference):
            return trajectories.load_csv_trajectory(ref.path)
        if isinstance(ref, (OrganMotionReference, TraceReference)):
            from . import organ_motion

            if isinstance(ref, OrganMotionReference):
                motion = organ_motion.make_motion(ref.motion, ref.parameters)
            else:
                motion = organ_motion.load_trace(
                    ref.path, ref.axis_map, ref.centre, ref.centre_on,
                    ref.lowpass_hz or None, ref.max_gap_s)
            return motion if ref.scale == 1.0 else organ_motion.ScaledReference(motion,
                                                                                ref.scale)
        if isinstance(ref, SineReference):
            return trajectories.SineTrajectory(amplitude=tuple(ref.amplitude),
                                               frequency_hz=tuple(ref.frequency_hz),
                                               phase=tuple(ref.phase), offset=tuple(ref.offset),
                                               name=ref.name)
        return trajectories.data_collection_trajectory(ref.seed, self.geometry(),
                                                       duration_s=self.duration_s,
                                                       torque_limit_Nm=self.torque_limit())

    @property
    def plant_time_step_s(self) -> float:
        """The plant's step, s (``plant.time_step``)."""
        return self.plant.time_step

    # -- validation --------------------------------------------------------------------------
    def validate(self) -> "Scenario":
        """Check every field before anything is built; returns self.

        Raises:
            InvalidConfigError, InvalidGeometryError, MissingFileError: see the class docstring.
        """
        for name, kind in (("robot", Robot), ("plant", MultibodyPlantConfig),
                           ("simulator", SimulatorConfig), ("visualization", VisualizationConfig),
                           ("guard", GuardConfig)):
            if not isinstance(getattr(self, name), kind):
                raise InvalidConfigError(
                    f"{name} must be a {kind.__name__}, got {type(getattr(self, name)).__name__}"
                    + (" (a dict: load it with load_scenario, or build the dataclass with "
                       f"{kind.__name__}(**d))" if isinstance(getattr(self, name), dict) else ""))
        try:
            self.robot.build()
        except InvalidGeometryError as err:
            raise InvalidGeometryError(f"robot: {err}") from None
        except TypeError as err:
            raise InvalidConfigError(f"robot: {err}") from None
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
        self._validate_controller()
        self._validate_reference()
        if self.feedforward not in FEEDFORWARD_MODES:
            raise InvalidConfigError(f"feedforward must be one of {FEEDFORWARD_MODES}, got "
                                     f"{self.feedforward!r}")
        if self.tuner is not None:
            self._validate_tuner()
        if self.sensor_noise is not None:
            noise = self.sensor_noise
            if not isinstance(noise, SensorNoise):
                raise InvalidConfigError(f"sensor_noise must be None or a SensorNoise, got "
                                         f"{type(noise).__name__}")
            try:
                std = np.broadcast_to(np.asarray(noise.std, dtype=float), (12,))
            except (TypeError, ValueError):
                std = np.array([np.nan])
            if not (np.all(np.isfinite(std)) and np.all(std >= 0)):
                raise InvalidConfigError(f"sensor_noise.std needs 12 finite values >= 0 (rad, m, "
                                         f"rad/s, m/s), got {noise.std}")
            _check_int("sensor_noise.seed", noise.seed, 0, MAX_SEED)
        as_number("payload_scale", self.payload_scale, 0.1, 10.0)
        if not isinstance(self.contact, bool):
            raise InvalidConfigError(f"contact must be true or false, got {self.contact!r}")
        if self.torque_limit_Nm is not None:
            as_number("torque_limit_Nm", self.torque_limit_Nm, lo=0.0, lo_open=True)
        self.guard.validate()
        check_multiple("guard.check_period_s", self.guard.check_period_s, "plant.time_step", h)
        if self.hardware is not None:
            self._validate_hardware()
        if self.learning is not None:
            if not isinstance(self.learning, IlcDriver):
                raise InvalidConfigError(f"learning must be None or an IlcDriver, got "
                                         f"{type(self.learning).__name__}")
            self.learning.validate(self.control_period_s)
        if self.disturbance is not None:
            d = self.disturbance
            if not isinstance(d, ToolDisturbance):
                raise InvalidConfigError(f"disturbance must be None or a ToolDisturbance, got "
                                         f"{type(d).__name__}")
            if d.kind not in ("push", "twist", "contact"):
                raise InvalidConfigError(f"disturbance.kind must be 'push', 'twist' or "
                                         f"'contact', got {d.kind!r}")
            for name in ("magnitude", "start_s", "duration_s", "frequency_hz"):
                as_number(f"disturbance.{name}", getattr(d, name), 0.0)
            axis = np.asarray(d.direction, dtype=float) if np.ndim(d.direction) == 1 else None
            if axis is None or axis.shape != (3,) or not np.isfinite(axis).all() \
                    or np.linalg.norm(axis) == 0:
                raise InvalidConfigError(f"disturbance.direction must be 3 finite numbers, not "
                                         f"all zero, got {d.direction!r}")
        return self

    def _validate_hardware(self) -> None:
        hw = self.hardware
        if not isinstance(hw, Hardware):
            raise InvalidConfigError(f"hardware must be None or a Hardware, got "
                                     f"{type(hw).__name__}")
        for name, kind in (("encoders", Encoders), ("motors", Motors), ("estimator", Estimator)):
            if not isinstance(getattr(hw, name), kind):
                raise InvalidConfigError(f"hardware.{name} must be a {kind.__name__}, got "
                                         f"{type(getattr(hw, name)).__name__}")
        _check_int("hardware.encoders.counts_per_rev", hw.encoders.counts_per_rev, 16, 2**40)
        as_number("hardware.encoders.noise_counts", hw.encoders.noise_counts, 0.0, 1e6)
        _check_int("hardware.encoders.seed", hw.encoders.seed, 0, MAX_SEED)
        try:
            hw.motors.build()
        except (StewartError, TypeError) as err:
            raise InvalidConfigError(f"hardware.motors: {err}") from None
        as_number("hardware.estimator.rate_cutoff_hz", hw.estimator.rate_cutoff_hz, 0.0,
                  0.5 / self.control_period_s, lo_open=True)
        as_number("hardware.estimator.fk_tolerance_counts", hw.estimator.fk_tolerance_counts,
                  0.0, 1.0, lo_open=True)
        delay = _check_int("hardware.computation_delay_periods", hw.computation_delay_periods,
                           0, 100)
        if (delay > MAX_COMPENSATED_DELAY and isinstance(self.controller, LqiDriver)
                and self.controller.delay_compensation):
            raise InvalidConfigError(
                f"hardware.computation_delay_periods = {delay} with the LQI's delay compensation "
                f"gives a model of 6 x (3 + {delay}) = {6 * (3 + delay)} states whose Riccati "
                f"equation is re-solved every schedule period (thousands of times slower than "
                f"real time); at most {MAX_COMPENSATED_DELAY} periods are compensated: set "
                f"controller.delay_compensation: false, or lengthen control_period_s")
        if self.sensor_noise is not None:
            raise InvalidConfigError("sensor_noise is the ideal pose sensor's; on the robot as "
                                     "built the encoders are noisy: set "
                                     "hardware.encoders.noise_counts instead")

    def _validate_tuner(self) -> None:
        t = self.tuner
        if not isinstance(t, (AnnTunerDriver, RatioTunerDriver, WeightSchedule)):
            raise InvalidConfigError(f"tuner must be None, an AnnTunerDriver, a RatioTunerDriver "
                                     f"or a WeightSchedule, got {type(t).__name__}")
        if isinstance(self.controller, PdDriver):
            raise InvalidConfigError("a tuner drives the LQI's weights (its omega input): use an "
                                     "LqiDriver controller with a tuner")
        if isinstance(t, WeightSchedule):
            times = as_array("tuner.t", t.t)
            if times.ndim != 1 or times.size < 1 or times[0] != 0.0 or np.any(np.diff(times) <= 0):
                raise InvalidConfigError(f"tuner.t must be increasing times starting at 0 s, got "
                                         f"{t.t!r:.80}")
            for name in ("omega_Q", "omega_R"):
                values = as_array(f"tuner.{name}", getattr(t, name))
                if values.shape != times.shape:
                    raise InvalidConfigError(f"tuner.{name} needs one value per time "
                                             f"({times.size}), got {values.size}")
                if np.any(values < OMEGA_MIN) or np.any(values > OMEGA_MAX):
                    raise InvalidConfigError(f"tuner.{name} must be in [{OMEGA_MIN:g}, "
                                             f"{OMEGA_MAX:g}]")
            return
        as_number("tuner.period_s", t.period_s, lo=0.0, lo_open=True)
        check_multiple("tuner.period_s", t.period_s, "control_period_s", self.control_period_s)
        _check_int("tuner.feature_window", t.feature_window, 1, 100_000)
        if isinstance(t, RatioTunerDriver) and not t.weights:
            raise MissingFileError("a RatioTunerDriver needs its weights (tuner.weights): "
                                   "`stewart-drake evaluate` trains them")
        if t.weights and not Path(t.weights).exists():
            kind = "ANN tuner" if isinstance(t, AnnTunerDriver) else "ratio tuner"
            raise MissingFileError(f"no {kind} weights at {t.weights} (tuner.weights): check the "
                                   f"path" + (", or leave it empty for the shipped weights"
                                              if isinstance(t, AnnTunerDriver) else ""))

    def _validate_controller(self) -> None:
        c = self.controller
        if isinstance(c, LqiDriver):
            for name in ("omega_Q", "omega_R"):
                as_number(f"controller.{name}", getattr(c, name), OMEGA_MIN, OMEGA_MAX)
            as_number("controller.schedule_period_s", c.schedule_period_s, 0.0, lo_open=True)
            check_multiple("controller.schedule_period_s", c.schedule_period_s,
                           "control_period_s", self.control_period_s)
            if c.riccati not in RICCATI_MODES:
                raise InvalidConfigError(f"controller.riccati must be one of {RICCATI_MODES}, "
                                         f"got {c.riccati!r}")
            if c.gain_transfer not in GAIN_TRANSFER_MODES:
                raise InvalidConfigError(f"controller.gain_transfer must be one of "
                                         f"{GAIN_TRANSFER_MODES}, got {c.gain_transfer!r}")
            for name in ("anti_windup", "delay_compensation", "reference_governor",
                         "schedule_pose"):
                if not isinstance(getattr(c, name), bool):
                    raise InvalidConfigError(f"controller.{name} must be true or false, got "
                                             f"{getattr(c, name)!r}")
            if not isinstance(c.scales, LqiScalesConfig):
                raise InvalidConfigError(f"controller.scales must be an LqiScalesConfig, got "
                                         f"{type(c.scales).__name__}")
            try:
                c.scales.build()
            except (StewartError, TypeError) as err:
                raise InvalidConfigError(f"controller.scales: {err}") from None
        elif isinstance(c, PdDriver):
            for name in ("bandwidth_hz", "damping", "schedule_period_s"):
                as_number(f"controller.{name}", getattr(c, name), 0.0, lo_open=True)
        elif isinstance(c, UserController):
            if not isinstance(c.factory, str) or not c.factory:
                raise InvalidConfigError("controller.factory must name a registered controller "
                                         "(register_controller, or --plugin NAME)")
            for key, value in c.parameters.items():
                as_number(f"controller.parameters.{key}", value)
        else:
            raise InvalidConfigError(f"controller must be an LqiDriver, PdDriver or "
                                     f"UserController, got {type(c).__name__}")

    def _validate_reference(self) -> None:
        from . import trajectories

        ref = self.reference
        if isinstance(ref, NamedReference):
            trajectories.make_trajectory(ref.name)          # unknown name: lists the known ones
        elif isinstance(ref, CsvReference):
            if not ref.path or not Path(ref.path).exists():
                raise MissingFileError(f"no reference CSV at {ref.path!r} (reference.path): "
                                       f"check the path")
        elif isinstance(ref, SineReference):
            self.make_reference()                            # checks shapes and overflow
        elif isinstance(ref, DataCollectionReference):
            _check_int("reference.seed", ref.seed, 0, MAX_SEED)
        elif isinstance(ref, (OrganMotionReference, TraceReference)):
            as_number("reference.scale", ref.scale, 0.0, 1.0, lo_open=True)
            if isinstance(ref, TraceReference):
                from .organ_motion import CENTRE_MODES

                if not ref.path or not Path(ref.path).exists():
                    raise MissingFileError(f"no trace at {ref.path!r} (reference.path): check "
                                           f"the path")
                if ref.centre_on not in CENTRE_MODES:
                    raise InvalidConfigError(f"reference.centre_on must be one of "
                                             f"{CENTRE_MODES}, got {ref.centre_on!r}")
                as_number("reference.lowpass_hz", ref.lowpass_hz, 0.0)
                as_number("reference.max_gap_s", ref.max_gap_s, 0.0, lo_open=True)
                as_array("reference.centre", ref.centre, shape=(6,))
            else:
                self.make_reference()              # names an unknown motion or parameter
        else:
            raise InvalidConfigError(f"reference must be a NamedReference, CsvReference, "
                                     f"SineReference, DataCollectionReference, "
                                     f"OrganMotionReference or TraceReference, got "
                                     f"{type(ref).__name__}")

    # -- pickling through YAML (Drake's config structs do not pickle) -------------------------
    def __reduce__(self):
        return (_scenario_from_yaml, (dump_scenario(self),))


def use_paper_tuner(scenario: "Scenario", tuner: AnnTunerDriver) -> "Scenario":
    """Give ``scenario`` the paper's ANN ``tuner`` and, for an LQI, the paper's gain switching
    (``gain_transfer = "none"``; see :class:`AnnTunerDriver`). Returns the scenario (changed in
    place)."""
    scenario.tuner = tuner
    if isinstance(scenario.controller, LqiDriver):
        scenario.controller = dataclasses.replace(scenario.controller, gain_transfer="none")
    return scenario


#: Largest computation delay the LQI compensates, control periods: its model has 6 (3 + d)
#: states, and a run's cost grows about as their cube (0.26x real time at 20, 0.02x at 40 on
#: one core of the reference machine).
MAX_COMPENSATED_DELAY = 20
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


def _check_int(name: str, value, lo: int, hi: int) -> int:
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or not lo <= value <= hi:
        raise InvalidConfigError(f"{name} must be an integer in [{lo}, {hi}], got {value!r}")
    return int(value)


def _scenario_from_yaml(text: str) -> Scenario:
    return yaml_load_typed(schema=Scenario, data=text, allow_schema_with_no_yaml=True)


def dump_scenario(scenario: Scenario, path=None) -> str:
    """The scenario as YAML text (``yaml_dump_typed``); also written to ``path`` if given."""
    text = yaml_dump_typed(scenario)
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
