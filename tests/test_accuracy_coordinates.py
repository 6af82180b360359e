"""The rods' BallRpyJoint coordinates stay far from gimbal lock at every pose inside the limits."""

import numpy as np
import pytest

from stewart_drake.plant import ball_joints
from stewart_drake.plant.closed_chain import assemble
from stewart_drake.plant.plant import make_plant
from stewart_drake.references.trajectories import paper_manoeuvre
from stewart_drake.robot import limits
from stewart_drake.robot.geometry import X_HOME

#: Box around the reachable workspace (README: roll +-37, pitch -40..37, yaw +-52 deg at home;
#: X -0.088..0.188, Y +-0.163, Z 0.20..0.41 m at home orientation), a little wider on every axis.
_BOX_LO = np.array([-0.75, -0.75, -1.0, -0.10, -0.18, 0.19])
_BOX_HI = np.array([0.75, 0.75, 1.0, 0.20, 0.18, 0.42])
#: Measured max |pitch| over the sample below: 35.1 deg (leg 5; 11603 poses); asserted with a
#: margin. Before the rod frames were spun onto the bolt axis it was 85.9 deg (leg 2).
MAX_PITCH_DEG = 45.0


@pytest.fixture(scope="module")
def reachable_sample(geometry):
    """Poses inside every limit of limits.is_reachable, from 4e5 uniform draws in the box."""
    x = np.random.default_rng(0).uniform(_BOX_LO, _BOX_HI, (400_000, 6))
    return x[limits.is_reachable(geometry, x).reachable]


def test_analytic_rpy_equals_drake_joint_angles(geometry, random_poses, reachable_sample):
    plant, context, handles, _, _ = make_plant(geometry)
    worst_pitch = reachable_sample[
        np.argmax(np.abs(ball_joints.rod_ball_rpy(geometry, reachable_sample)[..., 1]).max(axis=-1))
    ]
    for x in [X_HOME, worst_pitch, *random_poses[:8]]:
        assemble(plant, context, handles, x)
        drake = np.array([joint.get_angles(context) for joint in handles.rod_balls])
        np.testing.assert_allclose(ball_joints.rod_ball_rpy(geometry, x), drake, atol=1e-9)


def test_singular_directions_lie_outside_the_crank_joint_cone(geometry):
    """Gimbal lock needs a rod 70.6 deg out of its crank's plane; the rod end allows 35."""
    misalignment = np.rad2deg(ball_joints.singular_direction_misalignment(geometry))
    np.testing.assert_allclose(misalignment, 70.65, atol=0.01)
    assert np.all(misalignment > geometry.crank_joint_cone_deg + 30)
    np.testing.assert_allclose(np.rad2deg(ball_joints.pitch_bound(geometry)), 54.35, atol=0.01)


def test_no_pose_inside_the_limits_comes_near_gimbal_lock(geometry, reachable_sample):
    assert len(reachable_sample) > 10_000  # the sample covers the workspace
    spread = reachable_sample.max(axis=0) - reachable_sample.min(axis=0)
    assert np.all(spread > [1.2, 1.2, 1.4, 0.25, 0.3, 0.18])
    pitch = np.abs(ball_joints.rod_ball_rpy(geometry, reachable_sample)[..., 1])
    assert np.all(pitch <= ball_joints.pitch_bound(geometry) + 1e-12)
    assert np.rad2deg(pitch.max()) < MAX_PITCH_DEG


def test_paper_manoeuvre_keeps_rods_clear_of_gimbal_lock_at_any_spin(geometry):
    x = paper_manoeuvre().evaluate(np.arange(0.0, 10.0, 1e-2))[0]
    assert np.rad2deg(np.abs(ball_joints.rod_ball_rpy(geometry, x)[..., 1]).max()) < 15.0  # 13.0
    # Whatever a rod's spin, |pitch| <= its turn from home relative to the crank: 63.6 deg here.
    assert np.rad2deg(ball_joints.rod_turn_from_home(geometry, x).max()) < 70.0
