"""ball_joints.py: the rods' BallRpyJoint angles in closed form against what Drake's plant holds
after assemble, and the bounds the module derives from them."""

import numpy as np

from stewart_drake.plant import ball_joints
from stewart_drake.plant.closed_chain import assemble
from stewart_drake.plant.plant import make_plant
from stewart_drake.robot.geometry import X_HOME


def test_rod_ball_rpy_is_what_the_plant_s_ball_joints_hold(geometry, random_poses):
    plant, context, handles, _, _ = make_plant(geometry)
    np.testing.assert_allclose(ball_joints.rod_ball_rpy(geometry, X_HOME), 0.0, atol=1e-11)
    rpy = ball_joints.rod_ball_rpy(geometry, random_poses[:20])
    for x, expected in zip(random_poses[:20], rpy):
        assemble(plant, context, handles, x)
        drake = np.array([joint.get_angles(context) for joint in handles.rod_balls])
        np.testing.assert_allclose(expected, drake, rtol=0, atol=1e-9)
    assert np.abs(rpy).max() > 0.05  # the poses do turn the rods


def test_the_rod_s_turn_from_home_bounds_its_pitch(geometry, random_poses):
    """|pitch| <= turn for the no-spin frames, and the turn is the angle between the rod and
    its home direction, both seen from the crank."""
    rpy = ball_joints.rod_ball_rpy(geometry, random_poses)
    turn = ball_joints.rod_turn_from_home(geometry, random_poses)
    assert np.all(np.abs(rpy[..., 1]) <= turn + 1e-12)
    np.testing.assert_allclose(ball_joints.rod_turn_from_home(geometry, X_HOME), 0.0, atol=1e-7)
    # the rotation z -> e_F turns by the angle between them: R_FM[2, 2] = cos(turn)
    roll, pitch = rpy[..., 0], rpy[..., 1]
    np.testing.assert_allclose(np.cos(roll) * np.cos(pitch), np.cos(turn), atol=1e-12)


def test_pitch_bound_is_ninety_degrees_less_the_gap_to_the_cone(geometry):
    gap = ball_joints.singular_direction_misalignment(geometry) - np.deg2rad(
        geometry.crank_joint_cone_deg
    )
    bound = ball_joints.pitch_bound(geometry)
    assert bound.shape == (6,) and np.all((0 < bound) & (bound <= np.pi / 2))
    np.testing.assert_allclose(bound, np.pi / 2 - np.clip(gap, 0, None))
    assert np.all(ball_joints.singular_direction_misalignment(geometry) <= np.pi / 2)
