"""The reference validator's per-pose arithmetic, compiled with numba: the closed-form IK's
reach ratios (:func:`closure`), the leg terms, the Jacobian and the ball joints' angles
(:func:`pose_terms`), and the motor torques a motion needs (:func:`effort`); and the forward
kinematics by Newton of a control period (:func:`fk_newton`: the encoders' pose on the robot).

:func:`~.limits.validate_trajectory` checks every sample of a reference (every millisecond of
a run). Its numpy form runs each formula as a batched operation on (6, 3)-sized blocks, where
numpy's per-call cost exceeds the arithmetic, and the motors' torques evaluate the task inertia
M_x seven times per pose (at the pose and a forward-difference step along each coordinate, for
the velocity-product forces): 80 % of the check's time. Here the same formulas run as loops,
pose by pose, with the same forward differences (the same step); numpy keeps what it does in
one call per stretch (the arcsines, the singular values), so that those are its own.

The sums of :func:`closure` and :func:`pose_terms` are taken in the orders numpy's ``einsum``
and ``sum`` take them in :func:`~.kinematics.ik_unchecked`, :func:`~.kinematics.leg_terms`,
:func:`~.kinematics.jacobian_of` and :func:`~.limits.joint_angles_of` (``einsum`` sums three
terms with two SIMD lanes for some subscripts, one after the other for others), so that the
ratios, J and the joints' cosines are numpy's to the last bit (numpy 2's orders; a test holds
the validator's report to the numpy one's on real references). The task inertia of
:func:`effort` is summed in another order than numpy's matrix products (BLAS, whose rounding
depends on the CPU's kernel); the forward differences divide that rounding by their step
(1e-7), so the torques differ from numpy's by up to 5e-10 of the peak torque (2e-10 on the
paper manoeuvre), while each is 2e-8 of the peak from the same forward differences in exact
arithmetic (docs/performance.md).

Compiled on first use (about 7 s, once per machine) or loaded from numba's disk cache
(:func:`~stewart_drake.base.compiled.njit_cached`), with numpy's error model: a division by zero
gives inf or NaN, as numpy's. :data:`reference` holds the same functions uncompiled (their
``py_func``), for a test of the compiled code against its own source.
"""

from __future__ import annotations

import hashlib
import math
from pathlib import Path

import numpy as np

from ..base.compiled import interpreted, njit_cached


def source_digest() -> str:
    """SHA-256 (16 hex digits) of this module's source: the kernels that compile these
    functions in (the servo bus's, the crank servo's) hold it against the digest their numba
    cache was written with, as numba's cache notices a change of their own file only.

    Raises:
        OSError: the source is not shipped (then they compile every time).
    """
    return hashlib.sha256(Path(__file__).read_bytes()).hexdigest()[:16]


def compiled_against(digest: str):
    """The decorator of a module whose kernels compile these in: numba with numpy's error
    model (a leg that cannot close gives NaN, not an error), its disk cache used while this
    module's :func:`source_digest` is ``digest`` (the module's own constant, which a test of it
    holds equal) and compiled afresh in every process otherwise."""
    try:
        cache = source_digest() == digest
    except OSError:  # sources not shipped: compile every time
        cache = False

    def njit(function):
        return njit_cached(function, cache, error_model="numpy")

    return njit


def _njit(function):
    """:func:`~stewart_drake.base.compiled.njit_cached` with numpy's error model (a division
    by zero gives inf or NaN, a square root of a negative NaN: the numpy form's values)."""
    return njit_cached(function, error_model="numpy")


#: Entries of the ``body`` array of :func:`effort`, in order (:func:`~.statics.kernel_constants`
#: builds it from the geometry): inertias in kg m^2, masses in kg, gravity in m/s^2, the
#: forward-difference step in rad or m. Each leg's lengths and its crank's inertia about the
#: shaft are in the ``legs`` rows (:data:`~.single_pose.LEG_COLUMNS`: p_E 0-2, P_B 3-5, d_B 6-8,
#: w_B 9-11, a 12, s^2 - a^2 13, s 14, shaft inertia 15).
BODY = (
    "platform_Ixx",
    "platform_Iyy",
    "platform_Izz",
    "platform_mass",
    "rod_mass",
    "rod_inertia",
    "gravity",
    "crank_mass",
    "step",
)

#: :func:`effort`'s status of a pose: its torques computed; a pose one forward-difference step
#: away cannot be reached; J^T exactly singular (a zero pivot); the torques not finite.
OK, STEP_UNREACHABLE, SINGULAR, NOT_FINITE = 0, 1, 2, 3


@_njit
def _rotation(x, R, E):
    """R_BE (3, 3) and the rpy rate map E (3, 3) of pose x, in place: the products of
    :func:`~.kinematics.rotation_rpy` and :func:`~.kinematics.angular_velocity_map`."""
    cr, cp, cy = math.cos(x[0]), math.cos(x[1]), math.cos(x[2])
    sr, sp, sy = math.sin(x[0]), math.sin(x[1]), math.sin(x[2])
    R[0, 0] = cy * cp
    R[0, 1] = cy * sp * sr - sy * cr
    R[0, 2] = cy * sp * cr + sy * sr
    R[1, 0] = sy * cp
    R[1, 1] = sy * sp * sr + cy * cr
    R[1, 2] = sy * sp * cr - cy * sr
    R[2, 0] = -sp
    R[2, 1] = cp * sr
    R[2, 2] = cp * cr
    E[0, 0], E[0, 1], E[0, 2] = cy * cp, -sy, 0.0
    E[1, 0], E[1, 1], E[1, 2] = sy * cp, cy, 0.0
    E[2, 0], E[2, 1], E[2, 2] = -sp, 0.0, 1.0


@_njit
def _lever_arms(x, legs, R, r, q):
    """r_i = R_BE p_i (6, 3) and the platform joints q_i = r_i + p (6, 3), in place; each sum
    in the order of numpy's ``einsum("...jk,ik->...ij")`` (its two SIMD lanes: terms 0 and 2,
    then term 1)."""
    for i in range(6):
        for j in range(3):
            r[i, j] = (R[j, 0] * legs[i, 0] + R[j, 2] * legs[i, 2]) + R[j, 1] * legs[i, 1]
            q[i, j] = r[i, j] + x[3 + j]


@_njit
def _lmn(legs, q, i):
    """(L, M, N) of leg i with platform joints q (6, 3): theta_i solves
    M sin theta + N cos theta = L (:func:`~.kinematics.ik_unchecked`'s sums, in its order)."""
    lx, ly, lz = q[i, 0] - legs[i, 3], q[i, 1] - legs[i, 4], q[i, 2] - legs[i, 5]
    a = legs[i, 12]
    L = (lx * lx + ly * ly + lz * lz) - legs[i, 13]
    M = 2.0 * a * (lx * legs[i, 9] + ly * legs[i, 10] + lz * legs[i, 11])
    return L, M, 2.0 * a * (lx * legs[i, 6] + ly * legs[i, 7] + lz * legs[i, 8])


@_njit
def _closure(legs, q, c, s):
    """cos theta_i and sin theta_i (6,) of the closed-form IK of platform joints q (6, 3), in
    place, without the angles: with rho = L / sqrt(M^2 + N^2) and phi = atan2(N, M),
    theta = asin(rho) - phi (:func:`~.kinematics.ik_unchecked`'s rho, to the last bit), so
    cos theta = sqrt(1 - rho^2) cos phi + rho sin phi and sin theta = rho cos phi -
    sqrt(1 - rho^2) sin phi. Returns False when a leg cannot close (not |rho| <= 1)."""
    for i in range(6):
        L, M, N = _lmn(legs, q, i)
        h = math.hypot(M, N)
        rho = L / h
        if not abs(rho) <= 1.0:
            return False
        root = math.sqrt((1.0 - rho) * (1.0 + rho))
        c[i] = root * (M / h) + rho * (N / h)
        s[i] = rho * (M / h) - root * (N / h)
    return True


@_njit
def closure(x, legs, body, ratio, M, N):
    """The reach ratios of the closed-form IK of poses x (n, 6) [rad, m], in place: ratio
    (n, 6) = L / sqrt(M^2 + N^2), and M, N (n, 6), of which theta = asin(ratio) - atan2(N, M)
    where |ratio| <= 1 (:func:`~.kinematics.ik_unchecked`'s arithmetic; numpy takes the
    arcsines). legs (6, LEG_SIZE), body: as :func:`effort`'s."""
    R, E, r, q = np.empty((3, 3)), np.empty((3, 3)), np.empty((6, 3)), np.empty((6, 3))
    for n in range(x.shape[0]):
        _rotation(x[n], R, E)
        _lever_arms(x[n], legs, R, r, q)
        for i in range(6):
            L, M[n, i], N[n, i] = _lmn(legs, q, i)
            ratio[n, i] = L / math.hypot(M[n, i], N[n, i])


@_njit
def _leg_terms(legs, c, s, E, r, q, ell, e_N, G, J):
    """The leg terms of :func:`~.kinematics.leg_terms` for a pose whose E, r and q are set
    and the cosines c and sines s (6,) of its motor angles: the rods ell (6, 3), the crank-tip
    directions e_N (6, 3), G (6, 3, 3) = -[r_i]x E (the rotation columns of dq_i/dx) and
    J (6, 6) = d theta / d x, in place, each sum in the order of numpy's ``einsum`` in
    :func:`~.kinematics.leg_terms` and :func:`~.kinematics.jacobian_of`."""
    for i in range(6):
        a = legs[i, 12]
        for k in range(3):
            ell[i, k] = q[i, k] - (
                legs[i, 3 + k] + a * (c[i] * legs[i, 6 + k] + s[i] * legs[i, 9 + k])
            )
            e_N[i, k] = -s[i] * legs[i, 6 + k] + c[i] * legs[i, 9 + k]
        r0, r1, r2 = r[i, 0], r[i, 1], r[i, 2]
        for col in range(3):
            e0, e1, e2 = E[0, col], E[1, col], E[2, col]
            G[i, 0, col] = -(((0.0 + 0.0 * e0) + -r2 * e1) + r1 * e2)
            G[i, 1, col] = -(((0.0 + r2 * e0) + 0.0 * e1) + -r0 * e2)
            G[i, 2, col] = -(((0.0 + -r1 * e0) + r0 * e1) + 0.0 * e2)
        l0, l1, l2 = ell[i, 0], ell[i, 1], ell[i, 2]
        den = a * ((l0 * e_N[i, 0] + l1 * e_N[i, 1]) + l2 * e_N[i, 2])
        for col in range(3):
            J[i, col] = (((0.0 + l0 * G[i, 0, col]) + l1 * G[i, 1, col]) + l2 * G[i, 2, col]) / den
            J[i, 3 + col] = ell[i, col] / den


@_njit
def pose_terms(x, theta, legs, body, joints, J, crank, cos_p):
    """The Jacobian and the ball joints' cosines of poses x (n, 6) [rad, m] with motor angles
    theta (n, 6) (NaN for a leg that cannot close: its terms NaN), in place: J (n, 6, 6), as
    :func:`~.kinematics.jacobian_of`; crank (n, 6) = e_l . u_i, the sine of the rod's tilt out
    of its crank's plane; cos_p (n, 6) = R^T e_l . (the socket's axis), the cosine of the rod's
    angle in its platform socket (:func:`~.limits.joint_angles_of`, whose arcsines numpy takes).

    Args:
        legs (6, LEG_SIZE), body: as :func:`effort`'s. joints: (6, 6) per leg the motor shaft
            u_i and the socket's axis in the platform frame (unit vectors).
    """
    R, E = np.empty((3, 3)), np.empty((3, 3))
    r, q, ell, e_N = np.empty((6, 3)), np.empty((6, 3)), np.empty((6, 3)), np.empty((6, 3))
    c, s, G = np.empty(6), np.empty(6), np.empty((6, 3, 3))
    for n in range(x.shape[0]):
        _rotation(x[n], R, E)
        _lever_arms(x[n], legs, R, r, q)
        for i in range(6):
            c[i], s[i] = math.cos(theta[n, i]), math.sin(theta[n, i])
        _leg_terms(legs, c, s, E, r, q, ell, e_N, G, J[n])
        for i in range(6):
            norm = math.sqrt(ell[i, 0] * ell[i, 0] + ell[i, 1] * ell[i, 1] + ell[i, 2] * ell[i, 2])
            e0, e1, e2 = ell[i, 0] / norm, ell[i, 1] / norm, ell[i, 2] / norm
            crank[n, i] = e0 * joints[i, 0] + e1 * joints[i, 1] + e2 * joints[i, 2]
            acc = 0.0
            for k in range(3):
                acc += (((0.0 + R[0, k] * e0) + R[1, k] * e1) + R[2, k] * e2) * joints[i, 3 + k]
            cos_p[n, i] = acc


@_njit
def _inertia(body, legs, R, E, ell, e_N, G, J, M, K, B, P):
    """The task inertia M_x (6, 6) of :func:`~.statics.task_inertia` from a pose's leg terms, in
    place (K (3, 3), B and P (6, 6): scratch): the platform (rpy and translation), the cranks
    about their shafts with the motors' reflected inertia, and the rods.

    Per rod i, with its velocity maps V_tip = a_i e_N J_i (crank tip) and Gq_i = [G_i, I]
    (platform joint), both (3, 6): m_r V_com^T V_com with V_com = (V_tip + Gq_i) / 2, plus
    I_r W^T W with W = [ell_i]x (Gq_i - V_tip) / s_i^2 the rod's rotation normal to its axis.
    Expanded: with g_i = Gq_i^T e_N (6,), Gq_i^T V_tip = a_i g_i J_i^T and V_tip^T V_tip =
    a_i^2 |e_N|^2 J_i J_i^T; and [ell]x^T [ell]x = |ell|^2 I - ell ell^T, whose second term
    drops because ell^T (Gq_i - V_tip) = 0 (the rod keeps its length: that is J_i's definition),
    so I_r W^T W = I_r |ell|^2 / s_i^4 (Gq_i - V_tip)^T (Gq_i - V_tip). The same quantity as
    the numpy form's, rounded otherwise."""
    quarter_rod, i_rod = 0.25 * body[4], body[5]
    # Platform: E^T (R diag(I) R^T) E = K^T diag(I) K with K = R^T E.
    for j in range(3):
        for k in range(3):
            K[j, k] = R[0, j] * E[0, k] + R[1, j] * E[1, k] + R[2, j] * E[2, k]
    for j in range(6):
        for k in range(6):
            M[j, k] = 0.0
    for j in range(3):
        for k in range(j, 3):
            M[j, k] = body[0] * K[0, j] * K[0, k] + body[1] * K[1, j] * K[1, k]
            M[j, k] += body[2] * K[2, j] * K[2, k]
        M[3 + j, 3 + j] = body[3]
    # Rods and cranks: sum_i alpha_i Gq_i^T Gq_i + gamma_i (J_i g_i^T + g_i J_i^T)
    # + delta_i J_i J_i^T. B's rows: gamma_i g_i; P: the J_i J_i^T and J_i g_i^T sums.
    for j in range(6):
        for k in range(6):
            P[j, k] = 0.0
    for i in range(6):
        a, s, shaft = legs[i, 12], legs[i, 14], legs[i, 15]
        n0, n1, n2 = e_N[i, 0], e_N[i, 1], e_N[i, 2]
        beta = i_rod * (ell[i, 0] * ell[i, 0] + ell[i, 1] * ell[i, 1] + ell[i, 2] * ell[i, 2])
        beta /= s * s * s * s
        alpha = quarter_rod + beta
        gamma = a * (quarter_rod - beta)
        delta = a * a * (n0 * n0 + n1 * n1 + n2 * n2) * alpha + shaft
        for col in range(3):
            B[i, col] = gamma * (G[i, 0, col] * n0 + G[i, 1, col] * n1 + G[i, 2, col] * n2)
        B[i, 3], B[i, 4], B[i, 5] = gamma * n0, gamma * n1, gamma * n2
        for j in range(3):  # alpha Gq^T Gq = alpha [[G^T G, G^T], [G, I]]
            for k in range(j, 3):
                M[j, k] += alpha * (
                    G[i, 0, j] * G[i, 0, k] + G[i, 1, j] * G[i, 1, k] + G[i, 2, j] * G[i, 2, k]
                )
            for k in range(3):
                M[j, 3 + k] += alpha * G[i, k, j]
            M[3 + j, 3 + j] += alpha
        for j in range(6):
            Jj = J[i, j]
            for k in range(j, 6):
                P[j, k] += delta * Jj * J[i, k]
    for j in range(6):
        for k in range(j, 6):
            acc = P[j, k]
            for i in range(6):
                acc += J[i, j] * B[i, k] + B[i, j] * J[i, k]
            M[j, k] += acc
    for j in range(6):
        for k in range(j):
            M[j, k] = M[k, j]


@_njit
def _lu6(A, x):
    """LU with partial pivoting of A (6, 6) in place (A overwritten by its factors), the row
    swaps and the elimination applied to x (6,) as well; returns the sign of the row
    permutation, or 0.0 where a pivot is exactly zero (x partly overwritten)."""
    sign = 1.0
    for k in range(6):
        p = k
        for i in range(k + 1, 6):
            if abs(A[i, k]) > abs(A[p, k]):
                p = i
        if A[p, k] == 0.0:
            return 0.0
        if p != k:
            sign = -sign
            for j in range(6):
                A[k, j], A[p, j] = A[p, j], A[k, j]
            x[k], x[p] = x[p], x[k]
        for i in range(k + 1, 6):
            f = A[i, k] / A[k, k]
            for j in range(k + 1, 6):
                A[i, j] -= f * A[k, j]
            x[i] -= f * x[k]
    return sign


@_njit
def lu_solve6(A, x):
    """Solve A y = x for A (6, 6) and x (6,) in place, by LU with partial pivoting (LAPACK's
    dgesv): A is overwritten by its factors and x by y. Returns False (x partly overwritten)
    when a pivot is exactly zero, where dgesv reports a singular matrix. The one 6 x 6 solve
    of the compiled code (the LQI's step calls it too), written as loops in one order: the
    compiled and the interpreted form give the same bits."""
    if _lu6(A, x) == 0.0:
        return False
    for k in range(5, -1, -1):
        acc = x[k]
        for j in range(k + 1, 6):
            acc -= A[k, j] * x[j]
        x[k] = acc / A[k, k]
    return True


@_njit
def _gravity(body, legs, e_N, G, J, w):
    """dV/dx (6,) of :func:`~.statics.gravity_gradient_of` from the crank-tip directions e_N
    (6, 3) (whose z is the cosine of the motor angle untilted), G and J of a pose, in place."""
    g = body[6]
    for col in range(6):
        acc = 0.0
        z_rows = 0.0
        for i in range(6):
            acc += g * legs[i, 12] * e_N[i, 2] * (0.5 * body[7] + 0.5 * body[4]) * J[i, col]
            z_rows += G[i, 2, col] if col < 3 else (1.0 if col == 5 else 0.0)
        w[col] = acc + 0.5 * body[4] * g * z_rows
    w[5] += body[3] * g


@_njit
def _pose_effort(x, x_dot, x_ddot, theta, legs, body, T, work, vectors, blocks):
    """The torques T (6,) of one pose (see :func:`effort`), in place, with scratch arrays
    ``work`` (8, 6), ``vectors`` (12, 6, 3) and ``blocks`` (12, 6, 6); returns its status."""
    step = body[8]
    c, s, c_k, s_k = work[0], work[1], work[2], work[3]
    x_k, w, dM_x_dot = work[4], work[5], work[6]
    r, q, ell, e_N = vectors[0], vectors[1], vectors[2], vectors[3]
    r_k, q_k = vectors[4], vectors[5]
    R, E, R_k, E_k = blocks[0, :3, :3], blocks[1, :3, :3], blocks[2, :3, :3], blocks[3, :3, :3]
    K, J, M, J_k, M_k = blocks[4, :3, :3], blocks[5], blocks[6], blocks[7], blocks[8]
    B, P, A = blocks[9], blocks[10], blocks[11]
    G, G_k = vectors[6:9].reshape((6, 3, 3)), vectors[9:12].reshape((6, 3, 3))
    _rotation(x, R, E)
    _lever_arms(x, legs, R, r, q)
    for i in range(6):
        c[i], s[i] = math.cos(theta[i]), math.sin(theta[i])
    _leg_terms(legs, c, s, E, r, q, ell, e_N, G, J)
    _inertia(body, legs, R, E, ell, e_N, G, J, M, K, B, P)
    _gravity(body, legs, e_N, G, J, w)
    for j in range(6):
        for k in range(6):
            w[j] += M[j, k] * x_ddot[k]
    # Velocity-product forces by forward differences (:func:`~.statics.coriolis_forces`).
    for k in range(6):
        for j in range(6):
            x_k[j] = x[j]
        x_k[k] += step
        _rotation(x_k, R_k, E_k)
        _lever_arms(x_k, legs, R_k, r_k, q_k)
        if not _closure(legs, q_k, c_k, s_k):
            return STEP_UNREACHABLE
        _leg_terms(legs, c_k, s_k, E_k, r_k, q_k, ell, e_N, G_k, J_k)
        _inertia(body, legs, R_k, E_k, ell, e_N, G_k, J_k, M_k, K, B, P)
        quad = 0.0
        for i in range(6):
            acc = 0.0
            for j in range(6):
                acc += (M_k[i, j] - M[i, j]) / step * x_dot[j]
            dM_x_dot[i] = acc
            quad += x_dot[i] * acc
        for i in range(6):
            w[i] += dM_x_dot[i] * x_dot[k]
        w[k] -= 0.5 * quad
    for i in range(6):  # T = J^-T w
        T[i] = w[i]
        for j in range(6):
            A[i, j] = J[j, i]
    if not lu_solve6(A, T):
        return SINGULAR
    for i in range(6):
        if not math.isfinite(T[i]):
            return NOT_FINITE
    return OK


@_njit
def effort(x, x_dot, x_ddot, theta, legs, body, T, status):
    """The motor torques that move the closed chain along (x, x_dot, x_ddot), pose by pose:
    T = J^-T (M_x x_ddot + c(x, x_dot) + dV/dx), as :func:`~.statics.inverse_dynamics_of`
    (no friction), c by forward differences of M_x with step ``body[BODY.index("step")]``.

    Args:
        x, x_dot, x_ddot: (n, 6) poses [rad, m], rates and accelerations (SI), reachable poses.
        theta: (n, 6) their motor angles, rad (:func:`~.kinematics.ik_unchecked`'s).
        legs: (6, LEG_SIZE) per leg the columns of :data:`~.single_pose.LEG_COLUMNS`
            (:func:`~.statics.kernel_constants`).
        body: the constants of :data:`BODY`.
        T: (n, 6) torques, N m, filled in place. status: (n,) int64, filled with each pose's
            status (:data:`OK`, :data:`STEP_UNREACHABLE`, :data:`SINGULAR`, :data:`NOT_FINITE`);
            T is not set for a pose whose status is not OK.
    Returns:
        the number of poses whose status is not OK.
    """
    work, vectors, blocks = np.empty((8, 6)), np.empty((12, 6, 3)), np.empty((12, 6, 6))
    bad = 0
    for n in range(x.shape[0]):
        status[n] = _pose_effort(
            x[n], x_dot[n], x_ddot[n], theta[n], legs, body, T[n], work, vectors, blocks
        )
        bad += status[n] != OK
    return bad


@_njit
def joint_inertia(legs, body, x, M_theta, J_inv):
    """The chain's joint-space inertia M_theta = J^-T M_x J^-1 (6, 6) kg m^2 at pose x (6,) and
    J^-1 (6, 6), in place (:func:`~.statics.crank_inertia_matrix`'s quantity, the task inertia
    of :func:`_inertia`): for a controller that re-schedules its gains every few periods.
    Returns False where a leg cannot close or J is singular (the outputs then undefined)."""
    R, E = np.empty((3, 3)), np.empty((3, 3))
    r, q = np.empty((6, 3)), np.empty((6, 3))
    theta, c, s = np.empty(6), np.empty(6), np.empty(6)
    ik_angles(legs, x, R, E, r, q, theta)
    for i in range(6):
        if not math.isfinite(theta[i]):
            return False
        c[i], s[i] = math.cos(theta[i]), math.sin(theta[i])
    ell, e_N, G, J = np.empty((6, 3)), np.empty((6, 3)), np.empty((6, 3, 3)), np.empty((6, 6))
    _leg_terms(legs, c, s, E, r, q, ell, e_N, G, J)
    Mx, K, B, P = np.empty((6, 6)), np.empty((3, 3)), np.empty((6, 6)), np.empty((6, 6))
    _inertia(body, legs, R, E, ell, e_N, G, J, Mx, K, B, P)
    A, col = np.empty((6, 6)), np.empty(6)
    for k in range(6):  # J^-1 column by column
        for i in range(6):
            col[i] = 1.0 if i == k else 0.0
            for j in range(6):
                A[i, j] = J[i, j]
        if not lu_solve6(A, col):
            return False
        for i in range(6):
            J_inv[i, k] = col[i]
    for i in range(6):  # M_theta = J_inv^T Mx J_inv
        for k in range(6):
            acc = 0.0
            for a in range(6):
                row = 0.0
                for b in range(6):
                    row += Mx[a, b] * J_inv[b, k]
                acc += J_inv[a, i] * row
            M_theta[i, k] = acc
    return True


# -- forward kinematics by Newton (one reading of the encoders) ------------------------------------


@_njit
def ik_angles(legs, x, R, E, r, q, theta):
    """theta (6,) of pose x by the closed-form IK, in place (NaN for a leg that cannot close),
    with R, E, r, q (the pose's rotation, rate map, lever arms and platform joints) set for
    :func:`jacobian_at`."""
    _rotation(x, R, E)
    _lever_arms(x, legs, R, r, q)
    for i in range(6):
        L, M, N = _lmn(legs, q, i)
        h = math.sqrt(M * M + N * N)
        theta[i] = math.asin(L / h) - math.atan2(N, M) if abs(L) <= h else math.nan


@_njit
def jacobian_at(legs, theta, E, r, q, J):
    """J = d theta / d x (6, 6), in place, at the pose :func:`ik_angles` last set E, r, q and
    theta for."""
    c, s = np.empty(6), np.empty(6)
    for i in range(6):
        c[i], s[i] = math.cos(theta[i]), math.sin(theta[i])
    ell, e_N, G = np.empty((6, 3)), np.empty((6, 3)), np.empty((6, 3, 3))
    _leg_terms(legs, c, s, E, r, q, ell, e_N, G, J)


@_njit
def _det_sign(J):
    """The sign of det J (6, 6) from its LU factors (0.0 where a pivot is zero)."""
    A = J.copy()
    sign = _lu6(A, np.zeros(6))
    for k in range(6):
        if A[k, k] < 0.0:
            sign = -sign
    return sign


@_njit
def _all_finite(v):
    """Whether every entry of ``v`` is finite."""
    for k in range(v.size):
        if not math.isfinite(v.flat[k]):
            return False
    return True


@_njit
def fk_newton(legs, mode, tol, max_iterations, x_start, theta_read, x, J):
    """The pose whose IK gives the encoders' reading, by Newton from ``x_start``: the algorithm
    of :meth:`~stewart_drake.control.estimator.PoseEstimator.estimate` (the same steps, its
    branch guard and step halving), compiled. In place: x (6,) the last iterate, J (6, 6) the
    Jacobian there when converged.

    Args:
        legs: (6, LEG_SIZE) :func:`~.single_pose.leg_constants` (the encoders' zero errors in
            the last column, subtracted from the reading). mode: +1 or -1, sign det J of the
            assembly mode to stay in. tol: rad, the largest residual of a converged pose.
            max_iterations: Newton steps at most. x_start: (6,) [rad, m].
            theta_read: (6,) the encoders' reading, rad.
    Returns:
        whether every residual is within ``tol``.
    Source: FK by Newton on paper eq. 6 (ours; docs/hardware.md).
    """
    R, E, r, q = np.empty((3, 3)), np.empty((3, 3)), np.empty((6, 3)), np.empty((6, 3))
    th, th_c = np.empty(6), np.empty(6)
    candidate, dx, target = np.empty(6), np.empty(6), np.empty(6)
    x[:] = x_start
    for i in range(6):
        target[i] = theta_read[i] - legs[i, legs.shape[1] - 1]
    ik_angles(legs, x, R, E, r, q, th)
    for step in range(max_iterations + 1):
        worst = 0.0
        for i in range(6):
            dx[i] = (th[i] - target[i] + math.pi) % (2 * math.pi) - math.pi
            worst = max(worst, abs(dx[i])) if math.isfinite(dx[i]) else math.inf
        jacobian_at(legs, th, E, r, q, J)
        if worst <= tol:
            return True
        if step == max_iterations or not _all_finite(J) or not lu_solve6(J.copy(), dx):
            return False
        accepted = False
        for _ in range(20):  # the branch guard and the workspace: halve the step
            for i in range(6):
                candidate[i] = x[i] - dx[i]
            ik_angles(legs, candidate, R, E, r, q, th_c)
            if _all_finite(th_c):
                big = False
                for i in range(6):
                    big = big or abs(dx[i]) >= 1e-3
                if not big:
                    accepted = True
                    break
                jacobian_at(legs, th_c, E, r, q, J)
                if _det_sign(J) == mode:
                    accepted = True
                    break
            for i in range(6):
                dx[i] *= 0.5
        if not accepted:
            return False
        x[:] = candidate
        th[:] = th_c
    return False


#: Every function above as the Python numba compiles (its ``py_func``), calling the others'
#: ``py_func``: the uncompiled kernels, equal to the compiled ones by construction.
reference = interpreted(globals())
