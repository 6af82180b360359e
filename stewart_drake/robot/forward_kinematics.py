"""Forward kinematics: the platform's pose from the six motor angles (Newton on the closed-form
inverse kinematics, :func:`fk`), and the resolution that the encoders' counts give that pose
(:func:`encoder_pose_noise`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..base.checks import as_array, as_number, as_poses, check_int
from ..base.errors import (
    ForwardKinematicsError,
)
from .kinematics import X_HOME, RobotGeometry, ik_unchecked, jacobian_unchecked, wrap_angle


@dataclass(frozen=True)
class FkStatus:
    """How a forward-kinematics solve ended (for a batch: all converged, worst case).

    Attributes:
        converged: True if max_i |ik(x)_i - theta_i| <= tol.
        iterations: Newton steps taken (the largest over a batch).
        residual: max_i |ik(x)_i - theta_i| at the returned pose, rad (largest over a batch).
    """

    converged: bool
    iterations: int
    residual: float


def _fk_residual(geometry: RobotGeometry, x, theta_target):
    """(theta of x, wrapped residual (n, 6), 2-norm (n,), max-abs (n,)); inf where unreachable."""
    theta, _ = ik_unchecked(geometry, x)
    r = wrap_angle(theta - theta_target)
    bad = ~np.all(np.isfinite(r), axis=-1)
    norm2 = np.where(bad, np.inf, np.linalg.norm(np.where(np.isfinite(r), r, 0.0), axis=-1))
    norm_max = np.where(bad, np.inf, np.abs(np.where(np.isfinite(r), r, 0.0)).max(axis=-1))
    return theta, r, norm2, norm_max


def _assembly_mode(geometry: RobotGeometry, x, theta) -> np.ndarray:
    """(n,) sign of det J(x): +-1, 0 where J is singular or not finite."""
    J = jacobian_unchecked(geometry, x, theta)
    finite = np.all(np.isfinite(J), axis=(-2, -1))
    return np.where(finite, np.sign(np.linalg.det(np.where(finite[..., None, None], J, 0.0))), 0.0)


def fk_unchecked(
    geometry: RobotGeometry,
    theta,
    x0=None,
    tol: float = 1e-12,
    max_iter: int = 50,
    max_halvings: int = 30,
):
    """Vectorized forward kinematics without raising: Newton on the closed-form IK.

    x_{k+1} = x_k - alpha J(x_k)^{-1} wrap(ik(x_k) - theta), alpha = 1, 1/2, 1/4, ... until the
    iterate is reachable, ||ik(x) - theta||_2 decreases (backtracking) and sign det J(x) is that
    of x0: no step crosses a singularity into another assembly mode (without this, 4 of 8099
    poses spread over the whole workspace converged, from home, to a different pose with the same
    motor angles). The IK branch is the one of :func:`~.kinematics.ik`, so ``fk(ik(x)) = x`` for
    every reachable x of the initial pose's assembly mode that the iteration can reach.

    Args:
        geometry: the robot.
        theta: (6,) or (..., 6) motor angles in rad (compared modulo 2 pi).
        x0: (6,) or (..., 6) initial pose [rad, m]; default the home pose X_HOME.
        tol: convergence threshold on max_i |ik(x)_i - theta_i|, rad.
        max_iter: Newton steps at most per pose.
        max_halvings: step halvings at most per Newton step.
    Returns:
        x: (..., 6) pose [phi, theta, psi, X, Y, Z] in rad and m (the last iterate if failed).
        converged: (...) bool.
        iterations: (...) int, Newton steps taken.
        residual: (...) max_i |ik(x)_i - theta_i| in rad, inf if x0 is unreachable.
    Source: Newton's method with the analytic :func:`~.kinematics.jacobian` (J = d theta / d x).
    """
    # Newton's iterates, residuals and masks are the batch's arrays; the line search updates
    # them in place where it accepts a step.
    theta = np.asarray(theta, dtype=float)
    batch = theta.shape[:-1]
    target = theta.reshape(-1, 6)
    n = target.shape[0]
    x = np.array(
        np.broadcast_to(X_HOME if x0 is None else np.asarray(x0, dtype=float), batch + (6,)),
        dtype=float,
    ).reshape(-1, 6)
    th_k, r, err2, errmax = _fk_residual(geometry, x, target)
    iterations = np.zeros(n, dtype=int)
    failed = ~np.isfinite(err2)  # the initial pose is unreachable
    mode = _assembly_mode(geometry, x, th_k)  # sign det J: steps may not cross a singularity
    for _ in range(max_iter):
        idx = np.flatnonzero(~failed & (errmax > tol))
        if idx.size == 0:
            break
        dx, ok_dir = _newton_step(geometry, x[idx], th_k[idx], r[idx])
        iterations[idx] += 1
        state = (x, th_k, r, err2, errmax)
        accepted = _line_search(geometry, state, target, mode, idx, dx, ok_dir, tol, max_halvings)
        failed[idx[~accepted]] = True  # no descent step: stalled or singular
    converged = errmax <= tol
    return (
        x.reshape(batch + (6,)),
        converged.reshape(batch),
        iterations.reshape(batch),
        errmax.reshape(batch),
    )


def _newton_step(geometry: RobotGeometry, x, theta, r):
    """(dx (n, 6), ok (n,)): the Newton direction J(x)^-1 r of each pose x (n, 6) with motor
    angles theta and residual r, and where it is finite (a J with an inf or NaN is replaced by
    the identity there, and marked not ok)."""
    J = jacobian_unchecked(geometry, x, theta)
    finite = np.all(np.isfinite(J), axis=(-2, -1))
    J = np.where(finite[:, None, None], J, np.eye(6))
    try:
        dx = np.linalg.solve(J, r[..., None])[..., 0]
    except np.linalg.LinAlgError:  # a singular J somewhere in the batch
        dx = np.einsum("nij,nj->ni", np.linalg.pinv(J), r)
    return dx, finite & np.all(np.isfinite(dx), axis=-1)


def _line_search(geometry, state, target, mode, idx, dx, ok_dir, tol, max_halvings):
    """Backtrack from the iterates ``idx`` of ``state`` = (x, theta, r, err2, errmax) along
    -alpha dx, alpha = 1, 1/2, 1/4, ... (up to ``max_halvings`` halvings) until the iterate is
    reachable, its residual decreases (or is within ``tol``) and sign det J keeps the start's
    assembly ``mode``; ``state``'s arrays take the accepted steps in place. Only the iterates
    with ``ok_dir`` are tried. Returns (idx.size,) bool, whether each took a step."""
    x, th_k, r, err2, errmax = state
    alpha = np.ones(idx.size)
    pending = ok_dir.copy()
    accepted = np.zeros(idx.size, dtype=bool)
    for _ in range(max_halvings + 1):
        p = np.flatnonzero(pending)
        if p.size == 0:
            break
        cand = x[idx[p]] - alpha[p, None] * dx[p]
        th_c, r_c, e2_c, emax_c = _fk_residual(geometry, cand, target[idx[p]])
        good = (
            np.isfinite(e2_c)
            & ((e2_c < err2[idx[p]]) | (emax_c <= tol))
            & (_assembly_mode(geometry, cand, th_c) == mode[idx[p]])
        )
        g = p[good]
        x[idx[g]], th_k[idx[g]], r[idx[g]] = cand[good], th_c[good], r_c[good]
        err2[idx[g]], errmax[idx[g]] = e2_c[good], emax_c[good]
        accepted[g] = True
        pending[g] = False
        alpha[p[~good]] *= 0.5
    return accepted


def fk(
    geometry: RobotGeometry, theta, x0=None, tol: float = 1e-12, max_iter: int = 50
) -> tuple[np.ndarray, FkStatus]:
    """Forward kinematics: the platform pose whose closed-form IK gives the motor angles theta.

    Args:
        geometry: the robot.
        theta: (6,) or (..., 6) motor angles in rad.
        x0: (6,) or (..., 6) initial pose [rad, m]; default the home pose. The solution is the
            assembly mode Newton reaches from x0 (from home: the robot's working mode).
        tol: max_i |ik(x)_i - theta_i| at convergence, rad.
        max_iter: Newton steps at most.
    Returns:
        x: (..., 6) pose [phi, theta, psi, X, Y, Z] in rad and m.
        status: :class:`FkStatus` (for a batch: all converged, largest iterations and residual).
    Raises:
        ForwardKinematicsError: some pose did not converge (the first one is named, with its
            residual); also when x0 is unreachable or every step leads out of the workspace.
        InvalidConfigError: theta or x0 not (..., 6) or not finite, tol <= 0, max_iter < 1.
    Source: Newton on :func:`~.kinematics.ik` with the analytic
        :func:`~.kinematics.jacobian`, backtracking on ||ik(x) - theta|| (see
        :func:`fk_unchecked`).
    """
    theta = as_array("motor angles theta", theta, last=6)
    x0 = None if x0 is None else as_poses("initial pose x0", x0)
    tol = as_number("tol", tol, 0.0, lo_open=True)
    check_int("max_iter", max_iter, 1)
    x, converged, iterations, residual = fk_unchecked(geometry, theta, x0, tol, max_iter)
    if not np.all(converged):
        k = int(np.argmax(~converged.reshape(-1)))
        th = np.asarray(theta, dtype=float).reshape(-1, 6)[k]
        if not np.isfinite(residual.reshape(-1)[k]):
            raise ForwardKinematicsError(
                f"forward kinematics cannot start (batch index {k}): the initial pose x0 is "
                f"unreachable; give a reachable x0 (default: the home pose)"
            )
        raise ForwardKinematicsError(
            f"forward kinematics did not converge for motor angles "
            f"[{', '.join(f'{v:.6g}' for v in th)}] rad (batch index {k}): residual "
            f"{residual.reshape(-1)[k]:.3g} rad after {iterations.reshape(-1)[k]} Newton steps "
            f"(tol {tol:g}). Give an initial pose x0 closer to the solution, raise max_iter or "
            f"tol, or check that the angles come from a reachable pose."
        )
    status = FkStatus(
        bool(np.all(converged)), int(iterations.max(initial=0)), float(residual.max(initial=0.0))
    )
    return x, status


def encoder_floor(geometry: RobotGeometry, x, quantum_rad: float) -> np.ndarray:
    """The encoders' floor per axis: the RMS error of each pose coordinate when every motor
    angle is rounded to whole encoder counts (uniform over one count q, variance q^2 / 12,
    independent between motors), to first order through J^-1 (J: the inverse kinematics'
    Jacobian, theta_dot = J x_dot): sqrt(diag((q^2 / 12) J^-1 J^-T)).

    Args:
        geometry: the robot. x: (6,) or (n, 6) poses [phi, theta, psi, X, Y, Z] (rad, m).
        quantum_rad: one encoder count, rad (2 pi / counts per revolution).
    Returns:
        (6,) or (n, 6), as x: RMS per axis [rad, rad, rad, m, m, m].
    Raises:
        InvalidConfigError: ``quantum_rad`` not > 0, poses not finite (6,) rows.
        SingularPoseError, UnreachablePoseError: a pose where J is not invertible.
    """
    from .kinematics import jacobian

    q = as_number("quantum_rad", quantum_rad, 0.0, lo_open=True)
    x = as_poses("x", x)
    J_inv = np.linalg.inv(jacobian(geometry, x))  # x_dot = J^-1 theta_dot
    return np.sqrt((q * q / 12.0) * np.sum(J_inv**2, axis=-1))


def encoder_pose_noise(
    geometry: RobotGeometry, x, quantum_rad: float, max_poses: int | None = None
) -> tuple[float, float]:
    """The RMS error that rounding the motor angles to whole encoder counts puts in the pose
    forward kinematics recovers, at the poses ``x``: the encoders' floor on a measured pose.

    Each angle's rounding error is uniform over one count q, variance q^2 / 12, independent
    between motors; to first order the pose's error is J^-1 times it (J: the inverse
    kinematics' Jacobian, theta_dot = J x_dot), so its covariance is (q^2 / 12) J^-1 J^-T. The
    figures are the RMS over the poses of the translation's and the rotation's (roll, pitch,
    yaw) total standard deviation.

    Args:
        geometry: the robot. x: (6,) or (n, 6) poses [phi, theta, psi, X, Y, Z] (rad, m).
        quantum_rad: one encoder count, rad (2 pi / counts per revolution).
        max_poses: evaluate every k-th pose, k = n // max_poses, so that at most about twice
            that many Jacobians are inverted (a run's reference at 1 kHz; None: every pose).
    Returns:
        (m, rad): the translation's and the rotation's RMS error.
    Raises:
        InvalidConfigError: ``quantum_rad`` not > 0, poses not finite (6,) rows.
        SingularPoseError, UnreachablePoseError: a pose where J is not invertible.
    """
    x = np.atleast_2d(as_poses("x", x))
    if max_poses is not None:
        x = x[:: max(1, len(x) // max(1, int(max_poses)))]
    cov_diag = encoder_floor(geometry, x, quantum_rad) ** 2  # (n, 6): diag of J^-1 J^-T q^2/12
    rotation = float(np.sqrt(np.mean(np.sum(cov_diag[:, :3], axis=1))))
    translation = float(np.sqrt(np.mean(np.sum(cov_diag[:, 3:], axis=1))))
    return translation, rotation
