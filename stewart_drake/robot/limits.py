"""Joint limits, nearness to singularity, and the one validator of a reference path.

Per leg: loop closure (|L|/sqrt(M^2+N^2) <= 1), motor travel, and the two ball-joint cones
(fields of :class:`~stewart_drake.robot.geometry.StewartGeometry`); per pose: cond(J) and
1/sigma_max(J) (:func:`~.kinematics.singularity_measures`); along a path, optionally, the
clearance between the robot's parts (:mod:`~.clearance`) and the torque and speed the motion needs
from each motor (:func:`~.statics.motor_effort`) against what its servo gives
(:class:`MotorLimits`). :func:`validate_trajectory` is the only check of a sampled reference:
every entry point (the run, the collection, the tasks, ``stewart-drake check``) calls it.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache, reduce
from typing import TYPE_CHECKING, Any

import numpy as np

from ..base.checks import as_array, as_number, as_poses
from ..base.errors import InvalidConfigError, UnreachablePoseError
from .kinematics import (
    DEFAULT_COND_THRESHOLD,
    X_HOME,
    RobotGeometry,
    ik,
    ik_unchecked,
    jacobian_of,
    leg_terms,
    platform_joints,
    rotation_rpy,
    singular_values_of,
    singularity_measures_of,
    wrap_angle,
)

if TYPE_CHECKING:
    from .servo import ServoModel
from .path_checks import (
    SampleKinematics,
    clearance_fields,
    compiled_kinematics,
    effort_fields,
    raise_first_refusal,
)
from .trajectory_report import LimitViolation, TrajectoryReport

#: Default lower bound on 1/sigma_max(J) = sigma_min(J^{-1}), (rad or m) of pose per rad of motor.
#: J = d theta / d x; its largest singular value blows up at a crank's dead point (rod aligned
#: with the crank-tip velocity's normal plane): there the motors cannot *move* the platform along
#: the matching direction, the edge of the workspace. cond(J) misses it when all six legs reach
#: the dead point together (pure heave: cond 26 at Z = 0.20 m, 30 at Z = 0.41 m), so this second
#: measure is checked too. cond(J) -> inf with sigma_max bounded is the other singularity, where
#: sigma_min(J) -> 0 and the motors cannot *hold* the platform against some wrench (T = J^{-T} w).
#: Reference robot: 0.044 at home, 0.021 at least along the paper manoeuvre (2x margin), 0.041
#: along the data-collection excitation; 0.011 at Z = 0.20 m and 0.019 at Z = 0.41 m in heave.
DEFAULT_MIN_SIGMA_MIN_INV = 0.01

#: Default smallest clearance between two parts a reference may leave, m
#: (``GuardConfig.min_clearance_m``; :mod:`~.clearance`).
DEFAULT_MIN_CLEARANCE_M = 0.003
#: Default spacing of the clearance measures along a path: no part moves more than this between
#: two, m.
DEFAULT_CLEARANCE_RESOLUTION_M = 0.001

#: Names of the per-leg limits, in the order reports list them. Margins are >= 0 inside a limit:
#: ``closure`` 1 - |L|/sqrt(M^2+N^2) (dimensionless); the others in rad.
LIMITS = ("closure", "motor_angle", "crank_joint", "platform_joint")


@lru_cache(maxsize=32)
def _home_rod_in_platform(geometry: RobotGeometry) -> np.ndarray:
    """(6, 3) unit rod directions (crank tip -> platform joint) at home, platform frame E."""
    theta = ik(geometry, X_HOME)
    q_B, _ = platform_joints(geometry, X_HOME)
    ell = q_B - geometry.crank_tips(theta)
    e_l = ell / np.linalg.norm(ell, axis=-1, keepdims=True)
    return e_l @ rotation_rpy(X_HOME[:3])  # R^T e_l, row-wise


def joint_angles(geometry: RobotGeometry, x, theta=None) -> dict:
    """The angles the limits of :func:`limit_margins` bound, per leg, (..., 6) each in rad.

    Returns a dict:
        ``motor_angle``: theta_i wrapped to [-pi, pi).
        ``crank_joint``: misalignment of the rod end at the crank tip, asin |e_l . u_i|. The rod
            end's bolt is parallel to the motor shaft u_i, so the rod turns freely in the crank's
            plane of rotation and this angle is its tilt out of that plane (19.4 deg at home).
        ``platform_joint``: angle between the rod and the axis of its ball socket on the
            platform; each socket is mounted along its rod's home direction (0 at home).
    NaN where a leg cannot close.
    """
    x = np.asarray(x, dtype=float)
    if theta is None:
        theta, _ = ik_unchecked(geometry, x)
    q_B, _ = platform_joints(geometry, x)
    ell = q_B - geometry.crank_tips(theta)
    return joint_angles_of(geometry, theta, ell, rotation_rpy(x[..., :3]))


def joint_angles_of(geometry: RobotGeometry, theta, ell, R) -> dict:
    """:func:`joint_angles` from the motor angles theta (..., 6), the rod vectors ell
    (..., 6, 3) and R_BE (..., 3, 3) of the poses (their :class:`~.kinematics.LegTerms`)."""
    return _angles_of(theta, *_joint_cosines(geometry, ell, R))


def _joint_cosines(geometry: RobotGeometry, ell, R) -> tuple:
    """(e_l . u_i, R^T e_l . (the socket's axis)) (..., 6) each, of the rods ell (..., 6, 3) at
    R_BE (..., 3, 3): the sine of each rod's tilt out of its crank's plane and the cosine of its
    angle in its platform socket (:func:`~.path_kernels.pose_terms` computes the same)."""
    e_l = ell / np.linalg.norm(ell, axis=-1, keepdims=True)
    e_l_E = np.einsum("...ji,...kj->...ki", R, e_l)  # rows R^T e_l
    cos_p = np.sum(e_l_E * _home_rod_in_platform(geometry), axis=-1)
    return np.sum(e_l * geometry.u_B, axis=-1), cos_p


def _angles_of(theta, crank, cos_p) -> dict:
    """:func:`joint_angles` from the motor angles theta and the rods' cosines of
    :func:`_joint_cosines`, (..., 6) each."""
    return {
        "motor_angle": wrap_angle(theta),
        "crank_joint": np.arcsin(np.clip(np.abs(crank), 0.0, 1.0)),
        "platform_joint": np.arccos(np.clip(cos_p, -1.0, 1.0)),
    }


@lru_cache(maxsize=32)
def _joint_axes(geometry: RobotGeometry) -> np.ndarray:
    """(6, 6) per leg its motor shaft u_i and its socket's axis in the platform frame, for
    :func:`~.path_kernels.pose_terms`; read-only."""
    axes = np.ascontiguousarray(np.hstack([geometry.u_B, _home_rod_in_platform(geometry)]))
    axes.setflags(write=False)
    return axes


def limit_margins(geometry: RobotGeometry, x, theta=None, ratio=None) -> dict:
    """Distance of reachable pose(s) x to every per-leg limit; >= 0 inside, < 0 violated.

    Args:
        x: (6,) or (..., 6) poses [rad, m].
        theta, ratio: optional outputs of :func:`ik_unchecked` for x (saves one IK).
    Returns:
        dict name -> (..., 6) for the names of :data:`LIMITS`:
        ``closure`` = 1 - |L|/sqrt(M^2+N^2) (dimensionless, >= 0 here: every leg closes);
        ``motor_angle`` = distance of theta_i to [motor_angle_min_deg, motor_angle_max_deg], rad;
        ``crank_joint`` = crank_joint_cone_deg - misalignment, rad;
        ``platform_joint`` = platform_joint_cone_deg - socket angle, rad
        (angles of :func:`joint_angles`; limits are fields of :class:`StewartGeometry`).
    Raises:
        UnreachablePoseError: a leg cannot close at a pose (names the first pose and leg; the
            other limits are not defined there). :func:`is_reachable` reports such poses
            instead, and :func:`limit_margins_unchecked` gives NaN for them.
        InvalidConfigError: x, theta or ratio not (..., 6), not finite, or a position beyond 1 km.
    """
    x = as_poses("pose x", x)
    if theta is None or ratio is None:
        theta, ratio = ik_unchecked(geometry, x)
    else:
        theta = as_array("motor angles theta", theta, shape=x.shape)
        ratio = as_array("reach ratio", ratio, shape=x.shape)
    closed = np.abs(ratio) <= 1.0
    if not np.all(closed):
        k = int(np.argmax(~np.all(closed.reshape(-1, 6), axis=1)))
        row = ratio.reshape(-1, 6)[k]
        leg = int(np.argmax(np.where(np.isfinite(row), np.abs(row), np.inf)))
        raise UnreachablePoseError(leg, row[leg], pose=x.reshape(-1, 6)[k])
    return limit_margins_unchecked(geometry, x, theta, ratio)


def limit_margins_unchecked(geometry: RobotGeometry, x, theta=None, ratio=None) -> dict:
    """:func:`limit_margins` of any finite poses: ``closure`` < 0 where a leg cannot close, the
    other margins NaN there (workspace sweeps, :func:`is_reachable`)."""
    x = np.asarray(x, dtype=float)
    if theta is None or ratio is None:
        theta, ratio = ik_unchecked(geometry, x)
    return margins_of(geometry, ratio, joint_angles(geometry, x, theta))


def margins_of(geometry: RobotGeometry, ratio, angles: dict) -> dict:
    """:func:`limit_margins_unchecked` from the reach ratios (..., 6) and the
    :func:`joint_angles` of the poses."""
    lo, hi = np.deg2rad(geometry.motor_angle_min_deg), np.deg2rad(geometry.motor_angle_max_deg)
    m = angles["motor_angle"]
    return {
        "closure": 1.0 - np.abs(ratio),
        "motor_angle": np.minimum(m - lo, hi - m),
        "crank_joint": np.deg2rad(geometry.crank_joint_cone_deg) - angles["crank_joint"],
        "platform_joint": np.deg2rad(geometry.platform_joint_cone_deg) - angles["platform_joint"],
    }


def reachable_from_margins(margins: dict) -> np.ndarray:
    """(...) bool: every leg inside every limit of :data:`LIMITS` by ``margins``
    (:func:`limit_margins_unchecked`); NaN counts as violated."""
    return reduce(np.logical_and, (np.all(margins[name] >= 0.0, axis=-1) for name in LIMITS))


@dataclass(frozen=True)
class Reachability:
    """Result of :func:`is_reachable`; truthy iff every pose is reachable.

    Attributes:
        reachable: (...) bool, every leg inside every limit of :data:`LIMITS`.
        margins: dict name -> (..., 6), see :func:`limit_margins`.
        theta: (..., 6) motor angles in rad (NaN where a leg cannot close).
    """

    reachable: np.ndarray
    margins: dict
    theta: np.ndarray

    def __bool__(self) -> bool:
        return bool(np.all(self.reachable))

    def violations(self, index: int = 0) -> list:
        """Violated limits of pose ``index`` of the flattened batch, worst first.

        Returns:
            list of :class:`LimitViolation`; only ``closure`` for a leg that cannot close.
        """
        out = []
        for name in LIMITS:
            m = np.asarray(self.margins[name], dtype=float).reshape(-1, 6)[index]
            for leg in range(6):
                if name != "closure" and not np.isfinite(m[leg]):
                    continue  # the leg does not close: reported above
                if not m[leg] >= 0.0:
                    out.append(LimitViolation(leg, name, float(m[leg])))
        return sorted(out, key=lambda v: v.margin)


def is_reachable(geometry: RobotGeometry, x) -> Reachability:
    """Check pose(s) x against loop closure, motor range and ball-joint cones, before a move.

    Args:
        geometry: the robot; its limit fields set the ranges.
        x: (6,) or (..., 6) poses [phi, theta, psi, X, Y, Z] in rad and m.
    Returns:
        :class:`Reachability`: ``bool(result)``, per-pose ``reachable``, per-leg ``margins`` and
        ``violations()`` naming the leg, the limit and by how much.
    Raises:
        InvalidConfigError: x not (..., 6), not finite, or a position beyond 1 km.
    """
    x = as_poses("pose x", x)
    theta, ratio = ik_unchecked(geometry, x)
    margins = limit_margins_unchecked(geometry, x, theta, ratio)
    return Reachability(reachable_from_margins(margins), margins, theta)


#: Default share of the servos' peak torque and no-load speed a reference may use; the rest is
#: left to the feedback (``GuardConfig.effort_margin``).
DEFAULT_EFFORT_MARGIN = 0.9


@dataclass(frozen=True)
class MotorLimits:
    """What the motors give at the crank shafts, and how much of it a reference may use.

    Attributes:
        peak_torque_Nm: the drive's peak torque, N m, or None (unlimited: not checked).
        max_speed_rad_s: the no-load speed through the gearbox, rad/s, or None.
        margin: the share of each a reference may use, in (0, 1].
        servo: the :class:`~.servo.ServoModel` whose friction the motors also overcome, or None.
    """

    peak_torque_Nm: float | None = None
    max_speed_rad_s: float | None = None
    margin: float = DEFAULT_EFFORT_MARGIN
    servo: ServoModel | None = None


def validate_trajectory(
    geometry: RobotGeometry,
    t,
    x,
    cond_threshold: float = DEFAULT_COND_THRESHOLD,
    raise_unreachable: bool = True,
    min_sigma_min_inv: float = DEFAULT_MIN_SIGMA_MIN_INV,
    raise_refused: bool = False,
    x_dot=None,
    x_ddot=None,
    clearance=None,
    min_clearance_m: float = DEFAULT_MIN_CLEARANCE_M,
    clearance_resolution_m: float = DEFAULT_CLEARANCE_RESOLUTION_M,
    motor_limits: MotorLimits | None = None,
    allow_infeasible: bool = False,
    compiled: bool = True,
) -> TrajectoryReport:
    """Validate a sampled path before running it: limits, margins and nearness to singularity.

    Args:
        geometry: the robot; its limit fields set the ranges.
        t: (n,) sample times in s, increasing.
        x: (n, 6) poses [phi, theta, psi, X, Y, Z] in rad and m. Only the samples are checked:
            sample finer than the shortest feature of the path.
        cond_threshold: cond(J) above this counts as too close to a singularity (> 1).
        raise_unreachable: raise on a leg that cannot close (else report it as ``closure``).
        min_sigma_min_inv: 1/sigma_max(J) below this ((rad or m) per rad, >= 0) counts as too
            close to a dead point (see :data:`DEFAULT_MIN_SIGMA_MIN_INV`).
        raise_refused: raise on the first refused sample (what a run needs), not only report.
        x_dot, x_ddot: optional (n, 6) rates and accelerations of the path; checked finite.
        clearance: a :class:`~.clearance.ClearanceModel`: no two parts closer than
            ``min_clearance_m``, m, measured wherever a part has moved ``clearance_resolution_m``
            (m; :func:`~.clearance.sample_indices`), so between measures it is at least the
            smaller measured value minus that resolution.
        motor_limits: :class:`MotorLimits` for the torque and crank speed the motion needs
            (:func:`~.statics.motor_effort`, needs x_dot and x_ddot; inertia and friction too).
        allow_infeasible: with ``raise_refused``, a motor over its limit is reported
            (``first_effort_violation``) but not raised: the run goes on and saturates.
        compiled: kinematics and torques compiled (:func:`~.path_checks.compiled_kinematics`,
            :func:`~.statics.motor_effort_compiled`; False: numpy, the same report but for the
            torques' last digits: docs/performance.md, "The reference check before a run").
    Returns:
        :class:`TrajectoryReport` (``summary()`` prints it).
    Raises:
        UnreachablePoseError: with ``raise_unreachable``: the first time, worst leg and ratio.
        JointLimitError: with ``raise_refused``, the first time a leg leaves a joint limit.
        SingularPoseError: with ``raise_refused``, the first time cond(J) > cond_threshold or
            1/sigma_max(J) < min_sigma_min_inv, naming the measure (whichever comes first).
        InterferenceError: with ``raise_refused`` and ``clearance``, the first time two parts
            come closer than ``min_clearance_m``, naming them.
        MotorLimitError: with ``raise_refused`` and ``motor_limits`` (not ``allow_infeasible``),
            the first time a motor needs more torque or speed than it may use (motor, excess).
        InvalidConfigError: t and x of mismatched shapes or not finite (the first non-finite
            pose, rate or acceleration named with its time), t not increasing, a bad threshold.
    Source: the one validator of a reference; every run calls it through
        :func:`~stewart_drake.run.plan.validate_reference` before anything is simulated.
    """
    # Long for its docstring: the one validator of a reference documents every check and error.
    t, x = _checked_samples(t, x, x_dot, x_ddot)
    checks = _PathChecks(
        as_number("cond_threshold", cond_threshold, 1.0, lo_open=True),
        as_number("min_sigma_min_inv", min_sigma_min_inv, 0.0),
        raise_unreachable,
        raise_refused,
        clearance,
        min_clearance_m,
        clearance_resolution_m,
        motor_limits,
        allow_infeasible,
        compiled,
    )
    return _validated(geometry, t, x, x_dot, x_ddot, checks)


@dataclass(frozen=True)
class _PathChecks:
    """The checks :func:`validate_trajectory` was asked for (its arguments, the thresholds
    checked), handed whole to its steps."""

    cond_threshold: float
    min_sigma_min_inv: float
    raise_unreachable: bool
    raise_refused: bool
    clearance: Any
    min_clearance_m: float
    clearance_resolution_m: float
    motor_limits: MotorLimits | None
    allow_infeasible: bool
    compiled: bool


def _validated(geometry, t, x, x_dot, x_ddot, checks: _PathChecks) -> TrajectoryReport:
    """:func:`validate_trajectory` of checked samples. The kinematics of the samples (inverse
    kinematics, leg terms, Jacobian) are computed once, for the limits, the singularity
    measures and the motors' effort alike."""
    kin = _sample_kinematics(geometry, x, checks.compiled)
    ratio = kin.ratio
    cond, inv = singularity_measures_of(singular_values_of(kin.J))
    closed = np.abs(ratio) <= 1.0
    if checks.raise_unreachable and not np.all(closed):
        _raise_unreachable(geometry, t, x, x_dot, x_ddot, ratio, checks)
    margins = margins_of(geometry, ratio, _angles_of(kin.theta, kin.crank, kin.cos_p))
    cond_f = np.where(np.isnan(cond), np.inf, cond)
    inv_f = np.where(np.isnan(inv), 0.0, inv)
    reachable = np.all(closed, axis=1)
    series = {"t": t, "margins": margins, "cond": cond, "sigma_min_inv": inv}
    extra = {"series": series}
    if checks.clearance is not None:
        threshold = as_number("min_clearance_m", checks.min_clearance_m, 0.0)
        extra.update(
            clearance_fields(
                checks.clearance,
                t,
                x,
                reachable,
                threshold,
                checks.clearance_resolution_m,
                series,
                kin.theta,
            )
        )
    if checks.motor_limits is not None:
        extra.update(
            effort_fields(
                geometry,
                t,
                x,
                x_dot,
                x_ddot,
                reachable,
                checks.motor_limits,
                series,
                kin,
            )
        )
    report = _report(t, margins, cond_f, inv_f, checks, extra)
    if checks.raise_refused and not report.ok:
        raise_first_refusal(report, t, x, cond_f, inv_f, checks.allow_infeasible)
    return report


def sample_effort(geometry: RobotGeometry, x, x_dot, x_ddot, servo=None) -> tuple:
    """The torque and crank speed each motor needs at each sample, as the validator's motor
    check computes them (:func:`validate_trajectory` with ``motor_limits``: the compiled
    kinematics and effort, pose by pose, so a sample's numbers do not depend on the samples
    beside it), for a caller that bounds them sample by sample
    (:mod:`stewart_drake.run.shaping`).

    Args:
        x, x_dot, x_ddot: (n, 6) poses [rad, m], their rates and accelerations (SI).
        servo: a :class:`~.servo.ServoModel` whose friction the motors also overcome, or None.
    Returns:
        (T, theta_dot): (n, 6) torques in N m and crank rates in rad/s; inf at a sample whose
        legs do not all close or whose Jacobian is not finite (the validator refuses it).
    Source: :func:`~.statics.motor_effort_compiled` (inverse dynamics plus the servo's
        friction), the validator's own.
    """
    from .statics import motor_effort_compiled

    x = np.ascontiguousarray(x, dtype=float).reshape(-1, 6)
    x_dot = np.asarray(x_dot, dtype=float).reshape(-1, 6)
    x_ddot = np.asarray(x_ddot, dtype=float).reshape(-1, 6)
    kin = _sample_kinematics(geometry, x, True)
    ok = np.all(np.abs(kin.ratio) <= 1.0, axis=1) & np.all(np.isfinite(kin.J), axis=(1, 2))
    T, speed = np.full(x.shape, np.inf), np.full(x.shape, np.inf)
    rows = np.flatnonzero(ok)
    if rows.size:
        T[rows], speed[rows] = motor_effort_compiled(
            geometry, x[rows], x_dot[rows], x_ddot[rows], servo, kin.theta[rows], kin.J[rows]
        )
    return T, speed


def _sample_kinematics(geometry, x, compiled: bool) -> SampleKinematics:
    """The kinematics of the samples x (n, 6) that the checks read: compiled
    (:func:`~.path_checks.compiled_kinematics`) or numpy (:func:`~.kinematics.ik_unchecked`,
    :func:`~.kinematics.leg_terms`, :func:`~.kinematics.jacobian_of`, :func:`_joint_cosines`);
    the same numbers."""
    if compiled:
        return compiled_kinematics(geometry, x, _joint_axes(geometry))
    theta, ratio = ik_unchecked(geometry, x)
    terms = leg_terms(geometry, x, theta)  # NaN where a leg cannot close
    crank, cos_p = _joint_cosines(geometry, terms.ell, terms.R)
    return SampleKinematics(theta, ratio, jacobian_of(geometry, terms), crank, cos_p, terms)


def _raise_unreachable(geometry, t, x, x_dot, x_ddot, ratio, checks: _PathChecks):
    """Raise the UnreachablePoseError of the first sample where a leg cannot close; with
    ``raise_refused``, an earlier refusal of another kind first (the samples before it are
    validated)."""
    k = int(np.argmax(~np.all(np.abs(ratio) <= 1.0, axis=1)))
    if checks.raise_refused and k > 0:  # an earlier refusal of another kind comes first
        head = [None if v is None else np.asarray(v)[:k] for v in (x_dot, x_ddot)]
        _validated(geometry, t[:k], x[:k], head[0], head[1], checks)
    leg = int(np.argmax(np.where(np.isfinite(ratio[k]), np.abs(ratio[k]), np.inf)))
    raise UnreachablePoseError(leg, ratio[k, leg], t=t[k], pose=x[k])


def _checked_samples(t, x, x_dot, x_ddot) -> tuple:
    """(t (n,), x (n, 6)) checked: finite (the first non-finite pose, rate or acceleration named
    with its time), matching shapes, n > 0, t strictly increasing.

    Raises:
        InvalidConfigError: names what is wrong.
    """
    t = as_array("sample times t", t).reshape(-1)
    for name, arr in (("pose", x), ("rate", x_dot), ("acceleration", x_ddot)):
        arr = None if arr is None else np.asarray(arr, dtype=float)
        if arr is not None and arr.shape == (t.size, 6) and not np.isfinite(arr).all():
            k = int(np.argmax(~np.isfinite(arr).all(axis=1)))
            raise InvalidConfigError(f"the reference's {name} is not finite at t = {t[k]:.4g} s")
    x = as_poses("poses x", x)
    if x.shape != (t.size, 6) or t.size == 0:
        raise InvalidConfigError(
            f"validate_trajectory needs t (n,) and x (n, 6) with n > 0; got "
            f"t {t.shape} and x {x.shape}"
        )
    if np.any(np.diff(t) <= 0):
        raise InvalidConfigError("validate_trajectory needs strictly increasing sample times t")
    return t, x


def _report(t, margins: dict, cond_f, inv_f, checks: _PathChecks, extra: dict) -> TrajectoryReport:
    """The :class:`TrajectoryReport` of the margins and singularity measures along t (NaN
    already mapped to the worst value) against the thresholds of ``checks``, with the clearance
    and effort fields in ``extra``."""
    cond_threshold, min_sigma_min_inv = checks.cond_threshold, checks.min_sigma_min_inv
    min_margin, min_leg, min_t = {}, {}, {}
    first = None
    for name in LIMITS:
        m = np.where(np.isnan(margins[name]), -np.inf, margins[name])
        k, leg = np.unravel_index(int(np.argmin(m)), m.shape)
        min_margin[name], min_leg[name], min_t[name] = float(m[k, leg]), int(leg), float(t[k])
        bad = np.any(m < 0, axis=1)
        if np.any(bad):
            kb = int(np.argmax(bad))
            if first is None or t[kb] < first.t:
                lb = int(np.argmin(m[kb]))
                first = LimitViolation(lb, name, float(m[kb, lb]), float(t[kb]))
    over = cond_f > cond_threshold
    weak = inv_f < min_sigma_min_inv
    kc, ki = int(np.argmax(cond_f)), int(np.argmin(inv_f))
    return TrajectoryReport(
        ok=(
            first is None
            and not np.any(over)
            and not np.any(weak)
            and extra.get("first_interference") is None
            and extra.get("first_effort_violation") is None
        ),
        min_margin=min_margin,
        min_margin_leg=min_leg,
        min_margin_t=min_t,
        first_violation=first,
        max_cond=float(cond_f[kc]),
        max_cond_t=float(t[kc]),
        first_singular_t=float(t[int(np.argmax(over))]) if np.any(over) else None,
        min_sigma_min_inv=float(inv_f[ki]),
        cond_threshold=float(cond_threshold),
        min_sigma_min_inv_t=float(t[ki]),
        first_weak_t=float(t[int(np.argmax(weak))]) if np.any(weak) else None,
        sigma_min_inv_threshold=float(min_sigma_min_inv),
        **extra,
    )
