"""The kinematics of ONE pose, for what runs every control period: the closed-form IK in plain
Python floats (:func:`ik_scalar`, which the LQI's step compiles as written), and the IK and the
Jacobian with a few small arrays (:func:`ik_single`, :func:`jacobian_single`).

The same numbers as the batched, validated functions of :mod:`.kinematics` (tests hold them to
1e-12), computed without their per-call overhead, which dominates a (6,)-sized problem. The
per-leg constants the compiled code reads are one row per leg (:data:`LEG_COLUMNS`), built by
:func:`leg_rows`.
"""

import math
from functools import lru_cache

import numpy as np

from .kinematics import _NEXT, _PREV, RobotGeometry, ik_angles

#: The columns of one leg's row of per-leg constants (:func:`leg_rows`), in order, with their
#: widths: the platform joint p_i in E, the pivot P_i, the crank direction d_i and the crank
#: plane's second axis w_i in B (m, unit vectors), the crank length a_i (m), s_i^2 - a_i^2
#: (m^2), the rod length s_i (m), the crank's inertia about its shaft with the motor's
#: reflected inertia (kg m^2) and the encoder's zero error (rad).
LEG_COLUMNS = (
    ("p_E", 3),
    ("P_B", 3),
    ("d_B", 3),
    ("w_B", 3),
    ("crank_length", 1),
    ("leg_c", 1),
    ("rod_length", 1),
    ("shaft_inertia", 1),
    ("encoder_offset", 1),
)
#: Floats in one leg's row.
LEG_SIZE = sum(width for _, width in LEG_COLUMNS)


def leg_rows(geometry: RobotGeometry, leg_c) -> tuple:
    """The per-leg constants of the geometry: 6 tuples of :data:`LEG_SIZE` floats in the order
    of :data:`LEG_COLUMNS`, with ``leg_c`` (6,) the s_i^2 - a_i^2 the caller computed (the
    compiled code and the numpy forms each round it their own way; the row keeps theirs)."""
    return tuple(
        tuple(
            float(v)
            for v in (
                *geometry.p_E[i],
                *geometry.P_B[i],
                *geometry.d_B[i],
                *geometry.w_B[i],
                geometry.crank_lengths[i],
                leg_c[i],
                geometry.rod_lengths[i],
                geometry.shaft_inertias[i],
                geometry.encoder_offsets[i],
            )
        )
        for i in range(6)
    )


@lru_cache(maxsize=32)
def leg_constants(geometry: RobotGeometry) -> tuple:
    """The geometry as plain floats for :func:`ik_scalar` and the LQI's estimate: the rows of
    :func:`leg_rows` with s_i^2 - a_i^2 computed as :func:`ik_single` computes it."""
    return leg_rows(geometry, _ik_constants(geometry)[1])


@lru_cache(maxsize=32)
def _ik_constants(geometry: RobotGeometry) -> tuple[np.ndarray, np.ndarray]:
    """((6,) crank lengths a_i, (6,) s_i^2 - a_i^2) in m and m^2, read-only; each s_i^2 by
    Python's float power, as the scalar forms have always squared s."""
    a = [float(v) for v in geometry.crank_lengths]
    c = np.array([float(s) ** 2 - ai * ai for ai, s in zip(a, geometry.rod_lengths)])
    a_arr = np.array(a)
    a_arr.setflags(write=False)
    c.setflags(write=False)
    return a_arr, c


def ik_scalar(legs, x) -> list:
    """Motor angles of ONE pose in plain Python floats: :func:`~.kinematics.ik` without numpy.

    At 1 kHz between two plant steps, numpy's per-call overhead dominates a (6,)-sized problem
    and its code falls out of the CPU caches: this loop costs a quarter of :func:`ik_single` in
    a running simulation (benchmarks/realtime.py). The same numbers to 1e-15 (a test).

    Args:
        legs: :func:`leg_constants` of the geometry (or the same rows as a (6, LEG_SIZE) array,
            as the compiled step passes them). x: 6 floats [rad, m] (not validated).
    Returns:
        list of 6 motor angles, rad; NaN for a leg that cannot close.
    """
    cr, cp, cy = math.cos(x[0]), math.cos(x[1]), math.cos(x[2])
    sr, sp, sy = math.sin(x[0]), math.sin(x[1]), math.sin(x[2])
    r00, r01, r02 = cy * cp, cy * sp * sr - sy * cr, cy * sp * cr + sy * sr
    r10, r11, r12 = sy * cp, sy * sp * sr + cy * cr, sy * sp * cr - cy * sr
    r20, r21, r22 = -sp, cp * sr, cp * cr
    X, Y, Z = x[3], x[4], x[5]
    theta = []
    for ex, ey, ez, bx, by, bz, dx, dy, dz, wx, wy, wz, a, c, _s, _i, _o in legs:
        lx = r00 * ex + r01 * ey + r02 * ez + X - bx  # pivot to platform joint
        ly = r10 * ex + r11 * ey + r12 * ez + Y - by
        lz = r20 * ex + r21 * ey + r22 * ez + Z - bz
        M, N = 2.0 * a * (lx * wx + ly * wy + lz * wz), 2.0 * a * (lx * dx + ly * dy + lz * dz)
        # sqrt, not math.hypot: CPython's hypot has its own rounding, numba's calls libm's, and
        # the controller compiles this function (the same bits interpreted and compiled).
        norm = math.sqrt(M * M + N * N)
        L = lx * lx + ly * ly + lz * lz - c
        theta.append(math.asin(L / norm) - math.atan2(N, M) if abs(L) <= norm else math.nan)
    return theta


def ik_single(geometry: RobotGeometry, x) -> tuple[np.ndarray, tuple]:
    """Motor angles of ONE pose, with what :func:`jacobian_single` reuses.

    The same numbers as :func:`~.kinematics.ik` (a test holds them equal to 1e-12), computed
    with a few 3 x 3 and (6, 3) array operations instead of the batched, validated routines:
    about 10 times faster on a single pose, for the FK estimator and the gain re-scheduling,
    which run every control period.

    Args:
        x: (6,) finite pose [phi, theta, psi, X, Y, Z] in rad and m (not validated).
    Returns:
        theta (6,) rad, NaN for a leg that cannot close; and the intermediates (x, R_BE, r_B, l,
        theta) for :func:`jacobian_single` and :func:`leg_vectors_single`.
    """
    # Scalars by math (a numpy call per element costs more than the arithmetic): this runs
    # every control period, where each microsecond counts (benchmarks/realtime.py).
    roll, pitch, yaw = float(x[0]), float(x[1]), float(x[2])
    cr, cp, cy = math.cos(roll), math.cos(pitch), math.cos(yaw)
    sr, sp, sy = math.sin(roll), math.sin(pitch), math.sin(yaw)
    R = np.array(
        [
            [cy * cp, cy * sp * sr - sy * cr, cy * sp * cr + sy * sr],
            [sy * cp, sy * sp * sr + cy * cr, sy * sp * cr - cy * sr],
            [-sp, cp * sr, cp * cr],
        ]
    )
    a, leg_c = _ik_constants(geometry)
    r_B = geometry.p_E @ R.T
    l = r_B + (x[3:6] - geometry.P_B)  # pivot to platform joint
    L = (l * l).sum(axis=1) - leg_c
    M = 2.0 * a * (l * geometry.w_B).sum(axis=1)
    N = 2.0 * a * (l * geometry.d_B).sum(axis=1)
    with np.errstate(invalid="ignore", divide="ignore"):
        ratio = L / np.hypot(M, N)
    theta = ik_angles(ratio, M, N)
    return theta, (x, R, r_B, l, theta)


def leg_vectors_single(geometry: RobotGeometry, cache: tuple):
    """(ell (6, 3) rod vectors, e_N (6, 3) crank-tip directions, E (3, 3) the angular velocity map)
    of the pose :func:`ik_single` was given (its cache); as in :func:`~.kinematics.leg_terms`."""
    x, _, _, l, theta = cache
    a, d_B, w_B = geometry.crank_lengths[:, None], geometry.d_B, geometry.w_B
    with np.errstate(invalid="ignore"):
        c, s = np.cos(theta)[:, None], np.sin(theta)[:, None]
    cp, sp = np.cos(x[1]), np.sin(x[1])
    cy, sy = np.cos(x[2]), np.sin(x[2])
    E = np.array([[cy * cp, -sy, 0.0], [sy * cp, cy, 0.0], [-sp, 0.0, 1.0]])
    return l - a * (c * d_B + s * w_B), c * w_B - s * d_B, E


def jacobian_single(geometry: RobotGeometry, cache: tuple) -> np.ndarray:
    """Jacobian J = d theta / d x (6, 6) of the pose :func:`ik_single` was given (its cache).

    Rows (ell_i . dq_i/dx) / (a_i ell_i . e_N,i), with ell_i . d(q_i)/d(rpy) = (r_i x ell_i)^T E;
    inf or NaN at a singular or unreachable pose (not checked). Equal to
    :func:`~.kinematics.jacobian`.
    """
    r_B = cache[2]
    ell, e_N, E = leg_vectors_single(geometry, cache)
    # r x ell row by row (np.cross costs 15 us on (6, 3) arrays; this, 5)
    r_x_ell = r_B[:, _NEXT] * ell[:, _PREV] - r_B[:, _PREV] * ell[:, _NEXT]
    with np.errstate(invalid="ignore", divide="ignore"):
        return (
            np.hstack([r_x_ell @ E, ell])
            / (geometry.crank_lengths * (ell * e_N).sum(axis=1))[:, None]
        )


def ik_jacobian(geometry: RobotGeometry, x) -> tuple[np.ndarray, np.ndarray]:
    """(theta (6,), J (6, 6)) of ONE pose: :func:`ik_single` then :func:`jacobian_single`."""
    theta, cache = ik_single(geometry, x)
    return theta, jacobian_single(geometry, cache)
