"""The LQI's gain design (paper section III): error model, B(x), Hautus test, Riccati gain.

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
:class:`~.driver.LqiScales` (1 mrad / 1 mm of pose error by default). omega_Q and omega_R in
{0.1, 1, 10} then span soft to stiff controllers that all hold the platform.

The controller re-solves the gain online with the compiled :mod:`.reschedule`; this module is
the design in numpy and Drake: the gain at the start pose, the linear models
(:mod:`~stewart_drake.control.linear_model`), and the reference the compiled code is tested
against.
"""

from __future__ import annotations

import numpy as np
from pydrake.math import DiscreteAlgebraicRiccatiEquation

from ...base.checks import as_array, as_number, check_int
from ...base.errors import InvalidConfigError, RiccatiSolveError, SingularPoseError
from ...robot import kinematics, statics
from ...robot.geometry import StewartGeometry

N_E = 18  # error-model states [e_x, e_x_dot, z]
#: The reference governor takes over when the reference's feed-forward exceeds this fraction of
#: the torque limit, and keeps the holding torques of the pose it follows within it. The rest of
#: the limit is the headroom a motor at its bound keeps for feedback: it must exceed the motor's
#: Coulomb friction (0.018 N m on paper_hardware) for the motor to lift its crank back
#: (docs/hardware.md measures margins from 0.85 to 0.95). Ours: the paper has no torque limit.
GOVERNOR_MARGIN = 0.9
#: Relative size of the last term at which the Stein series of the warm re-solve stops
#: (:func:`~.reschedule.newton_gain`).
STEIN_TOL = 1e-16
#: The weights omega_Q, omega_R the LQI accepts (eq. 27; only their ratio sets the gain).
LQI_OMEGA_MIN, LQI_OMEGA_MAX = 1e-3, 1e3


def error_model(B_c: np.ndarray, h: float, delay_periods: int = 0) -> tuple[np.ndarray, np.ndarray]:
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
    check_int("delay_periods", delay_periods, 0)
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
    A_d[:N_E, n - 6 :] = B  # u_{k-d} acts now
    for j in range(d - 1):  # the history shifts by one
        A_d[N_E + 6 * (j + 1) : N_E + 6 * (j + 2), N_E + 6 * j : N_E + 6 * (j + 1)] = np.eye(6)
    B_d[N_E : N_E + 6] = np.eye(6)  # u_k is the newest
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

    The re-schedule computes B(x) compiled (:func:`~.reschedule.input_matrix`, the same numbers
    to 1e-12, a test); this numpy form stays for the design, and is not that kernel's uncompiled
    ``py_func``: it validates the pose (typed errors naming it), and its sums run in another
    order (BLAS, LAPACK), so its last bits differ from the loops' (measured: no pose of 200
    alike), and the start gain it gives seeds every run's re-schedules.
    """
    tau = kinematics.tau(geometry, x, theta)  # validates x and theta
    theta = kinematics.ik(geometry, x) if theta is None else theta
    try:
        B_c = np.linalg.solve(statics.task_inertia(geometry, x, theta), tau)
    except np.linalg.LinAlgError:
        B_c = np.full((6, 6), np.inf)
    if not np.isfinite(B_c).all():
        raise SingularPoseError("B_c", np.inf, np.inf, pose=np.ravel(x))
    return B_c


def body_constants(geometry: StewartGeometry) -> np.ndarray:
    """The robot's bodies as the compiled B(x) reads them (:data:`~.reschedule.BODY`): the
    platform's principal inertia (3) and mass, the rod's mass and transverse inertia, SI units
    (each leg's lengths and crank shaft inertia are in its row of
    :func:`~stewart_drake.robot.statics.kernel_constants`' legs). The first entries of the
    validator's constants, a writable copy."""
    from .reschedule import BODY

    return statics.kernel_constants(geometry)[1][: len(BODY)].copy()


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
    return {
        "stabilizable": rank_ab == n,
        "detectable": rank_ac == n,
        "rank_AB": int(rank_ab),
        "rank_AC": int(rank_ac),
        "n": n,
    }


def balance(A, B, Q, R):
    """Diagonal scaling e = D_x e~, u = D_u u~ with D = diag(Q)^-1/2, diag(R)^-1/2 of the
    Riccati problem (A, B, Q, R) (the compiled Newton step, :func:`~.reschedule.newton_gain`,
    scales the same way).

    The LQI's Q spans 1 (rates, 1/(1 rad/s)^2) to 2.5e9 (integrals, 1/(2e-5)^2): unscaled, the
    Riccati solution has cond(P) ~ 4e9 and the gains carry ~1e-8 relative rounding error; scaled,
    cond(P) ~ 400. Returns (A~, B~, Q~, R~, d_x, d_u).
    """
    qd, rd = np.diag(Q).copy(), np.diag(R).copy()
    d_x = 1.0 / np.sqrt(qd) if np.all(qd > 0) else np.ones(len(qd))
    d_u = 1.0 / np.sqrt(rd) if np.all(rd > 0) else np.ones(len(rd))
    return (
        A * (1 / d_x).reshape(-1, 1) * d_x.reshape(1, -1),
        B * (1 / d_x).reshape(-1, 1) * d_u.reshape(1, -1),
        Q * d_x.reshape(-1, 1) * d_x.reshape(1, -1),
        R * d_u.reshape(-1, 1) * d_u.reshape(1, -1),
        d_x,
        d_u,
    )


def _check_finite(**arrays) -> None:
    for name, M in arrays.items():
        if not np.all(np.isfinite(M)):
            raise RiccatiSolveError(f"{name} has non-finite entries; no gain computed")


def lqi_gain(A: np.ndarray, B: np.ndarray, Q: np.ndarray, R: np.ndarray) -> np.ndarray:
    """Optimal gain K = (R + B^T P B)^-1 B^T P A (eqs. 31-32); u = -K e.

    Solved on the diagonally scaled problem (:func:`balance`) with Drake's
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
        raise InvalidConfigError(
            f"lqi_gain needs A (n, n), B (n, m), Q (n, n), R (m, m); got "
            f"{np.shape(A)}, {np.shape(B)}, {np.shape(Q)}, {np.shape(R)}"
        )
    Ab, Bb, Qb, Rb, d_x, d_u = balance(A, B, Q, R)
    try:
        P = DiscreteAlgebraicRiccatiEquation(Ab, Bb, Qb, Rb)
    except (RuntimeError, ValueError, SystemExit) as err:
        # pydrake reports a failed precondition (e.g. (A, B) not stabilizable) as SystemExit.
        raise RiccatiSolveError(f"DiscreteAlgebraicRiccatiEquation failed: {err}") from None
    try:
        K = d_u[:, None] * np.linalg.solve(Rb + Bb.T @ P @ Bb, Bb.T @ P @ Ab) / d_x[None, :]
    except np.linalg.LinAlgError as err:
        raise RiccatiSolveError(
            f"R + B^T P B is singular ({err}); make R positive definite"
        ) from None
    if not np.all(np.isfinite(K)):
        raise RiccatiSolveError("Riccati gain is not finite")
    try:
        rho = np.max(np.abs(np.linalg.eigvals(A - B @ K)))
    except np.linalg.LinAlgError:
        rho = np.nan
    if not rho < 1.0:
        raise RiccatiSolveError(
            f"Riccati gain does not stabilize the model (spectral radius {rho:.6g})"
        )
    return K


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
    for _ in range(12):  # each pass adds or releases one motor
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
