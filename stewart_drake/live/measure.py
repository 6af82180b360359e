"""The robot read with the torque off: its pose and verdict, the calibration, the start.

:func:`measure_pose` is the dry run: it opens the scenario's bus, reads the crank angles once
and returns the pose by forward kinematics with the admissible set's verdict on it
(:class:`MeasuredPose`). :func:`admissible_start` refuses a pose outside that set, before a
session (:mod:`~.session`) powers anything; :func:`zero_counts_at` gives the calibration's zero
counts of cranks held at a known angle.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from ..base.errors import InvalidConfigError, StartPoseError


@dataclasses.dataclass(frozen=True)
class MeasuredPose:
    """The robot's pose read from its encoders with the torque off.

    Attributes:
        q: (6,) crank angles, rad (zero counts and directions applied).
        x: (6,) the pose [phi, theta, psi, X, Y, Z] (rad, m) by forward kinematics from home.
        flags: the admissible set's verdicts at x (:func:`~stewart_drake.plant.admissible.classify`,
            with the guard's bounds and the motors' peak torque): "reachable", "clear",
            "usable", "within_peak", "admissible" (bool) and "max_torque" (N m),
            "clearance" (m), "cond", "sigma_min_inv" ((rad or m) per rad).
        problem: why x is not admissible (one sentence), or None.
    """

    q: np.ndarray
    x: np.ndarray
    flags: dict
    problem: str | None

    def summary(self) -> str:
        """Two lines: the angles and pose, and the verdict."""
        deg = np.degrees
        pose = (
            f"roll {deg(self.x[0]):+.2f} pitch {deg(self.x[1]):+.2f} yaw {deg(self.x[2]):+.2f} "
            f"deg, X {self.x[3] * 1e3:+.2f} Y {self.x[4] * 1e3:+.2f} Z {self.x[5] * 1e3:.2f} mm"
        )
        angles = ", ".join(f"{v:+.1f}" for v in deg(self.q))
        verdict = "admissible" if self.problem is None else f"NOT admissible: {self.problem}"
        return f"cranks [{angles}] deg -> {pose}\n{verdict}"


def _first_problem(flags: dict) -> str | None:
    """The first check of the admissible set that ``flags`` (classify's, at one pose) fails."""
    if not flags["reachable"]:
        return "outside a joint's range or the rods' reach"
    if not flags["clear"]:
        return f"two parts closer than the guard allows ({flags['clearance'] * 1e3:.1f} mm)"
    if not flags["usable"]:
        return (
            f"too close to a singularity (cond(J) {flags['cond']:.0f}, 1/sigma_max(J) "
            f"{flags['sigma_min_inv']:.3g}; the guard's bounds)"
        )
    if not flags["within_peak"]:
        return f"holding it needs {flags['max_torque']:.3f} N m, over the motors' peak"
    if not flags["admissible"]:
        return f"holding it needs {flags['max_torque']:.3f} N m, over a reference's share"
    return None


def pose_verdict(plan, q) -> MeasuredPose:
    """The :class:`MeasuredPose` of crank angles ``q`` (6,) rad on the robot of ``plan`` (a
    :class:`~stewart_drake.run.plan.RunPlan`): forward kinematics from home, then the
    admissible set's checks with the guard's bounds (those ``teleop`` and ``check`` apply).

    Raises:
        StartPoseError: no pose has these angles (the forward kinematics does not converge:
            a crank off its calibration, or a servo's zero count wrong).
    """
    from ..base.errors import ForwardKinematicsError
    from ..plant.admissible import classify
    from ..plant.clearance import clearance_model
    from ..robot.forward_kinematics import fk

    q = np.asarray(q, dtype=float)
    try:
        x, _ = fk(plan.geometry, q - plan.geometry.encoder_offsets)  # the encoders' zero errors
    except ForwardKinematicsError:
        raise StartPoseError(
            f"no pose of the robot has the measured crank angles "
            f"[{', '.join(f'{v:+.1f}' for v in np.degrees(q))}] deg: check each servo's "
            f"zero_counts and direction in the scenario's bus (docs/robot.md, calibration)"
        ) from None
    guard = plan.scenario.guard
    flags = classify(
        plan.geometry,
        x[None],
        guard.cond_threshold,
        guard.min_clearance_m,
        plan.motor_limits,
        guard.min_sigma_min_inv,
        clearance=clearance_model(plan.plant_geometry),
    )
    keys = ("reachable", "clear", "usable", "within_peak", "admissible")
    one: dict = {k: bool(flags[k][0]) for k in keys}
    one.update(
        {k: float(flags[k][0]) for k in ("max_torque", "clearance", "cond", "sigma_min_inv")}
    )
    return MeasuredPose(q=q, x=x, flags=one, problem=_first_problem(one))


def bus_config(scenario):
    """The scenario's ``bus`` config, or InvalidConfigError saying how to give one."""
    bus = getattr(scenario, "bus", None)
    if bus is None:
        raise InvalidConfigError(
            "the scenario has no bus: add a 'bus:' section (port, baud_rate, ids, model, "
            "zero_counts, directions; docs/robot.md) or give --port"
        )
    return bus


def measure_pose(scenario, bus=None) -> MeasuredPose:
    """Read the robot's pose with the torque off (the dry run): open the bus of
    ``scenario.bus`` (or use ``bus``, an opened
    :class:`~stewart_drake.station.bus.driver.DynamixelBus`), read the crank angles once,
    close it.

    Args:
        scenario: a Scenario with a ``bus`` (or a RunPlan of one).
    Returns:
        :class:`MeasuredPose`.
    Raises:
        InvalidConfigError: no bus in the scenario. BusError, MissingServoError: the port, a
        servo. StartPoseError: the angles are no pose of the robot.
    """
    from ..run.plan import make_plan

    plan = make_plan(scenario, with_reference=False)
    if bus is not None:
        return pose_verdict(plan, bus.read_state().q)
    from ..station.bus.driver import DynamixelBus

    with DynamixelBus.from_config(bus_config(plan.scenario)) as opened:
        return pose_verdict(plan, opened.read_state().q)


def zero_counts_at(bus, angle_rad: float = 0.0) -> np.ndarray:
    """Calibration: the counts each servo reports while its crank is held at ``angle_rad``
    (0: the crank horizontal, pointing away from the base's centre along its leg's direction,
    docs/reference_geometry.md), i.e. the ``zero_counts`` to write in the scenario's bus.

    Args:
        bus: an opened :class:`~stewart_drake.station.bus.driver.DynamixelBus` (the
            torque off: the cranks are held by hand or by a jig); its ``directions`` must be
            right (a crank's counts grow as its tip rises for +1).
        angle_rad: the angle the cranks are held at, rad.
    Returns:
        (n,) int counts, rounded, each within the Present Position register's (signed 32 bits).
    Raises:
        InvalidConfigError: ``angle_rad`` not finite or beyond half a turn.
        BusError: a zero count outside the register's range (a servo's reading is wrong).
    """
    from ..base.errors import BusError
    from ..station.bus.protocol import rad_to_counts

    if not (math.isfinite(angle_rad) and abs(angle_rad) <= math.pi):
        raise InvalidConfigError(
            f"the calibration angle must be finite and within half a turn, got {angle_rad} rad"
        )
    q = bus.read_state().q  # with the bus's current zero counts and directions
    raw = rad_to_counts(q, bus.zero_counts, bus.directions)
    zeros = raw - rad_to_counts(np.full(len(q), angle_rad), 0, bus.directions)
    bad = np.flatnonzero(np.abs(zeros) >= 2**31)
    if bad.size:
        raise BusError(
            f"servo id {bus.ids[bad[0]]} reads {raw[bad[0]]} counts: its zero count would be "
            f"outside the encoder's signed 32-bit range; check its id and its reading"
        )
    return zeros.astype(int)


def admissible_start(scenario) -> MeasuredPose:
    """:func:`measure_pose`, refusing a pose outside the admissible set.

    Raises:
        StartPoseError: the measured pose fails a check (named); nothing was powered.
        as :func:`measure_pose`.
    """
    start = measure_pose(scenario)
    if start.problem is not None:
        raise StartPoseError(
            f"the robot rests at a pose outside the admissible set ({start.problem}); nothing "
            f"was powered. Measured: {start.summary().splitlines()[0]}"
        )
    return start
