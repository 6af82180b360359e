"""limits.py: the joint angles the limits bound, read back from Drake's assembled plant; the
margins as distances to the geometry's limits; the violations and refusals that name the leg.
(The validator along whole references: test_properties.py, test_robot_as_built.py.)"""

import numpy as np
import pytest

from stewart_drake.base.errors import JointLimitError, UnreachablePoseError
from stewart_drake.plant.closed_chain import assemble
from stewart_drake.plant.plant import make_plant
from stewart_drake.robot import kinematics, limits
from stewart_drake.robot.geometry import X_HOME


def test_joint_angles_are_the_angles_of_the_assembled_drake_plant(geometry, random_poses):
    """crank_joint = asin |e . u| and platform_joint = the rod's turn in the platform frame from
    its home direction, with e the rod body's z axis and R the platform's rotation, as Drake
    holds them after assemble (no formula shared with the module)."""
    plant, context, handles, _, _ = make_plant(geometry)

    def rods_in_platform(x):
        assemble(plant, context, handles, x)
        R_WE = plant.EvalBodyPoseInWorld(context, handles.platform).rotation().matrix()
        e_W = np.array(
            [
                plant.EvalBodyPoseInWorld(context, rod).rotation().matrix()[:, 2]
                for rod in handles.rods
            ]
        )
        return e_W, e_W @ R_WE

    _, home_E = rods_in_platform(X_HOME)
    for x in random_poses[:15]:
        angles = limits.joint_angles(geometry, x)
        e_W, e_E = rods_in_platform(x)
        np.testing.assert_allclose(
            angles["crank_joint"], np.arcsin(np.abs(np.sum(e_W * geometry.u_B, axis=1))), atol=1e-9
        )
        np.testing.assert_allclose(
            angles["platform_joint"],
            np.arccos(np.clip(np.sum(e_E * home_E, axis=1), -1, 1)),
            atol=1e-7,
        )
        np.testing.assert_allclose(
            angles["motor_angle"],
            [joint.get_angle(context) for joint in handles.motors],
            atol=1e-12,
        )
    home = limits.joint_angles(geometry, X_HOME)
    np.testing.assert_allclose(np.rad2deg(home["crank_joint"]), 19.4, atol=0.05)  # docstring
    np.testing.assert_allclose(home["platform_joint"], 0.0, atol=1e-7)


def test_margins_are_the_distances_to_the_geometry_s_limits(geometry, random_poses):
    for x in random_poses[:10]:
        m = limits.limit_margins(geometry, x)
        a = limits.joint_angles(geometry, x)
        theta = kinematics.ik(geometry, x)
        np.testing.assert_allclose(
            m["motor_angle"], np.minimum(theta + np.pi / 2, np.pi / 2 - theta), atol=1e-12
        )
        np.testing.assert_allclose(m["crank_joint"], np.deg2rad(35.0) - a["crank_joint"])
        np.testing.assert_allclose(m["platform_joint"], np.deg2rad(40.0) - a["platform_joint"])
        np.testing.assert_allclose(
            m["closure"], 1 - np.abs(kinematics.leg_reach_ratio(geometry, x))
        )
    assert limits.is_reachable(geometry, random_poses)


def _roll_ramp(geometry):
    """(t, x, k): a roll ramp from home to 0.9 rad whose legs all close, and the first sample
    past a joint limit, found pose by pose."""
    t = np.linspace(0.0, 1.0, 101)
    x = np.tile(X_HOME, (t.size, 1))
    x[:, 0] = 0.9 * t
    margins = limits.limit_margins_unchecked(geometry, x)
    bad = np.zeros(t.size, bool)
    for name in limits.LIMITS[1:]:
        bad |= np.any(margins[name] < 0, axis=1)
    assert np.all(np.abs(kinematics.leg_reach_ratio(geometry, x)) <= 1) and bad.any()
    return t, x, int(np.argmax(bad))


def test_a_pose_past_a_limit_is_reported_by_leg_limit_and_amount(geometry):
    _, x, k = _roll_ramp(geometry)
    result = limits.is_reachable(geometry, x[k])
    assert not result
    found = result.violations()
    margins = limits.limit_margins(geometry, x[k])
    expected = sorted(
        (float(margins[name][leg]), leg, name)
        for name in limits.LIMITS
        for leg in range(6)
        if margins[name][leg] < 0
    )
    assert [(v.margin, v.leg, v.limit) for v in found] == expected and found
    worst = found[0]
    assert str(worst) == (
        f"leg {worst.leg} exceeds its {worst.limit} limit by {np.rad2deg(-worst.margin):.3g} deg"
    )
    assert limits.is_reachable(geometry, x[k - 1])


def test_an_unreachable_pose_names_its_leg_or_gives_nan_margins(geometry):
    far = X_HOME + np.array([0, 0, 0, 0, 0, 0.5])
    with pytest.raises(UnreachablePoseError) as info:
        limits.limit_margins(geometry, np.array([X_HOME, far]))
    assert info.value.ratio > 1 and f"leg {info.value.leg}" in str(info.value)
    m = limits.limit_margins_unchecked(geometry, far)
    assert np.all(m["closure"] < 0) and np.isnan(m["crank_joint"]).all()
    result = limits.is_reachable(geometry, np.array([X_HOME, far]))
    np.testing.assert_array_equal(result.reachable, [True, False])
    assert result.violations(0) == []
    assert {v.limit for v in result.violations(1)} == {"closure"}


def test_the_validator_refuses_at_the_first_sample_past_a_limit(geometry):
    """A roll ramp: the sample at which the first margin turns negative, found here pose by
    pose, is the one the report and the JointLimitError name."""
    t, x, k = _roll_ramp(geometry)
    report = limits.validate_trajectory(geometry, t, x, cond_threshold=1e6, min_sigma_min_inv=0.0)
    assert not report.ok and report.first_violation.t == t[k]
    assert report.summary().startswith("REFUSED")
    with pytest.raises(
        JointLimitError,
        match=f"leg {report.first_violation.leg} leaves its {report.first_violation.limit} limit",
    ) as info:
        limits.validate_trajectory(
            geometry, t, x, cond_threshold=1e6, min_sigma_min_inv=0.0, raise_refused=True
        )
    assert info.value.margin < 0 and info.value.limit in limits.LIMITS
    ok = limits.validate_trajectory(
        geometry, t[:k], x[:k], cond_threshold=1e6, min_sigma_min_inv=0.0, raise_refused=True
    )
    assert ok.ok and ok.first_violation is None
