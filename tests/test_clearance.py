"""clearance.py: Drake's signed distances between the robot's parts against hand computations
at home, the pose-independent pairs, and refusals. (Clearance along paths, rods against the
kinematics' segments at many poses: test_robot_as_built.py.)"""

import itertools

import numpy as np
import pytest
from scipy.optimize import minimize_scalar

from stewart_drake.base.errors import UnreachablePoseError
from stewart_drake.plant.clearance import clearance_model, family
from stewart_drake.robot import kinematics, parts
from stewart_drake.robot.geometry import X_HOME


@pytest.fixture(scope="module")
def model(geometry):
    return clearance_model(geometry)


def _segment_distance(a0, a1, b0, b1):
    """Distance of segments a0-a1 and b0-b1: the distance from a point of the first to the
    second (projected and clamped) is convex along the first, so a bounded scalar search finds
    its minimum (no closed form shared with the code under test)."""

    def to_b(s):
        p = a0 + s * (a1 - a0)
        t = np.clip((p - b0) @ (b1 - b0) / ((b1 - b0) @ (b1 - b0)), 0.0, 1.0)
        return np.linalg.norm(p - b0 - t * (b1 - b0))

    return minimize_scalar(to_b, bounds=(0.0, 1.0), method="bounded", options={"xatol": 1e-12}).fun


def test_rod_tubes_at_home_are_apart_by_their_axes_distance_less_two_radii(geometry, model):
    theta = kinematics.ik(geometry, X_HOME)
    tip = geometry.crank_tips(theta)
    q, _ = kinematics.platform_joints(geometry, X_HOME)
    e = (q - tip) / np.linalg.norm(q - tip, axis=1, keepdims=True)
    inset = geometry.rod_end_radius + parts.TUBE_GAP + geometry.rod_radius  # capsule's caps
    axis = [(tip[i] + inset * e[i], q[i] - inset * e[i]) for i in range(6)]
    found = {(c.part_a, c.part_b): c.distance for c in model.contacts(X_HOME)}
    checked = 0
    for i, j in itertools.combinations(range(6), 2):
        key = (f"rod_{i}/tube", f"rod_{j}/tube")
        hand = _segment_distance(*axis[i], *axis[j]) - 2 * geometry.rod_radius
        if hand < 0.1:  # within Drake's query distance
            assert found[key] == pytest.approx(hand, abs=2e-6), key  # FCL GJK: ~1 um
            checked += 1
    assert checked >= 3  # at least the three leg pairs
    assert min(found.values()) == pytest.approx(0.018, abs=5e-4)  # 18 mm at home


def test_the_pose_independent_pairs_are_the_rod_ends_under_the_plate(geometry, model):
    """A rod end's sphere on its platform joint: PLATFORM_GAP below the plate, and two of them
    |p_E,i - p_E,j| - 2 r apart, at every pose; they are measured once and not queried again."""
    by_pair = {(c.part_a, c.part_b): c.distance for c in model.fixed}
    for i in range(6):
        assert by_pair[("platform/plate", f"rod_{i}/end_top")] == pytest.approx(
            parts.PLATFORM_GAP, abs=1e-9
        )
    for i, j in itertools.combinations(range(6), 2):
        hand = np.linalg.norm(geometry.p_E[i] - geometry.p_E[j]) - 2 * geometry.rod_end_radius
        assert by_pair[(f"rod_{i}/end_top", f"rod_{j}/end_top")] == pytest.approx(hand, abs=1e-9)
    assert [c.distance for c in model.fixed] == sorted(c.distance for c in model.fixed)
    assert ("platform/plate", "rod_0/end_top") not in model.pairs
    assert all(c.part_b.endswith("end_top") or c.part_a.endswith("end_top") for c in model.fixed)


def test_the_sweep_and_closest_agree_with_contacts_and_unreachable_is_nan(geometry, model):
    far = X_HOME + np.array([0, 0, 0, 0, 0, 0.5])
    distance, closest = model.sweep(np.array([X_HOME, far]))
    assert model.closest(X_HOME).distance == model.contacts(X_HOME)[0].distance
    assert distance[0] == pytest.approx(model.closest(X_HOME).distance, abs=1e-15)
    assert np.isnan(distance[1]) and closest[1] is None
    with pytest.raises(UnreachablePoseError, match="leg"):
        model.contacts(far)
    assert str(model.closest(X_HOME)).endswith("mm apart")
    assert family("rod_2/tube") == "rod tube" and family("base/motor_3") == "base motor"
