"""The seeded excitation of the tuner's training data (paper section III.D): every axis a sine at
1-5 Hz, its amplitudes shrunk until the path passes the pre-run checks and, with a torque limit,
the motors keep headroom (:func:`data_collection_trajectory`); :class:`DataCollectionReference`
is a scenario's choice of it.

Drake's YAML loader reads :class:`DataCollectionReference`'s field types: this module must not
use ``from __future__ import annotations``.
"""

from dataclasses import dataclass

import numpy as np

from ..base.checks import MAX_SEED, check_int
from ..robot import kinematics, limits
from ..robot.geometry import X_HOME, StewartGeometry
from .motion import Reference, ReferenceConfig
from .trajectories import SineTrajectory

#: Acceleration caps of the data-collection trajectories: rad/s^2 for angles, m/s^2 for positions.
DATA_ACCEL_CAP = (30.0, 30.0, 30.0, 3.0, 3.0, 3.0)
#: Fraction of the motors' limit the collection path's inverse-dynamics torques may use.
DATA_TORQUE_MARGIN = 0.7
#: Amplitudes the paper names for its data (angles +-pi/6 rad, translations 0.3 m).
PAPER_DATA_AMPLITUDE = (np.pi / 6, np.pi / 6, np.pi / 6, 0.3, 0.3, 0.3)


def _max_single_axis_amplitude(geometry: StewartGeometry, axis: int, ratio_max: float) -> float:
    """Largest a with home +- a e_axis reachable at ratio <= ratio_max (bisection)."""
    lo, hi = 0.0, PAPER_DATA_AMPLITUDE[axis]
    for _ in range(40):
        mid = 0.5 * (lo + hi)
        x = np.tile(X_HOME, (2, 1))
        x[0, axis] += mid
        x[1, axis] -= mid
        if np.all(np.abs(kinematics.leg_reach_ratio(geometry, x)) <= ratio_max):
            lo = mid
        else:
            hi = mid
    return lo


def _slack(
    geometry: StewartGeometry, x, ratio_max: float, cond_threshold: float, min_sigma_min_inv: float
) -> np.ndarray:
    """(n,) smallest margin of poses x (n, 6) over the checks of
    :func:`~stewart_drake.run.plan.validate_reference`, each normalized by its bound; < 0 where
    refused. Checks: closure at ``ratio_max``, motor travel, both ball-joint cones, then (only
    when every pose passes those: the SVD is the dear part) cond(J) and 1/sigma_max(J)."""
    theta, ratio = kinematics.ik_unchecked(geometry, x)
    margins = limits.limit_margins_unchecked(geometry, x, theta, ratio)
    travel = np.deg2rad(geometry.motor_angle_max_deg - geometry.motor_angle_min_deg) / 2
    slack = np.min(
        np.concatenate(
            [
                (ratio_max - np.abs(ratio)) / ratio_max,
                margins["motor_angle"] / travel,
                margins["crank_joint"] / np.deg2rad(geometry.crank_joint_cone_deg),
                margins["platform_joint"] / np.deg2rad(geometry.platform_joint_cone_deg),
            ],
            axis=-1,
        ),
        axis=-1,
    )
    slack = np.nan_to_num(slack, nan=-np.inf)
    if np.all(slack >= 0):
        cond, inv = kinematics.singularity_measures_unchecked(geometry, x, theta)
        singular = np.minimum(
            (cond_threshold - cond) / cond_threshold,
            (inv - min_sigma_min_inv) / max(min_sigma_min_inv, 1e-12),
        )
        slack = np.minimum(slack, np.nan_to_num(singular, nan=-np.inf))
    return slack


def data_collection_trajectory(
    seed: int = 0,
    geometry: StewartGeometry | None = None,
    duration_s: float = 10.0,
    ratio_max: float = 0.9,
    dt: float = 1e-3,
    cond_threshold: float = limits.DEFAULT_COND_THRESHOLD,
    min_sigma_min_inv: float = limits.DEFAULT_MIN_SIGMA_MIN_INV,
    torque_limit_Nm: float | None = None,
) -> SineTrajectory:
    """Excitation for the tuner's training data (paper section III.D), deterministic in ``seed``.

    Every axis moves at once, one sine each, with a frequency drawn in [1, 5] Hz and a random
    phase. The paper's amplitudes (+-pi/6 rad, 0.3 m) are far outside this robot's workspace, so
    each axis's amplitude is (a) capped by what that axis alone admits at |L|/sqrt(M^2+N^2) <=
    ``ratio_max``, (b) capped by DATA_ACCEL_CAP / (2 pi f)^2 so the torques stay physical, then
    (c) all amplitudes are scaled by the largest factor (bisection) with which the path passes
    every check of the pre-run validation (:func:`~stewart_drake.run.plan.validate_reference`
    sampled every ``dt`` over ``duration_s``: loop closure at ``ratio_max``, motor travel, both
    ball-joint cones, cond(J) and 1/sigma_max(J) with the given thresholds, GuardConfig's by
    default). The bisection runs on the critical samples only and is confirmed on all of them
    (docs/paper_notes.md).

    Args:
        seed: random seed of frequencies and phases. geometry: the robot (default reference).
        duration_s: s the path must pass over. ratio_max: closure bound, < 1. dt: sampling, s
            (the control period the pre-run check uses).
        cond_threshold, min_sigma_min_inv: singularity thresholds (GuardConfig's defaults).
        torque_limit_Nm: the motors' limit, N m, or None. With one, (d) the amplitudes shrink
            further until the inverse-dynamics torques of the path (gravity, inertia and
            velocity products, rotors included) stay within :data:`DATA_TORQUE_MARGIN` of it
            (the pre-run check then adds the friction against its own margin): the motors keep
            headroom for feedback (ours: the paper's robot has no limit; on the robot as built,
            without this every run of the collection loses the platform in 0.2 s).
    Returns:
        SineTrajectory named ``data_seed<seed>`` that ``validate_reference(..., dt=dt)`` accepts.
    """
    geometry = geometry or StewartGeometry()
    rng = np.random.default_rng(seed)
    f = rng.uniform(1.0, 5.0, 6)
    phase = rng.uniform(0, 2 * np.pi, 6)
    single = np.array([_max_single_axis_amplitude(geometry, k, ratio_max) for k in range(6)])
    amp = np.minimum(single, np.asarray(DATA_ACCEL_CAP) / (2 * np.pi * f) ** 2)
    t = np.arange(0.0, duration_s + 0.5 * dt, dt)  # the samples of validate_reference()

    def path(scale, times=t):
        return SineTrajectory(
            amplitude=tuple(scale * amp), frequency_hz=tuple(f), phase=tuple(phase)
        ).evaluate(times)

    scale = _scale_within_checks(
        geometry,
        lambda sc, k=slice(None): path(sc, t[k])[0],
        (ratio_max, cond_threshold, min_sigma_min_inv),
    )
    if torque_limit_Nm is not None:
        scale = _scale_within_torque(
            geometry, lambda sc: path(sc, t[::5]), scale, DATA_TORQUE_MARGIN * torque_limit_Nm
        )
    return SineTrajectory(
        amplitude=tuple(scale * amp),
        frequency_hz=tuple(f),
        phase=tuple(phase),
        name=f"data_seed{seed}",
    )


def _scale_within_checks(geometry: StewartGeometry, poses, checks: tuple) -> float:
    """The largest factor s <= 1 (bisection, a hair inside) with which ``poses(s, k)`` (the
    path's poses at the samples k, all by default) passes the checks of :func:`_slack`. The
    bisection runs on the samples that refused a scale so far, and each round is confirmed on
    all of them."""
    scale, critical = 1.0, np.zeros(0, dtype=int)
    for _ in range(20):  # each round adds the samples that refused the scale
        slack = _slack(geometry, poses(scale), *checks)
        if np.all(slack >= 0):
            break
        critical = np.union1d(
            critical, np.union1d(np.flatnonzero(slack < 0), np.argsort(slack)[:64])
        )
        lo, hi = 0.0, scale
        for _ in range(40):
            mid = 0.5 * (lo + hi)
            fits = np.all(_slack(geometry, poses(mid, critical), *checks) >= 0)
            lo, hi = (mid, hi) if fits else (lo, mid)
        scale = lo * (1 - 1e-3)  # a hair inside: no pass or fail by round-off
    return scale


def _scale_within_torque(geometry: StewartGeometry, motion, scale: float, bound: float) -> float:
    """``scale``, or the largest factor below it (bisection) with which the inverse-dynamics
    torques of ``motion(s)`` (pose, rate, acceleration) stay within ``bound``, N m."""
    from ..robot.statics import inverse_dynamics_torques

    def peak(sc):
        return np.abs(inverse_dynamics_torques(geometry, *motion(sc))).max()

    if peak(scale) > bound:
        lo, hi = 0.0, scale
        for _ in range(30):
            mid = 0.5 * (lo + hi)
            lo, hi = (mid, hi) if peak(mid) <= bound else (lo, mid)
        scale = lo
    return scale


@dataclass
class DataCollectionReference(ReferenceConfig):
    """The seeded excitation of the tuner's data collection (every axis at 1-5 Hz inside the
    workspace; :func:`data_collection_trajectory`), as long as the run, within the robot's
    workspace and its motors' torque limit."""

    seed: int = 0

    def validate(self) -> None:
        check_int("reference.seed", self.seed, 0, MAX_SEED)

    def make(
        self, geometry: StewartGeometry, duration_s: float, torque_limit_Nm: float | None
    ) -> Reference:
        return data_collection_trajectory(
            self.seed, geometry, duration_s=duration_s, torque_limit_Nm=torque_limit_Nm
        )

    @property
    def label(self) -> str:
        return f"data_seed{self.seed}"


__all__ = [
    "DATA_ACCEL_CAP",
    "DATA_TORQUE_MARGIN",
    "PAPER_DATA_AMPLITUDE",
    "data_collection_trajectory",
    "DataCollectionReference",
]
