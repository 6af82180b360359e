"""The servo-bus station's per-period arithmetic, compiled with numba: the pose from the crank
angles and its rate (:func:`measure_pose`), the plant state assembled at that pose
(:func:`plant_state`), and the bus's packets of a period, the sync write of Goal Current or, in
the servos' own position loop, of Profile Velocity and Goal Position built in place
(:func:`fill_sync_write`, :func:`fill_goal_write`) and the sync read's status packets parsed
(:func:`parse_status`).

Each control period the driver turns six crank angles and rates into the platform's pose and
rate, and the loggers and the guard read the robot's MultibodyPlant state assembled there. In
numpy these were some hundred small array operations (0.3 ms and 0.7 ms a period of a 2 ms
loop, benchmarks/robot_loop.py); here they are loops over the (6,)-sized arrays, in one call
each. The formulas are those of :class:`~stewart_drake.control.estimator.PoseEstimator`
(:func:`~stewart_drake.robot.path_kernels.fk_newton`: Newton on the closed-form IK, the branch
guard on sign det J), :func:`~stewart_drake.robot.single_pose.jacobian_single` and
:func:`~stewart_drake.plant.closed_chain.assembled_positions` with the rates of
:class:`~.measured_state.MeasuredPlantState`, to which tests hold them (1e-12); the sums of the
IK and the Jacobian are :mod:`~stewart_drake.robot.path_kernels`' (numpy's orders).

Compiled on first import (about 10 s, once per machine) or loaded from numba's disk cache
(:func:`~stewart_drake.base.compiled.njit_cached`); importing this module does it, so that no
control period compiles. :data:`reference` holds the same functions uncompiled (their
``py_func``), the same code by construction.
"""

from __future__ import annotations

import math

import numpy as np

from ...base.compiled import interpreted
from ...robot import path_kernels
from ...robot.path_kernels import fk_newton, ik_angles, jacobian_at, lu_solve6
from ...robot.single_pose import LEG_SIZE

#: :func:`~stewart_drake.robot.path_kernels.source_digest` of the source these kernels compile
#: in, as their numba cache was written (a test holds it current: change that file, update this
#: constant, which changes this file and so numba's stamp of it).
PATH_KERNELS_DIGEST = "3d946829dba818d4"
#: numba, numpy's error model, cached while :data:`PATH_KERNELS_DIGEST` holds.
_njit = path_kernels.compiled_against(PATH_KERNELS_DIGEST)


#: Entries of the ``layout`` array of :func:`plant_state`, in order: where the plant's state
#: keeps each coordinate (indices into q, then into the whole state [q, v]).
LAYOUT = (
    "motor_q",  # 6: each motor joint's position index
    "rod_q",  # 6: each rod ball joint's first position index (-1: rods without ball joints)
    "platform_q",  # 1: the platform's quaternion's first index (then its position)
    "platform_v",  # 1: the platform's angular velocity's first index in [q, v]
    "motor_v",  # 6: each motor joint's velocity index in [q, v]
)
LAYOUT_SIZE = 20


@_njit
def measure_pose(legs, mode, tol, max_iterations, x_start, theta_read, v_read, out):
    """The platform's pose and rate from one reading of the cranks, in place in ``out`` (12,):
    Newton on the closed-form IK from ``x_start``
    (:func:`~stewart_drake.robot.path_kernels.fk_newton`: PoseEstimator.estimate's steps),
    then x_dot = J^-1 theta_dot.

    Args:
        legs, mode, tol, max_iterations, x_start, theta_read: as ``fk_newton``'s.
        v_read: (6,) crank rates, rad/s. out: (12,) [x (6,), x_dot (6,)].
    Returns:
        whether Newton converged (else ``out`` holds the last iterate, its rate not computed).
    """
    J = np.empty((6, 6))
    x = out[:6]
    if not fk_newton(legs, mode, tol, max_iterations, x_start, theta_read, x, J):
        return False
    rate = v_read.copy()
    if not lu_solve6(J, rate):
        rate[:] = math.nan
    out[6:12] = rate
    return True


@_njit
def _rpy_of_min_rotation_from_z(z0, z1, z2, out, k):
    """out[k : k + 3] = roll-pitch-yaw of the smallest rotation taking e_z onto the unit
    vector z (:func:`~stewart_drake.plant.closed_chain._rpy_of_min_rotation_from_z`)."""
    v0, v1, v2 = -z1, z0, 0.0
    f = 1.0 / (1.0 + z2)
    # K = [v]x, R = I + K + K K / (1 + c): the entries the angles need.
    R00 = 1.0 + (-(v2 * v2) - v1 * v1) * f
    R10 = v2 + (v0 * v1) * f
    R20 = -v1 + (v0 * v2) * f
    R21 = v0 + (v1 * v2) * f
    R22 = 1.0 + (-(v1 * v1) - v0 * v0) * f
    out[k] = math.atan2(R21, R22)
    out[k + 1] = math.atan2(-R20, math.hypot(R00, R10))
    out[k + 2] = math.atan2(R10, R00)


@_njit
def plant_state(legs, u_B, R0, layout, x, out):
    """The robot's plant state assembled at the measured pose and rate x (12,), in place in
    ``out`` (nq + nv,): the cranks at the IK's angles, each rod aimed from its crank tip at its
    platform joint (ball joint rpy; no spin), the platform's quaternion [w, x, y, z] and
    position; velocities: the platform's w_WP = E(rpy) rpy_dot and p_dot, the cranks' J x_dot,
    the rest zero (:class:`~.measured_state.MeasuredPlantState`).

    Args:
        legs: (6, LEG_SIZE) leg constants. u_B: (6, 3) motor shafts. R0: (6, 3, 3) each rod
            frame's rotation at zero joint angles
            (:func:`~stewart_drake.plant.closed_chain.rod_zero_rotations`).
        layout: (LAYOUT_SIZE,) int64, the indices of :data:`LAYOUT`.
        x: (12,) [pose rad, m; rates rad/s, m/s].
    """
    R, E, r, q = np.empty((3, 3)), np.empty((3, 3)), np.empty((6, 3)), np.empty((6, 3))
    theta, J = np.empty(6), np.empty((6, 6))
    out[:] = 0.0
    ik_angles(legs, x, R, E, r, q, theta)
    for i in range(6):
        out[layout[i]] = theta[i]
        if layout[6 + i] < 0:
            continue
        c, s = math.cos(theta[i]), math.sin(theta[i])
        a, length = legs[i, 12], legs[i, 14]
        ell = np.empty(3)
        for k in range(3):
            tip = legs[i, 3 + k] + a * (c * legs[i, 6 + k] + s * legs[i, 9 + k])
            ell[k] = (q[i, k] - tip) / length
        # Rot(u, -theta) ell (Rodrigues), then into the zero-configuration rod frame.
        u0, u1, u2 = u_B[i, 0], u_B[i, 1], u_B[i, 2]
        cross0 = u1 * ell[2] - u2 * ell[1]
        cross1 = u2 * ell[0] - u0 * ell[2]
        cross2 = u0 * ell[1] - u1 * ell[0]
        dot = ell[0] * u0 + ell[1] * u1 + ell[2] * u2
        w0 = ell[0] * c - cross0 * s + u0 * dot * (1 - c)
        w1 = ell[1] * c - cross1 * s + u1 * dot * (1 - c)
        w2 = ell[2] * c - cross2 * s + u2 * dot * (1 - c)
        z = np.empty(3)
        for k in range(3):
            z[k] = w0 * R0[i, 0, k] + w1 * R0[i, 1, k] + w2 * R0[i, 2, k]
        _rpy_of_min_rotation_from_z(z[0], z[1], z[2], out, layout[6 + i])
    h0, h1, h2 = 0.5 * x[0], 0.5 * x[1], 0.5 * x[2]
    cr, sr, cp, sp = math.cos(h0), math.sin(h0), math.cos(h1), math.sin(h1)
    cy, sy = math.cos(h2), math.sin(h2)
    p = layout[12]
    out[p] = cr * cp * cy + sr * sp * sy
    out[p + 1] = sr * cp * cy - cr * sp * sy
    out[p + 2] = cr * sp * cy + sr * cp * sy
    out[p + 3] = cr * cp * sy - sr * sp * cy
    for k in range(3):
        out[p + 4 + k] = x[3 + k]
    w = layout[13]
    for k in range(3):
        out[w + k] = E[k, 0] * x[6] + E[k, 1] * x[7] + E[k, 2] * x[8]
        out[w + 3 + k] = x[9 + k]
    jacobian_at(legs, theta, E, r, q, J)
    for i in range(6):
        acc = 0.0
        for j in range(6):
            acc += J[i, j] * x[6 + j]
        out[layout[14 + i]] = acc


# -- the bus's packets of a period (DYNAMIXEL Protocol 2.0, :mod:`.protocol`) ---------------------


@_njit
def crc16(table, buf, n):
    """The Protocol 2.0 CRC-16 of ``buf[:n]`` (uint8), by ``table`` (256,) uint16
    (:data:`~.protocol._CRC_TABLE`): :func:`~.protocol.crc16`'s arithmetic."""
    crc = 0
    for k in range(n):
        crc = ((crc << 8) ^ int(table[((crc >> 8) ^ int(buf[k])) & 0xFF])) & 0xFFFF
    return crc


@_njit
def torque_command(tau, directions, torque_constant, amps_per_unit, limit, units, applied):
    """Goal Current units (n,) int64 for crank torques tau (n,) N m, in place: rint(tau dir / K_t
    / unit) clipped to +-``limit``, and ``applied`` (n,) the torques those units drive, N m
    (:func:`~.servos.torque_to_current_units`, the clip and
    :func:`~.servos.current_units_to_torque`, in their order of operations). Returns False,
    writing nothing, when a torque is not finite."""
    for k in range(tau.size):
        if not math.isfinite(tau[k]):
            return False
    for k in range(tau.size):
        u = int(np.rint(tau[k] * directions[k] / torque_constant / amps_per_unit))
        u = min(max(u, -limit), limit)
        units[k] = u
        applied[k] = u * amps_per_unit * torque_constant * directions[k]
    return True


@_njit
def crank_state(raw, zero_counts, directions, rad_per_count, rad_s_per_unit, kt, unit, out):
    """The cranks' angles, rates and torques from a sync read's values raw (n, 3) (current
    units, velocity units, position counts), in place in out (3, n) [q rad, v rad/s, tau N m]:
    :func:`~.protocol.counts_to_rad`, :func:`~.protocol.velocity_units_to_rad_s` and
    :func:`~.servos.current_units_to_torque`, in their order of operations."""
    for k in range(raw.shape[0]):
        out[0, k] = (raw[k, 2] - zero_counts[k]) * rad_per_count * directions[k]
        out[1, k] = raw[k, 1] * rad_s_per_unit * directions[k]
        out[2, k] = raw[k, 0] * unit * kt * directions[k]


@_njit
def fill_sync_write(table, packet, units):
    """The sync write of two-byte values ``units`` (n,) int64 (one per servo, two's complement)
    into ``packet`` (14 + 3 n,) uint8, in place: each servo's two data bytes after its id, then
    the CRC. The header, ids, address and length are the caller's, written once; no byte
    stuffing is needed (an id is at most 252, so no ``FF FF FD`` can form)."""
    n = units.size
    for k in range(n):
        value = int(units[k]) & 0xFFFF
        packet[13 + 3 * k] = value & 0xFF
        packet[14 + 3 * k] = value >> 8
    end = packet.size - 2
    crc = crc16(table, packet, end)
    packet[end] = crc & 0xFF
    packet[end + 1] = crc >> 8


@_njit
def fill_goal_write(table, packet, profile_units, counts):
    """The sync write of each crank's Profile Velocity ``profile_units`` (n,) int64 and Goal
    Position ``counts`` (n,) int64 (four bytes each, contiguous, two's complement) into
    ``packet`` (14 + 9 n,) uint8, in place: each servo's eight data bytes after its id, then the
    CRC; the header, ids, address and length are the caller's, written once. Returns False when
    the parameters hold the header's ``FF FF FD`` (no Goal Position within a servo's range can
    make one), which Protocol 2.0 stuffs: the packet must then be built with stuffing."""
    n = counts.size
    for k in range(n):
        base = 13 + 9 * k
        for b in range(4):
            packet[base + b] = (int(profile_units[k]) >> (8 * b)) & 0xFF
            packet[base + 4 + b] = (int(counts[k]) >> (8 * b)) & 0xFF
    end = packet.size - 2
    for k in range(8, end - 2):
        if packet[k] == 0xFF and packet[k + 1] == 0xFF and packet[k + 2] == 0xFD:
            return False
    crc = crc16(table, packet, end)
    packet[end] = crc & 0xFF
    packet[end + 1] = crc >> 8
    return True


@_njit
def _unstuffed(buf, start, stop, out):
    """Copy ``buf[start:stop]`` into ``out`` without the byte stuffing (an ``FD`` after
    ``FF FF FD``, :func:`~.protocol.unstuff`); returns the bytes written."""
    m = 0
    k = start
    while k < stop:
        out[m] = buf[k]
        m += 1
        if buf[k] == 0xFD and m >= 3 and out[m - 2] == 0xFF and out[m - 3] == 0xFF:
            if k + 1 < stop and buf[k + 1] == 0xFD:
                k += 1
        k += 1
    return m


@_njit
def _signed(body, offset, size):
    value = 0
    for b in range(size):
        value |= int(body[offset + b]) << (8 * b)
    if value >= 1 << (8 * size - 1):
        value -= 1 << (8 * size)
    return value


@_njit
def parse_status(table, buf, n_bytes, ids, found, raw):
    """The status packets of a sync read of Present Current, Velocity and Position (10 bytes
    from address 126) in ``buf[:n_bytes]``: for each servo of ``ids`` (n,) whose packet is
    whole and sound, ``found[k]`` is set and ``raw[k]`` = (current units, velocity units,
    position counts), signed. Bytes before a header, packets of other ids and an incomplete
    last packet are passed over, as the vendor's receive loop does; the status's error byte is
    not read (the vendor's GroupSyncRead does not either).

    Returns:
        the servos found (``found`` set so far, n when the read is complete), or -1: a whole
        packet whose CRC is wrong (the vendor's COMM_RX_CORRUPT).
    """
    body = np.empty(n_bytes, dtype=np.uint8)
    k = 0
    while k + 10 < n_bytes:
        if not (buf[k] == 0xFF and buf[k + 1] == 0xFF and buf[k + 2] == 0xFD and buf[k + 3] == 0):
            k += 1
            continue
        length = int(buf[k + 5]) | (int(buf[k + 6]) << 8)
        if length < 3 or length > 1024 or buf[k + 7] != 0x55:
            k += 1
            continue
        end = k + 7 + length
        if end > n_bytes:
            break  # the rest has not arrived
        if crc16(table, buf[k:], end - k - 2) != int(buf[end - 2]) | (int(buf[end - 1]) << 8):
            return -1
        m = _unstuffed(buf, k + 7, end - 2, body)  # instruction, error, data
        for j in range(ids.size):
            if ids[j] == buf[k + 4] and not found[j] and m >= 12:
                found[j] = True
                raw[j, 0] = _signed(body, 2, 2)
                raw[j, 1] = _signed(body, 4, 4)
                raw[j, 2] = _signed(body, 8, 4)
        k = end
    count = 0
    for j in range(ids.size):
        count += 1 if found[j] else 0
    return count


def warm_up() -> None:
    """Compile (or load from the cache) every entry with the types the station passes."""
    legs = np.zeros((6, LEG_SIZE))
    legs.setflags(write=False)
    x = np.array([0.0, 0.0, 0.0, 0.0, 0.0, 0.3])
    measure_pose(legs, 1.0, 1e-5, 1, x, np.zeros(6), np.zeros(6), np.zeros(12))
    layout = np.arange(LAYOUT_SIZE, dtype=np.int64)
    plant_state(legs, np.zeros((6, 3)), np.zeros((6, 3, 3)), layout, np.zeros(12), np.zeros(40))
    table = np.zeros(256, dtype=np.uint16)
    table.setflags(write=False)
    fill_sync_write(table, np.zeros(32, dtype=np.uint8), np.zeros(6, dtype=np.int64))
    units, counts = np.zeros(6, dtype=np.int64), np.zeros(6, dtype=np.int64)
    fill_goal_write(table, np.zeros(68, dtype=np.uint8), units, counts)
    n6 = np.ones(6)
    n6.setflags(write=False)
    torque_command(np.zeros(6), n6, 1.0, 1.0, 1, np.zeros(6, dtype=np.int64), np.zeros(6))
    crank_state(np.zeros((6, 3)), n6, n6, 1.0, 1.0, 1.0, 1.0, np.zeros((3, 6)))
    ids = np.arange(6, dtype=np.int64)
    ids.setflags(write=False)
    parse_status(table, np.zeros(16, dtype=np.uint8), 0, ids, np.zeros(6, bool), np.zeros((6, 3)))


#: Every function above as the Python numba compiles (its ``py_func``): the uncompiled form.
reference = interpreted(globals())

warm_up()
