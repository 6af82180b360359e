"""The stages of :mod:`.lqi_step`, compiled with numba: what the LQI runs every control period.

Same names, signatures and results as the numpy reference (a test holds them equal to 1e-12
relative; they give the same bits); written as loops over the (6,)-sized arrays, where a numpy
call costs more than its arithmetic. One compiled :func:`step` per period (:func:`observe`, then
:func:`act`) replaces some sixty numpy and Python calls; the controller's Python update only
reads its input, takes its state and calls it. The gain re-schedule is compiled here too
(:func:`warm_gain`), with no numpy reference of its own: it is tested against the numpy
functions it replaces (:func:`~.lqi.input_matrix_single`, :func:`~.lqi.error_model`,
:func:`~.lqi.lqi_gain`).

Compilation is cached on disk (``cache=True``): the first import on a machine (and Python
version) compiles for about 40 s (docs/performance.md), later processes load the machine
code in about a second. The cache goes where numba can write:
``NUMBA_CACHE_DIR`` if set, else ``__pycache__`` beside this file, else the user's cache folder;
when none of them is writable (a read-only install and home), a folder in the system's temporary
directory (:func:`_njit`). :func:`.kernel_cache.will_compile` tells, without importing this
module, whether importing it will compile.
"""

from __future__ import annotations

import math

import numba
import numpy as np

from ..robot.kinematics import ik_scalar
from . import lqi_step
from .kernel_cache import (  # noqa: F401 - DEPENDENCIES_DIGEST, sources_digest: named here too
    DEPENDENCIES_DIGEST,
    fallback_cache_dir,
    sources_digest,
    use_cache,
)
from .lqi_step import (
    ALPHA,
    ANTI_WINDUP,
    COUNTER,
    CRANK_LENGTH,
    E_BAR,
    ESTIMATOR,
    FK_JUMP,
    FRICTION,
    FRICTION_RATE,
    GAIN_CHANGED,
    GOVERNED,
    GOVERNED_STEPS,
    GOVERNOR_BOUND,
    HOLD,
    INTEGRAL_NORM,
    J_INV,
    K_OLD,
    K_PART,
    LEG_C,
    NEED_GOVERNOR,
    NEED_NEWTON,
    NEED_SCHEDULE,
    NONFINITE_SAMPLE,
    OMEGA,
    OMEGA_Q,
    OMEGA_R,
    PENDING,
    POSE_IN,
    SATURATED_STEPS,
    SCHEDULE_POSE,
    STATUS,
    STEPS_PER_SCHEDULE,
    T_APPLIED,
    T_FF,
    T_PART,
    TORQUE_LIMIT,
    TRANSFER,
    TRANSFER_INTEGRAL,
    TRANSFER_NONE,
    WINDOW,
    WINDOW_ROW,
    X_D,
    X_HAT,
    H,
    Z,
)


def _njit(function):
    """``numba.njit(cache=True)(function)``, with the cache where numba can write.

    numba refuses to cache (RuntimeError at decoration) when neither ``NUMBA_CACHE_DIR``, the
    source's ``__pycache__`` nor the user's cache folder is writable: the cache then goes to
    :func:`~.kernel_cache.fallback_cache_dir`, and if even that fails the function compiles in
    every process. Without the cache (:func:`~.kernel_cache.use_cache`) too.
    """
    if not _CACHE:
        return numba.njit(function)
    try:
        return numba.njit(cache=True)(function)
    except RuntimeError:
        pass
    if not numba.config.CACHE_DIR:
        numba.config.CACHE_DIR = fallback_cache_dir()
        try:
            return numba.njit(cache=True)(function)
        except RuntimeError:
            numba.config.CACHE_DIR = ""
    return numba.njit(function)


_fallback_cache_dir = fallback_cache_dir  # the name this module's callers and tests know
_CACHE = use_cache()
#: The closed-form IK of :func:`~stewart_drake.robot.kinematics.ik_scalar`, and the sums of
#: :mod:`.lqi_step` whose bits must match the reference's, compiled as written.
ik_compiled = _njit(ik_scalar)
matvec = _njit(lqi_step.matvec)
solve6 = _njit(lqi_step.solve6)


@_njit
def part(array, bounds, k):
    """:func:`.lqi_step.part`."""
    return array[bounds[k, 0] : bounds[k, 1]]


# -- the gain's re-schedule: B(x), the error model, Newton's step ---------------------------------

#: Entries of the ``body`` array of :func:`input_matrix`, in order (see
#: :func:`~.lqi.inertia_constants`).
BODY = (
    "crank_length",
    "rod_length",
    "leg_c",
    "platform_Ixx",
    "platform_Iyy",
    "platform_Izz",
    "platform_mass",
    "shaft_inertia",
    "rod_mass",
    "rod_inertia",
)


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
def input_matrix(legs, body, x):
    """:func:`~.lqi.input_matrix_single` compiled: (B_c = M_x(x)^-1 J^T (6, 6), J (6, 6), ok),
    the same numbers to 1e-12 (a test), ok False where B_c is not finite.

    Args:
        legs: (6, 9) [p_E, P_B, d_B] per leg. body: the constants of :data:`BODY`.
        x: (6,) pose [rad, m].
    Source: paper eqs. 6 and 18 (corrected), the task inertia of
    :func:`~stewart_drake.robot.statics.task_inertia` (docs/paper_notes.md).
    """
    # Long: one compiled kernel, lqi.input_matrix_single (IK, Jacobian, task inertia) as loops,
    # stage for stage in the same order, so that the two read side by side.
    a, s, leg_c = body[0], body[1], body[2]
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
    for i in range(6):
        for k in range(3):
            r_B[i, k] = R[k, 0] * legs[i, 0] + R[k, 1] * legs[i, 1] + R[k, 2] * legs[i, 2]
        lx, ly, lz = (
            r_B[i, 0] + x[3] - legs[i, 3],
            r_B[i, 1] + x[4] - legs[i, 4],
            r_B[i, 2] + x[5] - legs[i, 5],
        )
        dx, dy, dz = legs[i, 6], legs[i, 7], legs[i, 8]
        L = lx * lx + ly * ly + lz * lz - leg_c
        M, N = 2.0 * a * lz, 2.0 * a * (lx * dx + ly * dy + lz * dz)
        theta = math.asin(L / math.sqrt(M * M + N * N)) - math.atan2(N, M)
        c, sn = math.cos(theta), math.sin(theta)
        ell[i, 0], ell[i, 1], ell[i, 2] = lx - a * c * dx, ly - a * c * dy, lz - a * (c * dz + sn)
        e_N[i, 0], e_N[i, 1], e_N[i, 2] = -sn * dx, -sn * dy, c - sn * dz
        rxl = (
            r_B[i, 1] * ell[i, 2] - r_B[i, 2] * ell[i, 1],
            r_B[i, 2] * ell[i, 0] - r_B[i, 0] * ell[i, 2],
            r_B[i, 0] * ell[i, 1] - r_B[i, 1] * ell[i, 0],
        )
        scale = a * (ell[i, 0] * e_N[i, 0] + ell[i, 1] * e_N[i, 1] + ell[i, 2] * e_N[i, 2])
        for j in range(3):
            J[i, j] = (rxl[0] * E[0, j] + rxl[1] * E[1, j] + rxl[2] * E[2, j]) / scale
            J[i, 3 + j] = ell[i, j] / scale
    # Task inertia: platform (rotation in rpy coordinates, translation), cranks, rods.
    RI = np.empty((3, 3))  # R diag(I_p): I_B = R diag(I_p) R^T
    for i in range(3):
        for j in range(3):
            RI[i, j] = R[i, j] * body[3 + j]
    I_B = np.zeros((3, 3))
    for i in range(3):
        for j in range(3):
            for k in range(3):
                I_B[i, j] += RI[i, k] * R[j, k]
    Mx = np.zeros((6, 6))
    Mx[:3, :3] = _at_b(E, _at_b(I_B, E))  # I_B is symmetric: E^T I_B E
    for k in range(3):
        Mx[3 + k, 3 + k] = body[6]
    Mx += body[7] * _at_b(J, J)
    V_com, W = np.empty((18, 6)), np.empty((18, 6))
    for i in range(6):
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
    Mx += body[8] * _at_b(V_com, V_com)
    Mx += body[9] * _at_b(W, W)
    B_c, ok = lu_solve(Mx, np.ascontiguousarray(J.T))
    return B_c, J, ok and _finite(B_c) and _finite(J)


@_njit
def zoh_model(B_c, h, d):
    """:func:`~.lqi.error_model` without its checks: (A (n, n), B (n, 6)), n = 18 + 6 d."""
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
    """:func:`~.lqi.lqi_gain_warm`'s iteration (Hewer's Newton method on the problem balanced
    as :func:`~.lqi.balance` does, each step one :func:`stein` solve): (K, iterations),
    iterations -1 when a Stein series diverges (K does not stabilize), -2 without convergence
    in ``max_iter``."""
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


# -- estimate -------------------------------------------------------------------------------------


@_njit
def estimate(legs, crank_length, leg_c, h, alpha, fk_jump, theta, x_hat, J_inv):
    """:func:`.lqi_step.estimate`: one Newton chord step and the rate filter (paper eq. 6)."""
    x0 = np.empty(6)
    for i in range(6):
        x0[i] = x_hat[i] + h * x_hat[6 + i]
    theta0 = ik_compiled((legs, crank_length, leg_c), x0)
    r = np.empty(6)
    for j in range(6):
        r[j] = (theta0[j] - theta[j] + math.pi) % (2 * math.pi) - math.pi
    dx = matvec(J_inv, r)
    total, largest = 0.0, 0.0
    for i in range(6):
        total += dx[i]
        largest = max(largest, abs(dx[i]))
    if not (largest <= fk_jump and math.isfinite(total)):
        return False
    for i in range(6):
        x = x0[i] - dx[i]
        x_hat[6 + i] += alpha * ((x - x_hat[i]) / h - x_hat[6 + i])
        x_hat[i] = x
    return True


@_njit
def filter_rate(h, alpha, x, x_hat):
    """:func:`.lqi_step.filter_rate`."""
    for i in range(6):
        x_hat[6 + i] += alpha * ((x[i] - x_hat[i]) / h - x_hat[6 + i])
        x_hat[i] = x[i]


# -- re-schedule and govern: what is due ----------------------------------------------------------


@_njit
def schedule_due(c, counter, omega, status):
    """:func:`.lqi_step.schedule_due` (eqs. 27, 31-33)."""
    due = (
        (counter[0] >= c[STEPS_PER_SCHEDULE] and c[SCHEDULE_POSE] != 0.0)
        or omega[0] != status[OMEGA_Q]
        or omega[1] != status[OMEGA_R]
    )
    counter[0] = 1.0 if due else counter[0] + 1.0
    return due


@_njit
def _max_abs(v):
    """max |v_i|, NaN if any entry is NaN (as numpy's max)."""
    largest = 0.0
    for value in v:
        if math.isnan(value):
            return math.nan
        largest = max(largest, abs(value))
    return largest


@_njit
def governor_needed(bound, T_ff):
    """:func:`.lqi_step.governor_needed`."""
    return bound < _max_abs(T_ff) < math.inf


@_njit
def observe(c, legs, u, state, bounds):
    """:func:`.lqi_step.observe`."""
    flags = 0
    if c[ESTIMATOR] != 0.0 and not estimate(
        legs,
        c[CRANK_LENGTH],
        c[LEG_C],
        c[H],
        c[ALPHA],
        c[FK_JUMP],
        part(u, bounds, POSE_IN),
        part(state, bounds, X_HAT),
        part(state, bounds, J_INV).reshape((6, 6)),
    ):
        flags |= NEED_NEWTON
    if schedule_due(
        c, part(state, bounds, COUNTER), part(u, bounds, OMEGA), part(state, bounds, STATUS)
    ):
        flags |= NEED_SCHEDULE
    if governor_needed(c[GOVERNOR_BOUND], part(u, bounds, T_FF)):
        flags |= NEED_GOVERNOR
    return flags


# -- act ------------------------------------------------------------------------------------------


@_njit
def push_window(window, e_bar, T):
    """:func:`.lqi_step.push_window` (eqs. 35-36 samples)."""
    total = 0.0
    for i in range(6):
        total += e_bar[i] + T[i]
    if not math.isfinite(total):
        return False
    w = (window.size - 2) // WINDOW_ROW
    head = int(window[-1])
    for i in range(6):
        window[WINDOW_ROW * head + i] = e_bar[i]
        window[WINDOW_ROW * head + 6 + i] = T[i]
    window[-2] = min(window[-2] + 1.0, w)
    window[-1] = (head + 1) % w
    return True


@_njit
def error_state(x, ref, z, pending):
    """:func:`.lqi_step.error_state` (eqs. 23-25)."""
    e = np.empty(18 + pending.size)
    for i in range(12):
        e[i] = x[i] - ref[i]
    for i in range(6):
        e[12 + i] = z[i]
    for i in range(pending.size):
        e[18 + i] = pending[i]
    return e


@_njit
def transfer_gain(mode, K_old, K, e, z):
    """:func:`.lqi_step.transfer_gain`."""
    K_I = np.ascontiguousarray(K[:, 12:18])
    if mode == TRANSFER_INTEGRAL:
        target = matvec(K_old[:, 12:18], z)
    else:
        target = matvec(K_old, e) - (matvec(K, e) - matvec(K_I, z))
    z_new, ok = solve6(K_I, target)
    if not ok:
        return False
    for i in range(6):
        z[i] = z_new[i]
        e[12 + i] = z_new[i]
    return True


@_njit
def friction_feedforward(friction, rate, J_inv, x_d_rate, T_ff):
    """:func:`.lqi_step.friction_feedforward`: T_ff + friction tanh(J x_dot_d / rate)."""
    theta_dot, ok = solve6(J_inv, x_d_rate.copy())
    if not ok:
        return T_ff
    out = np.zeros(6)
    for i in range(6):
        out[i] = T_ff[i] + friction * math.tanh(theta_dot[i] / rate)
    return out


@_njit
def feedback(K, e, T_ff, T):
    """:func:`.lqi_step.feedback`: T = T_ff - K e (paper eq. 34)."""
    Ke = matvec(K, e)
    for i in range(6):
        T[i] = T_ff[i] - Ke[i]


@_njit
def saturate(limit, T):
    """:func:`.lqi_step.saturate`."""
    if limit < _max_abs(T) < math.inf:
        for i in range(6):
            T[i] = min(max(T[i], -limit), limit)
        return True
    return False


@_njit
def push_pending(pending, T, T_ff):
    """:func:`.lqi_step.push_pending`."""
    for i in range(pending.size - 1, 5, -1):
        pending[i] = pending[i - 6]
    for i in range(6):
        pending[i] = T[i] - T_ff[i]


@_njit
def integrate(h, e, z):
    """:func:`.lqi_step.integrate`: z+ = z + h e_x (paper eq. 23)."""
    for i in range(6):
        z[i] = e[12 + i] + h * e[i]


@_njit
def act(c, u, state, bounds, mode):
    """:func:`.lqi_step.act`."""
    flags = 0
    status, z, T = part(state, bounds, STATUS), part(state, bounds, Z), part(state, bounds, T_PART)
    e_bar, window = part(state, bounds, E_BAR), part(state, bounds, WINDOW)
    if window.size and not push_window(window, e_bar, part(u, bounds, T_APPLIED)):
        flags |= NONFINITE_SAMPLE
    ref, T_ff = part(u, bounds, X_D), part(u, bounds, T_FF)
    if c[GOVERNOR_BOUND] < math.inf:
        hold = part(state, bounds, HOLD)
        if mode & GOVERNED:
            ref, T_ff = hold[:18], hold[18:]
            status[GOVERNED_STEPS] += 1.0
        else:
            for i in range(24):
                hold[i] = 0.0
            for i in range(6):
                hold[i] = ref[i]
                hold[18 + i] = T_ff[i]
    if c[FRICTION] > 0.0:
        J_inv = part(state, bounds, J_INV)
        T_ff = friction_feedforward(
            c[FRICTION], c[FRICTION_RATE], J_inv.reshape((6, 6)), ref[6:12], T_ff
        )
    x = part(state, bounds, X_HAT) if c[ESTIMATOR] != 0.0 else part(u, bounds, POSE_IN)
    K = part(state, bounds, K_PART)
    K = K.reshape((6, K.size // 6))
    pending = part(state, bounds, PENDING)
    e = error_state(x, ref, z, pending)
    if mode & GAIN_CHANGED and c[TRANSFER] != TRANSFER_NONE:
        K_old = part(state, bounds, K_OLD)
        transfer_gain(c[TRANSFER], K_old.reshape((6, K_old.size // 6)), K, e, z)
    feedback(K, e, T_ff, T)
    saturated = saturate(c[TORQUE_LIMIT], T)
    if saturated:
        status[SATURATED_STEPS] += 1.0
    if pending.size:
        push_pending(pending, T, T_ff)
    if not (saturated and c[ANTI_WINDUP] != 0.0):
        integrate(c[H], e, z)
    norm = 0.0
    for i in range(6):
        norm += z[i] * z[i]
    status[INTEGRAL_NORM] = math.sqrt(norm)
    for i in range(6):
        e_bar[i] = e[i]
    return flags


@_njit
def step(c, legs, u, state, bounds):
    """:func:`.lqi_step.step`."""
    need = observe(c, legs, u, state, bounds)
    if need:
        return need, 0
    return 0, act(c, u, state, bounds, 0)


def _readonly(array: np.ndarray) -> np.ndarray:
    array.setflags(write=False)
    return array


def warm_up() -> None:
    """Compile (or load from the cache) every entry the controller calls, with the argument
    types it passes, so that no control period pays for it: a real-time run must not stall
    on its first step. Called once, when the module is first imported."""
    from .lqi_step import LqiLayout, StepConstants

    # Zero constants (the estimator off) with the layout they imply, the constants sized from
    # their fields: numba does not check bounds, so an array shorter than the stages index
    # would be read past its end. The types, not the values, decide what is compiled.
    lay = LqiLayout.build(24, 1, True, False, 50)
    c = _readonly(np.zeros(len(StepConstants.get_fields())))
    legs = _readonly(np.zeros((6, 9)))
    u, state, bounds = np.zeros(lay.u_size), np.zeros(lay.state_size), lay.bounds()
    step(c, legs, u, state, bounds)
    act(c, u, state, bounds, 0)
    filter_rate(1e-3, 0.5, np.zeros(6), np.zeros(12))
    body, x, K = (
        _readonly(np.ones(len(BODY))),
        np.array([0.0, 0.0, 0.0, 0.0, 0.0, 0.3]),
        np.zeros((6, 24)),
    )
    try:  # compiled before it runs; zero legs make no pose
        warm_gain(legs, body, x, 1e-3, 1, np.eye(24), np.eye(6), K, np.inf, 1, 1e-16)
    except (ZeroDivisionError, ValueError, np.linalg.LinAlgError):  # ValueError: not compiled
        pass


warm_up()
