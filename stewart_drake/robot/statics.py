"""Statics and dynamics of the closed chain: gravity by virtual work, holding torques, task
inertia, velocity-product forces and the motor torques a motion needs.

Drake's tree quantities (``CalcMassMatrix``, gravity generalized forces) ignore the six loop
constraints, so the closed chain's torques come from virtual work through the Jacobian
J = d theta / d x (:func:`~.kinematics.jacobian`): T . d theta = w . d x, w = J^T T. The task-space
equations of motion are those of the Lagrangian L = 1/2 x_dot^T M_x(x) x_dot - V(x) in the pose
coordinates x = [rpy, p]: M_x x_ddot + c(x, x_dot) + dV/dx = J^T T
(:func:`inverse_dynamics_torques`).
"""

from __future__ import annotations

from functools import lru_cache

import numpy as np

from ..base.errors import InvalidConfigError, SingularPoseError
from .kinematics import (
    DEFAULT_COND_THRESHOLD,
    X_HOME,
    LegTerms,
    RobotGeometry,
    checked_poses,
    finite_or_singular,
    ik,
    jacobian,
    jacobian_of,
    leg_terms,
    rotation_rpy,
    skew,
    wrench_map,
)
from .single_pose import LEG_SIZE, leg_rows, leg_vectors_single

#: Feed-forward modes of :func:`feedforward_torques`.
FEEDFORWARD_MODES = ("gravity", "inverse_dynamics", "none")


def gravity_gradient(geometry: RobotGeometry, x, theta=None, J=None) -> np.ndarray:
    """dV/dx of the potential energy of platform, cranks and rods, (..., 6) in N m/rad and N.

    V = g [m_p Z + sum_i (m_c z_crank,i + m_r z_rod,i)], COMs at the geometric centres: the
    crank's at P_i + (a_i/2)(cos th d_i + sin th w_i), the rod's at the midpoint of tip_i and q_i.
    Pass theta and J (the Jacobian at x) when already computed, to save work.
    """
    terms = leg_terms(geometry, x, ik(geometry, x) if theta is None else theta)
    return gravity_gradient_of(geometry, terms, jacobian_of(geometry, terms) if J is None else J)


def gravity_gradient_of(geometry: RobotGeometry, terms: LegTerms, J: np.ndarray) -> np.ndarray:
    """:func:`gravity_gradient` from the poses' :class:`~.kinematics.LegTerms` and Jacobian."""
    g = geometry.gravity
    a = geometry.crank_lengths
    # d(tip_z)/d theta_i = a_i e_N,z: cos theta_i exactly when w_i = z (d_i . z = 0).
    dtheta_coeff = g * a * terms.e_N[..., 2] * (0.5 * geometry.crank_mass + 0.5 * geometry.rod_mass)
    grad = np.einsum("...i,...ij->...j", dtheta_coeff, J)
    grad = grad + 0.5 * geometry.rod_mass * g * np.sum(terms.Gq[..., 2, :], axis=-2)
    grad[..., 5] += geometry.platform_mass * g
    return grad


def holding_torques(geometry: RobotGeometry, x, theta=None) -> np.ndarray:
    """Static motor torques that hold pose x against gravity, (..., 6) in N m.

    Solves J^T T = dV/dx (virtual work through the Jacobian; Drake's tree gravity term ignores the
    loop constraints). Includes the weight of the cranks and rods, not only the platform's.
    Args:
        x: (6,) or (..., 6) poses [rad, m]; theta: optional (..., 6) motor angles of x.
    Returns:
        (..., 6) finite torques, N m.
    Raises:
        UnreachablePoseError: if x is unreachable.
        SingularPoseError: J^T is singular (no torques hold the pose) or J is unbounded.
        InvalidConfigError: x or theta not (..., 6) or not finite.
    """
    x, theta = checked_poses(geometry, x, theta)
    terms = leg_terms(geometry, x, theta)
    J = finite_or_singular("J", jacobian_of(geometry, terms), x)
    grad = gravity_gradient_of(geometry, terms, J)
    try:
        T = np.linalg.solve(np.swapaxes(J, -1, -2), grad[..., None])[..., 0]
    except np.linalg.LinAlgError:
        cond = np.linalg.cond(J.reshape(-1, 6, 6))
        k = int(np.argmax(np.where(np.isfinite(cond), cond, np.inf)))
        raise SingularPoseError(
            "cond", np.inf, DEFAULT_COND_THRESHOLD, pose=x.reshape(-1, 6)[k]
        ) from None
    return finite_or_singular("T", T, x)


#: The tool tip in the platform frame E, m: the end of the tool drawn on the platform (8 cm up),
#: where the station's ``tool_wrench`` acts.
p_ETool = np.array([0.0, 0.0, 0.08])


def tool_load_torques(geometry: RobotGeometry, x, wrench_W, p_EP=p_ETool) -> np.ndarray:
    """Static motor torques that hold pose x against gravity AND a wrench on the tool, (6,) N m.

    Equilibrium of the platform: the motors' wrench (:func:`~.kinematics.wrench_map`) balances
    gravity (:func:`holding_torques`) and the external wrench [torque (3) N m, force (3) N] in
    the world frame, applied at p_EP on the platform (default the tool tip). What a disturbance
    costs the motors before any control: if it exceeds their peak torque, no controller can
    hold the pose.

    Args:
        x: (6,) pose [rad, m]; wrench_W: (6,) [torque, force]; p_EP: (3,) m in the platform frame.
    Raises:
        as :func:`holding_torques` (UnreachablePoseError, SingularPoseError, InvalidConfigError).
    """
    x = np.asarray(x, dtype=float)
    w = np.asarray(wrench_W, dtype=float)
    r_W = rotation_rpy(x[:3]) @ np.asarray(p_EP, dtype=float)
    moment = w[:3] + np.cross(r_W, w[3:])  # about the platform origin
    T_ext = np.linalg.solve(wrench_map(geometry, x), -np.concatenate([moment, w[3:]]))
    return holding_torques(geometry, x) + T_ext


def task_inertia(geometry: RobotGeometry, x, theta=None) -> np.ndarray:
    """Task-space mass matrix M_x(x) of the whole closed chain, (..., 6, 6), SI units.

    Kinetic energy T = 1/2 x_dot^T M_x x_dot of the platform (in rpy coordinates), the cranks
    (about their shafts) and the rods (COM translation + rotation about axes normal to the rod;
    the rods' free spin carries no energy coupling). Exact for the reduced model; Coriolis terms
    are not included.
    """
    terms = leg_terms(geometry, x, ik(geometry, x) if theta is None else theta)
    return task_inertia_of(geometry, terms, jacobian_of(geometry, terms))


def task_inertia_of(geometry: RobotGeometry, terms: LegTerms, J: np.ndarray) -> np.ndarray:
    """:func:`task_inertia` from the poses' :class:`~.kinematics.LegTerms` and Jacobian."""
    return _inertia_from_terms(geometry, terms.R, J, terms.ell, terms.e_N, terms.E, terms.Gq)


def task_inertia_single(geometry: RobotGeometry, cache: tuple, J: np.ndarray) -> np.ndarray:
    """:func:`task_inertia` (6, 6) of ONE pose, from :func:`~.single_pose.ik_single`'s cache and
    its Jacobian J (:func:`~.single_pose.jacobian_single`): the per-step path of the gain
    re-scheduling (equal to the batched function; a test holds them to 1e-12)."""
    R, r_B = cache[1], cache[2]
    ell, e_N, E = leg_vectors_single(geometry, cache)
    Gq = np.zeros((6, 3, 6))
    Gq[:, :, :3] = -skew(r_B) @ E
    Gq[:, :, 3:] = np.eye(3)
    return _inertia_from_terms(geometry, R, J, ell, e_N, E, Gq)


def _inertia_from_terms(geometry, R, J, ell, e_N, E, Gq) -> np.ndarray:
    """The task inertia from the leg terms (batched or single; see :func:`task_inertia`)."""
    a, s = geometry.crank_lengths, geometry.rod_lengths
    I_B = R @ np.diag(geometry.platform_inertia) @ np.swapaxes(R, -1, -2)
    M = np.zeros(J.shape[:-2] + (6, 6))
    M[..., :3, :3] = np.swapaxes(E, -1, -2) @ I_B @ E
    M[..., 3:, 3:] = geometry.platform_mass * np.eye(3)
    # Cranks: principal axis y is the shaft (x along the crank, z = w_i at theta = 0), with the
    # motor's rotor behind its gearhead.
    I_shaft = geometry.shaft_inertias
    if np.all(I_shaft == I_shaft[0]):  # one inertia: scaling J^T J rounds as it always has
        M = M + I_shaft[0] * (np.swapaxes(J, -1, -2) @ J)
    else:
        M = M + np.swapaxes(J, -1, -2) @ (I_shaft[:, None] * J)
    # Rods: velocity maps (..., 6, 3, 6) of the tip and the platform joint; sums over the legs
    # as one (18, 6) product (matmul, several times faster than einsum on one pose).
    V_tip = a[:, None, None] * e_N[..., :, None] * J[..., :, None, :]
    V_com = (0.5 * (V_tip + Gq)).reshape(J.shape[:-2] + (18, 6))
    W = ((skew(ell) @ (Gq - V_tip)) / (s * s)[:, None, None]).reshape(J.shape[:-2] + (18, 6))
    M = M + geometry.rod_mass * (np.swapaxes(V_com, -1, -2) @ V_com)
    M = M + geometry.rod_inertia[0] * (np.swapaxes(W, -1, -2) @ W)
    return M


#: Forward-difference step of :func:`coriolis_forces`, rad or m.
CORIOLIS_STEP = 1e-7


def coriolis_forces(
    geometry: RobotGeometry, x, x_dot, step: float = CORIOLIS_STEP, M=None
) -> np.ndarray:
    """Velocity-product forces c(x, x_dot) of the task-space dynamics, (..., 6) in N m and N.

    c_i = sum_jk (dM_ij/dx_k - 1/2 dM_jk/dx_i) x_dot_j x_dot_k: the Coriolis and centrifugal
    terms of the Lagrangian 1/2 x_dot^T M_x(x) x_dot (M_x from :func:`task_inertia`), with the six
    derivatives dM_x/dx_k by forward differences (six more evaluations of M_x, vectorized over
    the batch; relative error about ``step``).

    Args:
        x: (..., 6) reachable poses [rad, m]; x_dot: (..., 6) rates [rad/s, m/s].
        step: finite-difference step in rad or m.
        M: M_x(x) when already computed.
    Raises:
        UnreachablePoseError: a pose (or a pose ``step`` away) cannot be reached.
    """
    x = np.asarray(x, dtype=float)
    x_dot = np.asarray(x_dot, dtype=float)
    M = task_inertia(geometry, x) if M is None else M
    c = np.zeros(np.broadcast_shapes(x.shape, x_dot.shape))
    for k in range(6):
        e = np.zeros(6)
        e[k] = step
        dM = (task_inertia(geometry, x + e) - M) / step  # dM/dx_k
        dM_x_dot = np.einsum("...ij,...j->...i", dM, x_dot)
        c += dM_x_dot * x_dot[..., k : k + 1]  # (dM/dx_k x_dot) x_dot_k
        c[..., k] -= 0.5 * np.einsum("...i,...i->...", x_dot, dM_x_dot)  # 1/2 x_dot^T dM_k x_dot
    return c


def inverse_dynamics_torques(geometry: RobotGeometry, x, x_dot, x_ddot, theta=None) -> np.ndarray:
    """Motor torques that move the closed chain along (x, x_dot, x_ddot), (..., 6) in N m.

    T = J^-T (M_x x_ddot + c(x, x_dot) + dV/dx): the task-space equations of motion (module
    docstring) with the motors' reflected inertia in M_x (``geometry.motor_reflected_inertia``);
    no friction (:func:`motor_effort` adds a servo's). The rods' free spin about their own axes
    (Table I: 1e-6 kg m^2) is left out. A test holds this to Drake's inverse dynamics of the tree
    projected on the closed chain's motions (:func:`~.closed_chain.closed_chain_inverse_dynamics`).

    Args:
        x, x_dot, x_ddot: (..., 6) pose [rad, m], rate [rad/s, m/s], acceleration [rad/s^2, m/s^2].
        theta: (..., 6) motor angles of x when already known.
    Raises:
        UnreachablePoseError: x leaves the workspace. SingularPoseError: J^T is singular.
    """
    x, theta = checked_poses(geometry, x, theta)
    terms = leg_terms(geometry, x, theta)
    J = finite_or_singular("J", jacobian_of(geometry, terms), x)
    return inverse_dynamics_of(geometry, x, x_dot, x_ddot, terms, J)


def inverse_dynamics_of(
    geometry: RobotGeometry, x, x_dot, x_ddot, terms: LegTerms, J: np.ndarray
) -> np.ndarray:
    """:func:`inverse_dynamics_torques` of checked poses x from their
    :class:`~.kinematics.LegTerms` and finite Jacobian J (computed once for the checks of a
    path, :func:`~.limits.validate_trajectory`).

    Raises:
        UnreachablePoseError: a pose a finite-difference step from x cannot be reached.
        SingularPoseError: J^T is singular.
    """
    M = task_inertia_of(geometry, terms, J)
    w = (
        gravity_gradient_of(geometry, terms, J)
        + np.einsum("...ij,...j->...i", M, np.asarray(x_ddot, dtype=float))
        + coriolis_forces(geometry, x, x_dot, M=M)
    )
    T = np.linalg.solve(np.swapaxes(J, -1, -2), w[..., None])[..., 0]
    return finite_or_singular("T", T, x)


def motor_effort(geometry: RobotGeometry, x, x_dot, x_ddot, servo=None):
    """What the motors must give for a motion: torques and speeds at the crank shafts.

    Args:
        x, x_dot, x_ddot: (..., 6) pose, rate and acceleration of the platform (SI).
        servo: a :class:`~.servo.ServoModel` whose viscous and Coulomb friction the motors must
            also overcome, or None (ideal torque sources). Its reflected inertia is the
            geometry's ``motor_reflected_inertia`` (``Scenario.geometry()`` sets it).
    Returns:
        (T, theta_dot): (..., 6) torques in N m (:func:`inverse_dynamics_torques` plus friction
        b theta_dot + F_c sign(theta_dot)) and (..., 6) crank rates theta_dot = J x_dot in rad/s.
    Raises:
        as :func:`inverse_dynamics_torques`.
    """
    x, theta = checked_poses(geometry, x, None)
    terms = leg_terms(geometry, x, theta)
    J = finite_or_singular("J", jacobian_of(geometry, terms), x)
    return motor_effort_of(geometry, x, x_dot, x_ddot, servo, terms, J)


def motor_effort_of(geometry: RobotGeometry, x, x_dot, x_ddot, servo, terms: LegTerms, J):
    """:func:`motor_effort` of checked poses x from their :class:`~.kinematics.LegTerms` and
    finite Jacobian J (the validator of a path computes them once for all its checks).

    Raises:
        as :func:`inverse_dynamics_of`.
    """
    theta_dot = np.einsum("...ij,...j->...i", J, np.asarray(x_dot, dtype=float))
    T = inverse_dynamics_of(geometry, x, x_dot, x_ddot, terms, J)
    if servo is not None:
        T = T + servo.viscous_damping * theta_dot + servo.coulomb_friction_Nm * np.sign(theta_dot)
    return T, theta_dot


def motor_effort_compiled(geometry: RobotGeometry, x, x_dot, x_ddot, servo, theta, J):
    """:func:`motor_effort_of` with the inverse dynamics compiled
    (:func:`~.path_kernels.effort`, pose by pose, the same forward differences): what the
    validator of a path runs on every sample, in about a tenth of the time. The crank rates are
    the numpy form's to the last bit; the torques differ by up to 5e-10 of their peak (2e-10 on
    the paper manoeuvre): the forward differences divide the rounding of M_x, summed in another
    order than numpy's BLAS sums it, by their step, and each form is 2e-8 of the peak from the
    same differences in exact arithmetic at the top of the workspace. A pose the compiled form
    cannot finish (a pose a step away unreachable, J^T exactly singular, a torque not finite) is
    left to the numpy form, for its error.

    Args:
        x, x_dot, x_ddot: (n, 6) reachable poses [rad, m], their rates and accelerations (SI).
        servo: a :class:`~.servo.ServoModel` or None, as :func:`motor_effort`.
        theta: (n, 6) the poses' motor angles, rad. J: (n, 6, 6) their finite Jacobians.
    Returns:
        (T, theta_dot): (n, 6) torques in N m and crank rates in rad/s.
    Raises:
        as :func:`inverse_dynamics_of`.
    """
    from .path_kernels import effort

    x = np.ascontiguousarray(x, dtype=float)
    x_dot = np.ascontiguousarray(x_dot, dtype=float)
    theta = np.ascontiguousarray(theta, dtype=float)
    legs, body = kernel_constants(geometry)
    T = np.empty(x.shape)
    status = np.empty(x.shape[0], dtype=np.int64)
    if effort(x, x_dot, np.ascontiguousarray(x_ddot, dtype=float), theta, legs, body, T, status):
        terms = leg_terms(geometry, x, theta)
        return motor_effort_of(geometry, x, x_dot, x_ddot, servo, terms, J)
    theta_dot = np.einsum("...ij,...j->...i", J, x_dot)
    if servo is not None:
        T = T + servo.viscous_damping * theta_dot + servo.coulomb_friction_Nm * np.sign(theta_dot)
    return T, theta_dot


@lru_cache(maxsize=32)
def kernel_constants(geometry: RobotGeometry) -> tuple[np.ndarray, np.ndarray]:
    """(legs (6, :data:`~.single_pose.LEG_SIZE`) per leg the columns of
    :data:`~.single_pose.LEG_COLUMNS`, body (:data:`~.path_kernels.BODY`)) of ``geometry``
    for the compiled kernels of :mod:`.path_kernels` and the LQI's re-schedule, read-only;
    each constant computed as the numpy form computes it (s_i^2 - a_i^2 as s s - a a)."""
    from .path_kernels import BODY

    a, s = geometry.crank_lengths, geometry.rod_lengths
    legs = np.array(leg_rows(geometry, s * s - a * a), dtype=float).reshape(6, LEG_SIZE)
    values = {
        "platform_Ixx": geometry.platform_inertia[0],
        "platform_Iyy": geometry.platform_inertia[1],
        "platform_Izz": geometry.platform_inertia[2],
        "platform_mass": geometry.platform_mass,
        "rod_mass": geometry.rod_mass,
        "rod_inertia": geometry.rod_inertia[0],
        "gravity": geometry.gravity,
        "crank_mass": geometry.crank_mass,
        "step": CORIOLIS_STEP,
    }
    body = np.array([float(values[name]) for name in BODY])
    legs.setflags(write=False)
    body.setflags(write=False)
    return legs, body


def crank_inertia_matrix(geometry: RobotGeometry, x=X_HOME) -> np.ndarray:
    """Joint-space inertia M_theta = J^-T M_x J^-1 of the closed chain at pose x, (6, 6) kg m^2."""
    theta = ik(geometry, x)
    J_inv = np.linalg.inv(jacobian(geometry, x, theta))
    return J_inv.T @ task_inertia(geometry, x, theta) @ J_inv


def feedforward_torques(
    geometry: RobotGeometry, x_d, xdd_d=None, mode: str = "gravity", theta=None, xd_d=None
) -> np.ndarray:
    """Motor torques that hold (or accelerate) the platform along the reference, (..., 6) N m.

    Args:
        geometry: the robot the controller believes in (a payload it does not know is not here).
        x_d: (..., 6) reference pose [rad, m].
        xdd_d: (..., 6) reference acceleration [rad/s^2, m/s^2]; used by "inverse_dynamics".
        mode: "gravity": J^-T dV/dx, the static virtual-work torques of platform, cranks and rods
            (paper eq. 19's disturbance d, cancelled); "inverse_dynamics": also J^-T M_x(x_d)
            xdd_d and, when ``xd_d`` is given, the velocity-product forces
            (:func:`inverse_dynamics_torques`); "none": zeros.
        theta: (..., 6) motor angles of x_d when already known (IK is then skipped).
        xd_d: (..., 6) reference rate [rad/s, m/s] for the inverse dynamics' Coriolis terms.
    Raises:
        InvalidConfigError: unknown mode. UnreachablePoseError: x_d leaves the workspace.
    Source: virtual work through the Jacobian (tree gravity terms ignore the loop constraints).
    """
    _check_feedforward_mode(mode)
    x_d = np.asarray(x_d, dtype=float)
    if mode == "none":
        return np.zeros(x_d.shape)
    x_d, theta = checked_poses(geometry, x_d, theta)
    return feedforward_unchecked(geometry, x_d, theta, xdd_d, mode, xd_d)


def feedforward_unchecked(
    geometry: RobotGeometry, x_d, theta, xdd_d=None, mode: str = "gravity", xd_d=None
) -> np.ndarray:
    """:func:`feedforward_torques` of poses x_d (..., 6) already checked, with their motor
    angles theta (..., 6) (the reference's table, :func:`~stewart_drake.run.reference.
    sample_reference`, after its inverse kinematics): the arguments are not checked again.

    Raises:
        InvalidConfigError: an unknown mode, or "inverse_dynamics" without xdd_d.
        SingularPoseError: J is unbounded at a pose, or J^T singular.
    """
    _check_feedforward_mode(mode)
    if mode == "none":
        return np.zeros(np.shape(x_d))
    terms = leg_terms(geometry, x_d, theta)
    J = finite_or_singular("J", jacobian_of(geometry, terms), x_d)
    w = gravity_gradient_of(geometry, terms, J)
    if mode == "inverse_dynamics":
        if xdd_d is None:
            raise InvalidConfigError(
                "feedforward 'inverse_dynamics' needs the reference acceleration xdd_d"
            )
        if xd_d is not None:
            return inverse_dynamics_of(geometry, x_d, xd_d, xdd_d, terms, J)
        M = task_inertia_of(geometry, terms, J)
        w = w + np.einsum("...ij,...j->...i", M, np.asarray(xdd_d, dtype=float))
    return np.linalg.solve(np.swapaxes(J, -1, -2), w[..., None])[..., 0]


def _check_feedforward_mode(mode: str) -> None:
    if mode not in FEEDFORWARD_MODES:
        raise InvalidConfigError(f"feedforward must be one of {FEEDFORWARD_MODES}, got {mode!r}")
