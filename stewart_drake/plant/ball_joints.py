"""Where the rods' ``BallRpyJoint`` coordinates are singular, and how far the workspace stays.

Drake parses each SDF ball joint ``rod_ball_i`` into a ``BallRpyJoint``: the rod frame M relative
to a frame F fixed on the crank, R_FM = Rz(yaw) Ry(pitch) Rx(roll). Its rpy rates are singular
at pitch = +-pi/2 (gimbal lock), where R_FM maps M's x axis onto F's -+z axis. The SDF writer
chooses F so that rpy = 0 at home: z_F is the home rod direction, and ``closed_chain.assemble``
turns the rod from there by the smallest rotation onto its new direction (no spin about the
rod). For such a rotation R_FM[2, 0] = -e_F,x, so

    pitch = asin(e_F . x_F),      e_F = the rod's unit direction in F,

and gimbal lock needs the rod to point along +-x_F: 90 deg away from its home direction,
measured in the crank's frame. These two *singular directions* are fixed in the crank; this
module says where they sit relative to the crank joint's misalignment cone
(``StewartGeometry.crank_joint_cone_deg``, which bounds asin|e . u_i|) and computes the pitch
at any pose. Once simulated, a rod also spins about its own axis (nothing holds that angle; the
paper run leaves the rods up to 20 deg from the no-spin frames), which moves its rpy:
:func:`rod_turn_from_home` bounds |pitch| for any spin, and docs/accuracy.md reads both along
the paper run.
"""

from __future__ import annotations

from functools import lru_cache

import numpy as np

from ..robot import kinematics
from ..robot.geometry import StewartGeometry


def _rotation_about(u: np.ndarray, angle: np.ndarray) -> np.ndarray:
    """(..., 6, 3, 3) rotations by ``angle`` (..., 6) rad about the unit axes u (6, 3)."""
    from scipy.spatial.transform import Rotation

    rotvec = np.asarray(angle)[..., None] * u
    return Rotation.from_rotvec(rotvec.reshape(-1, 3)).as_matrix().reshape(rotvec.shape + (3,))


@lru_cache(maxsize=8)
def joint_frames_at_home(geometry: StewartGeometry) -> tuple[np.ndarray, np.ndarray]:
    """Home motor angles (6,) in rad and R_WF (6, 3, 3) of every rod joint's frame F at home
    (z_F along the home rod), read from the Drake plant."""
    from .plant import make_plant

    plant, context, handles, _, _ = make_plant(geometry)  # assembled at home, rpy = 0
    theta = np.array([joint.get_angle(context) for joint in handles.motors])
    R_WF = np.array(
        [plant.EvalBodyPoseInWorld(context, rod).rotation().matrix() for rod in handles.rods]
    )
    theta.setflags(write=False)  # cached: callers must not mutate
    R_WF.setflags(write=False)
    return theta, R_WF


def _rod_in_F(geometry: StewartGeometry, x, theta=None, R_WF_home=None) -> np.ndarray:
    """(..., 6, 3) unit rod direction (crank tip -> platform joint) in each rod joint's frame F."""
    x = np.asarray(x, dtype=float)
    if theta is None:
        theta, _ = kinematics.ik_unchecked(geometry, x)
    theta_home, plant_frames = joint_frames_at_home(geometry)
    R_WF_home = plant_frames if R_WF_home is None else R_WF_home
    q_B, _ = kinematics.platform_joints(geometry, x)
    ell = q_B - geometry.crank_tips(theta)
    e_W = ell / np.linalg.norm(ell, axis=-1, keepdims=True)
    R_WF = _rotation_about(geometry.u_B, theta - theta_home) @ R_WF_home  # (..., 6, 3, 3)
    return np.einsum("...ji,...j->...i", R_WF, e_W)


def rod_ball_rpy(geometry: StewartGeometry, x, theta=None, R_WF_home=None) -> np.ndarray:
    """Roll, pitch, yaw of every rod ball joint at pose(s) x, as ``closed_chain.assemble``
    writes them.

    Args:
        geometry: the robot.
        x: (6,) or (..., 6) poses [phi, theta, psi, X, Y, Z] in rad and m.
        theta: optional (..., 6) motor angles of x (saves one IK).
        R_WF_home: optional (6, 3, 3) orientations of the joint frames F at home, world frame,
            to study another choice of frames (z along the home rod); default the plant's.
    Returns:
        (..., 6, 3) [roll, pitch, yaw] in rad per leg, Drake's ``BallRpyJoint.get_angles``
        convention (R_FM = Rz(yaw) Ry(pitch) Rx(roll)), rods without spin; NaN where a leg
        cannot close.
    Source: F rotates with the crank about u_i, so R_WF(theta) = Rot(u_i, theta_i -
    theta_home,i) R_WF(home); R_FM is the smallest rotation z -> e_F (module docstring).
    """
    e_F = _rod_in_F(geometry, x, theta, R_WF_home)
    # Smallest rotation z -> e_F: R = I + K + K^2 / (1 + c), v = z x e_F = (-e_y, e_x, 0).
    ex, ey, ez = e_F[..., 0], e_F[..., 1], e_F[..., 2]
    R20, R21, R22, R10, R00 = -ex, -ey, ez, -ex * ey / (1 + ez), 1 - ex * ex / (1 + ez)
    return np.stack(
        [np.arctan2(R21, R22), np.arcsin(np.clip(-R20, -1.0, 1.0)), np.arctan2(R10, R00)], axis=-1
    )


def rod_turn_from_home(geometry: StewartGeometry, x, theta=None) -> np.ndarray:
    """(..., 6) angle in rad between each rod and its home direction, seen from its crank.

    Bounds |pitch| whatever the rod's spin about its own axis: sin(pitch) = -R_FM[2, 0] is a
    component of a unit vector normal to the rod, at most sin of this angle. Gimbal lock at any
    spin therefore needs a rod turned 90 deg from home relative to its crank.
    """
    return np.arccos(np.clip(_rod_in_F(geometry, x, theta)[..., 2], -1.0, 1.0))


def singular_direction_misalignment(geometry: StewartGeometry, R_WF_home=None) -> np.ndarray:
    """(6,) crank-joint misalignment asin|x_F . u_i| of each rod joint's singular directions, rad.

    A rod along +-x_F puts its ``BallRpyJoint`` at pitch = +-pi/2. Where this angle exceeds
    ``crank_joint_cone_deg`` the singular directions lie outside the rod end's cone, so no pose
    inside the limits can reach them; where it is smaller, only the rod's turn in the crank's
    plane (free in a rod end) separates it from gimbal lock, and :func:`rod_ball_rpy` over the
    workspace measures that distance. ``R_WF_home`` as in :func:`rod_ball_rpy`.
    """
    if R_WF_home is None:
        _, R_WF_home = joint_frames_at_home(geometry)
    return np.arcsin(
        np.clip(np.abs(np.einsum("ij,ij->i", R_WF_home[:, :, 0], geometry.u_B)), 0.0, 1.0)
    )


def pitch_bound(geometry: StewartGeometry) -> np.ndarray:
    """(6,) largest |pitch| in rad any pose inside the crank joint's cone can give, per leg.

    A rod inside the cone is at most ``crank_joint_cone_deg`` out of the crank's plane, the
    singular directions :func:`singular_direction_misalignment` out of it, so the angle between
    them is at least their difference and |pitch| = 90 deg - that angle. pi/2 (no bound) where a
    singular direction lies inside the cone.
    """
    gap = singular_direction_misalignment(geometry) - np.deg2rad(geometry.crank_joint_cone_deg)
    return np.pi / 2 - np.clip(gap, 0.0, None)
