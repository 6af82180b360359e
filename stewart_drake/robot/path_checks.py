"""The checks of a reference path beyond the per-leg limits, for
:func:`~.limits.validate_trajectory`. The samples' kinematics by compiled code
(:func:`compiled_kinematics`); the report's entries of its optional checks, the clearance
between parts (:func:`clearance_fields`) and the motors' torque and speed
(:func:`effort_fields`); and the typed error of a refused path's first refusal
(:func:`raise_first_refusal`)."""

from typing import Any, NamedTuple

import numpy as np

from ..base.checks import as_number
from ..base.errors import (
    InterferenceError,
    InvalidConfigError,
    JointLimitError,
    MotorLimitError,
    SingularPoseError,
    StewartError,
    UnreachablePoseError,
)
from .kinematics import LegTerms, finite_or_singular, ik_angles
from .trajectory_report import TrajectoryReport


def clearance_fields(
    model, t, x, reachable, threshold: float, resolution_m: float, series: dict, theta
) -> dict:
    """The clearance entries of a :class:`TrajectoryReport` (see
    :func:`~.limits.validate_trajectory`); adds the measured series to ``series``.

    Args:
        model: the :class:`~stewart_drake.plant.clearance.ClearanceModel`.
        t: (n,) s. x: (n, 6) poses [rad, m]. reachable: (n,) bool, the poses measured.
        threshold: the smallest clearance allowed, m. resolution_m: the measures' spacing, m.
        theta: (n, 6) the poses' motor angles, rad.
    """
    rows = np.flatnonzero(reachable)
    if rows.size == 0:
        return {"clearance_threshold": threshold}
    rows = rows[model.sample_indices(x[rows], resolution_m, theta[rows])]
    # Pairs farther than this need no names: they cannot be the path's critical pair.
    distance, closest = model.sweep(x[rows], max_distance=max(threshold, 0.0) + 0.02)
    series.update(clearance_t=t[rows], clearance=distance)
    k = int(np.nanargmin(distance))
    low = np.flatnonzero(distance < threshold)
    first = None
    if low.size:
        c = closest[low[0]]
        first = (float(t[rows[low[0]]]), c.part_a, c.part_b, float(c.distance))
    design = model.fixed[0] if model.fixed else None  # the same at every pose
    if design is not None and design.distance < threshold:
        first = (float(t[rows[0]]), design.part_a, design.part_b, float(design.distance))
    parts = (
        f"{closest[k].part_a} and {closest[k].part_b}"
        if closest[k] is not None
        else "every pair farther"
    )
    return {
        "min_clearance": float(distance[k]),
        "min_clearance_t": float(t[rows[k]]),
        "min_clearance_parts": parts,
        "clearance_threshold": threshold,
        "first_interference": first,
        "design_clearance": float("nan") if design is None else design.distance,
        "design_clearance_parts": "" if design is None else f"{design.part_a} and {design.part_b}",
        "clearance_profile": (t[rows].copy(), np.asarray(distance, float), float(resolution_m)),
    }


class SampleKinematics(NamedTuple):
    """The kinematics of a path's samples that the checks of
    :func:`~.limits.validate_trajectory` read, computed once (NaN where a leg cannot close).

    Attributes:
        theta: (n, 6) motor angles, rad. ratio: (n, 6) reach ratios L / sqrt(M^2 + N^2).
        J: (n, 6, 6) Jacobians d theta / d x.
        crank: (n, 6) e_l . u_i, the sine of each rod's tilt out of its crank's plane.
        cos_p: (n, 6) the cosine of each rod's angle in its platform socket.
        terms: the :class:`~.kinematics.LegTerms` of the numpy form, or None (compiled).
    """

    theta: np.ndarray
    ratio: np.ndarray
    J: np.ndarray
    crank: np.ndarray
    cos_p: np.ndarray
    terms: LegTerms | None


def compiled_kinematics(geometry, x, joints) -> SampleKinematics:
    """The :class:`SampleKinematics` of poses x (n, 6) [rad, m] by
    :func:`~.path_kernels.closure` and :func:`~.path_kernels.pose_terms`, the motor angles'
    arcsines by :func:`~.kinematics.ik_angles`: the numpy form's
    numbers to the last bit (a test holds the reports equal).

    Args:
        geometry: the robot. joints: (6, 6) per leg its motor shaft and its socket's axis in
            the platform frame.
    """
    from .path_kernels import closure, pose_terms
    from .statics import kernel_constants

    legs, body = kernel_constants(geometry)
    x = np.ascontiguousarray(x, dtype=float)
    ratio, M, N = np.empty(x.shape), np.empty(x.shape), np.empty(x.shape)
    closure(x, legs, body, ratio, M, N)
    theta = ik_angles(ratio, M, N)
    J, crank, cos_p = np.empty(x.shape + (6,)), np.empty(x.shape), np.empty(x.shape)
    pose_terms(x, theta, legs, body, joints, J, crank, cos_p)
    return SampleKinematics(theta, ratio, J, crank, cos_p, None)


def effort_fields(
    geometry, t, x, x_dot, x_ddot, reachable, limits_, series: dict, kin: SampleKinematics
) -> dict:
    """The torque and speed entries of a :class:`TrajectoryReport` (see
    :func:`~.limits.validate_trajectory`), from the samples' kinematics; adds the torque and
    speed series to ``series``.

    Args:
        t: (n,) s. x, x_dot, x_ddot: (n, 6) poses, rates and accelerations (SI).
        reachable: (n,) bool, the samples whose legs all close (the others are not checked).
        limits_: the :class:`~.limits.MotorLimits`.
        kin: the samples' :class:`SampleKinematics`: the torques by the numpy form
            (:func:`~.statics.motor_effort_of`) with its leg terms, else compiled
            (:func:`~.statics.motor_effort_compiled`).
    Raises:
        InvalidConfigError: no rate or acceleration, or a margin out of (0, 1].
        UnreachablePoseError, SingularPoseError: as :func:`~.statics.inverse_dynamics_of`.
    """
    from .statics import motor_effort_compiled, motor_effort_of

    if x_dot is None or x_ddot is None:
        raise InvalidConfigError(
            "checking the motors' torque and speed needs the reference's "
            "rate and acceleration (x_dot, x_ddot)"
        )
    margin = as_number("effort margin", limits_.margin, 0.0, 1.0, lo_open=True)
    rows = np.flatnonzero(reachable)
    if rows.size == 0:
        return {}
    x_rows = x[rows]
    motion = (x_rows, np.asarray(x_dot, float)[rows], np.asarray(x_ddot, float)[rows])
    J = finite_or_singular("J", kin.J[rows], x_rows)
    if kin.terms is None:
        T, speed = motor_effort_compiled(geometry, *motion, limits_.servo, kin.theta[rows], J)
    else:
        T, speed = motor_effort_of(geometry, *motion, limits_.servo, kin.terms.rows(rows), J)
    for name, value in (("torque", T), ("speed", speed)):
        series[name] = np.full(x.shape, np.nan)
        series[name][rows] = value
    out: dict = {}
    first: MotorLimitError | None = None
    out["effort_margin"] = margin
    for name, value, bound in (
        ("torque", np.abs(T), limits_.peak_torque_Nm),
        ("speed", np.abs(speed), limits_.max_speed_rad_s),
    ):
        k, motor = np.unravel_index(int(np.argmax(value)), value.shape)
        limit = float("nan") if bound is None else margin * float(bound)
        out.update(
            {
                f"peak_{name}": float(value[k, motor]),
                f"peak_{name}_motor": int(motor),
                f"peak_{name}_t": float(t[rows[k]]),
                f"{name}_limit": limit,
            }
        )
        if bound is not None and np.any(value > limit):
            kb = int(np.argmax(np.any(value > limit, axis=1)))
            mb = int(np.argmax(value[kb]))
            if first is None or t[rows[kb]] < first.t:
                first = MotorLimitError(
                    mb, name, float(value[kb, mb]), limit, float(t[rows[kb]]), x[rows[kb]]
                )
    out["first_effort_violation"] = first
    return out


def raise_first_refusal(report: TrajectoryReport, t, x, cond, inv, allow_infeasible: bool = False):
    """Raise the typed error of the earliest refused sample of a validated path (a motor over
    its limit only without ``allow_infeasible``); nothing when only that remains.

    Args:
        report: the path's report. t: (n,) s. x: (n, 6) poses [rad, m]. cond, inv: (n,) its
            cond(J) and 1/sigma_max(J), NaN mapped to the worst value.
    Raises:
        UnreachablePoseError, JointLimitError, SingularPoseError, InterferenceError,
            MotorLimitError: the earliest refusal (ties in that order).
    """
    candidates: list[tuple[Any, int, StewartError]] = []  # (t, rank, error)
    if report.first_interference is not None:
        ti, a, b, d = report.first_interference
        k = int(np.searchsorted(t, ti))
        candidates.append((ti, 3, InterferenceError(a, b, d, report.clearance_threshold, ti, x[k])))
    if report.first_effort_violation is not None and not allow_infeasible:
        candidates.append((report.first_effort_violation.t, 4, report.first_effort_violation))
    v = report.first_violation
    if v is not None:
        k = int(np.searchsorted(t, v.t))
        error = (
            UnreachablePoseError(v.leg, 1.0 - v.margin, v.t, x[k])
            if v.limit == "closure"
            else JointLimitError(v.leg, v.limit, v.margin, v.t, x[k])
        )
        candidates.append((v.t, 0, error))
    if report.first_singular_t is not None:
        k = int(np.searchsorted(t, report.first_singular_t))
        candidates.append(
            (t[k], 1, SingularPoseError("cond", cond[k], report.cond_threshold, t[k], x[k]))
        )
    if report.first_weak_t is not None:
        k = int(np.searchsorted(t, report.first_weak_t))
        candidates.append(
            (
                t[k],
                2,
                SingularPoseError(
                    "sigma_min_inv", inv[k], report.sigma_min_inv_threshold, t[k], x[k]
                ),
            )
        )
    if candidates:
        raise min(candidates, key=lambda c: c[:2])[2]
