"""The robot's closed chain in a plant: assembled at a pose, its loops' closure, its dynamics.

:func:`assemble` writes a consistent configuration of every joint for a platform pose into a
Context (and :func:`assembled_positions` computes the same positions for a batch of poses);
:func:`loop_closure_errors` and :class:`LoopClosure` measure how far each loop is from closed;
:func:`closed_chain_inverse_dynamics` gives the motor torques of a motion from Drake's
inverse dynamics of the tree. The plant is :func:`~.plant.add_stewart_plant`'s.
"""

from __future__ import annotations

import math
from functools import lru_cache

import numpy as np
from pydrake.math import RollPitchYaw, RotationMatrix
from pydrake.multibody.plant import MultibodyPlant
from pydrake.systems.framework import Context

from ..base.errors import InvalidConfigError
from ..robot import kinematics
from ..robot.geometry import StewartGeometry
from .plant import StewartPlantHandles, make_plant, platform_pose, pose_to_transform
from .sdf import rod_zero_rotations


def _min_rotation(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Smallest rotation taking unit vector a onto unit vector b, (3, 3)."""
    v = np.cross(a, b)
    c = float(np.dot(a, b))
    if c < -1 + 1e-12:
        raise InvalidConfigError(
            "rod direction flipped by 180 degrees: the pose is not assemblable"
        )
    K = np.array([[0, -v[2], v[1]], [v[2], 0, -v[0]], [-v[1], v[0], 0]])
    return np.eye(3) + K + K @ K / (1 + c)


def assemble(
    plant: MultibodyPlant, context: Context, handles: StewartPlantHandles, x, x_dot=None
) -> np.ndarray:
    """Write a consistent configuration of every joint for platform pose x into ``context``.

    Cranks from the closed-form IK, rods pointing from crank tip to platform joint (no spin),
    platform at x; with gear play (:mod:`~.backlash`) each rotor at its crank's angle, the play
    at 0. With ``x_dot`` (6,) [rad/s, m/s], velocities are set consistently too
    (theta_dot = J x_dot); otherwise all velocities are zero.
    Returns:
        (6,) motor angles in rad.
    Raises:
        UnreachablePoseError: x cannot be reached (names the leg).
    """
    g = handles.geometry
    x = np.asarray(x, dtype=float)
    theta = kinematics.ik(g, x)
    for joint, angle in zip(handles.motors, theta):
        joint.set_angle(context, float(angle))
    for joint in handles.plays:
        joint.set_angle(context, 0.0)
    plant.SetFloatingBaseBodyPoseInWorldFrame(context, handles.platform, pose_to_transform(x))
    q_B, _ = kinematics.platform_joints(g, x)
    tips = g.crank_tips(theta)
    for i, joint in enumerate(handles.rod_balls):
        joint.set_angles(context, np.zeros(3))
        X_WF = plant.EvalBodyPoseInWorld(context, handles.rods[i])  # rod frame at rpy = 0
        z_F = X_WF.rotation().inverse().multiply((q_B[i] - tips[i]) / g.rod_lengths[i])
        R_FM = _min_rotation(np.array([0.0, 0.0, 1.0]), np.asarray(z_F))
        joint.set_angles(context, RollPitchYaw(RotationMatrix(R_FM)).vector())
    plant.SetVelocities(
        context, handles.model_instance, np.zeros(plant.num_velocities(handles.model_instance))
    )
    if x_dot is not None:
        _set_velocities(plant, context, handles, x, np.asarray(x_dot, dtype=float), theta)
    return theta


def assembled_positions(plant: MultibodyPlant, handles: StewartPlantHandles, x) -> np.ndarray:
    """The plant's positions q of the robot assembled at poses x, vectorized: (..., nq).

    The same configuration :func:`assemble` writes (a test holds them to 1e-12), computed in
    numpy for a batch: crank angles from the IK; each rod's ball-joint rpy from its direction,
    the joint frame F being the rod's SDF frame turned with its crank, R_WF = Rot(u_i, theta_i)
    R0_i; the platform's quaternion [w, x, y, z] and position. For sweeps that only pose the
    robot (clearance), where :func:`assemble` would cost a Drake call per joint.

    Args:
        x: (..., 6) poses [rad, m]; unreachable ones give NaN rows.
    """
    g = handles.geometry
    x = np.asarray(x, dtype=float)
    theta, _ = kinematics.ik_unchecked(g, x)
    q_B, _ = kinematics.platform_joints(g, x)
    ell = (q_B - g.crank_tips(theta)) / g.rod_lengths[:, None]  # (..., 6, 3) unit
    q = np.zeros(x.shape[:-1] + (plant.num_positions(),))
    R0 = _rod_zero_rotations_cached(g)
    motors, rod_balls = handles.motors, handles.rod_balls
    for i in range(6):
        q[..., motors[i].position_start()] = theta[..., i]
        if not rod_balls:
            continue
        u = g.u_B[i]
        c, s_ = np.cos(theta[..., i])[..., None], np.sin(theta[..., i])[..., None]
        # Rot(u, -theta) ell (Rodrigues), then into the zero-configuration rod frame.
        v = ell[..., i, :]
        v = v * c - np.cross(u, v) * s_ + u * (v @ u)[..., None] * (1 - c)
        z_F = v @ R0[i]
        rpy = _rpy_of_min_rotation_from_z(z_F)
        start = rod_balls[i].position_start()
        q[..., start : start + 3] = rpy
    start = handles.platform.floating_positions_start()
    q[..., start : start + 4] = _quaternion_rpy(x[..., :3])
    q[..., start + 4 : start + 7] = x[..., 3:]
    return q


def rod_bodies_positions(geometry: StewartGeometry, states) -> np.ndarray:
    """Positions (N, nq) of the plant with rods as bodies, from the states (N, >= 13) of a plant
    whose rods are distance constraints (its positions first): the same motor angles and
    platform pose, each rod from crank tip to platform joint without spin. How a run of the
    "distance" model is drawn and checked with the rods' shapes.
    """
    plant, context, handles, _, _ = make_plant(geometry, rod_model="distance")
    bodies, _, body_handles, _, _ = make_plant(geometry)
    states = np.atleast_2d(np.asarray(states, dtype=float))
    poses = []
    for row in states[:, : plant.num_positions()]:
        plant.SetPositions(context, row)
        poses.append(platform_pose(plant, context, handles)[0])
    q = assembled_positions(bodies, body_handles, np.array(poses))
    for joint, body_joint in zip(handles.motors, body_handles.motors):
        q[:, body_joint.position_start()] = states[:, joint.position_start()]
    return q


@lru_cache(maxsize=32)
def _rod_zero_rotations_cached(geometry: StewartGeometry) -> tuple:
    return tuple(rod_zero_rotations(geometry))


def _rpy_of_min_rotation_from_z(z: np.ndarray) -> np.ndarray:
    """(..., 3) roll-pitch-yaw of the smallest rotation taking e_z onto the unit vectors z."""
    v = np.stack([-z[..., 1], z[..., 0], np.zeros(z.shape[:-1])], axis=-1)  # e_z x z
    c = z[..., 2]
    K = np.zeros(z.shape[:-1] + (3, 3))
    K[..., 0, 2], K[..., 1, 2] = v[..., 1], -v[..., 0]
    K[..., 2, 0], K[..., 2, 1] = -v[..., 1], v[..., 0]
    K[..., 0, 1], K[..., 1, 0] = -v[..., 2], v[..., 2]
    R = np.eye(3) + K + (K @ K) / (1 + c)[..., None, None]
    roll = np.arctan2(R[..., 2, 1], R[..., 2, 2])
    pitch = np.arctan2(-R[..., 2, 0], np.hypot(R[..., 0, 0], R[..., 1, 0]))
    yaw = np.arctan2(R[..., 1, 0], R[..., 0, 0])
    return np.stack([roll, pitch, yaw], axis=-1)


def _quaternion_rpy(rpy: np.ndarray) -> np.ndarray:
    """(..., 4) unit quaternion [w, x, y, z] of R = Rz(yaw) Ry(pitch) Rx(roll)."""
    h = 0.5 * np.asarray(rpy, dtype=float)
    cr, sr = np.cos(h[..., 0]), np.sin(h[..., 0])
    cp, sp = np.cos(h[..., 1]), np.sin(h[..., 1])
    cy, sy = np.cos(h[..., 2]), np.sin(h[..., 2])
    return np.stack(
        [
            cr * cp * cy + sr * sp * sy,
            sr * cp * cy - cr * sp * sy,
            cr * sp * cy + sr * cp * sy,
            cr * cp * sy - sr * sp * cy,
        ],
        axis=-1,
    )


def _set_velocities(plant, context, handles, x, x_dot, theta):
    """Velocities consistent with x_dot: motors, platform, rods (normal rotation, no spin)."""
    g = handles.geometry
    J = kinematics.jacobian(g, x, theta)
    theta_dot = J @ x_dot
    for joint, rate in zip(handles.motors, theta_dot):
        joint.set_angular_rate(context, float(rate))
    E = kinematics.angular_velocity_map(x[:3])
    from pydrake.multibody.math import SpatialVelocity

    plant.SetFreeBodySpatialVelocity(
        context, handles.platform, SpatialVelocity(E @ x_dot[:3], x_dot[3:])
    )
    # Rod angular velocity w = ell x (v_q - v_tip) / s_i^2, as an rpy rate of the ball joint.
    q_B, r_B = kinematics.platform_joints(g, x)
    tips = g.crank_tips(theta)
    c, s_ = np.cos(theta), np.sin(theta)
    for i, joint in enumerate(handles.rod_balls):
        ell = q_B[i] - tips[i]
        v_q = x_dot[3:] + np.cross(E @ x_dot[:3], r_B[i])
        a, s = float(g.crank_lengths[i]), float(g.rod_lengths[i])
        v_tip = a * theta_dot[i] * (-s_[i] * g.d_B[i] + c[i] * g.w_B[i])
        w_rod_W = np.cross(ell, v_q - v_tip) / s**2
        w_crank_W = theta_dot[i] * g.u_B[i]
        X_WC = plant.EvalBodyPoseInWorld(context, handles.cranks[i])
        X_CF = joint.frame_on_parent().GetFixedPoseInBodyFrame()
        R_WF = X_WC.rotation().multiply(X_CF.rotation())
        # BallRpyJoint's generalized velocity is w_FM expressed in F (not rpy rates).
        joint.set_angular_velocity(
            context, np.asarray(R_WF.inverse().multiply(w_rod_W - w_crank_W))
        )


def closed_chain_inverse_dynamics(
    plant: MultibodyPlant,
    context: Context,
    handles: StewartPlantHandles,
    x,
    x_dot,
    x_ddot,
    step: float = 1e-6,
) -> np.ndarray:
    """Motor torques that move the plant's closed chain along (x, x_dot, x_ddot), (6,) in N m.

    Drake's inverse dynamics of the tree, tau = M v_dot + C v - tau_g (``CalcInverseDynamics``
    and ``CalcGravityGeneralizedForces``, with the actuators' reflected inertia), projected on
    the motions the loops allow: with v = N x_dot the tree velocities of a platform rate (as
    :func:`assemble` sets them, rods without spin), the ball constraints' forces do no work
    along N, so N^T tau = N^T B T = J^T T (the motors' rows of N are J). v_dot = N x_ddot +
    (dN/dt) x_dot, the second term by a central difference along x_dot. Joint damping and
    friction are not included. Overwrites the positions and velocities in ``context``.

    Args:
        x, x_dot, x_ddot: (6,) pose, rate and acceleration of the platform (SI).
        step: finite-difference step on the pose, rad or m.
    Returns:
        (6,) torques, N m: the independent check of
        :func:`~.statics.inverse_dynamics_torques` (a test holds them together).
    Raises:
        UnreachablePoseError: x (or a pose ``step`` away along x_dot) cannot be assembled.
    """
    from pydrake.multibody.tree import MultibodyForces

    x, x_dot, x_ddot = (np.asarray(v, dtype=float) for v in (x, x_dot, x_ddot))

    def velocities(pose, rate):
        assemble(plant, context, handles, pose, rate)
        return plant.GetVelocities(context).copy()

    N = np.column_stack([velocities(x, e) for e in np.eye(6)])
    speed = float(np.linalg.norm(x_dot))
    dN_x_dot = np.zeros(N.shape[0])
    if speed > 0:
        d = step * x_dot / speed
        dN_x_dot = (velocities(x + d, x_dot) - velocities(x - d, x_dot)) * (speed / (2 * step))
    assemble(plant, context, handles, x, x_dot)
    tau = plant.CalcInverseDynamics(
        context, N @ x_ddot + dN_x_dot, MultibodyForces(plant)
    ) - plant.CalcGravityGeneralizedForces(context)
    J = kinematics.jacobian(handles.geometry, x)
    return np.linalg.solve(J.T, N.T @ tau)


def loop_closure_errors(
    plant: MultibodyPlant, context: Context, handles: StewartPlantHandles
) -> np.ndarray:
    """(6,) distance in m between each rod's top end and its platform joint (0 when closed);
    with rods as distance constraints, |crank tip to platform joint - rod length s_i|."""
    # The ignores: pydrake's stubs type multiply's (3, n) array argument as a RigidTransform.
    X_WE = plant.EvalBodyPoseInWorld(context, handles.platform)
    p_W_joint = X_WE.multiply(handles.geometry.p_E.T)  # type: ignore[arg-type]  # (3, 6) joints
    rods = handles.rods
    if not rods:
        a = handles.geometry.crank_lengths
        p_W_tip = np.column_stack(
            [
                plant.EvalBodyPoseInWorld(context, crank).multiply(np.array([a[i], 0.0, 0.0]))  # type: ignore[arg-type]
                for i, crank in enumerate(handles.cranks)
            ]
        )
        length = np.sqrt(((p_W_joint - p_W_tip) ** 2).sum(axis=0))
        return np.abs(length - handles.geometry.rod_lengths)
    p_W_top = np.column_stack(
        [
            plant.EvalBodyPoseInWorld(context, rod).multiply(handles.rod_top_in_rod[i])
            for i, rod in enumerate(rods)
        ]
    )
    return np.sqrt(((p_W_top - p_W_joint) ** 2).sum(axis=0))


class LoopClosure:
    """:func:`loop_closure_errors` of the plant's positions q, from q alone (no Context, no
    forward kinematics of the tree), in plain Python floats: for a check at every step of a run,
    where a Context's kinematics or numpy's per-call overhead on (6, 3) arrays costs several
    times more (docs/plant_speed.md).

    Crank tips from the crank angles (the motor joints', plus the gear play's where the plant
    has one; as :meth:`~.geometry.StewartGeometry.crank_tips`); with rods as bodies, each rod's
    top at s_i R_WF R_FM(rpy) e_z from its tip, where R_WF =
    Rot(u_i, theta_i) R0_i is the ball joint's frame (as :func:`assembled_positions` poses it)
    and R_FM = Rz(yaw) Ry(pitch) Rx(roll) Drake's BallRpyJoint; the platform joints from its
    (normalized) quaternion and position. A test holds it to :func:`loop_closure_errors` at
    1e-12 m.

    Args:
        handles: the plant's :class:`StewartPlantHandles`.
    """

    def __init__(self, handles: StewartPlantHandles):
        g = handles.geometry
        self._motors = [joint.position_start() for joint in handles.motors]
        self._plays = [joint.position_start() for joint in handles.plays]
        self._balls = [joint.position_start() for joint in handles.rod_balls]
        self._platform = handles.platform.floating_positions_start()
        R0 = _rod_zero_rotations_cached(g)
        self._legs = [
            tuple(
                float(v)
                for v in (
                    g.crank_lengths[i],
                    g.rod_lengths[i],
                    *g.P_B[i],
                    *g.d_B[i],
                    *g.w_B[i],
                    *g.u_B[i],
                    *g.p_E[i],
                    *np.ravel(R0[i]),
                )
            )
            for i in range(6)
        ]

    def __call__(self, q) -> np.ndarray:
        """(6,) distance in m between each rod's top end and its platform joint, from q (nq,)."""
        q = np.asarray(q, dtype=float).tolist()
        i = self._platform
        w, x, y, z = q[i : i + 4]
        n = 1.0 / math.sqrt(w * w + x * x + y * y + z * z)
        w, x, y, z = w * n, x * n, y * n, z * n
        r00, r01, r02 = 1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)
        r10, r11, r12 = 2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)
        r20, r21, r22 = 2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)
        X, Y, Z = q[i + 4 : i + 7]
        out = []
        for k, leg in enumerate(self._legs):
            a, s, px, py, pz, dx, dy, dz, wx, wy, wz, ux, uy, uz, ex, ey, ez, *R0 = leg
            th = q[self._motors[k]]
            if self._plays:  # the crank turns on its rotor through the gear's play
                th += q[self._plays[k]]
            c, sn = math.cos(th), math.sin(th)
            # The crank tip as P + a c d + a sn w: untilted (w = z, d_z = 0) each added term is
            # an exact zero, the sums of the upright crank to the bit.
            tx = px + a * c * dx + a * sn * wx
            ty = py + a * c * dy + a * sn * wy
            tz = pz + a * c * dz + a * sn * wz
            jx = r00 * ex + r01 * ey + r02 * ez + X - tx  # tip to platform joint
            jy = r10 * ex + r11 * ey + r12 * ez + Y - ty
            jz = r20 * ex + r21 * ey + r22 * ez + Z - tz
            if not self._balls:
                out.append(abs(math.sqrt(jx * jx + jy * jy + jz * jz) - s))
                continue
            j = self._balls[k]
            cr, sr = math.cos(q[j]), math.sin(q[j])
            cp, sp = math.cos(q[j + 1]), math.sin(q[j + 1])
            cy, sy = math.cos(q[j + 2]), math.sin(q[j + 2])
            fx, fy, fz = cy * sp * cr + sy * sr, sy * sp * cr - cy * sr, cp * cr  # R_FM e_z
            vx = R0[0] * fx + R0[1] * fy + R0[2] * fz  # R0 R_FM e_z, then Rot(u, theta)
            vy = R0[3] * fx + R0[4] * fy + R0[5] * fz
            vz = R0[6] * fx + R0[7] * fy + R0[8] * fz
            uv = (ux * vx + uy * vy + uz * vz) * (1 - c)
            lx = vx * c + (uy * vz - uz * vy) * sn + ux * uv
            ly = vy * c + (uz * vx - ux * vz) * sn + uy * uv
            lz = vz * c + (ux * vy - uy * vx) * sn + uz * uv
            gx, gy, gz = s * lx - jx, s * ly - jy, s * lz - jz
            out.append(math.sqrt(gx * gx + gy * gy + gz * gz))
        return np.array(out)


def states_without_play(plant, handles, states) -> np.ndarray:
    """The plant states of a robot with gear play as the plant without it (the SDF's, same rod
    model: :func:`~.plant.make_plant`) holds them: each motor joint at its crank's angle and
    rate, every other joint as it is. For what draws or checks a run on that plant (replays,
    the clearance model).

    Args:
        plant, handles: the plant with gear play and its handles.
        states: (N, nq + nv) its states.
    Returns:
        (N, nq0 + nv0) states of the plant without play; ``states`` itself without gear play.
    """
    states = np.atleast_2d(np.asarray(states, dtype=float))
    if not handles.plays:
        return states
    bare, _, bare_handles, _, _ = make_plant(handles.geometry, rod_model=handles.rod_model)
    nq, nq0 = plant.num_positions(), bare.num_positions()
    out = np.zeros((states.shape[0], nq0 + bare.num_velocities()))
    plays = {f"motor_{i}": play for i, play in enumerate(handles.plays)}
    for index in bare.GetJointIndices(bare_handles.model_instance):
        joint0 = bare.get_joint(index)
        joint = plant.GetJointByName(joint0.name(), handles.model_instance)
        play = plays.get(joint0.name())
        for k in range(joint0.num_positions()):
            out[:, joint0.position_start() + k] = states[:, joint.position_start() + k]
            if play is not None:
                out[:, joint0.position_start() + k] += states[:, play.position_start()]
        for k in range(joint0.num_velocities()):
            column = states[:, nq + joint.velocity_start() + k]
            if play is not None:
                column = column + states[:, nq + play.velocity_start()]
            out[:, nq0 + joint0.velocity_start() + k] = column
    return out
