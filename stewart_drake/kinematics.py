"""Closed-form kinematics and statics of the rotary Stewart platform (pure numpy, no Drake plant).

Pose x = [phi, theta, psi, X, Y, Z] (rad, rad, rad, m, m, m): orientation of E in B as Drake's
RollPitchYaw, R_BE = Rz(psi) Ry(theta) Rx(phi), and the position p_BE of E's origin. Every function
takes a single pose (6,) or a batch (..., 6) and broadcasts; motor angles theta are (..., 6) in rad.

Per leg i (reference_geometry.md):
    q_i = R_BE p_i + p_BE          platform joint centre, base frame
    tip_i = P_i + a (cos theta_i d_i + sin theta_i z)
    ell_i = q_i - tip_i             rod vector, |ell_i| = s
"""

from __future__ import annotations

import numpy as np

from .errors import UnreachablePoseError
from .geometry import StewartGeometry

_Z = np.array([0.0, 0.0, 1.0])


def rotation_rpy(rpy) -> np.ndarray:
    """R_BE = Rz(psi) Ry(theta) Rx(phi) for rpy (..., 3) in rad; returns (..., 3, 3).

    Same convention as ``pydrake.math.RollPitchYaw(rpy).ToRotationMatrix()`` (a test checks), but
    vectorized. Paper eq. 3 prints Rx Ry Rz with two wrong entries; see docs/paper_notes.md.
    """
    rpy = np.asarray(rpy, dtype=float)
    c, s = np.cos(rpy), np.sin(rpy)
    cr, cp, cy = c[..., 0], c[..., 1], c[..., 2]
    sr, sp, sy = s[..., 0], s[..., 1], s[..., 2]
    R = np.empty(rpy.shape[:-1] + (3, 3))
    R[..., 0, 0] = cy * cp
    R[..., 0, 1] = cy * sp * sr - sy * cr
    R[..., 0, 2] = cy * sp * cr + sy * sr
    R[..., 1, 0] = sy * cp
    R[..., 1, 1] = sy * sp * sr + cy * cr
    R[..., 1, 2] = sy * sp * cr - cy * sr
    R[..., 2, 0] = -sp
    R[..., 2, 1] = cp * sr
    R[..., 2, 2] = cp * cr
    return R


def angular_velocity_map(rpy) -> np.ndarray:
    """E(rpy) with w_BE_B = E @ rpy_dot for R = Rz Ry Rx; returns (..., 3, 3).

    Singular at pitch = +-pi/2 (gimbal lock), far outside this robot's workspace.
    """
    rpy = np.asarray(rpy, dtype=float)
    cp, sp = np.cos(rpy[..., 1]), np.sin(rpy[..., 1])
    cy, sy = np.cos(rpy[..., 2]), np.sin(rpy[..., 2])
    E = np.zeros(rpy.shape[:-1] + (3, 3))
    E[..., 0, 0] = cy * cp
    E[..., 1, 0] = sy * cp
    E[..., 2, 0] = -sp
    E[..., 0, 1] = -sy
    E[..., 1, 1] = cy
    E[..., 2, 2] = 1.0
    return E


def _skew(v: np.ndarray) -> np.ndarray:
    S = np.zeros(v.shape[:-1] + (3, 3))
    S[..., 0, 1], S[..., 0, 2] = -v[..., 2], v[..., 1]
    S[..., 1, 0], S[..., 1, 2] = v[..., 2], -v[..., 0]
    S[..., 2, 0], S[..., 2, 1] = -v[..., 1], v[..., 0]
    return S


def platform_joints(geometry: StewartGeometry, x) -> tuple[np.ndarray, np.ndarray]:
    """Platform joint centres of pose x (..., 6).

    Returns:
        q_B: (..., 6, 3) joint centres q_i in the base frame, m.
        r_B: (..., 6, 3) R_BE p_i, the lever arms from E's origin, base frame, m.
    """
    x = np.asarray(x, dtype=float)
    R = rotation_rpy(x[..., :3])
    r_B = np.einsum("...jk,ik->...ij", R, geometry.p_E)
    return r_B + x[..., None, 3:6], r_B


def _lmn(geometry: StewartGeometry, x):
    q_B, r_B = platform_joints(geometry, x)
    l = q_B - geometry.P_B                       # pivot to platform joint, (..., 6, 3)
    a, s = geometry.crank_length, geometry.rod_length
    L = np.sum(l * l, axis=-1) - (s * s - a * a)
    M = 2.0 * a * l[..., 2]
    N = 2.0 * a * np.sum(l * geometry.d_B, axis=-1)
    return L, M, N, q_B, r_B


def leg_reach_ratio(geometry: StewartGeometry, x) -> np.ndarray:
    """(..., 6) ratio L / sqrt(M^2 + N^2) per leg; |ratio| > 1 means the leg cannot close.

    Source: reference_geometry.md, "Closed-form inverse kinematics"; paper eq. 6's C/sqrt(A^2+B^2).
    """
    L, M, N, _, _ = _lmn(geometry, x)
    with np.errstate(divide="ignore", invalid="ignore"):
        return L / np.hypot(M, N)


def ik_unchecked(geometry: StewartGeometry, x) -> tuple[np.ndarray, np.ndarray]:
    """Vectorized IK without raising, for workspace sweeps.

    Returns:
        theta: (..., 6) motor angles in rad, NaN where a leg cannot close.
        ratio: (..., 6) L / sqrt(M^2 + N^2) per leg.
    """
    L, M, N, _, _ = _lmn(geometry, x)
    with np.errstate(divide="ignore", invalid="ignore"):
        ratio = L / np.hypot(M, N)
        theta = np.where(np.abs(ratio) <= 1.0,
                         np.arcsin(np.clip(ratio, -1.0, 1.0)) - np.arctan2(N, M), np.nan)
    return theta, ratio


def ik(geometry: StewartGeometry, x, t=None) -> np.ndarray:
    """Closed-form inverse kinematics: motor angles of the pose(s) x.

    Args:
        geometry: the robot.
        x: (6,) or (..., 6) pose [phi, theta, psi, X, Y, Z] in rad and m.
        t: optional times (s) matching the batch, only used to name the failure.
    Returns:
        (..., 6) motor angles theta_i in rad, leg order of reference_geometry.md:
        theta_i = asin(L / sqrt(M^2 + N^2)) - atan2(N, M).
    Raises:
        UnreachablePoseError: naming the first pose (and time) and the first leg with
            |L| / sqrt(M^2 + N^2) > 1.
    Source: paper eq. 6, rewritten for the reference geometry (docs/paper_notes.md).
    """
    x = np.asarray(x, dtype=float)
    theta, ratio = ik_unchecked(geometry, x)
    bad = ~(np.abs(ratio) <= 1.0)                # also catches NaN
    if np.any(bad):
        flat_bad = bad.reshape(-1, 6)
        k = int(np.argmax(flat_bad.any(axis=1)))
        leg = int(np.argmax(flat_bad[k]))
        t_k = None if t is None else float(np.asarray(t, dtype=float).reshape(-1)[k])
        raise UnreachablePoseError(leg, ratio.reshape(-1, 6)[k, leg], t=t_k,
                                   pose=x.reshape(-1, 6)[k])
    return theta


def _leg_terms(geometry: StewartGeometry, x, theta=None):
    """Per-leg vectors used by the Jacobian, statics and inertia, all (..., 6, 3)."""
    x = np.asarray(x, dtype=float)
    if theta is None:
        theta = ik(geometry, x)
    q_B, r_B = platform_joints(geometry, x)
    tip = geometry.crank_tips(theta)
    ell = q_B - tip
    c, s = np.cos(theta)[..., None], np.sin(theta)[..., None]
    e_N = -s * geometry.d_B + c * _Z           # crank-tip velocity direction per unit theta_dot
    E = angular_velocity_map(x[..., :3])
    # dq_i/dx = [-[r_i]x E, I]: (..., 6, 3, 6)
    Gq = np.zeros(r_B.shape + (6,))
    Gq[..., :3] = -np.einsum("...ijk,...kl->...ijl", _skew(r_B), E)
    Gq[..., 3:] = np.eye(3)
    return theta, q_B, r_B, tip, ell, e_N, E, Gq


def jacobian(geometry: StewartGeometry, x, theta=None) -> np.ndarray:
    """Analytic Jacobian J = d theta / d x of the inverse kinematics.

    Args:
        x: (..., 6) pose; theta: optional (..., 6) motor angles of x (saves one IK).
    Returns:
        (..., 6, 6), row i = (ell_i . dq_i/dx) / (a ell_i . e_N,i), rad per (rad or m);
        theta_dot = J @ x_dot with x_dot = [phi_dot, theta_dot, psi_dot, X_dot, Y_dot, Z_dot].
    Raises:
        UnreachablePoseError: if x is unreachable.
    Entries are inf at a singular pose (rod orthogonal to the crank-tip velocity).
    """
    theta, q_B, r_B, tip, ell, e_N, E, Gq = _leg_terms(geometry, x, theta)
    num = np.einsum("...ik,...ikl->...il", ell, Gq)
    den = geometry.crank_length * np.sum(ell * e_N, axis=-1)
    with np.errstate(divide="ignore", invalid="ignore"):
        return num / den[..., None]


def tau(geometry: StewartGeometry, x, theta=None) -> np.ndarray:
    """Wrench map tau: generalized force on the platform per unit motor torque, (..., 6, 6).

    By virtual work, T . d theta = w . d x, so w = J^T T and tau = J^T, with w conjugate to
    x = [phi, theta, psi, X, Y, Z] (N m per rad of roll/pitch/yaw, N along X, Y, Z).
    This is paper eq. 18 with its tau_2 corrected (1 / (a e_l . e_N) instead of e_l . e_N / a)
    and expressed in roll-pitch-yaw coordinates: tau = blockdiag(E^T, I) @ wrench_map(x).
    """
    return np.swapaxes(jacobian(geometry, x, theta), -1, -2)


def wrench_map(geometry: StewartGeometry, x, theta=None) -> np.ndarray:
    """Corrected paper eq. 18: [M_B; F_B] = W T, (..., 6, 6).

    M_B is the moment about E's origin and F_B the force on the platform, both in the base frame,
    for motor torques T (N m). Column i = [r_i x e_l,i ; e_l,i] / (a e_l,i . e_N,i), e_l the rod
    direction: a massless rod carries force F_i = T_i / (a e_l . e_N) along itself.
    Source: paper eqs. 11-18; the paper's eq. 15 multiplies by e_l . e_N where it must divide.
    """
    theta, q_B, r_B, tip, ell, e_N, E, Gq = _leg_terms(geometry, x, theta)
    e_l = ell / np.linalg.norm(ell, axis=-1, keepdims=True)
    tau1 = np.concatenate([np.cross(r_B, e_l), e_l], axis=-1)       # (..., 6 legs, 6)
    scale = 1.0 / (geometry.crank_length * np.sum(e_l * e_N, axis=-1))
    return np.swapaxes(tau1 * scale[..., None], -1, -2)


def wrench_map_paper_eq18(geometry: StewartGeometry, x, theta=None) -> np.ndarray:
    """Paper eq. 18 exactly as printed: tau_1 diag(e_l . e_N / |a|), (..., 6, 6).

    Kept to document the discrepancy (docs/paper_notes.md); use :func:`wrench_map` or :func:`tau`.
    """
    theta, q_B, r_B, tip, ell, e_N, E, Gq = _leg_terms(geometry, x, theta)
    e_l = ell / np.linalg.norm(ell, axis=-1, keepdims=True)
    tau1 = np.concatenate([np.cross(r_B, e_l), e_l], axis=-1)
    scale = np.sum(e_l * e_N, axis=-1) / geometry.crank_length
    return np.swapaxes(tau1 * scale[..., None], -1, -2)


def gravity_gradient(geometry: StewartGeometry, x, theta=None) -> np.ndarray:
    """dV/dx of the potential energy of platform, cranks and rods, (..., 6) in N m/rad and N.

    V = g [m_p Z + sum_i (m_c z_crank,i + m_r z_rod,i)], COMs at the geometric centres: the
    crank's at P_i + (a/2)(cos th d + sin th z), the rod's at the midpoint of tip_i and q_i.
    """
    theta, q_B, r_B, tip, ell, e_N, E, Gq = _leg_terms(geometry, x, theta)
    J = jacobian(geometry, x, theta)
    g = geometry.gravity
    a = geometry.crank_length
    dtheta_coeff = g * a * np.cos(theta) * (0.5 * geometry.crank_mass + 0.5 * geometry.rod_mass)
    grad = np.einsum("...i,...ij->...j", dtheta_coeff, J)
    grad = grad + 0.5 * geometry.rod_mass * g * np.sum(Gq[..., 2, :], axis=-2)
    grad[..., 5] += geometry.platform_mass * g
    return grad


def holding_torques(geometry: StewartGeometry, x, theta=None) -> np.ndarray:
    """Static motor torques that hold pose x against gravity, (..., 6) in N m.

    Solves J^T T = dV/dx (virtual work through the Jacobian; Drake's tree gravity term ignores the
    loop constraints). Includes the weight of the cranks and rods, not only the platform's.
    Raises:
        UnreachablePoseError: if x is unreachable.
        numpy.linalg.LinAlgError: at a singular pose.
    """
    theta = ik(geometry, x) if theta is None else theta
    J = jacobian(geometry, x, theta)
    return np.linalg.solve(np.swapaxes(J, -1, -2), gravity_gradient(geometry, x, theta)[..., None])[..., 0]


def task_inertia(geometry: StewartGeometry, x, theta=None) -> np.ndarray:
    """Task-space mass matrix M_x(x) of the whole closed chain, (..., 6, 6), SI units.

    Kinetic energy T = 1/2 x_dot^T M_x x_dot of the platform (in rpy coordinates), the cranks
    (about their shafts) and the rods (COM translation + rotation about axes normal to the rod;
    the rods' free spin carries no energy coupling). Exact for the reduced model; Coriolis terms
    are not included.
    """
    theta, q_B, r_B, tip, ell, e_N, E, Gq = _leg_terms(geometry, x, theta)
    J = jacobian(geometry, x, theta)
    a, s = geometry.crank_length, geometry.rod_length
    x = np.asarray(x, dtype=float)
    R = rotation_rpy(x[..., :3])
    I_E = np.diag(geometry.platform_inertia)
    I_B = R @ I_E @ np.swapaxes(R, -1, -2)
    M = np.zeros(x.shape[:-1] + (6, 6))
    M[..., :3, :3] = np.swapaxes(E, -1, -2) @ I_B @ E
    M[..., 3:, 3:] = geometry.platform_mass * np.eye(3)
    # Cranks: principal axis y is the shaft (x along the crank, z up at theta = 0).
    I_shaft = geometry.crank_inertia[1] + geometry.crank_mass * (0.5 * a) ** 2
    M = M + I_shaft * np.einsum("...ij,...ik->...jk", J, J)
    # Rods: velocity maps (..., 6, 3, 6) of the tip and the platform joint.
    V_tip = a * e_N[..., :, None] * J[..., :, None, :]
    V_com = 0.5 * (V_tip + Gq)
    W = np.einsum("...ijk,...ikl->...ijl", _skew(ell), Gq - V_tip) / (s * s)  # rod w, normal part
    M = M + geometry.rod_mass * np.einsum("...ijk,...ijl->...kl", V_com, V_com)
    M = M + geometry.rod_inertia[0] * np.einsum("...ijk,...ijl->...kl", W, W)
    return M
