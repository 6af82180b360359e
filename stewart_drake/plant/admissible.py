"""The admissible set: which poses the robot may be asked to hold, by one rule for every caller.

A pose is admissible when every leg closes inside its motor travel and ball-joint cones
(:func:`~.limits.limit_margins_unchecked`), no two parts are closer than a clearance (the robot's
collision geometry, :mod:`~.clearance`), the Jacobian is well conditioned (cond(J) and
1/sigma_max(J), the guard's thresholds) and the static holding torques are within the share of
the motors' peak torque a reference may use (virtual work, :func:`~.statics.holding_torques`).
``stewart-drake workspace`` maps it, ``teleop`` stops its reference at its boundary, and
``check`` applies the same thresholds sample by sample along a reference (with the dynamic
torques added there). Vectorized over poses: one numpy pass for the kinematics and the torques,
then Drake's signed distances for the poses that reach.
"""

from __future__ import annotations

import numpy as np

from ..robot import kinematics, limits, statics
from ..robot.geometry import StewartGeometry
from .clearance import clearance_model

#: Clearances are measured up to this distance (beyond, a map shows this value), m.
CLEARANCE_CAP_M = 0.02


def classify(
    geometry: StewartGeometry,
    x,
    cond_threshold: float = limits.DEFAULT_COND_THRESHOLD,
    min_clearance_m: float | None = limits.DEFAULT_MIN_CLEARANCE_M,
    motor_limits: limits.MotorLimits | None = None,
    min_sigma_min_inv: float = limits.DEFAULT_MIN_SIGMA_MIN_INV,
    clearance=None,
) -> dict:
    """Classify pose(s) x: reachable, clear of interference, conditioning and holding torques.

    Args:
        geometry: the robot (its limit fields set the ranges, its part sizes the clearance).
        x: (..., 6) poses [phi, theta, psi, X, Y, Z] in rad and m.
        cond_threshold: cond(J) above this is "too close to a singularity".
        min_clearance_m: two parts closer than this, m, interfere; None: the clearance is not
            judged (``clearance`` NaN, ``clear`` = ``reachable``).
        motor_limits: the motors' peak torque and the share of it a reference may use; None or
            an unlimited peak: every finite holding torque is within the motors.
        min_sigma_min_inv: 1/sigma_max(J) below this ((rad or m) per rad) is "too close to a
            dead point" (the guard's and ``check``'s second singularity measure).
        clearance: the :class:`~.clearance.ClearanceModel` to measure with (default: that of
            ``geometry``; a run's robot with its payload passes its own).
    Returns:
        dict of arrays:
        ``reachable`` (...) bool, every leg inside every limit of ``limits.LIMITS``;
        ``clear`` (...) bool, reachable and no two parts closer than ``min_clearance_m``
        (the pairs whose distance the design fixes, ``ClearanceModel.fixed``, included: when
        they are closer, no pose is clear);
        ``usable`` (...) bool, clear, cond(J) <= cond_threshold and 1/sigma_max(J) >=
        min_sigma_min_inv (the motors ignored);
        ``within_peak`` (...) bool, usable and max_i |T_i| <= the motors' peak torque;
        ``admissible`` (...) bool, usable and max_i |T_i| <= margin * peak (what a reference
        may use, as ``check`` and ``teleop`` judge a pose);
        ``clearance`` (...) smallest distance between two parts, m (capped at
        :data:`CLEARANCE_CAP_M`), NaN where not reachable;
        ``cond`` (...) cond(J), NaN where a leg cannot close;
        ``sigma_min_inv`` (...) 1/sigma_max(J), (rad or m) per rad;
        ``torques`` (..., 6) static holding torques in N m, NaN where not reachable;
        ``max_torque`` (...) max_i |T_i| in N m, NaN where not reachable;
        ``bottleneck`` (...) int, the motor with the largest |T_i|, -1 where not reachable.
    """
    x = np.asarray(x, dtype=float)
    theta, ratio = kinematics.ik_unchecked(geometry, x)
    margins = limits.limit_margins_unchecked(geometry, x, theta, ratio)
    reachable = limits.reachable_from_margins(margins)
    cond, inv = kinematics.singularity_measures_unchecked(geometry, x, theta)
    torques, max_torque, bottleneck = _holding_torques(
        geometry, x, theta, reachable & np.isfinite(cond)
    )
    distance, clear = _clearances(geometry, x, reachable, min_clearance_m, clearance)
    with np.errstate(invalid="ignore"):
        usable = clear & (cond <= cond_threshold) & (inv >= min_sigma_min_inv)
    if motor_limits is None or motor_limits.peak_torque_Nm is None:
        within_peak = admissible = usable & np.isfinite(max_torque)
    else:
        peak = motor_limits.peak_torque_Nm
        with np.errstate(invalid="ignore"):
            within_peak = usable & (max_torque <= peak)
            admissible = usable & (max_torque <= motor_limits.margin * peak)
    return {
        "reachable": reachable,
        "clear": clear,
        "usable": usable,
        "within_peak": within_peak,
        "admissible": admissible,
        "clearance": distance,
        "cond": cond,
        "sigma_min_inv": inv,
        "torques": torques,
        "max_torque": max_torque,
        "bottleneck": bottleneck,
    }


def _holding_torques(geometry: StewartGeometry, x, theta, ok):
    """(torques (..., 6) N m, max_i |T_i| (...) N m, its motor (...) int) at the poses ``ok``
    marks; NaN, NaN and -1 elsewhere."""
    torques = np.full(x.shape[:-1] + (6,), np.nan)
    if np.any(ok):
        torques[ok] = statics.holding_torques(geometry, x[ok], theta[ok])
    abs_t = np.abs(torques)
    max_torque = np.where(ok, np.max(np.where(ok[..., None], abs_t, 0.0), axis=-1), np.nan)
    bottleneck = np.where(ok, np.argmax(np.where(ok[..., None], abs_t, 0.0), axis=-1), -1)
    return torques, max_torque, bottleneck


def _clearances(geometry: StewartGeometry, x, reachable, min_clearance_m, clearance):
    """(smallest distance between two parts (...) m, capped, NaN where not reachable; clear
    (...) bool) as :func:`classify` gives them."""
    distance = np.full(x.shape[:-1], np.nan)
    if min_clearance_m is None:
        return distance, reachable
    model = clearance_model(geometry) if clearance is None else clearance
    if np.any(reachable):
        distance[reachable] = model.sweep(x[reachable], max_distance=CLEARANCE_CAP_M)[0]
    # The pairs fixed by the design (rod ends on the platform) hold at every pose or none.
    fixed_ok = not model.fixed or model.fixed[0].distance >= min_clearance_m
    return distance, reachable & (distance >= min_clearance_m) & fixed_ok
