"""A run's plan: every value a validated scenario implies, computed once, then only read.

A :class:`~.scenario.Scenario` says what a run is (the robot, its motors, the reference, the
controller, the periods); :func:`make_plan` says how it is built. It validates the scenario (the
one place a run's scenario is validated) and derives, once, what the station, the Diagram, the
reference check and the simulator need: the robot the controller believes in and the one that is
simulated, the servo, the torque and motor limits, the computation delay, the sample offset, the
reference object and the controller's factory. Everything below the plan (the station, the
guard, the learner) receives these values and never reads the scenario again.

Before a run is built, its plan is checked (:func:`checked_plan`): the memory the run needs
(:func:`~.memory.check_run_memory`) and the reference (:func:`check_reference`: every sample of
x_d(t) at the control period against the reach, the joint limits, both singularity measures, the
clearance between the robot's parts and the motors' torque and speed, naming the first refusal),
whose report the plan keeps (``report``): a checked plan is not checked again.

    plan = make_plan(load_scenario("paper_hardware"))
    sd = make_stewart_diagram(plan)          # or build_simulator(plan), run_experiment(plan)
"""

from __future__ import annotations

import dataclasses
import warnings
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np

from ..base.errors import FeasibilityWarning, InvalidConfigError, StewartError
from ..control.contract import resolve_controller
from ..references.motion import Reference
from ..robot.geometry import StewartGeometry
from ..robot.kinematics import X_HOME
from ..robot.limits import (
    DEFAULT_COND_THRESHOLD,
    DEFAULT_MIN_SIGMA_MIN_INV,
    MotorLimits,
    validate_trajectory,
)
from ..robot.servo import ServoModel
from ..robot.trajectory_report import TrajectoryReport, merge_reports
from ..station.bus.station import HardwareStation
from ..station.station import StewartStation
from .memory import check_run_memory
from .scenario import Scenario


@dataclass(frozen=True)
class RunPlan:
    """The values a validated scenario implies (:func:`make_plan`); SI units.

    Attributes:
        scenario: the validated scenario the plan was made from (read it, do not change it:
            the values below are not recomputed); on the servo bus with ``hardware: null``,
            with the robot built with the bus's servos (:func:`as_built`).
        geometry: the robot the controller believes in: ``robot`` with, on the robot as built,
            the motors' reflected inertia (rotor inertia x gear ratio^2); with
            ``temperature_c`` and ``compensate_temperature``, at that temperature
            (:meth:`~stewart_drake.robot.geometry.StewartGeometry.at_temperature`).
        plant_geometry: the robot that is simulated: ``robot_as_built``, or the robot
            ``robot_tolerances`` draws about ``robot`` (both None: ``robot``), with
            the same reflected inertia as ``geometry`` and ``payload_scale`` on the platform's
            mass and inertia, at ``temperature_c`` (None: at its own ``lengths_at_c``); its
            ``encoder_offsets`` are the simulated encoders' zero errors, which the estimator
            takes back with ``geometry``'s.
        servo: the servo of ``hardware.motors`` (None on the ideal robot).
        torque_limit_Nm: the saturation in force, N m: the lowest of ``torque_limit_Nm``, with
            hardware the servo's peak torque, and on the servo bus ``K_t`` times its current
            limit (None: unlimited).
        motor_limits: what a reference may ask of the motors: that limit, the servo's no-load
            speed at the crank, its friction and ``guard.effort_margin``.
        delay_periods: control periods between a measurement and its torque (0 on the ideal
            robot).
        plant_time_step_s, control_period_s, log_period_s, duration_s: the run's step, periods
            and length, s.
        sample_offset_s: when the controllers sample within their period, s: half a plant step
            (the controller contract's "Sampling").
        encoder_count_at_tip: (m, rad) one encoder count at the crank tip, as a translation
            and as a rotation of the platform; (1e-6 m, 1e-5 rad) on the ideal robot, which
            reads exact angles (the learner's additive floor).
        reference: the reference object (:class:`~.motion.Reference`: ``evaluate(t)``), or
            None for a plan made without one (a live reference, or only the robot's values).
        controller_factory: ``f(ControllerContext) -> System``, the run's controller.
        station_factory: ``f(plan, meshcat) -> Diagram``:
            :class:`~stewart_drake.station.station.StewartStation`, or with ``bus`` the
            :class:`~stewart_drake.station.bus.station.HardwareStation`, chosen once, here.
        report: the reference check's report when the plan was checked (:func:`checked_plan`;
            :class:`~stewart_drake.robot.trajectory_report.TrajectoryReport`, without its
            series), or None.
    """

    scenario: Scenario
    geometry: StewartGeometry
    plant_geometry: StewartGeometry
    servo: ServoModel | None
    torque_limit_Nm: float | None
    motor_limits: MotorLimits
    delay_periods: int
    plant_time_step_s: float
    control_period_s: float
    log_period_s: float
    duration_s: float
    sample_offset_s: float
    encoder_count_at_tip: tuple[float, float]
    reference: Any  # a motion.Reference, or None
    controller_factory: Callable
    station_factory: Callable
    report: TrajectoryReport | None = None


def make_plan(
    scenario: Scenario | RunPlan | None = None,
    *,
    reference=None,
    controller=None,
    with_reference: bool = True,
) -> RunPlan:
    """Validate ``scenario`` and derive every value of its run (:class:`RunPlan`).

    Args:
        scenario: the run (default: ``Scenario()``, the paper's experiment on the ideal robot),
            validated here; or a plan, not validated again: returned as it is, or with the
            reference or controller given here (or its reference made, if it has none).
        reference: a reference overriding ``scenario.reference``: an object with
            ``evaluate(t)``, a Drake ``Trajectory``, a CSV path or a name
            (:func:`~.trajectories.as_trajectory`).
        controller: a controller factory or registered name overriding ``scenario.controller``
            (:mod:`~stewart_drake.control.contract`).
        with_reference: False for a plan without a reference object (a live reference, or when
            only the robot's values are needed: nothing is read or sampled).
    Returns:
        the :class:`RunPlan`.
    Raises:
        InvalidConfigError, InvalidGeometryError, MissingFileError: the scenario does not
            validate (the message names the field), or a controller name is not registered.
    """
    from ..references.trajectories import as_trajectory

    plan = (
        scenario
        if isinstance(scenario, RunPlan)
        else _robot_plan((scenario if scenario is not None else Scenario()).validate())
    )
    changes: dict[str, Any] = {}
    if reference is not None:
        changes["reference"] = as_trajectory(reference)
        changes["report"] = None  # the check of another reference
    elif with_reference and plan.reference is None:
        changes["reference"] = _made_reference(plan.scenario, plan.geometry, plan.torque_limit_Nm)
    if controller is not None:
        changes["controller_factory"] = (
            resolve_controller(controller) if isinstance(controller, str) else controller
        )
    return dataclasses.replace(plan, **changes) if changes else plan


def checked_plan(
    scenario: Scenario | RunPlan | None = None,
    *,
    reference=None,
    controller=None,
    progress: bool = False,
    report: TrajectoryReport | None = None,
) -> RunPlan:
    """The plan of a run about to be built, checked before anything is: the scenario validated
    (:func:`make_plan`), the memory the run needs (:func:`~.memory.check_run_memory`, before the
    reference
    is made: a trace too long for the machine is refused before it is read) and the reference
    (:func:`check_reference_shown`), whose report the plan keeps.

    Args:
        scenario, reference, controller: as :func:`make_plan`.
        progress: show a bar while a long reference is checked.
        report: the check's report when the caller has already checked this reference (it is
            then not checked again). A plan already checked (its ``report`` set) with nothing
            overridden is returned as it is.
    Returns:
        the :class:`RunPlan`, its ``report`` set (without the report's series).
    Raises:
        InvalidConfigError: a bad scenario field, a run that needs more memory than the machine
            has. UnreachablePoseError, JointLimitError, SingularPoseError, InterferenceError,
            MotorLimitError: the reference's first refusal (:func:`check_reference`).
    """
    if isinstance(scenario, RunPlan) and scenario.report is not None:
        if reference is None and controller is None and report is None:
            return scenario  # checked once, when it was made
    plan = make_plan(scenario, with_reference=False)  # validated once, here
    check_run_memory(plan.scenario)
    plan = make_plan(plan, reference=reference, controller=controller)
    report = report if report is not None else plan.report
    if report is None:
        report = check_reference_shown(plan, progress=progress, keep_series=False)
    return dataclasses.replace(plan, report=report)


def as_built(scenario: Scenario) -> Scenario:
    """``scenario`` with, on the servo bus and ``hardware: null``, the robot built with the bus's
    servos (:meth:`~stewart_drake.station.bus.servos.DynamixelBusConfig.hardware`); itself
    otherwise (not validated)."""
    if scenario.bus is None or scenario.hardware is not None:
        return scenario
    return dataclasses.replace(scenario, hardware=scenario.bus.hardware(scenario.control_period_s))


def robot_geometry(scenario: Scenario) -> StewartGeometry:
    """The robot ``scenario``'s controller believes, as :class:`RunPlan`'s ``geometry``,
    without deriving a run: its ``robot`` section (on the servo bus, built with its servos:
    :func:`as_built`) with its motors' reflected inertia.

    Returns:
        :class:`~stewart_drake.robot.geometry.StewartGeometry`.
    Raises:
        as :func:`make_plan` (the scenario is validated here).
    """
    return _believed_robot(as_built(scenario.validate()))[0]


def robot_motor_limits(scenario: Scenario) -> MotorLimits:
    """What the motors of ``scenario``'s robot give and a reference may use, as
    :class:`RunPlan`'s ``motor_limits``, without deriving a run: ``peak_torque_Nm`` is the
    plan's ``torque_limit_Nm`` (N m, None: unlimited), ``servo`` its servo (None on the ideal
    robot).

    Returns:
        :class:`~stewart_drake.robot.limits.MotorLimits`.
    Raises:
        as :func:`make_plan` (the scenario is validated here).
    """
    built = as_built(scenario.validate())
    return _motor_limits(built, _believed_robot(built)[1])


def run_reference(scenario: Scenario) -> Reference:
    """The reference object of ``scenario``'s run, as :class:`RunPlan`'s ``reference``
    (``scenario.reference`` made for the believed robot, the run's length and the motors'
    torque limit), without deriving the rest of the run.

    Returns:
        an object with ``evaluate(t)`` -> (pose, rate, acceleration), each (n, 6)
        (:func:`~stewart_drake.references.trajectories.as_trajectory`).
    Raises:
        as :func:`make_plan` (the scenario is validated here).
    """
    built = as_built(scenario.validate())
    geometry, servo = _believed_robot(built)
    return _made_reference(built, geometry, _motor_limits(built, servo).peak_torque_Nm)


def _made_reference(scenario: Scenario, geometry: StewartGeometry, torque_limit_Nm):
    """``scenario.reference`` made for ``geometry``, the run's length and ``torque_limit_Nm``
    (:func:`~stewart_drake.references.trajectories.as_trajectory`)."""
    from ..references.trajectories import as_trajectory

    return as_trajectory(scenario.reference.make(geometry, scenario.duration_s, torque_limit_Nm))


def _believed_robot(scenario: Scenario) -> tuple:
    """(geometry, servo or None) of :func:`robot_geometry`, for a scenario already as built."""
    geometry = scenario.robot.build()
    if scenario.temperature_c is not None and scenario.compensate_temperature:
        geometry = geometry.at_temperature(scenario.temperature_c)
    servo = None if scenario.hardware is None else scenario.hardware.motors.build()
    if servo is not None:
        geometry = geometry.replace(motor_reflected_inertia=servo.reflected_inertia)
    return geometry, servo


def _simulated_robot(scenario: Scenario, geometry: StewartGeometry) -> StewartGeometry:
    """:class:`RunPlan`'s ``plant_geometry`` of a scenario already as built, whose believed
    robot is ``geometry``: ``robot_as_built``, or the robot ``robot_tolerances`` draws
    (neither: the ``robot`` section), at the run's ``temperature_c``, with ``geometry``'s
    reflected inertia and ``payload_scale`` on the platform's mass and inertia; ``geometry``
    itself when none of these differ from it."""
    if scenario.robot_as_built is not None:
        simulated = scenario.robot_as_built.build()
    elif scenario.robot_tolerances is not None:
        simulated = scenario.robot_tolerances.as_built(scenario.robot.build())
    elif scenario.temperature_c is None or scenario.compensate_temperature:
        simulated = None  # the believed robot, at the run's temperature already
    else:
        simulated = scenario.robot.build()
    if simulated is None:
        simulated = geometry
    else:
        if scenario.temperature_c is not None:
            simulated = simulated.at_temperature(scenario.temperature_c)
        simulated = simulated.replace(motor_reflected_inertia=geometry.motor_reflected_inertia)
    if scenario.payload_scale != 1.0:
        k = scenario.payload_scale
        simulated = simulated.replace(
            platform_mass=simulated.platform_mass * k,
            platform_inertia=tuple(k * v for v in simulated.platform_inertia),
        )
    return simulated


def _motor_limits(scenario: Scenario, servo: ServoModel | None) -> MotorLimits:
    """:func:`robot_motor_limits` of a scenario already as built, whose servo is ``servo``:
    the saturation is the lowest of ``torque_limit_Nm``, the servo's peak torque and on the
    servo bus ``K_t`` times its current limit."""
    limits = [
        v
        for v in (
            scenario.torque_limit_Nm,
            None if servo is None else servo.peak_torque_Nm,
            None if scenario.bus is None else scenario.bus.torque_limit_Nm(),
        )
        if v is not None
    ]
    return MotorLimits(
        min(limits) if limits else None,
        None if servo is None else servo.no_load_speed_rad_s,
        scenario.guard.effort_margin,
        servo,
    )


#: How far from ``robot.lengths_at_c`` an uncompensated run may be before its summary says so,
#: K (a kelvin moves the platform about 7-10 um: docs/calibration.md, "Temperature").
TEMPERATURE_NOTE_K = 1.0


def temperature_note(plan: RunPlan) -> str | None:
    """One line for a run's summary when the robot runs more than :data:`TEMPERATURE_NOTE_K`
    away from the temperature its lengths were measured at (``robot.lengths_at_c``) and the
    controller is not told (``compensate_temperature`` false): how far, and the error that
    makes at home by forward kinematics
    (:func:`~stewart_drake.robot.temperature.temperature_error`), which the encoders' pose
    keeps and the ideal pose sensor (no ``hardware``, no ``bus``) does not; None otherwise."""
    from ..robot.temperature import temperature_error

    scenario = plan.scenario
    t = scenario.temperature_c
    if t is None or scenario.compensate_temperature:
        return None
    dt = t - plan.geometry.lengths_at_c
    if abs(dt) <= TEMPERATURE_NOTE_K:
        return None
    words = (
        f"temperature: the robot runs at {t:g} C, {abs(dt):.3g} K "
        f"{'warmer' if dt > 0 else 'colder'} than its lengths were measured at "
        f"(robot.lengths_at_c {plan.geometry.lengths_at_c:g} C), uncompensated "
        f"(compensate_temperature: false)"
    )
    try:
        moved, turned = temperature_error(plan.geometry, X_HOME, dt)
    except StewartError:  # the scaled robot has no pose near home: the words alone
        return words
    cost = f"{moved[0] * 1e6:.3g} um and {turned[0] * 1e6:.2g} urad"
    if scenario.hardware is None and scenario.bus is None:
        return (
            f"{words}: the ideal pose sensor sees the true pose (encoders would leave {cost} "
            f"at home)"
        )
    return f"{words}: the pose the encoders give is about {cost} off at home"


def _robot_plan(scenario: Scenario) -> RunPlan:
    """The plan of a validated ``scenario`` without its reference object (on the servo bus,
    of the robot built with its servos: :func:`as_built`)."""
    scenario = as_built(scenario)
    geometry, servo = _believed_robot(scenario)
    limits = _motor_limits(scenario, servo)
    h_plant = scenario.plant.time_step
    crank = float(np.max(geometry.crank_lengths))  # the longest crank
    tip = (
        (1e-6, 1e-5)
        if scenario.hardware is None
        else (
            scenario.hardware.encoders.quantum_rad * crank,
            scenario.hardware.encoders.quantum_rad * crank / geometry.platform_radius,
        )
    )
    return RunPlan(
        scenario=scenario,
        geometry=geometry,
        plant_geometry=_simulated_robot(scenario, geometry),
        servo=servo,
        torque_limit_Nm=limits.peak_torque_Nm,
        motor_limits=limits,
        delay_periods=0
        if scenario.hardware is None
        else scenario.hardware.computation_delay_periods,
        plant_time_step_s=h_plant,
        control_period_s=scenario.control_period_s,
        log_period_s=scenario.log_period_s,
        duration_s=scenario.duration_s,
        sample_offset_s=0.5 * h_plant,
        encoder_count_at_tip=tip,
        reference=None,
        controller_factory=scenario.controller.resolve(),
        station_factory=StewartStation if scenario.bus is None else HardwareStation,
    )


#: Samples :func:`validate_reference` checks at once (5 s at 1 kHz; about 9 kB each while checked).
VALIDATE_CHUNK_SAMPLES = 5_000


def validate_reference(
    trajectory: Reference,
    geometry: StewartGeometry,
    duration_s: float,
    dt: float = 1e-3,
    cond_threshold: float = DEFAULT_COND_THRESHOLD,
    min_sigma_min_inv: float = DEFAULT_MIN_SIGMA_MIN_INV,
    raise_refused: bool = True,
    progress=None,
    keep_series: bool = True,
    **checks,
) -> TrajectoryReport:
    """Sample a trajectory on [0, duration_s] every ``dt`` and validate it, in stretches of
    :data:`VALIDATE_CHUNK_SAMPLES` samples, so that the memory the check takes beyond its
    ``series`` does not grow with the duration.

    The samples go to :func:`~stewart_drake.robot.limits.validate_trajectory`, the one validator
    of a reference: finite pose, rate and acceleration; loop closure, motor travel, ball-joint
    cones; cond(J) and 1/sigma_max(J); with ``checks``, the clearance between parts and the
    motors' torque and speed; each failure naming its first time and leg, parts, motor or measure.

    Args:
        trajectory: an object with ``evaluate(t)`` -> (pose, rate, acceleration), each (n, 6).
        geometry: the robot. duration_s: s, > 0. dt: sampling period, s (the control period).
        cond_threshold, min_sigma_min_inv: singularity thresholds (see the validator).
        raise_refused: raise on the first refused sample (else only report it).
        progress: None, or an object with ``update(n)`` (a tqdm bar) told of each stretch's
            samples as it is checked.
        keep_series: keep the report's sample-by-sample ``series`` (for plots; about 0.3 kB a
            sample); False drops each stretch's.
        checks: keyword arguments of the validator (``clearance``, ``min_clearance_m``,
            ``motor_limits``, ``allow_infeasible``).
    Returns:
        :class:`~stewart_drake.robot.trajectory_report.TrajectoryReport`.
    Raises:
        InvalidConfigError, UnreachablePoseError, JointLimitError, SingularPoseError,
            InterferenceError, MotorLimitError: see
            :func:`~stewart_drake.robot.limits.validate_trajectory`; InvalidConfigError also for
            a duration beyond a reference's ``end_time`` (a CSV or Drake trajectory).
    """
    if not (np.isfinite(duration_s) and duration_s > 0):
        raise InvalidConfigError(f"duration must be > 0 s, got {duration_s}")
    end = getattr(trajectory, "end_time", None)
    if end is not None and duration_s > end + 1e-9:
        raise InvalidConfigError(
            f"the reference {getattr(trajectory, 'name', '')} ends at "
            f"t = {end:g} s: run at most that long (duration_s) or extend it"
        )
    t_all = np.arange(0.0, duration_s + 0.5 * dt, dt)
    reports = []
    for start in range(0, t_all.size, VALIDATE_CHUNK_SAMPLES):
        t = t_all[start : start + VALIDATE_CHUNK_SAMPLES]
        x, x_dot, x_ddot = trajectory.evaluate(t)
        report = validate_trajectory(
            geometry,
            t,
            x,
            cond_threshold=cond_threshold,
            min_sigma_min_inv=min_sigma_min_inv,
            raise_refused=raise_refused,
            x_dot=x_dot,
            x_ddot=x_ddot,
            **checks,
        )
        reports.append(report if keep_series else dataclasses.replace(report, series={}))
        if progress is not None:
            progress.update(t.size)
    return merge_reports(reports)


def check_reference(
    plan: Scenario | RunPlan,
    trajectory=None,
    raise_refused: bool = True,
    progress=None,
    keep_series: bool = True,
    duration_s: float | None = None,
) -> TrajectoryReport:
    """Refuse a reference the robot of ``plan`` cannot follow, before anything is simulated.

    Samples x_d(t) on [0, duration_s] at the control period and checks finiteness, loop closure,
    motor travel, ball-joint cones, both singularity measures, the clearance between the robot's
    parts and the torque and speed each motor must give (the scenario's ``guard`` thresholds,
    the plan's ``motor_limits``), with :func:`validate_reference`. A run checks the robot
    that is simulated, its payload included (``plant_geometry``).

    Args:
        plan: a :class:`RunPlan` or a scenario (planned here).
        trajectory: the reference object (default: the plan's).
        raise_refused: False reports every refusal in the report instead of raising the first
            (``stewart-drake check``).
        progress, keep_series: as :func:`validate_reference` (a bar told of the samples
            checked; the report's sample-by-sample series kept or not).
        duration_s: the length checked, s (default: the plan's): a path that is not the
            plan's run (the poses ``calibrate --plan`` writes).
    Returns:
        the :class:`~stewart_drake.robot.trajectory_report.TrajectoryReport` (``summary()``
        prints it).
    Raises:
        InvalidConfigError: a non-finite sample (pose, rate or acceleration), first time named,
            or a run longer than a bounded reference.
        UnreachablePoseError: first time, leg and ratio |L|/sqrt(M^2+N^2) > 1.
        JointLimitError: first time, leg and limit (motor_angle, crank_joint, platform_joint).
        SingularPoseError: first time with cond(J) > cond_threshold or 1/sigma_max(J) <
            min_sigma_min_inv.
        InterferenceError: first time two parts come closer than ``guard.min_clearance_m``.
        MotorLimitError: first time a motor needs more torque or speed than it may use, unless
            ``guard.allow_infeasible`` (then a :class:`~.errors.FeasibilityWarning`).
    """
    from ..plant.clearance import clearance_model

    plan = make_plan(plan, with_reference=trajectory is None)
    trajectory = plan.reference if trajectory is None else trajectory
    guard, geometry = plan.scenario.guard, plan.plant_geometry
    report = validate_reference(
        trajectory,
        geometry,
        plan.duration_s if duration_s is None else duration_s,
        dt=plan.control_period_s,
        cond_threshold=guard.cond_threshold,
        min_sigma_min_inv=guard.min_sigma_min_inv,
        raise_refused=raise_refused,
        progress=progress,
        keep_series=keep_series,
        clearance=clearance_model(geometry),
        min_clearance_m=guard.min_clearance_m,
        motor_limits=plan.motor_limits,
        allow_infeasible=guard.allow_infeasible,
    )
    if raise_refused and not report.feasible:
        # Not feasible means a motor limit was exceeded: the first violation is recorded.
        assert report.first_effort_violation is not None
        warnings.warn(
            FeasibilityWarning(
                f"running a reference the motors cannot follow (guard.allow_infeasible): "
                f"{report.first_effort_violation.need}; expect saturation"
            ),
            stacklevel=2,
        )
    return report


#: Control-period samples above which a shown check has a bar (a minute at 1 kHz: the check
#: takes about 3 s; a 20-minute trace checks for about a minute).
CHECK_BAR_SAMPLES = 60_000


def check_reference_shown(plan: RunPlan, reference=None, progress: bool = False, **kwargs):
    """:func:`check_reference` of ``plan`` (and ``reference``),
    behind a tqdm bar ("checking") when ``progress`` and the check has more than
    :data:`CHECK_BAR_SAMPLES` samples.

    Args:
        plan: the run. reference: the reference (default: the plan's). progress: show the bar.
        kwargs: ``raise_refused``, ``keep_series`` of ``check_reference``.
    Returns:
        the :class:`~stewart_drake.robot.trajectory_report.TrajectoryReport`.
    """
    from tqdm import tqdm

    samples = int(plan.duration_s / plan.control_period_s) + 1
    shown = progress and samples > CHECK_BAR_SAMPLES
    with tqdm(total=samples, desc="checking", unit=" samples", disable=not shown) as bar:
        return check_reference(plan, reference, progress=bar if shown else None, **kwargs)
