"""LQI regulator of paper section III as a Drake LeafSystem, with online gain re-scheduling.

Error model (paper eqs. 19-25). Per pose coordinate the error is a double integrator driven by the
motor torques through B(x) = M_x(x)^-1 tau(x) (tau = J^T, eq. 18 corrected; M_x the task-space
inertia of platform, cranks and rods); gravity is the constant disturbance d of eq. 19 and is
cancelled by a virtual-work feed-forward. With the integral of the pose error z (eq. 23) the
state is e = [e_x (6), e_x_dot (6), z (6)] (block order; the paper interleaves e_x and e_x_dot).
Sampled at h with zero-order hold, the double integrator has the closed form

    e_x+     = e_x + h e_x_dot + h^2/2 B u
    e_x_dot+ = e_x_dot + h B u
    z+       = z + h e_x               (the controller's own rectangle-rule integrator)

so no matrix exponential is needed. Gains come from Drake's DiscreteAlgebraicRiccatiEquation
(eqs. 31-32, with eq. 32's missing "B^T P A" restored) and the law is u = T_ff - K_p e_bar - K_I z
(eq. 34).

Weights (departure from eq. 27, docs/paper_notes.md): Q = omega_Q I and R = omega_R I on errors in
SI units make the torque far too cheap relative to a 1 mm error, so the gains cannot hold the
platform. We apply eq. 27 to *normalized* errors and torques (Bryson's rule):
Q = omega_Q diag(1/s_e^2, 1/s_v^2, 1/s_z^2), R = omega_R diag(1/s_T^2), with the scales of
:class:`LqiScales` (1 mrad / 1 mm of pose error by default). omega_Q and omega_R in {0.1, 1, 10}
then span soft to stiff controllers that all hold the platform.
"""

from __future__ import annotations

import math
import warnings
from dataclasses import dataclass

import numpy as np
from pydrake.math import DiscreteAlgebraicRiccatiEquation, RealDiscreteLyapunovEquation
from pydrake.systems.framework import LeafSystem

from ..checks import as_array, as_number
from ..errors import InvalidConfigError, RiccatiSolveError, SingularPoseError, UnreachablePoseError
from ..model import kinematics, statics
from ..model.geometry import X_HOME, StewartGeometry
from .contract import LQI_STATUS_NAMES, PoseTorqueController

N_E = 18        # error-model states [e_x, e_x_dot, z]
#: How the gain is re-solved at a re-schedule (see :class:`LqiController`).
RICCATI_MODES = ("warm", "track", "cold")
GAIN_TRANSFER_MODES = ("integral", "feedback", "none")
#: The reference governor takes over when the reference's feed-forward exceeds this fraction of
#: the torque limit, and keeps the holding torques of the pose it follows within it. The rest of
#: the limit is the headroom of a motor at its bound for feedback: it must exceed the motor's
#: Coulomb friction (0.018 N m on paper_hardware) for the motor to lift its crank back. At
#: 0.35 N m (headroom 0.035 N m) the paper manoeuvre completes in every run of a 12-run
#: perturbation set (tests/test_hardware.py) at 0.85 (8.8 mrad | 29.5 mm from the reference at
#: most: the platform follows the governed pose closely, which strays further), 0.9 (25.5 mrad |
#: 21.4 mm) and 0.92; at 0.95 (0.0175 N m, below the friction) it loses the platform in 1 and
#: strays up to 0.13 rad | 0.0498 m in the others. Ours: the paper has no torque limit.
GOVERNOR_MARGIN = 0.9
OMEGA_MIN, OMEGA_MAX = 1e-3, 1e3


@dataclass(frozen=True)
class LqiScales:
    """Normalization of the LQI cost (Bryson's rule); SI units.

    Attributes:
        pose: (6,) acceptable pose error [rad, rad, rad, m, m, m].
        rate: (6,) acceptable rate error [rad/s x3, m/s x3].
        integral: (6,) acceptable integral of the pose error [rad s x3, m s x3].
        torque: acceptable motor torque, N m (same for the six motors).
    """

    pose: tuple = (1e-3, 1e-3, 1e-3, 1e-3, 1e-3, 1e-3)
    rate: tuple = (1.0, 1.0, 1.0, 0.1, 0.1, 0.1)
    integral: tuple = (2e-5, 2e-5, 2e-5, 2e-5, 2e-5, 2e-5)
    torque: float = 0.3

    def __post_init__(self):
        for name in ("pose", "rate", "integral"):
            v = as_array(f"LqiScales.{name}", getattr(self, name), shape=(6,))
            # 1/s^2 must stay finite and > 0: scales within 1e-100 .. 1e100.
            if np.any(v < 1e-100) or np.any(v > 1e100):
                raise InvalidConfigError(f"LqiScales.{name} needs 6 values in [1e-100, 1e100], "
                                         f"got {v}")
            object.__setattr__(self, name, tuple(float(c) for c in v))
        object.__setattr__(self, "torque", as_number("LqiScales.torque [N m]", self.torque,
                                                     1e-100, 1e100))

    def Q_unit(self, delay_periods: int = 0) -> np.ndarray:
        """(18 + 6 d, 18 + 6 d) state weight at omega_Q = 1. The d delayed torques of
        :func:`error_model` get 1e-6 of the torque weight: almost free, but not zero, so the
        diagonal scaling of the Riccati solve stays defined."""
        s = np.concatenate([self.pose, self.rate, self.integral,
                            np.full(6 * delay_periods, self.torque * 1e3)])
        return np.diag(1.0 / s**2)

    def R_unit(self) -> np.ndarray:
        """(6, 6) torque weight at omega_R = 1."""
        return np.eye(6) / self.torque**2


def error_model(B_c: np.ndarray, h: float, delay_periods: int = 0) -> tuple[np.ndarray,
                                                                           np.ndarray]:
    """Discrete error model (A, B) at sample time h for continuous input matrix B_c (6, 6).

    Args:
        B_c: (6, 6) input matrix. h: sample time, s.
        delay_periods: d >= 0 periods between a sample and the torque it computes: the state is
            augmented with the d torques already commanded but not yet acting (newest first),
            e = [e_x, e_x_dot, z, u_{k-1}, ..., u_{k-d}], and e+ = A e + B u_k with the oldest
            acting on the error dynamics (ours: the paper has no delay).
    Returns:
        A (n, n), B (n, 6) of e+ = A e + B u, n = 18 + 6 d, e = [e_x, e_x_dot, z, ...]; paper
        eqs. 21-25 with an exact zero-order hold of the double integrators.
    Raises:
        InvalidConfigError: B_c not a finite (6, 6) array, h not in (0, 1] s (a slower
            controller cannot hold the platform; the bound also keeps h^2 B_c finite), d < 0.
    """
    B_c = as_array("input matrix B_c", B_c, shape=(6, 6))
    h = as_number("sample time h [s]", h, 0.0, 1.0, lo_open=True)
    if isinstance(delay_periods, bool) or not isinstance(delay_periods, (int, np.integer)) \
            or delay_periods < 0:
        raise InvalidConfigError(f"delay_periods must be an integer >= 0, got {delay_periods!r}")
    I = np.eye(6)
    A = np.zeros((N_E, N_E))
    A[0:6, 0:6] = I
    A[0:6, 6:12] = h * I
    A[6:12, 6:12] = I
    A[12:18, 0:6] = h * I
    A[12:18, 12:18] = I
    B = np.zeros((N_E, 6))
    B[0:6] = 0.5 * h * h * B_c
    B[6:12] = h * B_c
    d = int(delay_periods)
    if d == 0:
        return A, B
    n = N_E + 6 * d
    A_d, B_d = np.zeros((n, n)), np.zeros((n, 6))
    A_d[:N_E, :N_E] = A
    A_d[:N_E, n - 6:] = B                                   # u_{k-d} acts now
    for j in range(d - 1):                                  # the history shifts by one
        A_d[N_E + 6 * (j + 1):N_E + 6 * (j + 2), N_E + 6 * j:N_E + 6 * (j + 1)] = np.eye(6)
    B_d[N_E:N_E + 6] = np.eye(6)                            # u_k is the newest
    return A_d, B_d


def input_matrix(geometry: StewartGeometry, x, theta=None) -> np.ndarray:
    """B_c(x) = M_x(x)^-1 tau(x): pose acceleration per unit motor torque, (6, 6).

    Args:
        x: (6,) pose [rad, m]; theta: optional (6,) motor angles of x.
    Returns:
        (6, 6) finite, (rad/s^2 or m/s^2) per N m.
    Raises:
        UnreachablePoseError, SingularPoseError, InvalidConfigError: see kinematics.jacobian.
    Source: paper eq. 22 sets b = tau (unit inertia); dividing by the task inertia M_x, with the
    legs' inertia (:func:`statics.task_inertia`), is ours (docs/paper_notes.md); tau = J^T (eq. 18
    corrected).
    """
    tau = kinematics.tau(geometry, x, theta)         # validates x and theta
    theta = kinematics.ik(geometry, x) if theta is None else theta
    try:
        B_c = np.linalg.solve(statics.task_inertia(geometry, x, theta), tau)
    except np.linalg.LinAlgError:
        B_c = np.full((6, 6), np.inf)
    if not np.isfinite(B_c).all():
        raise SingularPoseError("B_c", np.inf, np.inf, pose=np.ravel(x))
    return B_c


def input_matrix_single(geometry: StewartGeometry, x) -> tuple[np.ndarray, np.ndarray]:
    """:func:`input_matrix` of ONE pose by the single-pose kernels (about 5 times faster), and
    the Jacobian it used: the per-step path of the gain re-scheduling.

    Args:
        x: (6,) finite pose [rad, m] (not validated: the controller's own estimate).
    Returns:
        (B_c (6, 6), J (6, 6)).
    Raises:
        SingularPoseError: B_c not finite (a singular or unreachable pose).
    """
    _, cache = kinematics.ik_single(geometry, x)
    J = kinematics.jacobian_single(geometry, cache)
    try:
        B_c = np.linalg.solve(statics.task_inertia_single(geometry, cache, J), J.T)
    except np.linalg.LinAlgError:
        B_c = np.full((6, 6), np.inf)
    if not np.isfinite(B_c).all():
        raise SingularPoseError("B_c", np.inf, np.inf, pose=np.ravel(x))
    return B_c, J


def hautus_checks(A: np.ndarray, B: np.ndarray, C: np.ndarray, tol: float = 1e-9) -> dict:
    """Stabilizability of (A, B) and detectability of (A, C) by the Hautus test (eqs. 28-29).

    Every eigenvalue with |lambda| >= 1 (here all are 1: chains of integrators) must satisfy
    rank [lambda I - A, B] = n and rank [lambda I - A; C] = n.
    Returns:
        dict with ``stabilizable``, ``detectable`` (bool) and the minimum ranks found.
    Raises:
        InvalidConfigError: A not (n, n), B not (n, m), C not (p, n), or non-finite entries.
    """
    A = as_array("A", A)
    n = A.shape[0] if A.ndim == 2 else -1
    if A.shape != (n, n) or n < 1:
        raise InvalidConfigError(f"A must be square (n, n), got {A.shape}")
    B, C = as_array("B", B), as_array("C", C)
    if B.ndim != 2 or B.shape[0] != n or C.ndim != 2 or C.shape[1] != n:
        raise InvalidConfigError(f"B must be ({n}, m) and C (p, {n}); got {B.shape} and {C.shape}")
    tol = as_number("tol", tol, 0.0)
    try:
        eigs = np.linalg.eigvals(A)
        unstable = np.unique(np.round(eigs[np.abs(eigs) >= 1 - 1e-9], 9))
        rank_ab, rank_ac = n, n
        for lam in unstable:
            M = lam * np.eye(n) - A
            rank_ab = min(rank_ab, np.linalg.matrix_rank(np.hstack([M, B]), tol))
            rank_ac = min(rank_ac, np.linalg.matrix_rank(np.vstack([M, C]), tol))
    except np.linalg.LinAlgError as err:
        raise InvalidConfigError(f"Hautus test failed numerically ({err}); scale A, B, C") from None
    return {"stabilizable": rank_ab == n, "detectable": rank_ac == n,
            "rank_AB": int(rank_ab), "rank_AC": int(rank_ac), "n": n}


def _balance(A, B, Q, R):
    """Diagonal scaling e = D_x e~, u = D_u u~ with D = diag(Q)^-1/2, diag(R)^-1/2.

    The LQI's Q spans 1 (rates, 1/(1 rad/s)^2) to 2.5e9 (integrals, 1/(2e-5)^2): unscaled, the
    Riccati solution has cond(P) ~ 4e9 and the gains carry ~1e-8 relative rounding error; scaled,
    cond(P) ~ 400. Returns (A~, B~, Q~, R~, d_x, d_u).
    """
    qd, rd = np.diag(Q), np.diag(R)
    d_x = 1.0 / np.sqrt(qd) if np.all(qd > 0) else np.ones(len(qd))
    d_u = 1.0 / np.sqrt(rd) if np.all(rd > 0) else np.ones(len(rd))
    return (A * (1 / d_x)[:, None] * d_x[None, :], B * (1 / d_x)[:, None] * d_u[None, :],
            Q * d_x[:, None] * d_x[None, :], R * d_u[:, None] * d_u[None, :], d_x, d_u)


def _check_finite(**arrays) -> None:
    for name, M in arrays.items():
        if not np.all(np.isfinite(M)):
            raise RiccatiSolveError(f"{name} has non-finite entries; no gain computed")


def lqi_gain(A: np.ndarray, B: np.ndarray, Q: np.ndarray, R: np.ndarray) -> np.ndarray:
    """Optimal gain K = (R + B^T P B)^-1 B^T P A (eqs. 31-32); u = -K e.

    Solved on the diagonally scaled problem (:func:`_balance`) with Drake's
    DiscreteAlgebraicRiccatiEquation, then scaled back: the same gain, better conditioned.

    Args:
        A: (n, n), B: (n, m), Q: (n, n) symmetric >= 0, R: (m, m) symmetric > 0.
    Returns:
        (m, n) finite gain K with spectral radius of A - B K < 1.
    Raises:
        RiccatiSolveError: Drake's solver failed, or the result is not finite or not stabilizing.
        InvalidConfigError: shapes that do not match (n, n), (n, m), (n, n), (m, m).
    """
    _check_finite(A=A, B=B, Q=Q, R=R)
    n, m = np.shape(B) if np.ndim(B) == 2 else (-1, -1)
    if (np.shape(A), np.shape(Q), np.shape(R)) != ((n, n), (n, n), (m, m)) or min(n, m) < 1:
        raise InvalidConfigError(f"lqi_gain needs A (n, n), B (n, m), Q (n, n), R (m, m); got "
                                 f"{np.shape(A)}, {np.shape(B)}, {np.shape(Q)}, {np.shape(R)}")
    Ab, Bb, Qb, Rb, d_x, d_u = _balance(A, B, Q, R)
    try:
        P = DiscreteAlgebraicRiccatiEquation(Ab, Bb, Qb, Rb)
    except (RuntimeError, ValueError, SystemExit) as err:
        # pydrake reports a failed precondition (e.g. (A, B) not stabilizable) as SystemExit.
        raise RiccatiSolveError(f"DiscreteAlgebraicRiccatiEquation failed: {err}") from None
    try:
        K = d_u[:, None] * np.linalg.solve(Rb + Bb.T @ P @ Bb, Bb.T @ P @ Ab) / d_x[None, :]
    except np.linalg.LinAlgError as err:
        raise RiccatiSolveError(f"R + B^T P B is singular ({err}); make R positive definite") \
            from None
    if not np.all(np.isfinite(K)):
        raise RiccatiSolveError("Riccati gain is not finite")
    try:
        rho = np.max(np.abs(np.linalg.eigvals(A - B @ K)))
    except np.linalg.LinAlgError:
        rho = np.nan
    if not rho < 1.0:
        raise RiccatiSolveError(f"Riccati gain does not stabilize the model (spectral radius {rho:.6g})")
    return K


def lqi_gain_warm(A: np.ndarray, B: np.ndarray, Q: np.ndarray, R: np.ndarray, K_start,
                  tol: float = 1e-4, max_iter: int = 8) -> tuple[np.ndarray, int]:
    """The gain of :func:`lqi_gain` by Newton's method (Hewer's algorithm) from a nearby gain.

    Each iteration solves one Stein equation P = A_c^T P A_c + Q + K^T R K for A_c = A - B K
    (Drake's RealDiscreteLyapunovEquation, about 0.15 ms on 18 states) and sets
    K = (R + B^T P B)^-1 B^T P A. From any stabilizing K_start the iterates stay stabilizing and
    converge quadratically to the Riccati gain, so a gain from the previous re-schedule (a pose
    a few ms away) is refined in two iterations, about half the cost of a cold DARE. Newton's
    quadratic convergence makes the last step size an estimate of the previous iterate's error
    squared: the loop stops once the relative step is below ``tol`` (1e-4 gives at most 5e-9
    relative to the cold solve along the paper manoeuvre, in 2.05 iterations on average; tested).
    It iterates on the diagonally scaled problem (:func:`_balance`), without which the Stein
    solves' rounding (cond(P) ~ 4e9) alone would leave ~5e-8.

    Args:
        A (n, n), B (n, m), Q (n, n), R (m, m): as :func:`lqi_gain`. K_start: (m, n) stabilizing.
    Returns:
        (K (m, n), iterations).
    Raises:
        RiccatiSolveError: K_start does not stabilize (A, B), a Stein solution is not positive
            definite, or no convergence in ``max_iter`` iterations; the caller falls back to the
            cold :func:`lqi_gain`.
    Source: G. A. Hewer, IEEE TAC 16(4), 1971; paper eqs. 31-32.
    """
    K = np.asarray(K_start, dtype=float)
    _check_finite(A=A, B=B, Q=Q, R=R, K_start=K)
    A, B, Q, R, d_x, d_u = _balance(A, B, Q, R)     # iterate on the well-conditioned problem
    K = K * d_x[None, :] / d_u[:, None]
    for i in range(1, max_iter + 1):
        A_c = A - B @ K
        W = Q + K.T @ R @ K
        try:
            P = RealDiscreteLyapunovEquation(A_c, 0.5 * (W + W.T))
            np.linalg.cholesky(0.5 * (P + P.T))   # P > 0 <=> A_c is Schur stable (W > 0)
        except (RuntimeError, ValueError, SystemExit, np.linalg.LinAlgError) as err:
            raise RiccatiSolveError(f"warm start does not stabilize the model ({err})") from None
        K_next = np.linalg.solve(R + B.T @ P @ B, B.T @ P @ A)
        step = np.abs(K_next - K).max() / max(np.abs(K_next).max(), 1e-300)
        K = K_next
        if step < tol:
            if not np.all(np.isfinite(K)):
                break
            return d_u[:, None] * K / d_x[None, :], i
    raise RiccatiSolveError(f"Newton iteration did not converge in {max_iter} iterations")


def project_onto_torque_bound(d, T, G, bound: float) -> tuple[np.ndarray, np.ndarray]:
    """The step s nearest to d with |T + G s| <= bound for every motor: the Euclidean projection
    onto the linearized torque bound (a small QP, by an active set).

    A motor joins the active set when the current step would overload it, on the side it would
    cross; it leaves when its Lagrange multiplier turns negative (the bound pulls the step
    instead of pushing it). At most one side of a motor can be active (bound > 0), so the
    active rows stay independent for a non-singular G.

    Args:
        d: (6,) the step wanted [rad, m]. T: (6,) torques at s = 0, N m. G: (6, 6) d T / d x.
        bound: N m, > 0.
    Returns:
        (s (6,), C (k, 6)): the step, and the active bounds' rows (sign times the rows of G),
        whose null space is the tangent the step can still move along.
    Raises:
        numpy.linalg.LinAlgError: dependent active rows (a singular G).
    """
    predicted = T + G @ d
    side = np.sign(predicted)
    active = np.abs(predicted) > bound
    s, C = d, G[:0]
    for _ in range(12):                 # each pass adds or releases one motor
        if active.any():
            C = side[active, None] * G[active]
            lam = np.linalg.solve(C @ C.T, C @ d - (bound - side[active] * T[active]))
            if lam.min() < 0.0:
                active[np.flatnonzero(active)[np.argmin(lam)]] = False
                continue
            s = d - C.T @ lam
        else:
            s, C = d, G[:0]
        predicted = T + G @ s
        over = ~active & (np.abs(predicted) > bound * (1 + 1e-9))
        if not over.any():
            break
        k = int(np.argmax(np.where(over, np.abs(predicted), -np.inf)))
        active[k], side[k] = True, np.sign(predicted[k])
    return s, C


class LqiController(PoseTorqueController):
    """LQI torque controller of the platform pose, re-scheduled online (paper section III).

    Input ports:
        ``x`` (12,): pose estimate and rate [phi, theta, psi, X, Y, Z, their rates], rad, m, /s.
        ``x_d`` (18,): reference pose, rate and acceleration (same units, /s^2 for the last 6).
        ``T_ff`` (6,): feed-forward motor torques, N m (:mod:`~stewart_drake.simulation.reference`).
        ``omega`` (2,): [omega_Q, omega_R] > 0 (the ANN tuner drives it; else a constant).
    Output ports:
        ``T`` (6,): motor torques, N m, sampled at ``offset_s`` after each plant step and held;
            within +-torque_limit_Nm when the controller knows the motors' limit.
        ``status`` (7,): [omega_Q, omega_R in use, gain solves, failed solves, |z|, saturated
            steps, governed steps] (``status_names`` = :data:`~.contract.LQI_STATUS_NAMES`).
        ``e_bar`` (6,): the pose error x - x_d the last update acted on (for the density features,
            so they see exactly the controller's error at the controller's instants).
        ``integral`` (6,): the integral states z of eq. 23 [rad s, m s].
    The ports follow the controller contract (:mod:`~stewart_drake.control.contract`).
    Discrete state: u (6), z (6), status (7), e_bar (6), with an estimator x_hat (12), and one
    group the ports do not export: the steps since the last solve, K (6 n, row-major 6 x n,
    n = 18 + 6 d; :meth:`gain_in_use`), the d feedback torques commanded but not yet acting
    (6 d), the governor's last reference within reach (24) and the estimator's J^-1 (36).

    Args:
        geometry: the robot (for B(x)).
        period_s: control period h in s (paper: 1 ms).
        schedule_period_s: re-solve the DARE from the measured pose this often (a multiple of
            period_s). Set equal to period_s to re-schedule every step. A change of omega
            re-solves at once.
        scales: normalization of Q and R (:class:`LqiScales`).
        offset_s: time of the sample within the period. The diagram uses half a plant step, so
            the controller reads the state the plant just produced and its torque acts from the
            next plant step on: the zero-order-hold model above is then exact, with no extra
            step of delay (offset 0 would read the state one plant step old).
        x_initial: pose of the first gain (default home). x_dot_initial: its rate (the
            estimator's start; default at rest).
        riccati: "warm" (default) refines the last gain by Newton's method
            (:func:`lqi_gain_warm`) to convergence, falling back to the cold solve if that fails;
            "track" takes one Newton step per re-schedule (the gain follows the slowly moving
            pose and weights, converging over successive re-schedules; every iterate
            stabilizes); "cold" calls Drake's DARE at every re-schedule.
        torque_limit_Nm: the motors' torque limit, N m, or None: commands are clipped to it and,
            with ``anti_windup``, the integral states stop while a command is clipped.
        anti_windup: clamping (conditional integration) of z while saturated; without it a limit
            below the demand winds z up (ours: the paper has no limit).
        reference_governor: with a torque limit, a reference whose own feed-forward exceeds
            :data:`GOVERNOR_MARGIN` of the limit (a pose the motors cannot even hold: 0.413 N m
            at the paper manoeuvre's extreme, against a 0.35 N m limit) is not followed: the
            controller follows the nearest pose the motors can hold with that margin
            (:meth:`govern`), until the reference comes back within reach. Anti-windup alone
            cannot keep such a platform: past that pose gravity wins and it falls
            (docs/hardware.md). The margin is what keeps the platform itself holdable: the
            gains are stiff (10 to 25 N m of demand at 1 to 2 cm of error), so a motor at its
            bound is the only one whose feedback acts on its crank's error, and its crank sags
            until gravity and friction balance the bound; a pose whose own holding torque
            exceeds the limit by more than the friction is a point of no return. With the
            governed pose's holding torques at 0.9 of the limit, the platform stays within
            0.026 rad | 0.012 m of it and its own holding torque below 0.336 N m at 0.35 N m
            (12 perturbed runs). Ours: the paper has no limit.
        delay_periods: control periods between a sample and its torque acting (the computation
            delay); the error model is augmented with the pending torques (:func:`error_model`).
        gain_transfer: what carries over when the gain changes (new weights, a new pose).
            ``"integral"`` (default): the integral action, K_I,new z_new = K_I,old z_old, so the
            torque the integrator has learned (friction, model error) stays and only the
            proportional part follows the new gain. ``"feedback"``: the whole feedback,
            K_I,new z_new = K_old e - K_rest,new e_rest (no torque step at all); measured worse:
            switching from a stiff to a soft gain locks the stiff loop's transient torque into
            the soft integrator, which takes seconds to unwind (hindsight schedule on a
            multi-sine, J 1838 against 130 with ``"none"``; docs/results.md). ``"none"``: z is
            kept as is, a torque step K_I,new z - K_I,old z. All three are ours: the paper
            switches gains as they come (``"none"``).
        schedule_pose: re-schedule B(x) from the measured pose (default). False keeps the input
            matrix of the start pose, as a plain LQI would (the paper has one B; re-scheduling on
            the pose is ours): the gain is then re-solved only when omega changes.
        estimator: None to read the pose and rate on the ``x`` input; or a
            :class:`~stewart_drake.control.estimator.PoseEstimator`: the controller then reads
            the encoders on a ``motor_angle`` input (6, rad) and estimates the pose and rate in
            its own update (one Newton chord step per period with the Jacobian of the last
            re-schedule, :meth:`~.estimator.PoseEstimator.track`), exported as ``x_hat`` (12).
    Raises:
        InvalidConfigError: bad periods, riccati mode, limit or delay, or the Hautus checks
        fail at the start pose (a robot the motors barely move); RiccatiSolveError: no gain
        at home.
    """

    def __init__(self, geometry: StewartGeometry, period_s: float = 1e-3,
                 schedule_period_s: float = 1e-2, scales: LqiScales | None = None,
                 offset_s: float = 0.0, x_initial=None, riccati: str = "warm",
                 torque_limit_Nm: float | None = None, anti_windup: bool = True,
                 delay_periods: int = 0, estimator=None, x_dot_initial=None,
                 reference_governor: bool = True, schedule_pose: bool = True,
                 gain_transfer: str = "integral"):
        super().__init__(pose_input=estimator is None)
        if not (np.isfinite(period_s) and period_s > 0):
            raise InvalidConfigError(f"control period must be > 0 s, got {period_s}")
        self.status_names = LQI_STATUS_NAMES
        ratio = schedule_period_s / period_s
        if not (ratio >= 1 - 1e-9 and abs(ratio - round(ratio)) < 1e-6):
            raise InvalidConfigError(
                f"schedule_period_s ({schedule_period_s}) must be a whole multiple of the control "
                f"period ({period_s})")
        if riccati not in RICCATI_MODES:
            raise InvalidConfigError(f"riccati must be one of {RICCATI_MODES}, got {riccati!r}")
        if not (0 <= offset_s < period_s):
            raise InvalidConfigError(f"offset_s must be in [0, period_s), got {offset_s}")
        self.geometry = geometry
        self.estimator = estimator
        self.h = float(period_s)
        self.steps_per_schedule = int(round(ratio))
        self.scales = scales or LqiScales()
        self.riccati = riccati
        self.torque_limit = (None if torque_limit_Nm is None
                             else as_number("torque_limit_Nm", torque_limit_Nm, 0.0, lo_open=True))
        self.anti_windup = bool(anti_windup)
        self.governor = bool(reference_governor) and self.torque_limit is not None
        A, B = error_model(np.eye(6), self.h, delay_periods)      # checks delay_periods
        self.delay = int(delay_periods)
        self.n = A.shape[0]
        self._governor_bound = (GOVERNOR_MARGIN * self.torque_limit if self.governor
                                else np.inf)
        self._Q1, self._R1 = self.scales.Q_unit(self.delay), self.scales.R_unit()
        x0 = X_HOME if x_initial is None else np.asarray(x_initial, dtype=float)
        self.schedule_pose = bool(schedule_pose)
        if gain_transfer not in GAIN_TRANSFER_MODES:
            raise InvalidConfigError(f"gain_transfer must be one of {GAIN_TRANSFER_MODES}, got "
                                     f"{gain_transfer!r}")
        self.gain_transfer = gain_transfer
        self.x_initial = x0.copy()

        A, B = error_model(input_matrix(geometry, x0), self.h, self.delay)
        self.hautus = hautus_checks(A, B, np.sqrt(self._Q1))
        if not (self.hautus["stabilizable"] and self.hautus["detectable"]):
            h = self.hautus
            raise InvalidConfigError(
                f"the LQI cannot control this robot at the start pose: its error model fails the "
                f"Hautus checks (eqs. 28-29; rank [lambda I - A, B] = {h['rank_AB']}, "
                f"rank [lambda I - A; C] = {h['rank_AC']}, of {h['n']}): the motors barely move "
                f"the platform; check robot.platform_mass, robot.platform_inertia and the other "
                f"masses and inertias (kg, kg m^2)")
        K0 = lqi_gain(A, B, self._Q1, self._R1)
        self.K_initial = K0
        #: Newton iterations and cold solves so far (diagnostics, not state: a benchmark reads
        #: them after a run; they do not affect the simulation).
        self.solve_stats = {"warm": 0, "warm_iterations": 0, "cold": 0}

        T0 = statics.holding_torques(geometry, x0)
        self._u_index = self.DeclareDiscreteState(T0)
        self._z_index = self.DeclareDiscreteState(6)
        # status: omega_Q, omega_R in use, solves, failures, |z|, saturated steps (a state, so
        # logging it at 1 kHz calls no Python)
        self._s_index = self.DeclareDiscreteState(np.array([1.0, 1.0, 1.0, 0.0, 0.0, 0.0, 0.0]))
        self._e_index = self.DeclareDiscreteState(6)
        if estimator is not None:
            self._motor_angle = self.DeclareVectorInputPort("motor_angle", 6)
            v0 = np.zeros(6) if x_dot_initial is None else np.asarray(x_dot_initial, dtype=float)
            self._xhat_index = self.DeclareDiscreteState(np.concatenate([x0, v0]))
            self.DeclareStateOutputPort("x_hat", self._xhat_index)
        # What no port exports, in one group (one access per step): the steps since the last
        # gain solve (the first update re-solves at the measured pose), the gain K (6 n,
        # row-major), the d pending feedback torques (6 d, newest first), for the governor the
        # last reference (18) and feed-forward (6) within reach, for the estimator J^-1 (36).
        parts = {"counter": [float(self.steps_per_schedule)], "K": K0.reshape(-1),
                 "pending": np.zeros(6 * self.delay)}
        if self.governor:
            parts["hold"] = np.concatenate([x0, np.zeros(12), T0])
        if estimator is not None:
            _, J0 = kinematics.ik_jacobian(geometry, x0)
            parts["J_inv"] = np.linalg.inv(J0).reshape(-1)
        self._mem, start = {}, 0
        for name, value in parts.items():
            self._mem[name] = slice(start, start + len(value))
            start += len(value)
        self._mem_index = self.DeclareDiscreteState(np.concatenate(
            [np.asarray(v, dtype=float) for v in parts.values()]))
        self.DeclareStateOutputPort("T", self._u_index)
        self.DeclareStateOutputPort("status", self._s_index)
        self.DeclareStateOutputPort("e_bar", self._e_index)
        self.DeclareStateOutputPort("integral", self._z_index)
        self.DeclarePeriodicDiscreteUpdateEvent(period_sec=self.h, offset_sec=float(offset_s),
                                                update=self._Update)

    # -- gain ----------------------------------------------------------------------------------
    def _check_weights(self, omega_Q: float, omega_R: float) -> tuple[float, float]:
        return (as_number("omega_Q", omega_Q, OMEGA_MIN, OMEGA_MAX),
                as_number("omega_R", omega_R, OMEGA_MIN, OMEGA_MAX))

    def gain(self, x, omega_Q: float = 1.0, omega_R: float = 1.0, K_start=None) -> np.ndarray:
        """(6, n) LQI gain K = [K_p | K_I (| K_u)] at pose x for weights omega_Q, omega_R (eq. 33);
        n = 18, + 6 per period of delay (the gain on the pending torques).

        Args:
            K_start: optional (6, 18) nearby stabilizing gain: the gain is then refined from it
                by :func:`lqi_gain_warm` (same K to < 1e-8 relative), with the cold DARE as the
                fallback.
        Raises:
            InvalidConfigError: weights not in [1e-3, 1e3]; RiccatiSolveError: see lqi_gain.
        """
        x = as_array("pose x", x, shape=(6,))
        kinematics.ik(self.geometry, x)          # a typed error for a bad or unreachable pose
        return self._gain(x, omega_Q, omega_R, K_start)[0]

    def _gain(self, x, omega_Q, omega_R, K_start):
        """(K, J): the gain of :meth:`gain` and the Jacobian at x it used."""
        omega_Q, omega_R = self._check_weights(omega_Q, omega_R)
        B_c, J = input_matrix_single(self.geometry, np.asarray(x, dtype=float))
        A, B = error_model(B_c, self.h, self.delay)
        Q, R = omega_Q * self._Q1, omega_R * self._R1
        if K_start is not None:
            one_step = self.riccati == "track"
            try:
                K, iterations = lqi_gain_warm(A, B, Q, R, K_start,
                                              tol=np.inf if one_step else 1e-4,
                                              max_iter=1 if one_step else 8)
                self.solve_stats["warm"] += 1
                self.solve_stats["warm_iterations"] += iterations
                return K, J
            except RiccatiSolveError:
                pass                                    # fall back to the cold solve
        self.solve_stats["cold"] += 1
        return lqi_gain(A, B, Q, R), J

    def govern(self, hold, ref) -> np.ndarray:
        """The reference the governor follows when ``ref`` is out of reach: the pose nearest to
        ``ref[:6]`` (Euclidean in rad and m) whose holding torques are within
        :data:`GOVERNOR_MARGIN` of the limit, moving with the part of the reference's rate that
        keeps them there.

        One step of sequential quadratic programming per control period, from the last governed
        pose ``hold[:6]`` (so the governed reference moves continuously: started from ``ref``
        each time, the set of motors at the bound can switch and the reference jump by
        centimetres): the step towards ``ref`` projected exactly onto the motors' bound
        linearized at that pose by finite differences (one batched statics call;
        :func:`project_onto_torque_bound`). The reference moves little in a period, so one step
        is within 6 um | 2 urad and 3e-7 N m of three along the paper manoeuvre, at 0.6 ms
        instead of 1.1 ms.

        The projection must be exact: projected only onto the motors the full step would
        overload (motors 1 and 4 near the paper manoeuvre's extreme), a step can push another
        (motor 6) to the limit itself; such poses were refused and the governor held a stale
        pose with a stale rate, from 0.59 to 0.98 s, with motor 6 at the limit and no headroom:
        the platform sagged 17 mm and fell in half of the perturbed runs. The rate and
        acceleration are those of the reference projected onto the tangent of the active bounds
        (the derivative of the projection, curvature neglected), so the pose and the rate the
        LQI tracks agree. On the paper manoeuvre's extreme with a 0.35 N m limit the nearest
        such pose shifts Y and Z by up to 19 and 13 mm rather than giving up a fifth of a radian
        of roll. Ours: the paper has no torque limit.

        Args:
            hold: (24,) the last governed reference (followed at rest if no pose is found).
            ref: (18,) the reference out of reach.
        Returns:
            (24,) [pose (6), rate (6), acceleration (6), the pose's holding torques (6)].
        """
        bound, eps = GOVERNOR_MARGIN * self.torque_limit, 1e-6
        x = hold[:6] if np.any(hold[18:]) else ref[:6]
        try:
            T = statics.holding_torques(self.geometry, x + np.vstack([np.zeros(6),
                                                                     eps * np.eye(6)]))
            G = ((T[1:] - T[0]) / eps).T                           # d T / d x, (6, 6)
            step, C = project_onto_torque_bound(ref[:6] - x, T[0], G, bound)
            x = x + step
            T0 = statics.holding_torques(self.geometry, x)
            tangent = np.eye(6) - C.T @ np.linalg.solve(C @ C.T, C) if len(C) else np.eye(6)
        except (UnreachablePoseError, SingularPoseError, InvalidConfigError,
                np.linalg.LinAlgError):
            T0 = np.full(6, np.inf)
        if not np.abs(T0).max() <= self.torque_limit:
            return np.concatenate([hold[:6], np.zeros(12), hold[18:]])
        return np.concatenate([x, tangent @ ref[6:12], tangent @ ref[12:18], T0])

    def feedforward(self, context) -> np.ndarray:
        """(6,) feed-forward torques of this step, N m: the ``T_ff`` input (one place to read
        it, so a test can inject a fault there)."""
        return self._T_ff.Eval(context)

    # -- update --------------------------------------------------------------------------------
    def gain_in_use(self, context) -> np.ndarray:
        """(6, n) the gain K the controller's state holds in ``context`` (its own context)."""
        memory = context.get_discrete_state(self._mem_index).get_value()
        return memory[self._mem["K"]].reshape(6, self.n).copy()

    def _Update(self, context, discrete_state):
        # Every step runs here at 1 kHz, between two plant steps that push Python and numpy out
        # of the CPU caches: the state is read and written in place (views of discrete_state,
        # which Drake has already filled with the current values), (6,)-sized arithmetic is done
        # on Python floats (a numpy call costs more than its arithmetic here) and numpy is kept
        # for the gain product (benchmarks/realtime.py measures the whole Diagram).
        memory = discrete_state.get_mutable_value(self._mem_index)
        mem = self._mem
        if self.estimator is None:
            x = self._x.Eval(context).tolist()
        else:                                   # the pose from the encoders (docstring)
            x_hat = discrete_state.get_mutable_value(self._xhat_index)
            x_prev = x_hat.tolist()
            pose, rate = self.estimator.track_floats(
                self._motor_angle.Eval(context).tolist(), x_prev[:6], x_prev[6:],
                memory[mem["J_inv"]].tolist())
            x = pose + rate
            x_hat[:] = x
        ref = self._x_d.Eval(context)
        omega_Q, omega_R = self._omega.Eval(context).tolist()
        status = discrete_state.get_mutable_value(self._s_index)
        K = memory[mem["K"]].reshape(6, self.n)
        # Re-solve every schedule period, and at once when the weights change (the period then
        # restarts: a tuner updating omega every schedule period costs one solve per period).
        if (memory[0] >= self.steps_per_schedule and self.schedule_pose) \
                or omega_Q != status[0] or omega_R != status[1]:
            memory[0] = 0.0
            try:
                K_new, J = self._gain(np.array(x[:6]) if self.schedule_pose else self.x_initial,
                                      omega_Q, omega_R,
                                      K_start=K if self.riccati != "cold" else None)
                status[0], status[1] = omega_Q, omega_R
                status[2] += 1
                K_old = K.copy()
                K[:] = K_new
                if self.estimator is not None:
                    memory[mem["J_inv"]] = np.linalg.inv(J).reshape(-1)
            except (RiccatiSolveError, InvalidConfigError, UnreachablePoseError,
                    SingularPoseError, np.linalg.LinAlgError) as err:
                K_old = None
                status[3] += 1
                if status[3] == 1 or status[3] % 100 == 0:
                    warnings.warn(f"t = {context.get_time():.4f} s: gain re-schedule failed "
                                  f"({err}); keeping the last good gain "
                                  f"({int(status[3])} failures so far)", RuntimeWarning)
        else:
            K_old = None
        memory[0] += 1.0

        T_ff = self.feedforward(context)
        if self.governor:
            hold = memory[mem["hold"]]
            # out of reach; a non-finite T_ff is not governed (nor clipped below): it reaches
            # T, where the guard names it
            if self._governor_bound < abs(T_ff).max() < math.inf:
                hold[:] = self.govern(hold, ref)
                ref, T_ff = hold[:18], hold[18:]
                status[6] += 1
            else:                               # the last reference within reach, at rest
                hold[:6], hold[6:18], hold[18:] = ref[:6], 0.0, T_ff
        ref = ref.tolist()
        e_x = [a - b for a, b in zip(x, ref)]              # [e_x, e_x_dot], 12
        z = discrete_state.get_mutable_value(self._z_index)
        z_list = z.tolist()
        e = e_x + z_list
        if self.delay:
            pending = memory[mem["pending"]]
            e += pending.tolist()
        if K_old is not None and self.gain_transfer != "none":
            # Gain transfer (docstring): the new gain takes over the integral torque the old one
            # had learned ("integral") or its whole feedback ("feedback"), the integral states
            # taking up the difference. Ours: the paper switches gains as they come.
            K_I = K[:, 12:18]
            z_old = np.array(z_list)
            if self.gain_transfer == "integral":
                target = K_old[:, 12:18] @ z_old
            else:
                target = K_old @ e - (K @ e - K_I @ z_old)
            try:
                z_list = np.linalg.solve(K_I, target).tolist()
                e[12:18] = z_list
                z[:] = z_list
            except np.linalg.LinAlgError:
                pass                            # keep z: a step rather than no control
        feedback = K @ e                                     # K e, (6,)
        T = discrete_state.get_mutable_value(self._u_index)
        np.subtract(T_ff, feedback, out=T)
        saturated = False
        if self.torque_limit is not None and self.torque_limit < abs(T).max() < math.inf:
            np.clip(T, -self.torque_limit, self.torque_limit, out=T)
            saturated = True
            status[5] += 1
        if self.delay:                          # newest first: what was just commanded
            pending[6:] = pending[:-6].copy()
            pending[:6] = T - T_ff
        if not (saturated and self.anti_windup):   # clamping: z holds while saturated
            h = self.h
            z_list = [a + h * b for a, b in zip(z_list, e_x)]
            z[:] = z_list
        status[4] = math.sqrt(sum(v * v for v in z_list))
        discrete_state.get_mutable_value(self._e_index)[:] = e_x[:6]
