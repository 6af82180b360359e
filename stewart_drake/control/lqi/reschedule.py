"""The gain's re-schedule compiled with numba: B(x), the error model and Newton's method.

One compiled call per re-schedule (:func:`warm_gain`) computes the input matrix B(x) = M_x(x)^-1
J^T at the estimated pose (:func:`input_matrix`: the closed-form IK, the Jacobian and the task
inertia as loops), the discrete error model (:func:`zoh_model`) and the Riccati gain by Newton's
method from the last gain (:func:`newton_gain`, each step one :func:`stein` solve): about a fifth
of the cost of the numpy functions it replaces (:func:`~.gain.input_matrix`,
:func:`~.gain.error_model` and a Newton step in numpy with Drake's Stein solver;
benchmarks/realtime.py --riccati), to which tests hold it (1e-12 for B(x), 1e-8 for the gain
against the cold DARE). The same B(x)
serves the cold re-solve (:meth:`~.controller.LqiController.gain`), so the gain is scheduled on
one input matrix whichever way it is solved.

Importing this module compiles nothing: :mod:`.kernels` does (or loads numba's disk cache).
"""

from __future__ import annotations

import math

import numpy as np

from ...robot.path_kernels import BODY as PATH_BODY
from ..kernel_cache import njit_cached, use_cache
from .step import ik_compiled

_CACHE = use_cache()


def _njit(function):
    """:func:`~stewart_drake.control.kernel_cache.njit_cached`, cached while the sources the
    kernels inline are those they were compiled against."""
    return njit_cached(function, _CACHE)


#: Entries of the ``body`` array of :func:`input_matrix`, in order (see
#: :func:`~.gain.body_constants`): the first six of the reference validator's kernels, the
#: same constants (:data:`~stewart_drake.robot.path_kernels.BODY`); each leg's lengths and
#: shaft inertia are in its ``legs`` row, as the validator's.
BODY = PATH_BODY[:6]


@_njit
def lu_solve(A, B):
    """(X, ok): A X = B for A (m, m), B (m, k) by LU with partial pivoting; ok False where a
    pivot is exactly zero. Loops: for the 6 x 6 systems of the re-schedule, cheaper to run and
    to compile than LAPACK's wrappers."""
    m = A.shape[0]
    M, X = A.copy(), B.copy()
    for k in range(m):
        p = k
        for i in range(k + 1, m):
            if abs(M[i, k]) > abs(M[p, k]):
                p = i
        if M[p, k] == 0.0:
            return X, False
        if p != k:
            for j in range(m):
                M[k, j], M[p, j] = M[p, j], M[k, j]
            for j in range(X.shape[1]):
                X[k, j], X[p, j] = X[p, j], X[k, j]
        for i in range(k + 1, m):
            f = M[i, k] / M[k, k]
            for j in range(k + 1, m):
                M[i, j] -= f * M[k, j]
            for j in range(X.shape[1]):
                X[i, j] -= f * X[k, j]
    for k in range(m - 1, -1, -1):
        for j in range(X.shape[1]):
            acc = X[k, j]
            for i in range(k + 1, m):
                acc -= M[k, i] * X[i, j]
            X[k, j] = acc / M[k, k]
    return X, True


@_njit
def _at_b(A, B):
    """A^T B for small A (r, m), B (r, n), by loops."""
    out = np.zeros((A.shape[1], B.shape[1]))
    for k in range(A.shape[0]):
        for i in range(A.shape[1]):
            a = A[k, i]
            for j in range(B.shape[1]):
                out[i, j] += a * B[k, j]
    return out


@_njit
def _finite(A):
    for v in A.ravel():
        if not math.isfinite(v):
            return False
    return True


@_njit
def leg_jacobian(legs, body, x):
    """The closed-form IK and the Jacobian of pose x by loops, for :func:`input_matrix`: (R, E,
    J, r_B, ell, e_N), the platform's rotation (3, 3), the rate map of its rpy angles (3, 3), J =
    d theta / d x (6, 6), and per leg the platform joint about the platform's origin (6, 3), the
    rod (6, 3) and the crank tip's direction of motion (6, 3).

    Args:
        legs: (6, LEG_SIZE) per leg the columns of
            :data:`~stewart_drake.robot.single_pose.LEG_COLUMNS`. body: the constants of
            :data:`BODY`. x: (6,) pose [rad, m].
    Source: paper eqs. 6 and 18 (corrected), stage for stage as
    :func:`~stewart_drake.robot.single_pose.ik_single` and
    :func:`~stewart_drake.robot.single_pose.jacobian_single`.
    """
    cr, cp, cy = math.cos(x[0]), math.cos(x[1]), math.cos(x[2])
    sr, sp, sy = math.sin(x[0]), math.sin(x[1]), math.sin(x[2])
    R = np.array(
        [
            [cy * cp, cy * sp * sr - sy * cr, cy * sp * cr + sy * sr],
            [sy * cp, sy * sp * sr + cy * cr, sy * sp * cr - cy * sr],
            [-sp, cp * sr, cp * cr],
        ]
    )
    E = np.array([[cy * cp, -sy, 0.0], [sy * cp, cy, 0.0], [-sp, 0.0, 1.0]])
    J = np.empty((6, 6))
    r_B, ell, e_N = np.empty((6, 3)), np.empty((6, 3)), np.empty((6, 3))
    thetas = ik_compiled(legs, x)  # the closed-form IK's one scalar form
    for i in range(6):
        for k in range(3):
            r_B[i, k] = R[k, 0] * legs[i, 0] + R[k, 1] * legs[i, 1] + R[k, 2] * legs[i, 2]
        lx, ly, lz = (
            r_B[i, 0] + x[3] - legs[i, 3],
            r_B[i, 1] + x[4] - legs[i, 4],
            r_B[i, 2] + x[5] - legs[i, 5],
        )
        dx, dy, dz = legs[i, 6], legs[i, 7], legs[i, 8]
        wx, wy, wz = legs[i, 9], legs[i, 10], legs[i, 11]
        a = legs[i, 12]
        theta = thetas[i]
        c, sn = math.cos(theta), math.sin(theta)
        # The tip a (c d + sn w) as a c d + a sn w: untilted (w = z, d_z = 0) each added term
        # is an exact zero and these are the sums of the upright crank, to the bit.
        ell[i, 0] = lx - a * c * dx - a * sn * wx
        ell[i, 1] = ly - a * c * dy - a * sn * wy
        ell[i, 2] = lz - a * c * dz - a * sn * wz
        e_N[i, 0], e_N[i, 1], e_N[i, 2] = -sn * dx + c * wx, -sn * dy + c * wy, -sn * dz + c * wz
        rxl = (
            r_B[i, 1] * ell[i, 2] - r_B[i, 2] * ell[i, 1],
            r_B[i, 2] * ell[i, 0] - r_B[i, 0] * ell[i, 2],
            r_B[i, 0] * ell[i, 1] - r_B[i, 1] * ell[i, 0],
        )
        scale = a * (ell[i, 0] * e_N[i, 0] + ell[i, 1] * e_N[i, 1] + ell[i, 2] * e_N[i, 2])
        for j in range(3):
            J[i, j] = (rxl[0] * E[0, j] + rxl[1] * E[1, j] + rxl[2] * E[2, j]) / scale
            J[i, 3 + j] = ell[i, j] / scale
    return R, E, J, r_B, ell, e_N


@_njit
def task_inertia(body, legs, R, E, J, r_B, ell, e_N):
    """M_x (6, 6), the task-space inertia of platform (rotation in rpy coordinates,
    translation), cranks and rods, from :func:`leg_jacobian`'s terms: as
    :func:`~stewart_drake.robot.statics.task_inertia`, by loops."""
    RI = np.empty((3, 3))  # R diag(I_p): I_B = R diag(I_p) R^T
    for i in range(3):
        for j in range(3):
            RI[i, j] = R[i, j] * body[j]
    I_B = np.zeros((3, 3))
    for i in range(3):
        for j in range(3):
            for k in range(3):
                I_B[i, j] += RI[i, k] * R[j, k]
    Mx = np.zeros((6, 6))
    Mx[:3, :3] = _at_b(E, _at_b(I_B, E))  # I_B is symmetric: E^T I_B E
    for k in range(3):
        Mx[3 + k, 3 + k] = body[3]
    uniform = True
    for i in range(6):
        uniform = uniform and legs[i, 15] == legs[0, 15]
    if uniform:  # one shaft inertia: scaling J^T J rounds as the numpy form does
        Mx += legs[0, 15] * _at_b(J, J)
    else:
        JS = np.empty((6, 6))
        for i in range(6):
            for j in range(6):
                JS[i, j] = legs[i, 15] * J[i, j]
        Mx += _at_b(J, JS)
    V_com, W = np.empty((18, 6)), np.empty((18, 6))
    for i in range(6):
        a, s = legs[i, 12], legs[i, 14]
        # Gq: velocity of platform joint i per unit x rate, (3, 6) = [-skew(r_B) E, I]
        Gq = np.zeros((3, 6))
        rx, ry, rz = r_B[i, 0], r_B[i, 1], r_B[i, 2]
        for j in range(3):
            Gq[0, j] = -(-rz * E[1, j] + ry * E[2, j])
            Gq[1, j] = -(rz * E[0, j] - rx * E[2, j])
            Gq[2, j] = -(-ry * E[0, j] + rx * E[1, j])
            Gq[j, 3 + j] = 1.0
        V_tip = np.empty((3, 6))
        for k in range(3):
            for j in range(6):
                V_tip[k, j] = a * e_N[i, k] * J[i, j]
        D = Gq - V_tip
        ex, ey, ez = ell[i, 0], ell[i, 1], ell[i, 2]
        for j in range(6):
            for k in range(3):
                V_com[3 * i + k, j] = 0.5 * (V_tip[k, j] + Gq[k, j])
            W[3 * i, j] = (-ez * D[1, j] + ey * D[2, j]) / (s * s)
            W[3 * i + 1, j] = (ez * D[0, j] - ex * D[2, j]) / (s * s)
            W[3 * i + 2, j] = (-ey * D[0, j] + ex * D[1, j]) / (s * s)
    Mx += body[4] * _at_b(V_com, V_com)
    Mx += body[5] * _at_b(W, W)
    return Mx


@_njit
def input_matrix(legs, body, x):
    """B(x): (B_c = M_x(x)^-1 J^T (6, 6), J (6, 6), ok), pose acceleration per unit motor
    torque and the Jacobian; ok False where B_c is not finite (a singular or unreachable pose).
    The same numbers as :func:`~.gain.input_matrix` to 1e-12 (a test).

    Args:
        legs: (6, LEG_SIZE) per leg, as :func:`leg_jacobian`'s. body: the constants of
            :data:`BODY`. x: (6,) pose [rad, m].
    Source: paper eqs. 6 and 18 (corrected), the task inertia of
    :func:`~stewart_drake.robot.statics.task_inertia` (docs/paper_notes.md).
    """
    R, E, J, r_B, ell, e_N = leg_jacobian(legs, body, x)
    Mx = task_inertia(body, legs, R, E, J, r_B, ell, e_N)
    B_c, ok = lu_solve(Mx, np.ascontiguousarray(J.T))
    return B_c, J, ok and _finite(B_c) and _finite(J)


@_njit
def zoh_model(B_c, h, d):
    """:func:`~.gain.error_model` without its checks: (A (n, n), B (n, 6)), n = 18 + 6 d."""
    n = 18 + 6 * d
    A, B = np.zeros((n, n)), np.zeros((n, 6))
    for i in range(6):
        A[i, i] = A[6 + i, 6 + i] = A[12 + i, 12 + i] = 1.0
        A[i, 6 + i] = h
        A[12 + i, i] = h
        for j in range(6):
            B[i, j] = 0.5 * h * h * B_c[i, j]
            B[6 + i, j] = h * B_c[i, j]
    if d == 0:
        return A, B
    B_aug = np.zeros((n, 6))
    for i in range(18):  # u_{k-d} acts now
        for j in range(6):
            A[i, n - 6 + j] = B[i, j]
    for k in range(d - 1):  # the history shifts by one
        for j in range(6):
            A[18 + 6 * (k + 1) + j, 18 + 6 * k + j] = 1.0
    for j in range(6):  # u_k is the newest
        B_aug[18 + j, j] = 1.0
    return A, B_aug


@_njit
def warm_gain(legs, body, x, h, d, Q, R, K, tol, max_iter, stein_tol):
    """The re-schedule's gain in one call: B(x) (:func:`input_matrix`), the error model
    (:func:`zoh_model`) and Newton's method from K (:func:`newton_gain`). Returns (K, J^-1,
    iterations), iterations as :func:`newton_gain`'s, or -3 where B(x) is not finite (a
    singular or unreachable pose)."""
    B_c, J, ok = input_matrix(legs, body, x)
    if not ok:
        return K, J, -3
    A, B = zoh_model(B_c, h, d)
    K_new, iterations = newton_gain(A, B, Q, R, K, tol, max_iter, stein_tol)
    J_inv, ok = lu_solve(J, np.eye(6))
    return K_new, J_inv, iterations if ok else -3


# -- the gain's Newton step -----------------------------------------------------------------------


@_njit
def stein(A, W, tol, max_iter):
    """P with P = A^T P A + W (a Stein, or discrete Lyapunov, equation) by the squared Smith
    iteration: P_{k+1} = P_k + A_k^T P_k A_k, A_{k+1} = A_k^2 from P_0 = W, A_0 = A, which sums
    the series P = sum_j (A^j)^T W A^j in 2^k terms after k steps.

    Args:
        A: (n, n) with spectral radius < 1. W: (n, n) symmetric. tol: the iteration stops when
        the last term is below tol times the largest entry of P. max_iter: steps at most.
    Returns:
        (P (n, n) symmetric, steps); steps = -1 when the series did not converge (A not Schur
        stable: the terms grow or stay) or left the finite numbers.
    Source: R. A. Smith, SIAM J. Appl. Math. 16(1), 1968. For the LQI's 24 states about ten
    times faster than a Schur method here (benchmarks/realtime.py --riccati).
    """
    P = 0.5 * (W + W.T)
    Ak = np.ascontiguousarray(A)
    for k in range(1, max_iter + 1):
        term = np.ascontiguousarray(Ak.T) @ (P @ Ak)
        P = P + 0.5 * (term + term.T)
        size, change = 0.0, 0.0
        for v in P.ravel():
            size = max(size, abs(v))
        for v in term.ravel():
            change = max(change, abs(v))
        if not (math.isfinite(size) and math.isfinite(change)):
            return P, -1
        if change <= tol * size:
            return P, k
        Ak = Ak @ Ak
    return P, -1


@_njit
def newton_gain(A, B, Q, R, K, tol, max_iter, stein_tol):
    """The gain of :func:`~.gain.lqi_gain` by Newton's method (Hewer's algorithm) from a nearby
    stabilizing gain K: (K, iterations), iterations -1 when a Stein series diverges (K does not
    stabilize), -2 without convergence in ``max_iter``; the controller then falls back to the
    cold :func:`~.gain.lqi_gain`.

    Each iteration solves one Stein equation P = A_c^T P A_c + Q + K^T R K for A_c = A - B K
    (:func:`stein`: about 0.05 ms on 24 states, a sixth of Drake's RealDiscreteLyapunovEquation
    and of scipy's, to 1e-12 of them; benchmarks/realtime.py --riccati) and sets
    K = (R + B^T P B)^-1 B^T P A. From any stabilizing K the iterates stay stabilizing and
    converge quadratically to the Riccati gain, so a gain from the previous re-schedule (a pose
    a few ms away) is refined in two iterations, about half the cost of a cold DARE. Newton's
    quadratic convergence makes the last step size an estimate of the previous iterate's error
    squared: the loop stops once the relative step is below ``tol`` (1e-4 gives at most 5e-9
    relative to the cold solve along the paper manoeuvre, in 2.05 iterations on average;
    tests/test_speed_paths.py). It iterates on the problem balanced as :func:`~.gain.balance`
    does, without which the Stein solves' rounding (cond(P) ~ 4e9) alone would leave ~5e-8.

    Args:
        A (n, n), B (n, m), Q (n, n), R (m, m): as :func:`~.gain.lqi_gain`, C-contiguous.
        K: (m, n). tol: relative step at which to stop. max_iter: iterations at most.
        stein_tol: :func:`stein`'s (:data:`~.gain.STEIN_TOL`).
    Source: G. A. Hewer, IEEE TAC 16(4), 1971; paper eqs. 31-32.
    """
    n, m = B.shape
    d_x, d_u = np.ones(n), np.ones(m)
    q_positive, r_positive = True, True
    for i in range(n):
        q_positive = q_positive and Q[i, i] > 0
    for i in range(m):
        r_positive = r_positive and R[i, i] > 0
    if q_positive:
        for i in range(n):
            d_x[i] = 1.0 / math.sqrt(Q[i, i])
    if r_positive:
        for i in range(m):
            d_u[i] = 1.0 / math.sqrt(R[i, i])
    Ab, Qb = np.empty((n, n)), np.empty((n, n))
    Bb, Kb, Rb = np.empty((n, m)), np.empty((m, n)), np.empty((m, m))
    for i in range(n):
        for j in range(n):
            Ab[i, j] = A[i, j] * (1 / d_x[i]) * d_x[j]
            Qb[i, j] = Q[i, j] * d_x[i] * d_x[j]
        for j in range(m):
            Bb[i, j] = B[i, j] * (1 / d_x[i]) * d_u[j]
            Kb[j, i] = K[j, i] * d_x[i] / d_u[j]
    for i in range(m):
        for j in range(m):
            Rb[i, j] = R[i, j] * d_u[i] * d_u[j]
    Bt = np.ascontiguousarray(Bb.T)
    for it in range(1, max_iter + 1):
        A_c = Ab - Bb @ Kb
        P, steps = stein(A_c, Qb + np.ascontiguousarray(Kb.T) @ (Rb @ Kb), stein_tol, 64)
        if steps < 0:
            return K, -1
        BtP = Bt @ P
        K_next, ok = lu_solve(Rb + BtP @ Bb, BtP @ Ab)
        if not ok:
            return K, -2
        change, size = 0.0, 1e-300
        for i in range(m):
            for j in range(n):
                change = max(change, abs(K_next[i, j] - Kb[i, j]))
                size = max(size, abs(K_next[i, j]))
        Kb = K_next
        if change / size < tol:
            if not _finite(Kb):
                return K, -2
            out = np.empty((m, n))
            for i in range(m):
                for j in range(n):
                    out[i, j] = d_u[i] * Kb[i, j] / d_x[j]
            return out, it
    return K, -2
