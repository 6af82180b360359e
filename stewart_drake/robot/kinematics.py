"""Closed-form kinematics of the rotary Stewart platform (pure numpy, no Drake plant).

Pose x = [phi, theta, psi, X, Y, Z] (rad, rad, rad, m, m, m): orientation of E in B as Drake's
RollPitchYaw, R_BE = Rz(psi) Ry(theta) Rx(phi), and the position p_BE of E's origin. Every function
takes a single pose (6,) or a batch (..., 6) and broadcasts; motor angles theta are (..., 6) in rad.

Per leg i (reference_geometry.md; docs/robot.md, "Per-leg geometry"):
    q_i = R_BE p_i + p_BE          platform joint centre, base frame
    tip_i = P_i + a_i (cos theta_i d_i + sin theta_i w_i)   (w_i = z untilted)
    ell_i = q_i - tip_i             rod vector, |ell_i| = s_i

The functions take the robot as ``geometry``, a
:class:`~stewart_drake.robot.geometry.StewartGeometry`, read through the attributes
:class:`RobotGeometry` names (this module sits below the geometry, which checks itself with it).
Forward kinematics is in :mod:`.forward_kinematics`, statics in :mod:`.statics`, the limits and
the reference validator in :mod:`.limits`; all read the per-leg vectors of :func:`leg_terms`.
The one-pose forms of the control period (plain floats, small arrays) are in :mod:`.single_pose`.
"""

from typing import NamedTuple, Protocol, runtime_checkable

import numpy as np

from ..base.checks import as_array, as_poses
from ..base.errors import (
    InvalidConfigError,
    SingularPoseError,
    UnreachablePoseError,
)

#: Home pose [phi, theta, psi, X, Y, Z] in rad and m (docs/reference_geometry.md).
X_HOME = np.array([0.0, 0.0, 0.0, 0.0, 0.0, 0.30])
#: The names of the pose's six coordinates, in order: roll, pitch, yaw (rad), position (m).
AXIS_NAMES = ("phi", "theta", "psi", "X", "Y", "Z")
#: Display units of a pose error per axis: mrad for angles, mm for positions.
AXIS_UNITS = ("mrad", "mrad", "mrad", "mm", "mm", "mm")

#: Default threshold on cond(J) (SI units, J in rad per rad and rad per m). The reference robot
#: has cond(J) = 43.7 at home and at most 77.7 along the paper manoeuvre (eqs. 37-38); the random
#: reachable poses of the tests are drawn below 200. Used by :mod:`~.limits` (re-exported there).
DEFAULT_COND_THRESHOLD = 200.0
X_HOME.setflags(write=False)


@runtime_checkable
class RobotGeometry(Protocol):
    """The robot as the functions of the model layer read it: these attributes of
    :class:`~stewart_drake.robot.geometry.StewartGeometry` (names, units and meanings there).

    A structural type: the geometry checks itself with these functions (a robot that cannot
    close its legs at home is refused when it is built), so this module sits below it and cannot
    import it.
    """

    # Read-only properties: StewartGeometry is a frozen dataclass (and computes P_B), which a
    # protocol's plain, settable attributes would not accept.
    @property
    def crank_length(self) -> float: ...
    @property
    def rod_length(self) -> float: ...
    @property
    def crank_lengths(self) -> np.ndarray: ...
    @property
    def rod_lengths(self) -> np.ndarray: ...
    @property
    def shaft_inertias(self) -> np.ndarray: ...
    @property
    def encoder_offsets(self) -> np.ndarray: ...
    @property
    def P_B(self) -> np.ndarray: ...
    @property
    def p_E(self) -> np.ndarray: ...
    @property
    def d_B(self) -> np.ndarray: ...
    @property
    def w_B(self) -> np.ndarray: ...
    @property
    def u_B(self) -> np.ndarray: ...
    @property
    def motor_angle_min_deg(self) -> float: ...
    @property
    def motor_angle_max_deg(self) -> float: ...
    @property
    def crank_joint_cone_deg(self) -> float: ...
    @property
    def platform_joint_cone_deg(self) -> float: ...
    @property
    def platform_mass(self) -> float: ...
    @property
    def platform_inertia(self) -> tuple: ...
    @property
    def crank_mass(self) -> float: ...
    @property
    def crank_inertia(self) -> tuple: ...
    @property
    def rod_mass(self) -> float: ...
    @property
    def rod_inertia(self) -> tuple: ...
    @property
    def motor_reflected_inertia(self) -> float: ...
    @property
    def gravity(self) -> float: ...

    def crank_tips(self, theta) -> np.ndarray:
        """(..., 6, 3) crank-tip joint centres for motor angles theta (..., 6), base frame."""

    def __hash__(self) -> int:
        """Hashable: caches (functools.lru_cache) key on the geometry."""


_NEXT, _PREV = [1, 2, 0], [2, 0, 1]  # (a x b)_k = a_{k+1} b_{k+2} - a_{k+2} b_{k+1}


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


def skew(v: np.ndarray) -> np.ndarray:
    """(..., 3, 3) cross-product matrices [v]x of vectors v (..., 3): [v]x w = v x w."""
    S = np.zeros(v.shape[:-1] + (3, 3))
    S[..., 0, 1], S[..., 0, 2] = -v[..., 2], v[..., 1]
    S[..., 1, 0], S[..., 1, 2] = v[..., 2], -v[..., 0]
    S[..., 2, 0], S[..., 2, 1] = -v[..., 1], v[..., 0]
    return S


def platform_joints(geometry: RobotGeometry, x) -> tuple[np.ndarray, np.ndarray]:
    """Platform joint centres of pose x (..., 6).

    Returns:
        q_B: (..., 6, 3) joint centres q_i in the base frame, m.
        r_B: (..., 6, 3) R_BE p_i, the lever arms from E's origin, base frame, m.
    """
    x = np.asarray(x, dtype=float)
    R = rotation_rpy(x[..., :3])
    r_B = np.einsum("...jk,ik->...ij", R, geometry.p_E)
    return r_B + x[..., None, 3:6], r_B


def _lmn(geometry: RobotGeometry, x):
    q_B, r_B = platform_joints(geometry, x)
    l = q_B - geometry.P_B  # pivot to platform joint, (..., 6, 3)
    a, s = geometry.crank_lengths, geometry.rod_lengths
    L = np.sum(l * l, axis=-1) - (s * s - a * a)
    # l . w_i is l_z exactly when w_i = z (the products with its zeros are exact zeros).
    M = 2.0 * a * np.sum(l * geometry.w_B, axis=-1)
    N = 2.0 * a * np.sum(l * geometry.d_B, axis=-1)
    return L, M, N, q_B, r_B


def leg_reach_ratio(geometry: RobotGeometry, x) -> np.ndarray:
    """(..., 6) ratio L / sqrt(M^2 + N^2) per leg; |ratio| > 1 means the leg cannot close.

    Args:
        x: (6,) or (..., 6) finite poses [phi, theta, psi, X, Y, Z] in rad and m.
    Returns:
        (..., 6), never NaN: +-inf only for a platform joint exactly on its motor's shaft
        axis (M = N = 0) at the wrong distance (no crank angle closes the leg); 0 there at the
        right distance (every crank angle does).
    Raises:
        InvalidConfigError: x not (..., 6), not finite, or a position beyond 1 km.
    Source: reference_geometry.md, "Closed-form inverse kinematics"; paper eq. 6's C/sqrt(A^2+B^2).
    """
    L, M, N, _, _ = _lmn(geometry, as_poses("pose x", x))
    h = np.hypot(M, N)
    with np.errstate(divide="ignore", invalid="ignore"):
        ratio = L / h
    if not np.isfinite(ratio).all():  # only where h == 0 (finite poses, |p| <= 1 km)
        ratio = np.where(h == 0, np.where(L == 0, 0.0, np.copysign(np.inf, L)), ratio)
    return ratio


def ik_angles(ratio, M, N) -> np.ndarray:
    """The closed-form IK's motor angles from each leg's terms, the one numpy form of
    theta = asin(L / sqrt(M^2 + N^2)) - atan2(N, M) (:func:`ik`; the scalar form, which the
    controller compiles, is :func:`~.single_pose.ik_scalar`).

    Args:
        ratio: (..., 6) L / sqrt(M^2 + N^2). M, N: (..., 6) the leg's terms, m^2.
    Returns:
        (..., 6) rad; NaN where |ratio| > 1 or is NaN (the leg cannot close).
    """
    # No floating-point flag to silence: the clip keeps the arcsine's argument in [-1, 1], a NaN
    # passes quietly, and atan2 is defined everywhere.
    return np.where(
        np.abs(ratio) <= 1.0, np.arcsin(np.clip(ratio, -1.0, 1.0)) - np.arctan2(N, M), np.nan
    )


def ik_unchecked(geometry: RobotGeometry, x) -> tuple[np.ndarray, np.ndarray]:
    """Vectorized IK without raising, for workspace sweeps.

    Returns:
        theta: (..., 6) motor angles in rad, NaN where a leg cannot close.
        ratio: (..., 6) L / sqrt(M^2 + N^2) per leg.
    """
    L, M, N, _, _ = _lmn(geometry, x)
    with np.errstate(divide="ignore", invalid="ignore"):
        ratio = L / np.hypot(M, N)
    return ik_angles(ratio, M, N), ratio


def ik(geometry: RobotGeometry, x, t=None) -> np.ndarray:
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
        InvalidConfigError: x not (..., 6), not finite, or a position beyond 1 km.
    Source: paper eq. 6, rewritten for the reference geometry (docs/paper_notes.md).
    """
    x = as_poses("pose x", x)
    theta, ratio = ik_unchecked(geometry, x)
    bad = ~(np.abs(ratio) <= 1.0)  # also catches NaN
    if np.any(bad):
        flat_bad = bad.reshape(-1, 6)
        k = int(np.argmax(flat_bad.any(axis=1)))
        leg = int(np.argmax(flat_bad[k]))
        t_k = None if t is None else float(np.asarray(t, dtype=float).reshape(-1)[k])
        raise UnreachablePoseError(
            leg, ratio.reshape(-1, 6)[k, leg], t=t_k, pose=x.reshape(-1, 6)[k]
        )
    return theta


class LegTerms(NamedTuple):
    """The per-leg vectors of poses x (..., 6) that the Jacobian, the statics and the limits
    read (:func:`leg_terms`), computed once for all of them; base frame, SI units.

    Attributes:
        theta: (..., 6) motor angles, rad (NaN where a leg cannot close).
        q_B: (..., 6, 3) platform joint centres q_i. r_B: (..., 6, 3) their lever arms R_BE p_i.
        tip: (..., 6, 3) crank tips. ell: (..., 6, 3) rod vectors q_i - tip_i.
        e_N: (..., 6, 3) crank-tip velocity directions per unit theta_dot.
        E: (..., 3, 3) the angular velocity map of the rpy (:func:`angular_velocity_map`).
        Gq: (..., 6, 3, 6) dq_i/dx = [-[r_i]x E, I].
        R: (..., 3, 3) R_BE (:func:`rotation_rpy`).
    """

    theta: np.ndarray
    q_B: np.ndarray
    r_B: np.ndarray
    tip: np.ndarray
    ell: np.ndarray
    e_N: np.ndarray
    E: np.ndarray
    Gq: np.ndarray
    R: np.ndarray

    def rows(self, index) -> "LegTerms":
        """The terms of the poses ``index`` (an index array into the batch's first axis)."""
        return LegTerms(*(a[index] for a in self))


def leg_terms(geometry: RobotGeometry, x, theta) -> LegTerms:
    """The :class:`LegTerms` of poses x (..., 6) with their motor angles theta (..., 6) (NaN
    angles give NaN terms). Not validated."""
    x = np.asarray(x, dtype=float)
    R = rotation_rpy(x[..., :3])
    r_B = np.einsum("...jk,ik->...ij", R, geometry.p_E)
    q_B = r_B + x[..., None, 3:6]
    tip = geometry.crank_tips(theta)
    ell = q_B - tip
    c, s = np.cos(theta)[..., None], np.sin(theta)[..., None]
    e_N = -s * geometry.d_B + c * geometry.w_B  # crank-tip velocity direction per theta_dot
    E = angular_velocity_map(x[..., :3])
    # dq_i/dx = [-[r_i]x E, I]: (..., 6, 3, 6)
    Gq = np.zeros(r_B.shape + (6,))
    Gq[..., :3] = -np.einsum("...ijk,...kl->...ijl", skew(r_B), E)
    Gq[..., 3:] = np.eye(3)
    return LegTerms(theta, q_B, r_B, tip, ell, e_N, E, Gq, R)


def checked_poses(geometry: RobotGeometry, x, theta=None):
    """(x, theta) validated for the public Jacobian-based functions (here and in
    :mod:`.statics`); theta from :func:`ik` when not given.

    Raises:
        InvalidConfigError: x or theta not (..., 6) or not finite, or of different shapes.
        UnreachablePoseError: theta not given and a pose unreachable.
    """
    x = as_poses("pose x", x)
    if theta is None:
        return x, ik(geometry, x)
    theta = as_array("motor angles theta", theta, last=6)
    if theta.shape != x.shape:
        raise InvalidConfigError(f"theta {theta.shape} must match the poses x {x.shape}")
    return x, theta


def finite_or_singular(name: str, value: np.ndarray, x: np.ndarray) -> np.ndarray:
    """``value`` if finite, else SingularPoseError naming the first pose of x where it is not."""
    if np.isfinite(value).all():
        return value
    bad = ~np.isfinite(value.reshape(x.reshape(-1, 6).shape[0], -1)).all(axis=1)
    raise SingularPoseError(name, np.inf, np.inf, pose=x.reshape(-1, 6)[int(np.argmax(bad))])


def jacobian(geometry: RobotGeometry, x, theta=None) -> np.ndarray:
    """Analytic Jacobian J = d theta / d x of the inverse kinematics.

    Args:
        x: (..., 6) pose; theta: optional (..., 6) motor angles of x (saves one IK).
    Returns:
        (..., 6, 6), finite, row i = (ell_i . dq_i/dx) / (a_i ell_i . e_N,i), rad per (rad or m);
        theta_dot = J @ x_dot with x_dot = [phi_dot, theta_dot, psi_dot, X_dot, Y_dot, Z_dot].
    Raises:
        UnreachablePoseError: if x is unreachable.
        SingularPoseError: at a pose where a rod is exactly orthogonal to its crank-tip
            velocity (J unbounded; :func:`singular_values` reports it as inf instead).
        InvalidConfigError: x or theta not (..., 6) or not finite.
    """
    x, theta = checked_poses(geometry, x, theta)
    return finite_or_singular("J", jacobian_unchecked(geometry, x, theta), x)


def jacobian_unchecked(geometry: RobotGeometry, x, theta=None) -> np.ndarray:
    """:func:`jacobian` without checks: entries inf (or NaN) at a singular pose, NaN where x is
    unreachable; for Newton steps and singular values, which handle those themselves. theta:
    the motor angles of x (default :func:`ik`, which raises for an unreachable pose)."""
    theta = ik(geometry, x) if theta is None else theta
    return jacobian_of(geometry, leg_terms(geometry, x, theta))


def jacobian_of(geometry: RobotGeometry, terms: LegTerms) -> np.ndarray:
    """:func:`jacobian_unchecked` from the :class:`LegTerms` of the poses (computed once for
    the Jacobian, the statics and the limits)."""
    num = np.einsum("...ik,...ikl->...il", terms.ell, terms.Gq)
    den = geometry.crank_lengths * np.sum(terms.ell * terms.e_N, axis=-1)
    with np.errstate(divide="ignore", invalid="ignore"):
        return num / den[..., None]


def tau(geometry: RobotGeometry, x, theta=None) -> np.ndarray:
    """Wrench map tau: generalized force on the platform per unit motor torque, (..., 6, 6).

    By virtual work, T . d theta = w . d x, so w = J^T T and tau = J^T, with w conjugate to
    x = [phi, theta, psi, X, Y, Z] (N m per rad of roll/pitch/yaw, N along X, Y, Z).
    This is paper eq. 18 with its tau_2 corrected (1 / (a e_l . e_N) instead of e_l . e_N / a)
    and expressed in roll-pitch-yaw coordinates: tau = blockdiag(E^T, I) @ wrench_map(x).

    Raises:
        as :func:`jacobian` (UnreachablePoseError, SingularPoseError, InvalidConfigError).
    """
    return np.swapaxes(jacobian(geometry, x, theta), -1, -2)


def wrench_map(geometry: RobotGeometry, x, theta=None) -> np.ndarray:
    """Corrected paper eq. 18: [M_B; F_B] = W T, (..., 6, 6).

    M_B is the moment about E's origin and F_B the force on the platform, both in the base frame,
    for motor torques T (N m). Column i = [r_i x e_l,i ; e_l,i] / (a_i e_l,i . e_N,i), e_l the
    rod direction: a massless rod carries force F_i = T_i / (a_i e_l . e_N) along itself.
    Raises:
        as :func:`jacobian` (UnreachablePoseError, SingularPoseError, InvalidConfigError).
    Source: paper eqs. 11-18; the paper's eq. 15 multiplies by e_l . e_N where it must divide.
    """
    x, theta = checked_poses(geometry, x, theta)
    terms = leg_terms(geometry, x, theta)
    e_l = terms.ell / np.linalg.norm(terms.ell, axis=-1, keepdims=True)
    tau1 = np.concatenate([np.cross(terms.r_B, e_l), e_l], axis=-1)  # (..., 6 legs, 6)
    with np.errstate(divide="ignore", invalid="ignore"):
        scale = 1.0 / (geometry.crank_lengths * np.sum(e_l * terms.e_N, axis=-1))
        W = np.swapaxes(tau1 * scale[..., None], -1, -2)
    return finite_or_singular("W", W, x)


def wrench_map_paper_eq18(geometry: RobotGeometry, x, theta=None) -> np.ndarray:
    """Paper eq. 18 exactly as printed: tau_1 diag(e_l . e_N / |a|), (..., 6, 6).

    Kept to document the discrepancy (docs/paper_notes.md); use :func:`wrench_map` or :func:`tau`.
    """
    terms = leg_terms(geometry, x, ik(geometry, x) if theta is None else theta)
    e_l = terms.ell / np.linalg.norm(terms.ell, axis=-1, keepdims=True)
    tau1 = np.concatenate([np.cross(terms.r_B, e_l), e_l], axis=-1)
    scale = np.sum(e_l * terms.e_N, axis=-1) / geometry.crank_lengths
    return np.swapaxes(tau1 * scale[..., None], -1, -2)


def wrap_angle(angle):
    """Angles wrapped to [-pi, pi), rad."""
    return (np.asarray(angle) + np.pi) % (2.0 * np.pi) - np.pi


def singular_values_of(J: np.ndarray) -> np.ndarray:
    """(..., 6) descending singular values; NaN rows where J has NaN, inf where J has inf."""
    flat = J.reshape(-1, 6, 6)
    out = np.full(flat.shape[:1] + (6,), np.nan)
    nan = np.any(np.isnan(flat), axis=(-2, -1))
    inf = ~nan & np.any(np.isinf(flat), axis=(-2, -1))
    ok = ~nan & ~inf
    if np.any(ok):
        out[ok] = np.linalg.svd(flat[ok], compute_uv=False)
    out[inf, 0] = np.inf  # a rod orthogonal to its crank-tip velocity
    out[inf, 1:] = np.nan
    return out.reshape(J.shape[:-2] + (6,))


def singular_values(geometry: RobotGeometry, x, theta=None) -> np.ndarray:
    """Singular values of the Jacobian J = d theta / d x, (..., 6) descending.

    Args:
        x: (..., 6) poses [rad, m]; theta: optional (..., 6) motor angles of x.
    Returns:
        (..., 6) in SI units (rows rad, columns rad or m mixed); NaN where x is unreachable;
        [inf, NaN, ...] where a rod is orthogonal to its crank-tip velocity (J unbounded).
    """
    x = as_poses("pose x", x)
    if theta is None:
        theta, _ = ik_unchecked(geometry, x)
    return singular_values_of(jacobian_unchecked(geometry, x, theta))


def singularity_measures(geometry: RobotGeometry, x, theta=None):
    """How close pose(s) x are to a singularity: cond(J) and sigma_min(J^{-1}) = 1/sigma_max(J).

    cond(J) = sigma_max / sigma_min grows without bound at both kinds of singularity of this
    parallel robot: where a rod becomes orthogonal to its crank-tip velocity (sigma_max(J) -> inf,
    the edge of the workspace, where the platform cannot be pushed in some direction: the
    smallest singular value of J^{-1} -> 0) and where the rods' wrenches become dependent
    (sigma_min(J) -> 0, the platform gains an uncontrolled motion). When every leg reaches its
    dead point at once (pure heave at the top or bottom of the workspace) the rows of J grow
    together and cond(J) stays finite (22 at the bottom edge): watch sigma_min_inv as well.

    Args:
        x: (6,) or (..., 6) poses [rad, m]; theta: optional (..., 6) motor angles of x, rad.
    Returns:
        cond: (...) condition number of J (SI units, so it weights 1 rad as 1 m), dimensionless;
            inf exactly at a singularity.
        sigma_min_inv: (...) 1/sigma_max(J), the smallest singular value of J^{-1}, in
            (rad or m) per rad; 0 exactly at a rod-crank singularity.
    Raises:
        UnreachablePoseError: a leg cannot close at a pose (names the first pose and leg).
        InvalidConfigError: x or theta not (..., 6), not finite, or a position beyond 1 km.
    (:func:`singularity_measures_unchecked` gives NaN for unreachable poses instead, for sweeps.)
    """
    x = as_poses("pose x", x)
    theta = (
        ik(geometry, x) if theta is None else as_array("motor angles theta", theta, shape=x.shape)
    )
    return singularity_measures_unchecked(geometry, x, theta)


def singularity_measures_unchecked(geometry: RobotGeometry, x, theta=None):
    """:func:`singularity_measures` with NaN where x is unreachable (workspace sweeps, the
    validator of a path); x must still be finite poses (..., 6)."""
    return singularity_measures_of(singular_values(geometry, x, theta))  # validates x


def singularity_measures_of(sv: np.ndarray):
    """(cond, sigma_min_inv) of :func:`singularity_measures` from the singular values sv
    (..., 6) of the Jacobian (:func:`singular_values_of`)."""
    with np.errstate(divide="ignore", invalid="ignore"):
        cond = np.where(np.isinf(sv[..., 0]), np.inf, sv[..., 0] / sv[..., -1])
        inv = np.where(np.isinf(sv[..., 0]), 0.0, 1.0 / sv[..., 0])
    return cond, inv
