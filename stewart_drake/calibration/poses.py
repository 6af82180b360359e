"""The poses a calibration measures: candidates over the admissible set, the greedy D-optimal
choice among them, and the path that visits them (a reference the robot command drives).

Candidates are drawn uniformly in a box of poses (:class:`PoseBox`) and kept when admissible
(:func:`~stewart_drake.plant.admissible.classify`: every leg inside its limits, no two parts
closer than the clearance, the Jacobian well conditioned, the holding torques within the motors
when their limits are given) with a margin on every per-leg limit
(:func:`~stewart_drake.robot.limits.limit_margins`, :data:`MIN_MARGINS`), so that a robot off
its drawing by a few millimetres still reaches each of them.

The choice (:func:`choose_poses`) is greedy D-optimal on the identification's whitened, scaled
Jacobian (:mod:`~.identify`): starting from the tolerances' information (the identity in
scaled units), each step adds the candidate that most increases log det of the information,
log det(I_6 + J_c A^-1 J_c^T) for its six rows J_c, and updates A^-1 by Woodbury's identity.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from ..base.checks import as_number, as_poses, check_int
from ..base.errors import InvalidConfigError
from ..plant.admissible import classify
from ..references.smoothstep import smoothstep
from ..robot.geometry import StewartGeometry
from ..robot.kinematics import X_HOME
from ..robot.legs import N_PARAMETERS, LegParameters, derivatives
from ..robot.limits import LIMITS, limit_margins_unchecked
from ..robot.tolerances import Tolerances
from .identify import whitening
from .tracker import MeasurementNoise

#: Smallest margin a measured pose keeps to each per-leg limit of :data:`LIMITS`: ``closure``
#: (dimensionless) and the joint angles (rad, 3 degrees).
MIN_MARGINS = {"closure": 0.03, "motor_angle": 0.05, "crank_joint": 0.05, "platform_joint": 0.05}

#: Share of the torque a reference may use that a measured pose may take to hold itself: the
#: rest is left for the moves between poses.
TORQUE_SHARE = 0.8


@dataclass(frozen=True)
class PoseBox:
    """The box candidates are drawn from: |phi|, |theta|, |psi| <= ``rotation_rad``, |X|, |Y| <=
    ``xy_m``, Z in [``z_min_m``, ``z_max_m``] (rad, m). The admissible set cuts it."""

    rotation_rad: float = 0.3
    xy_m: float = 0.07
    z_min_m: float = 0.2
    z_max_m: float = 0.4

    def draw(self, rng: np.random.Generator, n: int) -> np.ndarray:
        """(n, 6) poses uniform in the box."""
        return np.column_stack(
            [
                rng.uniform(-self.rotation_rad, self.rotation_rad, (n, 3)),
                rng.uniform(-self.xy_m, self.xy_m, (n, 2)),
                rng.uniform(self.z_min_m, self.z_max_m, n),
            ]
        )


def admissible_with_margin(geometry: StewartGeometry, x, motor_limits=None) -> np.ndarray:
    """(N,) bool: each pose of x (N, 6) admissible (:func:`~stewart_drake.plant.admissible.
    classify`; with ``motor_limits``, a :class:`~stewart_drake.robot.limits.MotorLimits`, its
    holding torques within :data:`TORQUE_SHARE` of what a reference may use) with every per-leg
    limit kept at :data:`MIN_MARGINS`."""
    x = as_poses("poses", x).reshape(-1, 6)
    margins = limit_margins_unchecked(geometry, x)
    ok = np.ones(len(x), dtype=bool)
    for name in LIMITS:
        ok &= np.all(np.nan_to_num(margins[name], nan=-1.0) >= MIN_MARGINS[name], axis=1)
    if motor_limits is not None:  # the rest of the torque for the moves between poses
        motor_limits = replace(motor_limits, margin=TORQUE_SHARE * motor_limits.margin)
    if np.any(ok):
        verdict = classify(geometry, x[ok], motor_limits=motor_limits)["admissible"]
        ok[np.flatnonzero(ok)] = verdict
    return ok


def candidate_poses(
    geometry: StewartGeometry,
    count: int,
    seed: int,
    box: PoseBox | None = None,
    motor_limits=None,
) -> np.ndarray:
    """``count`` admissible poses with margin (:func:`admissible_with_margin`), drawn in
    ``box`` with ``seed``; (count, 6) [rad, m].

    Raises:
        InvalidConfigError: a count below 1 or a seed out of range; the box holds too few
            admissible poses (fewer than 1 in 100 drawn).
    """
    count = check_int("count", count, 1, 10**6)
    rng = np.random.default_rng(check_int("seed", seed, 0, 2**32 - 1))
    box = PoseBox() if box is None else box
    found: list[np.ndarray] = []
    kept, drawn = 0, 0
    while kept < count:
        if drawn > 100 * count + 10_000:
            raise InvalidConfigError(
                f"the pose box {box} holds too few admissible poses ({kept} of {drawn} drawn): "
                f"make it smaller or centre it on the workspace"
            )
        x = box.draw(rng, max(2 * count, 200))
        drawn += len(x)
        found.append(x[admissible_with_margin(geometry, x, motor_limits)])
        kept += len(found[-1])
    return np.concatenate(found)[:count]


def information_rows(
    geometry: StewartGeometry,
    poses,
    noise: MeasurementNoise,
    tolerances: Tolerances | None = None,
    legs: LegParameters | None = None,
) -> np.ndarray:
    """(N, 6, 66) each pose's rows of the identification's whitened Jacobian, the parameters
    scaled by their tolerances' standard deviations (:mod:`~.identify`), at the robot ``legs``
    (default nominal)."""
    tolerances = Tolerances() if tolerances is None else tolerances
    legs = LegParameters.nominal(geometry) if legs is None else legs
    J = derivatives(geometry, legs, poses).parameters
    W = whitening(geometry, legs, poses, noise)
    return np.einsum("nij,njk->nik", W, J) * tolerances.stds()


def choose_poses(rows: np.ndarray, count: int, on_step=None) -> np.ndarray:
    """Greedy D-optimal choice of ``count`` candidates (module docstring).

    Args:
        rows: (N, 6, 66) :func:`information_rows` of the candidates.
        count: how many to choose, 1 .. N.
        on_step: called after each choice (a progress bar's), or None.
    Returns:
        (count,) indices into the candidates, in the order chosen (a prefix is the choice of
        fewer).
    """
    rows = np.asarray(rows, dtype=float)
    count = check_int("count", count, 1, len(rows))
    A_inv = np.eye(N_PARAMETERS)
    free = np.ones(len(rows), dtype=bool)
    chosen = []
    eye6 = np.eye(6)
    for _ in range(count):
        JA = rows @ A_inv  # (N, 6, 66)
        M = eye6 + np.einsum("nik,njk->nij", JA, rows)
        sign, gain = np.linalg.slogdet(M)
        gain = np.where(free & (sign > 0), gain, -np.inf)
        k = int(np.argmax(gain))
        chosen.append(k)
        free[k] = False
        # Woodbury: (A + J^T J)^-1 = A^-1 - A^-1 J^T (I + J A^-1 J^T)^-1 J A^-1
        A_inv = A_inv - JA[k].T @ np.linalg.solve(M[k], JA[k])
        A_inv = 0.5 * (A_inv + A_inv.T)
        if on_step is not None:
            on_step()
    return np.array(chosen)


@dataclass(frozen=True)
class PosePath:
    """A path through the poses to measure, at rest at each for a while.

    Attributes:
        poses: (N, 6) the poses in the order visited, rad and m.
        windows: (N, 2) [start, end] of the time each is held settled, s of the path: measure
            (the tracker's average, the encoders' readings) within it.
        t: (M,) sample times, s, from 0; x: (M, 6) the path's poses there (a reference CSV's
            rows, :func:`~stewart_drake.references.samples.load_csv_trajectory`).
    """

    poses: np.ndarray
    windows: np.ndarray
    t: np.ndarray
    x: np.ndarray


#: The path's speeds: at most this along each rotation (rad/s) and translation (m/s).
PATH_SPEED = (0.2, 0.03)
#: Sampling period of the path's rows, s.
PATH_DT_S = 0.02


def _move(a: np.ndarray, b: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(times from 0, poses) of the quintic smoothstep from pose a to b, at rest at both ends,
    sampled every :data:`PATH_DT_S` (the first sample left out): its peak rate 1.875 |b - a| /
    T within :data:`PATH_SPEED`, T at least 1 s."""
    step = np.abs(b - a)
    peak = max(float(np.max(step[:3])) / PATH_SPEED[0], float(np.max(step[3:])) / PATH_SPEED[1])
    T = max(1.0, 1.875 * peak)
    n = int(np.ceil(T / PATH_DT_S))
    t = np.arange(1, n + 1) * (T / n)
    s = smoothstep(t / T)[0]
    return t, a + s[:, None] * (b - a)


#: Poses a block of a path in chosen order holds (:func:`pose_path`'s ``block``): the fewest an
#: identification takes, so that any prefix of the path holds the first choices but a block's.
PREFIX_BLOCK = 12


def _order(poses: np.ndarray, block: int | None = None) -> np.ndarray:
    """Indices of ``poses`` (N, 6) in nearest-neighbour tours (rotations weighted 0.15 m per
    rad): one from home through all of them (``block`` None), or one through each ``block``
    poses in turn, in their order (each tour from where the previous ended)."""
    weight = np.array([0.15] * 3 + [1.0] * 3)
    size = len(poses) if block is None else block
    here, order = X_HOME, []
    for start in range(0, len(poses), size):
        left = list(range(start, min(start + size, len(poses))))
        while left:
            dist = np.linalg.norm((poses[left] - here) * weight, axis=1)
            k = left.pop(int(np.argmin(dist)))
            order.append(k)
            here = poses[k]
    return np.array(order)


def pose_path(
    geometry: StewartGeometry,
    poses,
    dwell_s: float = 3.0,
    settle_s: float = 1.0,
    motor_limits=None,
    block: int | None = None,
) -> PosePath:
    """The path from home through ``poses`` (N, 6) and back, resting ``dwell_s`` at each.

    The poses are visited in the shortest order a nearest-neighbour tour finds, or with
    ``block`` (>= 1) in blocks of that many in the order given, each block a tour: poses in
    the order :func:`choose_poses` chose them and a block of :data:`PREFIX_BLOCK` keep each
    prefix of the path the choice of about as many (a session cut short still measured a good
    set), for a longer path (120 chosen poses: 903 s against 627 s at 3 s a pose).

    Each move is a straight line in pose coordinates along the quintic smoothstep
    (:func:`_move`); where a sample of a straight move is not admissible with margin
    (:func:`admissible_with_margin`), the move goes through home instead. The path rests 1.5 s
    at home first (the robot command's ramp in), then at each pose for ``dwell_s``, the first
    ``settle_s`` of it for the controller to settle (the window of each pose is the rest).

    Raises:
        InvalidConfigError: a pose not admissible with margin, ``settle_s`` not within
            ``dwell_s``, a non-positive dwell, a block below 1.
    """
    poses = as_poses("poses", poses).reshape(-1, 6)
    block = None if block is None else check_int("block", block, 1, 10**6)
    dwell_s = as_number("dwell_s", dwell_s, 0.0, lo_open=True)
    settle_s = as_number("settle_s", settle_s, 0.0)
    if settle_s >= dwell_s:
        raise InvalidConfigError(
            f"the settling time ({settle_s:g} s) must be shorter than the dwell ({dwell_s:g} s)"
        )
    bad = ~admissible_with_margin(geometry, poses, motor_limits)
    if np.any(bad):
        raise InvalidConfigError(
            f"pose {int(np.argmax(bad))} ({poses[int(np.argmax(bad))].tolist()}) is not "
            f"admissible with the margins {MIN_MARGINS}: choose poses inside the workspace"
        )
    order = _order(poses, block)
    ts, xs = [np.arange(0, 76) * PATH_DT_S], [np.repeat(X_HOME[None], 76, axis=0)]
    windows = []
    here = X_HOME
    for k in order:
        for leg in _legs_of_move(geometry, here, poses[k], motor_limits):
            t, x = leg
            ts.append(ts[-1][-1] + t)
            xs.append(x)
        start = ts[-1][-1]
        n = int(np.ceil(dwell_s / PATH_DT_S))
        ts.append(start + np.arange(1, n + 1) * (dwell_s / n))
        xs.append(np.repeat(poses[k][None], n, axis=0))
        windows.append((start + settle_s, start + dwell_s))
        here = poses[k]
    for t, x in _legs_of_move(geometry, here, X_HOME, motor_limits):
        ts.append(ts[-1][-1] + t)
        xs.append(x)
    ts.append(ts[-1][-1] + np.arange(1, 51) * PATH_DT_S)
    xs.append(np.repeat(X_HOME[None], 50, axis=0))
    return PosePath(
        poses=poses[order], windows=np.array(windows), t=np.concatenate(ts), x=np.concatenate(xs)
    )


def _legs_of_move(geometry, a, b, motor_limits) -> list:
    """The moves from a to b: straight, or through home when a straight one leaves the
    admissible set (a list of (t, x) of :func:`_move`)."""
    t, x = _move(a, b)
    if np.all(admissible_with_margin(geometry, x[::5], motor_limits)) or np.allclose(a, X_HOME):
        return [(t, x)]
    return [_move(a, X_HOME), _move(X_HOME, b)]
