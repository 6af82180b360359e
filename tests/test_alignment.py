"""The clock and the frames of ``stewart-drake verify``
(:mod:`~stewart_drake.verification.alignment`) against numbers found here another way: the
clock's score recomputed shift by shift in a few lines of numpy, the shift found against the
known delay of a synthetic motion, the frames against the emulated tracker's truth and a
rotation matrix written out by hand. Unit tests of a fraction of a second each:
tools/mutation.py runs them to mutate the module."""

import math

import numpy as np
import pytest
from harmonic_motion import Harmonics, rpy_matrix

from stewart_drake.base.errors import InvalidConfigError
from stewart_drake.base.lag import coarse_shift, refine_shift, shift_score, shift_scores
from stewart_drake.calibration.tracker import emulated_setup
from stewart_drake.robot.geometry import StewartGeometry
from stewart_drake.verification import alignment
from stewart_drake.verification.alignment import Frames, axis_weights, reference_poses

#: A motion on every axis, two harmonics each so that it repeats every 4 s only, about a pose
#: 0.3 m up (a score's constant parts are large against its differences).
MOTION = Harmonics(
    amplitude=(
        (0.02, -0.01, 0.015, 5e-3, 3e-3, -2e-3),
        (0.004, 0.003, -0.002, 1e-3, -1.5e-3, 0.8e-3),
    ),
    phase=(0.3, 1.1),
    centre=(0.01, -0.02, 0.03, 0.05, -0.04, 0.3),
)
#: A step of a power of two, so that times on it are exact and the score's grid is the samples.
STEP = 0.125


def seen_by(reference):
    def seen(times):
        return reference.evaluate(times)[0]

    return seen


def direct_score(t, y, weights, seen, d, offsets):
    """The weighted mean squared distance between y (n, 6) and the reference at t + d, each
    axis less its mean difference when ``offsets``, written out."""
    e = y - seen(t + d)
    if offsets:
        e = e - e.mean(axis=0)
    used = weights != 0
    return float(np.sum(weights[used] ** 2 * np.mean(e[:, used] ** 2, axis=0)))


def measured(delay_s, offsets=None, noise=0.0, n=160, seed=0, step=STEP, t0=3.0):
    """(t (n,), y (n, 6)): MOTION ``delay_s`` behind the times t (y(t) = x(t + delay_s)) plus
    ``offsets`` (6,) and Gaussian noise, Y and phi not measured (NaN)."""
    t = t0 + step * np.arange(n)
    y = MOTION.evaluate(t + delay_s)[0]
    if offsets is not None:
        y = y + offsets
    y = y + np.random.default_rng(seed).normal(0.0, noise, y.shape)
    y[:, [0, 4]] = np.nan
    return t, y


WEIGHTS = np.array([0.0, 0.15, 0.15, 1.0, 0.0, 1.0])
OFFSETS = np.array([0.0, 0.01, -0.02, 0.4, 0.0, -1.2])


# -- poses and frames ------------------------------------------------------------------------------


def test_the_reference_is_held_at_its_first_pose_before_zero_and_its_last_after_its_end():
    ended = Harmonics(MOTION.amplitude, phase=MOTION.phase, centre=MOTION.centre, end_time=10.0)
    t = np.array([-2.0, 0.0, 3.3, 10.0, 14.0])
    x = reference_poses(ended, t)
    assert x.shape == (5, 6) and x.dtype == float
    np.testing.assert_array_equal(x, MOTION.evaluate([0.0, 0.0, 3.3, 10.0, 10.0])[0])
    # Without an end it runs on, whether end_time is None or not there at all.
    x = reference_poses(MOTION, [-0.5, 0.5, 1e3])
    np.testing.assert_array_equal(x, MOTION.evaluate([0.0, 0.5, 1e3])[0])
    bare = type("Bare", (), {"evaluate": staticmethod(MOTION.evaluate)})()
    np.testing.assert_array_equal(reference_poses(bare, [-0.5, 1e3]), x[[0, 2]])


def test_frames_default_to_the_identity_and_only_the_axes_frames_remove_offsets():
    f = Frames("axes")
    np.testing.assert_array_equal(f.R_BT, np.eye(3))
    np.testing.assert_array_equal(f.p_BT, np.zeros(3))
    np.testing.assert_array_equal(f.p_EM, np.zeros(3))
    assert f.note == ""
    assert [Frames(h).removes_offsets for h in alignment.FRAME_KINDS] == [
        True,
        False,
        False,
        False,
    ]


def test_the_frames_words_say_where_they_came_from_and_the_offsets_removed():
    assert Frames("encoders").words() == (
        "none: the encoder log gives the platform's poses in the base frame"
    )
    assert Frames("base").words() == (
        "none: the file gives the platform's poses in the base frame; nothing removed"
    )
    assert Frames("registration", note="X_TB from 4 fiducials").words() == (
        "from the registration file, nothing fitted and no offset removed: X_TB from 4 fiducials"
    )
    tail = (
        ", nothing else: a rotation of the tracker, a scale or a marker away from the platform's "
        "origin are not removed and show as errors; a constant offset of the whole phantom is "
        "not judged (give --registration REG.yaml to judge it)"
    )
    head = "each measured axis taken as the base frame's axis its column names, its constant offset"
    assert Frames("axes").words() == head + " removed" + tail
    offsets = [0.01, 0.5, 0.0, 0.0123, -0.0004, 0.9]
    seen = [True, False, False, True, True, False]
    # 0.01 rad is 0.5730 deg; 12.3 mm; -0.4 mm; the axes not measured are not named.
    assert Frames("axes").words(offsets, seen) == (
        head + " removed (phi +0.573 deg, X +12.3 mm, Y -0.4 mm)" + tail
    )
    assert Frames("axes").words(offsets) == head + " removed" + tail


def test_the_frames_as_json_values():
    turn = math.radians(20.0)
    R = np.array(
        [[math.cos(turn), -math.sin(turn), 0], [math.sin(turn), math.cos(turn), 0], [0, 0, 1]]
    )
    f = Frames("registration", R, np.array([0.1, 0.2, 0.3]), np.array([0.0, 0.05, 0.0]))
    d = f.as_dict()
    assert d["how"] == "registration" and d["removes_offsets"] is False
    assert d["rotvec_BT_rad"] == pytest.approx([0.0, 0.0, turn], abs=1e-12)
    assert d["p_BT_m"] == [0.1, 0.2, 0.3] and d["p_EM_m"] == [0.0, 0.05, 0.0]
    assert Frames("axes").as_dict()["removes_offsets"] is True


def test_a_registration_gives_the_trackers_frame_in_the_base_and_the_markers_offset():
    setup = emulated_setup(StewartGeometry())
    reg = setup.registration()
    f = alignment.registered_frames(reg)
    T_TB = setup.X_TB.GetAsMatrix4()
    # X_BT = X_TB^-1: R_BT = R_TB^T, p_BT = -R_TB^T p_TB.
    np.testing.assert_allclose(f.R_BT, T_TB[:3, :3].T, atol=1e-15)
    np.testing.assert_allclose(f.p_BT, -T_TB[:3, :3].T @ T_TB[:3, 3], atol=1e-15)
    np.testing.assert_allclose(f.p_EM, setup.X_PM.GetAsMatrix4()[:3, 3], atol=1e-15)
    assert np.linalg.norm(f.p_EM) == pytest.approx(0.05)
    assert f.how == "registration" and f.note == reg.words() and not f.removes_offsets


def test_the_reference_seen_by_a_marker_off_the_platform_is_its_point_not_the_origin():
    p_EM = np.array([0.03, -0.02, 0.04])
    t = np.array([-1.0, 0.7, 2.9])
    x = MOTION.evaluate(np.clip(t, 0.0, None))[0]
    got = alignment.reference_seen(Frames("registration", p_EM=p_EM), MOTION, t)
    np.testing.assert_allclose(got[:, :3], x[:, :3], atol=0.0)
    np.testing.assert_allclose(got[:, 3:], x[:, 3:] + rpy_matrix(x[:, :3]) @ p_EM, atol=1e-15)
    np.testing.assert_array_equal(alignment.reference_seen(Frames("axes"), MOTION, t), x)


def test_the_platform_is_the_marker_less_its_offset_along_the_references_rotation():
    p_EM = np.array([0.03, -0.02, 0.04])
    x_d = MOTION.evaluate([0.2, 1.3])[0]
    y = np.array([[np.nan] * 3 + [0.1, 0.2, 0.3], [np.nan] * 3 + [-0.1, 0.0, 0.5]])
    before = y.copy()
    got = alignment.platform_poses(Frames("registration", p_EM=p_EM), y, x_d)
    np.testing.assert_allclose(got[:, 3:], y[:, 3:] - rpy_matrix(x_d[:, :3]) @ p_EM, atol=1e-15)
    assert np.all(np.isnan(got[:, :3]))
    np.testing.assert_array_equal(y, before)  # the measured poses are not changed
    same = alignment.platform_poses(Frames("axes"), y, x_d)
    np.testing.assert_array_equal(same, y)
    assert same is not y


def test_each_axis_weighs_in_the_score_as_a_point_0_15_m_from_it_or_not_at_all():
    assert alignment.ROTATION_WEIGHT_M == 0.15
    np.testing.assert_array_equal(
        axis_weights([True, False, True, True, False, True]), [0.15, 0, 0.15, 1.0, 0, 1.0]
    )
    np.testing.assert_array_equal(axis_weights(np.ones(6, bool)), [0.15] * 3 + [1.0] * 3)


# -- the clock -------------------------------------------------------------------------------------


@pytest.mark.parametrize("offsets", [True, False])
def test_the_score_of_every_shift_is_the_weighted_mean_squared_distance_at_it(offsets):
    t, y = measured(0.6, OFFSETS, noise=1e-4)
    seen = seen_by(MOTION)
    d, score = shift_scores(t, y, WEIGHTS, seen, (-1.0, 1.5), STEP, offsets)
    np.testing.assert_allclose(d, -1.0 + STEP * np.arange(21), atol=1e-15)
    expected = [direct_score(t, y, WEIGHTS, seen, s, offsets) for s in d]
    np.testing.assert_allclose(score, expected, rtol=1e-9, atol=1e-15)


def test_the_shifts_run_from_the_first_to_the_last_on_the_step():
    t, y = measured(0.6, OFFSETS, n=400, step=0.05)
    d, _ = shift_scores(t, y, WEIGHTS, seen_by(MOTION), (0.0, 2.3), 0.05, True)
    np.testing.assert_allclose(d, 0.05 * np.arange(47), atol=1e-12)  # 2.3 / 0.05 is 45.99..


def test_the_scores_grid_is_the_step_not_the_samples():
    # Samples every 0.05 s, scored every 0.125 s: the measured axes interpolated on that grid.
    t, y = measured(0.6, OFFSETS, n=400, step=0.05)
    seen = seen_by(MOTION)
    d, score = shift_scores(t, y, WEIGHTS, seen, (0.0, 1.0), STEP, True)
    grid = t[0] + STEP * np.arange(160)
    on_grid = np.column_stack([np.interp(grid, t, y[:, k]) for k in range(6)])
    expected = [direct_score(grid, on_grid, WEIGHTS, seen, s, True) for s in d]
    np.testing.assert_allclose(score, expected, rtol=1e-9, atol=1e-15)


@pytest.mark.parametrize("offsets", [True, False])
def test_the_coarse_shift_is_the_known_delay(offsets):
    # 150 samples, 4.7 cycles: the reference's mean over them changes with the shift, which
    # the offsets (0.4 m, 1.2 m) would turn into a pull on the shift were they kept.
    t, y = measured(0.625, OFFSETS if offsets else None, noise=2e-5, n=150)
    assert coarse_shift(t, y, WEIGHTS, seen_by(MOTION), (-1.5, 1.5), STEP, offsets) == (
        pytest.approx(0.625, abs=1e-12)
    )
    # A delay outside the shifts searched is not found: the nearest edge is.
    assert coarse_shift(t, y, WEIGHTS, seen_by(MOTION), (-1.5, 0.25), STEP, offsets) == (
        pytest.approx(0.25, abs=1e-12)
    )


@pytest.mark.parametrize("offsets", [True, False])
def test_the_score_at_one_shift_is_the_weighted_mean_squared_distance(offsets):
    t, y = measured(0.3, OFFSETS, noise=1e-4, step=0.037)
    seen = seen_by(MOTION)
    for d in (0.3, 0.2345, -0.7):
        got = shift_score(t, y, WEIGHTS, seen, d, offsets)
        assert got == pytest.approx(direct_score(t, y, WEIGHTS, seen, d, offsets), rel=1e-12)
    if offsets:  # the offsets removed, the distance at the delay is the noise alone
        noise = (0.15**2 * 2 + 2) * 1e-8
        assert shift_score(t, y, WEIGHTS, seen, 0.3, True) == pytest.approx(noise, rel=0.25)


@pytest.mark.parametrize("delay", [0.39, 0.4321, 0.48])
def test_the_refined_shift_is_the_known_delay_between_two_steps_to_a_microsecond(delay):
    t, y = measured(delay, OFFSETS)
    for d0 in (0.375, 0.5):  # either grid point next to it
        d = refine_shift(t, y, WEIGHTS, seen_by(MOTION), d0, STEP, True)
        assert d == pytest.approx(delay, abs=1e-6)
    # Only within a step of d0.
    d = refine_shift(t, y, WEIGHTS, seen_by(MOTION), 0.125, STEP, True)
    assert 0.245 < d <= 0.25


def test_the_refined_shift_is_the_least_score_of_all_the_samples():
    # 200 noisy samples: their least score, found here on a fine grid, is 2 ms from the delay,
    # and every other sample's is 1.7 ms from it.
    t, y = measured(0.4321, OFFSETS, noise=2e-4, n=200, seed=0)
    seen = seen_by(MOTION)
    fine = 0.4321 + np.linspace(-0.01, 0.01, 2001)
    best = fine[int(np.argmin([direct_score(t, y, WEIGHTS, seen, s, True) for s in fine]))]
    assert 1e-3 < best - 0.4321 < 5e-3
    assert refine_shift(t, y, WEIGHTS, seen, 0.375, STEP, True) == pytest.approx(best, abs=2e-5)


def test_the_refined_shift_evaluates_the_reference_at_20000_samples_at_most_evenly_picked():
    t, y = measured(0.4321, OFFSETS, n=50000, step=0.01)
    calls = []

    def seen(times):
        calls.append(np.array(times))
        return MOTION.evaluate(times)[0]

    d = refine_shift(t, y, WEIGHTS, seen, 0.43, 0.02, True)
    assert d == pytest.approx(0.4321, abs=2e-6)
    for times in calls:  # 20000 of the 50000, from the first to the last, every 2 or 3
        assert len(times) == 20000
        assert times[-1] - times[0] == pytest.approx(t[-1] - t[0], abs=1e-9)
        steps = np.diff(times)
        assert np.all((steps > 0.015) & (steps < 0.035))


def test_the_overlap_with_the_reference():
    """The samples a measured motion is compared on: inside the reference's span (an end, or
    from 0 s on), a margin in, ten at the least, else refused naming the two spans."""
    ended = Harmonics(MOTION.amplitude, phase=MOTION.phase, end_time=10.0)
    t = np.arange(-2.0, 13.0, 0.5)
    on = alignment.overlap(ended, t, 0.0)
    np.testing.assert_array_equal(t[on], np.arange(0.0, 10.5, 0.5))
    on = alignment.overlap(ended, t, 1.0)
    np.testing.assert_array_equal(t[on], np.arange(1.0, 9.5, 0.5))
    np.testing.assert_array_equal(t[alignment.overlap(MOTION, t, 0.0)], np.arange(0.0, 13.0, 0.5))
    with pytest.raises(InvalidConfigError) as err:
        alignment.overlap(ended, t, 3.6)  # 3.6 to 6.4: 6 samples
    assert str(err.value) == (
        "once aligned, the measured motion spans t = -2 to 12.5 s of the reference's clock, which "
        "runs over 0-10 s: no overlap; check --clock-offset and that the file recorded this motion"
    )
    short = Harmonics(MOTION.amplitude, phase=MOTION.phase, end_time=9.5)
    assert np.count_nonzero(alignment.overlap(short, t, 2.5)) == 10  # 2.5 to 7: ten samples do
    with pytest.raises(InvalidConfigError) as err:
        alignment.overlap(MOTION, t - 20.0, 0.0)
    assert "of the reference's clock, which runs from 0 s on: no overlap" in str(err.value)
    # A reference that says nothing of its end: from 0 on.
    bare = type("Bare", (), {"name": "bare", "evaluate": staticmethod(MOTION.evaluate)})()
    np.testing.assert_array_equal(
        alignment.overlap(bare, np.arange(-2.0, 13.0), 0.0)[:3], [0, 0, 1]
    )
    with pytest.raises(InvalidConfigError, match="which runs from 0 s on: no overlap"):
        alignment.overlap(bare, t - 20.0, 0.0)
    # in_span alone: no margin unless given, and no refusal.
    np.testing.assert_array_equal(alignment.in_span(ended, t), alignment.in_span(ended, t, 0.0))
    assert np.count_nonzero(alignment.in_span(ended, t)) == 21
