"""The error budget of a calibrated robot: where the robot as built settles (against the
temperature's own forward kinematics, against the encoders' equation), what a base frame handed
over off does (the robot right in the wrong frame: the frame's own displacement), blunders
rejected at no cost, and the laboratory's checks."""

from dataclasses import replace

import numpy as np
import pytest
from pydrake.math import RigidTransform, RollPitchYaw

from stewart_drake.base.errors import InvalidConfigError
from stewart_drake.calibration import budget, rehearsal
from stewart_drake.calibration.tracker import MeasurementNoise
from stewart_drake.robot import legs as model
from stewart_drake.robot.geometry import StewartGeometry
from stewart_drake.robot.temperature import temperature_error
from stewart_drake.robot.tolerances import Tolerances

GEOMETRY = StewartGeometry()


@pytest.fixture(scope="module")
def space():
    return rehearsal.workspace(GEOMETRY, 600, 20)


@pytest.fixture(scope="module")
def chosen(space):
    return rehearsal.pick(GEOMETRY, space, 60, "chosen", MeasurementNoise(), Tolerances(), 0)


def test_a_warm_robot_settles_where_the_temperature_model_puts_it(space):
    """A robot the controller knows exactly, 3 K warmer: its settled poses (the encoders'
    equation, then FK of the warm robot) equal temperature_error's (IK of the cold robot, FK of
    the warm one)."""
    truth = Tolerances().draw(GEOMETRY, 4)
    built = truth.geometry(GEOMETRY)
    H = space.held_out
    target = model.readings(GEOMETRY, truth, H)
    x = budget._settled(GEOMETRY, truth, target, H, 0.0, np.zeros(6), 3.0)
    moved, turned = budget._pose_errors(x, H)
    moved_ref, turned_ref = temperature_error(built, H, 3.0)
    np.testing.assert_allclose(moved, moved_ref, rtol=0, atol=1e-10)
    np.testing.assert_allclose(turned, turned_ref, rtol=0, atol=1e-9)
    assert 15e-6 < np.median(moved) < 30e-6  # 6-10 um/K (docs/calibration.md, Temperature)


def test_settled_cranks_solve_the_encoders_equation_with_the_cyclic_error(space):
    """The cranks found read, with offset and cyclic error, exactly the target readings; the
    cyclic error moves them by its own size."""
    truth = Tolerances().draw(GEOMETRY, 2)
    H = space.held_out[:10]
    target = model.readings(GEOMETRY, truth, H)
    phases = np.linspace(0.0, 5.0, 6)
    x = budget._settled(GEOMETRY, truth, target, H, 100e-6, phases, 0.0)
    theta = model.leg_ik(GEOMETRY, truth, x)
    read = theta + truth.encoder_offsets_rad + budget._cyclic(theta, 100e-6, phases)
    np.testing.assert_allclose(read, target, rtol=0, atol=1e-12)
    shift = np.abs(theta - (target - truth.encoder_offsets_rad))
    assert shift.max() <= 100e-6 + 1e-12 and shift.max() > 50e-6


def test_a_base_frame_handed_over_off_leaves_the_robot_right_in_the_wrong_frame(space, chosen):
    """Poses measured in a base frame 50 um / 100 urad off: the identified robot is consistent
    in that frame, so it settles at the frame's displacement of each pose (X_B'B^-1 applied),
    within the ideal calibration's own error; chi2 does not see it."""
    lab = budget.Laboratory(frame_m=50e-6, frame_rad=100e-6)
    seed = 3
    off = budget.static_error(GEOMETRY, space, lab, seed, indices=chosen)
    ideal = budget.static_error(GEOMETRY, space, budget.Laboratory(), seed, indices=chosen)
    X = budget.frame_offset(lab, seed).inverse()
    H = space.held_out
    moved_by_frame = np.array(
        [
            np.concatenate(
                [
                    RollPitchYaw(
                        (X @ RigidTransform(RollPitchYaw(h[:3]), h[3:])).rotation()
                    ).vector(),
                    (X @ RigidTransform(RollPitchYaw(h[:3]), h[3:])).translation(),
                ]
            )
            for h in H
        ]
    )
    _, expect_rad = budget._pose_errors(moved_by_frame, H)
    np.testing.assert_allclose(expect_rad, 100e-6, rtol=1e-6)
    assert off.translation_rms_m > 5 * ideal.translation_rms_m
    apart_m, apart_rad = budget._pose_errors(off.settled, moved_by_frame)
    assert np.sqrt(np.mean(apart_m**2)) < 2 * ideal.translation_rms_m + 2e-6
    assert np.sqrt(np.mean(apart_rad**2)) < 2 * ideal.rotation_rms_rad


def test_a_blunder_is_rejected_at_no_cost(space, chosen):
    ideal = budget.static_error(GEOMETRY, space, budget.Laboratory(), 1, indices=chosen)
    hit = budget.static_error(GEOMETRY, space, budget.Laboratory(blunders=2), 1, indices=chosen)
    assert hit.dropped == 2 and ideal.dropped == 0
    assert hit.translation_rms_m < 1.2 * ideal.translation_rms_m
    assert hit.rotation_rms_rad < 1.2 * ideal.rotation_rms_rad


def test_calibration_beats_the_drawing_and_the_table_says_so(space):
    rows = budget.budget_rows(
        GEOMETRY,
        space,
        [0, 1],
        rows=(("uncalibrated", None), ("ideal", budget.Laboratory(poses=40))),
    )
    assert np.mean(rows[0]["translation_um"]) > 100 * np.mean(rows[1]["translation_um"])
    assert 0.5 < np.mean(rows[1]["translation_um"]) < 20.0
    table = budget.budget_table(rows).splitlines()
    assert len(table) == 4 and "| ideal | 2 |" in table[3] and table[3].count("1.0x") == 2


@pytest.mark.parametrize(
    "change, words",
    [
        ({"fiducials": 4, "frame_m": 1e-5}, "not both"),
        ({"cyclic_rad": -1e-6}, "cyclic_rad"),
        ({"blunders": 61}, "blunders"),
        ({"delta_k": float("nan")}, "delta_k"),
    ],
)
def test_a_laboratory_refuses_what_it_cannot_be(change, words):
    with pytest.raises(InvalidConfigError, match=words):
        replace(budget.Laboratory(), **change)


def test_good_poses_flagged_through_a_blunders_pull_are_taken_back(space, chosen):
    """One pose 1 mm off among 60: its pull on the first fit flags good poses too; they are
    judged again against the fit without it and taken back, so exactly the blunder is dropped
    on every robot (dropping every pose the first fit flagged lost a good one on the fifth)."""
    lab = budget.Laboratory(blunders=1)
    dropped = [
        budget.static_error(GEOMETRY, space, lab, seed, indices=chosen).dropped for seed in range(5)
    ]
    assert dropped == [1] * 5
