"""Closed-loop confirmation of a design: the requirement motions run on the robot as built.

A design's kinematic evaluation says what its motors must give along each motion; this module
builds the design (:meth:`~stewart_drake.design.variables.Design.apply_to` on the hardware
scenario: its geometry, its motors, their encoders and servo model), carries the requirement's
payload, chooses the LQI's weights for its motor, and runs each motion of the requirements
(:class:`~stewart_drake.design.requirements.DesignRequirements`) on the Drake plant in
closed loop, so a design is judged by what it does: tracking (translation and rotation, RMS and
largest deviation) and effort (peak and RMS motor torque against the motor's peak and
continuous torque, peak crank speed against its no-load speed).

:func:`design_scenario` makes the scenario of one motion (a file of it, ``dump_scenario``, is what
every command takes); :func:`confirm` runs every motion through a runner
(:mod:`~stewart_drake.execution.runners`) and returns one row per motion. A motion the robot
cannot make (refused before it starts, or stopped by the guard) is a row that says why, not an
exception, so a report can show it.
"""

from __future__ import annotations

import copy
import dataclasses
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from ..base.checks import as_number
from ..base.errors import InvalidConfigError, StewartError
from ..base.measures import rms_per_axis
from ..base.tables import markdown_row, markdown_table
from ..control.lqi.driver import LqiDriver
from ..robot.kinematics import jacobian
from ..run.plan import robot_geometry, robot_motor_limits, run_reference
from ..run.scenario import ReferenceChoice, Scenario
from ..run.scenario_io import load_scenario
from .margins import CONTINUOUS_SHARE
from .requirements import DesignRequirements
from .variables import Design

#: The hardware scenario a design is built on by default (the robot as built: encoders, servo
#: model with friction and current-loop lag, one period of computation delay).
DEFAULT_BASE = "paper_hardware"
#: Longest run of a motion that repeats (one repeat period, at most this), s.
MAX_PERIODIC_S = 20.0
#: Longest run of a motion with an end (a recorded trace, a CSV), s: its start.
MAX_TRACE_S = 30.0


def torque_scale_Nm(motor_peak_Nm: float, base: Scenario) -> float:
    """The LQI's torque scale (``controller.scales.torque``, Bryson's rule) for a motor of peak
    ``motor_peak_Nm``: the base scenario's scale times the motor's peak over the base motor's
    (0.3 N m x peak / 0.7022 N m on ``paper_hardware``), so each motor may use the same share
    of its peak as the base robot's motor does. The base's motor gives exactly the base's scale.

    Raises:
        InvalidConfigError: a base without hardware (no motor to scale from) or without an LQI,
            or a peak that is not a positive number.
    """
    check_base(base)
    peak = as_number("motor peak torque [N m]", motor_peak_Nm, 0.0, lo_open=True)
    assert base.hardware is not None  # check_base
    return base.lqi().scales.torque * (peak / base.hardware.motors.peak_torque_Nm)


def design_scenario(
    design: Design,
    requirements: DesignRequirements,
    motion: ReferenceChoice,
    base: str | Path | Scenario = DEFAULT_BASE,
    duration_s: float | None = None,
) -> Scenario:
    """The scenario of ``motion`` on ``design`` as built, validated.

    Starting from ``base`` (a shipped name or a scenario file, loaded as the CLI loads it, or a
    :class:`~stewart_drake.run.scenario.Scenario`, copied): the design's robot, motors and
    encoder resolution (:meth:`Design.apply_to`); ``requirements.payload_kg`` added to the
    platform's mass as a point mass at its centre of mass, known to the controller; ``motion``
    (a copy) as the reference for ``duration_s`` or :func:`motion_duration_s` (at most
    :data:`MAX_TRACE_S` of a trace, :data:`MAX_PERIODIC_S` of a repeating motion, else the
    base's duration); the LQI's torque scale for the motor (:func:`torque_scale_Nm`), the other
    scales and omega_Q, omega_R the base's; the base's tuner only on the base's own robot and
    motors (a :class:`~stewart_drake.control.tuning.WeightSchedule` is kept). Why each:
    docs/design.md, "Closed-loop confirmation".

    Args:
        design: the design (:class:`~stewart_drake.design.variables.Design`).
        requirements: the requirements (their payload is used here).
        motion: one of ``requirements.motions`` (any scenario reference choice).
        base: the hardware scenario the design is built on (default ``paper_hardware``).
        duration_s: the run's length, s, or None (the default above); a motion with an end is
            never run past it.
    Returns:
        the validated scenario (the design's file: ``dump_scenario`` of it).
    Raises:
        InvalidConfigError: a base without hardware or without an LQI controller, a bad
            duration, a motion that is not a reference choice; as :meth:`Design.apply_to`.
        InvalidGeometryError: the design cannot be built (names the variable to change).
        MissingFileError: no such base scenario, or a motion's file missing.
    """
    _check_arguments(design, requirements, motion)
    scenario = load_base(base)
    scale = torque_scale_Nm(design.servo().peak_torque_Nm, scenario)  # checks the base
    assert scenario.hardware is not None
    robot, motors = copy.deepcopy(scenario.robot), copy.deepcopy(scenario.hardware.motors)
    design.apply_to(scenario)
    assert scenario.hardware is not None  # apply_to keeps the hardware
    # A tuner with a network (weights trained on the base robot) is dropped off it.
    if scenario.tuner is not None and scenario.tuner.weights_path() is not None:
        if scenario.robot != robot or scenario.hardware.motors != motors:
            scenario.tuner = None
    scenario.robot.platform_mass += float(requirements.payload_kg)
    # check_base made the controller an LQI: lqi() is the controller itself, changed.
    scales = dataclasses.replace(scenario.lqi().scales, torque=scale)
    scenario.controller = scenario.lqi(scales=scales)
    scenario.reference = copy.deepcopy(motion)
    scenario.validate()  # the reference before it is made for its length
    scenario.duration_s = motion_duration_s(scenario, duration_s)
    return scenario.validate()


def _check_arguments(design, requirements, motion) -> None:
    """Refuse arguments of :func:`design_scenario` of the wrong kind (InvalidConfigError), and
    requirements that do not validate."""
    if not isinstance(design, Design):
        raise InvalidConfigError(f"design must be a Design, got {type(design).__name__}")
    if not isinstance(requirements, DesignRequirements):
        raise InvalidConfigError(
            f"requirements must be DesignRequirements (load_requirements), got "
            f"{type(requirements).__name__}"
        )
    requirements.validate()
    if not isinstance(motion, ReferenceChoice):
        raise InvalidConfigError(
            f"motion must be a scenario reference choice (one of requirements.motions), got "
            f"{type(motion).__name__}"
        )


def motion_duration_s(scenario: Scenario, duration_s: float | None = None) -> float:
    """How long :func:`design_scenario` runs ``scenario.reference``, s (rules there):
    ``duration_s`` (or the default for the motion), never past the motion's end.

    Raises:
        InvalidConfigError: ``duration_s`` not a positive number.
    """
    asked = None if duration_s is None else as_number("duration_s", duration_s, 0.0, lo_open=True)
    reference = run_reference(scenario)
    end = getattr(reference, "end_time", None)
    if end is not None:  # as `check` and `reproduce` run a trace: from its first sample
        end = float(end) - float(getattr(reference, "start_time", 0.0))
    period = getattr(reference, "repeat_period_s", None)
    if asked is not None:
        length = asked
    elif end is not None:
        length = MAX_TRACE_S
    elif period is not None:
        length = min(float(period), MAX_PERIODIC_S)
    else:
        length = float(scenario.duration_s)
    return min(length, end) if end is not None else length


@dataclass(frozen=True)
class MotionRun:
    """One job of :func:`confirm`: a motion on a design as built.

    Attributes:
        label: the motion's name (display only). scenario: the run
            (:func:`design_scenario`). motor: the catalogue's name of the design's motor.
        continuous_torque_Nm: the motor's continuous torque, N m at the crank.
        torque_share, speed_share: the shares of the motor's peak torque and no-load speed the
            requirement's margins leave to the motions (1 - margin).
    """

    label: str
    scenario: Scenario
    motor: str
    continuous_torque_Nm: float
    torque_share: float
    speed_share: float


def confirm(
    design: Design,
    requirements: DesignRequirements,
    base: str | Path | Scenario = DEFAULT_BASE,
    runner=None,
    progress: bool = False,
    duration_s: float | None = None,
) -> list[dict]:
    """Run every motion of ``requirements`` on ``design`` as built, in closed loop.

    Every scenario is built (and so checked) before anything runs; the runs go through
    ``runner`` (default :class:`~stewart_drake.execution.runners.SerialRunner`; a
    ``ProcessRunner`` runs the motions in parallel processes). A run the guard stops leaves its
    logs up to the trip in the base's ``guard.divergence_dir`` (named in the row's reason).

    Args:
        design, requirements, base, duration_s: as :func:`design_scenario` (``duration_s``:
            every motion's length, s, or None for each motion's default).
        runner: a runner of :mod:`~stewart_drake.execution.runners`, or None.
        progress: show a bar over the motions.
    Returns:
        one row per motion, in the order of ``requirements.motions`` (plain JSON values;
        :func:`run_motion`): ``label``, ``motor``, ``duration_s``, ``completed`` and ``reason``
        (None, or why the motion was not made: a refusal before the run, a guard trip, a lost
        worker), and for a completed run its tracking and effort figures.
    Raises:
        InvalidConfigError, InvalidGeometryError, MissingFileError: as :func:`design_scenario`,
            before any run.
    """
    from ..execution.runners import SerialRunner, map_outcomes

    entry = design.catalogue_entry()
    jobs: dict[str, MotionRun] = {}
    for i, motion in enumerate(requirements.motions):
        scenario = design_scenario(design, requirements, motion, base, duration_s)
        jobs[f"{i}: {motion.label}"] = MotionRun(
            label=motion.label,
            scenario=scenario,
            motor=design.motor,
            continuous_torque_Nm=entry.continuous_torque_Nm,
            torque_share=1.0 - requirements.margins.torque,
            speed_share=1.0 - requirements.margins.speed,
        )
    outcomes = map_outcomes(
        runner or SerialRunner(), run_motion, jobs, progress, "design confirmation", "motion"
    )
    rows = []
    for job_id, job in jobs.items():
        outcome = outcomes[job_id]
        rows.append(outcome if isinstance(outcome, dict) else _failed_row(job, str(outcome)))
    return rows


def run_motion(job: MotionRun) -> dict:
    """Simulate one :class:`MotionRun` (in a worker) and reduce it to a row.

    Returns:
        dict of plain values: ``label``, ``motor``, ``duration_s``, ``completed`` (bool),
        ``reason`` (None, or the refusal or guard trip, one line with its error type), and when
        completed: ``rms_translation_um``, ``peak_translation_um`` (largest |p - p_d|, um),
        ``rms_rotation_urad``, ``peak_rotation_urad`` (the roll-pitch-yaw error's norm, urad),
        over the whole run (:func:`~.fidelity.fidelity`, from the true pose);
        ``peak_torque_Nm`` (largest |T| of the six motors) and ``peak_torque_fraction`` (of the
        motor's peak); ``rms_torque_Nm`` (the largest of the six motors' RMS torque) and
        ``rms_torque_fraction`` (of the motor's continuous torque); ``peak_speed_rad_s`` (largest
        |theta_dot| = |J x_dot| of the true pose and rate) and ``peak_speed_fraction`` (of the
        no-load speed); ``within_margins`` (peak torque and speed within the shares the margins
        leave, RMS torque within :data:`~.margins.CONTINUOUS_SHARE` of the continuous);
        ``motor_peak_Nm``, ``motor_continuous_Nm``, ``motor_no_load_rad_s``,
        ``torque_scale_Nm`` (the LQI's); ``wall_s``.
    Raises:
        nothing the robot causes (a refusal or a guard trip is the row's ``reason``); a bug
        propagates, and the runner makes it a :class:`~.runners.JobFailure`, a failed row.
    """
    from ..run.simulate import run_experiment

    t0 = time.perf_counter()
    row = _failed_row(job, None)
    try:
        result = run_experiment(job.scenario)
    except StewartError as err:  # refused before the run, or stopped by the guard
        row["reason"] = f"{type(err).__name__}: {err}"
        row["wall_s"] = time.perf_counter() - t0
        return row
    row.update(_figures(job, result))
    row["completed"] = True
    row["wall_s"] = time.perf_counter() - t0
    return row


def _figures(job: MotionRun, result) -> dict:
    """The tracking and effort figures of a completed run (:func:`run_motion`)."""
    from ..organ_motion.fidelity import fidelity

    geometry, servo = robot_geometry(job.scenario), robot_motor_limits(job.scenario).servo
    assert servo is not None  # design_scenario's base has hardware
    f = fidelity(result.t, result.x, result.x_d)
    T = np.asarray(result.T, dtype=float)
    peak_T = float(np.abs(T).max())
    rms_T = float(rms_per_axis(T).max())
    x = np.asarray(result.x, dtype=float)
    theta_dot = np.einsum("nij,nj->ni", jacobian(geometry, x[:, :6]), x[:, 6:12])
    peak_speed = float(np.abs(theta_dot).max())
    return {
        "rms_translation_um": 1e6 * f["rms_translation_m"],
        "peak_translation_um": 1e6 * f["peak_translation_m"],
        "rms_rotation_urad": 1e6 * f["rms_rotation_rad"],
        "peak_rotation_urad": 1e6 * f["peak_rotation_rad"],
        "peak_torque_Nm": peak_T,
        "peak_torque_fraction": peak_T / servo.peak_torque_Nm,
        "rms_torque_Nm": rms_T,
        "rms_torque_fraction": rms_T / job.continuous_torque_Nm,
        "peak_speed_rad_s": peak_speed,
        "peak_speed_fraction": peak_speed / servo.no_load_speed_rad_s,
        "within_margins": bool(
            peak_T <= job.torque_share * servo.peak_torque_Nm
            and peak_speed <= job.speed_share * servo.no_load_speed_rad_s
            and rms_T <= CONTINUOUS_SHARE * job.continuous_torque_Nm
        ),
    }


#: The columns of :func:`confirmation_table`.
TABLE_COLUMNS = (
    "motion",
    "s",
    "translation RMS / max, um",
    "rotation RMS / max, urad",
    "peak torque, N m (of peak)",
    "RMS torque, N m (of continuous)",
    "peak crank speed, rad/s (of no-load)",
    "within margins",
)
#: The header line of :func:`confirmation_table`.
TABLE_HEADER = markdown_row(TABLE_COLUMNS)


def confirmation_table(rows: list[dict]) -> str:
    """The rows of :func:`confirm` as a Markdown table, one line per motion (a motion not made
    says why instead of its figures, its ``|`` escaped)."""
    cells = []
    for r in rows:
        head = [r["label"], f"{r['duration_s']:g}"]
        if not r["completed"]:
            reason = str(r["reason"]).replace("|", "\\|")  # |phi - phi_d| in a cell
            cells.append(head + [f"not made: {reason}"] + [None] * 5)
            continue
        cells.append(
            head
            + [f"{r['rms_translation_um']:.1f} / {r['peak_translation_um']:.0f}"]
            + [f"{r['rms_rotation_urad']:.1f} / {r['peak_rotation_urad']:.0f}"]
            + [f"{r['peak_torque_Nm']:.3g} ({r['peak_torque_fraction']:.0%})"]
            + [f"{r['rms_torque_Nm']:.3g} ({r['rms_torque_fraction']:.0%})"]
            + [f"{r['peak_speed_rad_s']:.3g} ({r['peak_speed_fraction']:.1%})"]
            + ["yes" if r["within_margins"] else "no"]
        )
    return markdown_table(TABLE_COLUMNS, cells) + "\n"


def _failed_row(job: MotionRun, reason: str | None) -> dict[str, Any]:
    """A row with the job's description and no figures (``completed`` False)."""
    servo = job.scenario.hardware.motors if job.scenario.hardware is not None else None
    controller = job.scenario.controller
    return {
        "label": job.label,
        "motor": job.motor,
        "duration_s": float(job.scenario.duration_s),
        "completed": False,
        "reason": reason,
        "motor_peak_Nm": None if servo is None else float(servo.peak_torque_Nm),
        "motor_continuous_Nm": float(job.continuous_torque_Nm),
        "motor_no_load_rad_s": None if servo is None else float(servo.no_load_speed_rad_s),
        "torque_scale_Nm": (
            float(controller.scales.torque) if isinstance(controller, LqiDriver) else None
        ),
    }


def design_robustness(design: Design, requirements: DesignRequirements, base) -> dict:
    """What ``design``'s loop survives as the base scenario configures it on the design as built
    (:func:`~stewart_drake.analysis.robustness.loop_robustness` at home): a plain record of
    its :class:`~stewart_drake.control.robustness.RobustRange` with its verdict line, or
    ``{"holds": None, "verdict": why}`` when the base's controller has no such model.

    Raises:
        InvalidConfigError, InvalidGeometryError: as :func:`design_scenario`.
    """
    from ..analysis.robustness import loop_robustness
    from ..references.trajectories import NamedReference

    # The loop's model is the robot's at home: any motion of the task, or none.
    motion = requirements.motions[0] if requirements.motions else NamedReference("home")
    scenario = design_scenario(design, requirements, motion, base)
    robust = loop_robustness(scenario)
    if robust is None:
        name = type(scenario.controller).__name__
        return {"holds": None, "verdict": f"not modelled for a {name}"}
    return robust.record() | {"verdict": robust.verdict()}


def robustness_lines(robustness: dict) -> list[str]:
    """The designs' loops against what a shipped loop must survive, as a Markdown section:
    {role: :func:`design_robustness`'s record}."""
    from ..control.robustness import EXTRA_DELAY_S, GAIN_RANGE

    def pair(r, key):
        values = r.get(key)
        if values is None:
            return "-"
        return "unstable at gain 1" if values[0] is None else f"{values[0]:.2f} to {values[1]:.2f}"

    rows = [
        [role, r.get("loop", "-"), pair(r, "gains"), pair(r, "delayed_gains"), r["verdict"]]
        for role, r in robustness.items()
    ]
    header = ["design", "loop", "stable plant gains", "with the extra delay", "verdict"]
    return [
        "## The loop against what the catalogue does not know",
        "",
        f"A design is recommended only if its loop stays stable for a plant gain (true / "
        f"believed torque per command) of {GAIN_RANGE[0]:g} to {GAIN_RANGE[1]:g} with "
        f"{1e3 * EXTRA_DELAY_S:g} ms more delay than it was designed for (a host loop; the "
        "servos' own loop has the bus's delay outside it): the catalogue's rotor inertia within "
        "a factor of 2, the bus's own delay and 4 ms (stewart_drake/control/robustness.py).",
        "",
        markdown_table(header, rows),
        "",
    ]


def load_base(base: str | Path | Scenario) -> Scenario:
    """A fresh copy of the base scenario a design is built on: loaded from a shipped name or a
    scenario file (as the CLI loads it), or copied.

    Raises:
        MissingFileError, CorruptFileError, InvalidConfigError: as
            :func:`~stewart_drake.run.scenario_io.load_scenario`.
    """
    if isinstance(base, Scenario):
        return copy.deepcopy(base)  # through its YAML (Scenario.__reduce__)
    return load_scenario(base)


def check_base(base: Scenario) -> None:
    """Refuse a base on which a design's motor means nothing, or whose weights are not an
    LQI's.

    Raises:
        InvalidConfigError: a base without hardware, or whose controller is not an LqiDriver.
    """
    if base.hardware is None:
        raise InvalidConfigError(
            "a design is confirmed on the robot as built: the base scenario needs hardware "
            "(encoders and motors); use paper_hardware or a scenario with a hardware section"
        )
    if not isinstance(base.controller, LqiDriver):
        raise InvalidConfigError(
            f"a design's weights are chosen for the LQI: the base scenario's controller is "
            f"{type(base.controller).__name__}; use an LqiDriver"
        )


__all__ = [
    "DEFAULT_BASE",
    "MAX_PERIODIC_S",
    "MAX_TRACE_S",
    "TABLE_COLUMNS",
    "TABLE_HEADER",
    "MotionRun",
    "load_base",
    "check_base",
    "confirm",
    "confirmation_table",
    "design_scenario",
    "motion_duration_s",
    "run_motion",
    "torque_scale_Nm",
]
