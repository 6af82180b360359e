"""A tracker registered by a known motion
(:mod:`~stewart_drake.verification.registration_motion`): the frames fitted to the library's
registration motion as the emulated tracker saw it, held to that tracker's true frames
(:func:`~stewart_drake.calibration.tracker.emulated_setup`), its clock to the delay the run was
made with, its residual to the noise added; the fit's pieces (Kabsch, the rotation's error, the
shift by cross-correlation, the directions it leaves undetermined, the frames' standard
deviations) to numbers found here another way. Unit tests of a second or less each:
tools/mutation.py runs them to mutate the module."""

import math
import re
from dataclasses import dataclass

import numpy as np
import pytest
from harmonic_motion import Harmonics, rpy_matrix
from scipy.spatial.transform import Rotation

from stewart_drake.base import lag
from stewart_drake.base.errors import InvalidConfigError
from stewart_drake.calibration.tracker import emulated_setup
from stewart_drake.references.organ.library import make_motion
from stewart_drake.robot.geometry import StewartGeometry
from stewart_drake.verification import registration_motion as rm
from stewart_drake.verification.measured_motion import MeasuredMotion
from stewart_drake.verification.registration_motion import (
    MotionRegistration,
    fit_registration,
    rigid_shift,
)

SETUP = emulated_setup(StewartGeometry())
T_TB = SETUP.X_TB.GetAsMatrix4()
T_PM = SETUP.X_PM.GetAsMatrix4()
#: The truth: the tracker's frame in the base, the marker's in the platform.
R_BT, P_BT = T_TB[:3, :3].T, -T_TB[:3, :3].T @ T_TB[:3, 3]
R_PM, P_PM = T_PM[:3, :3], T_PM[:3, 3]
REGISTRATION = make_motion("registration")
XYZ = np.array([False] * 3 + [True] * 3)
#: The tracker's clock at the first sample, s; where the motion was then; its delay, s.
CLOCK_S, START_S, LATENCY_S = 500.0, 0.5, 0.06


def tracker_run(
    seconds=10.5, rate_hz=20.0, rotations=False, noise_m=0.0, noise_rad=0.0, seed=0, start_s=START_S
):
    """The registration motion as SETUP's tracker saw it, LATENCY_S late, its first sample at
    the motion's ``start_s`` (a MeasuredMotion)."""
    t = CLOCK_S + np.arange(int(round(seconds * rate_hz))) / rate_hz
    x = REGISTRATION.evaluate(t - CLOCK_S + start_s - LATENCY_S)[0]
    # The marker's pose in T, written out: X_TM = X_TB X_BP X_PM.
    R_BP = rpy_matrix(x[:, :3])
    R_TM = T_TB[:3, :3] @ R_BP @ R_PM
    p_TM = (T_TB[:3, :3] @ (x[:, 3:] + R_BP @ P_PM).T).T + T_TB[:3, 3]
    rng = np.random.default_rng(seed)
    p_TM = p_TM + rng.normal(0.0, noise_m / math.sqrt(3), p_TM.shape)
    rpy = Rotation.from_matrix(R_TM).as_euler("ZYX")[:, ::-1]
    if rotations:
        rpy = rpy + rng.normal(0.0, noise_rad / math.sqrt(3), rpy.shape)
        seen = np.ones(6, bool)
    else:
        rpy[:] = np.nan
        seen = XYZ
    return MeasuredMotion("/d/reg.csv", "tracker", t, np.column_stack([rpy, p_TM]), seen)


def angle_between(R_a, R_b) -> float:
    return float(Rotation.from_matrix(R_a.T @ R_b).magnitude())


# -- the fit ---------------------------------------------------------------------------------------


def test_the_frames_of_a_marker_of_positions_only_are_the_trackers():
    run = tracker_run(seconds=10.05)  # 201 samples: 10 s, the shortest fitted
    assert run.t[-1] - run.t[0] == 10.0
    fit = fit_registration(REGISTRATION, run)
    assert angle_between(fit.R_BT, R_BT) < 1e-8
    np.testing.assert_allclose(fit.p_BT, P_BT, atol=1e-8)
    np.testing.assert_allclose(fit.p_PM, P_PM, atol=1e-8)
    np.testing.assert_array_equal(fit.R_PM, np.eye(3))  # its axes are not measured
    # The clock not given: found, the shift of the tracker's clock onto the motion's.
    assert fit.shift_s == pytest.approx(START_S - LATENCY_S - CLOCK_S, abs=1e-7)
    assert fit.rms_m < 1e-8 and math.isnan(fit.rms_rad)
    assert fit.samples == 201 and fit.motion == "registration" and fit.measured == "/d/reg.csv"
    assert fit.sigma_M[0] == 0.0
    assert fit.words().startswith("fitted to registration measured in /d/reg.csv (201 samples, ")
    assert fit.words().endswith(" um RMS off the motion once fitted)")


def test_the_frames_of_a_6dof_marker_and_its_noise():
    # The tracker's first sample at the motion's 61 s: the motion repeats every 60 s, and only
    # the clocks' relation tells the shift from the one a period earlier (which the search
    # without it takes).
    run = tracker_run(rotations=True, noise_m=50e-6, noise_rad=100e-6, seed=3, start_s=61.0)
    fit = fit_registration(REGISTRATION, run, clock_offset_s=61.0 - CLOCK_S)
    assert angle_between(fit.R_BT, R_BT) < 2e-3
    np.testing.assert_allclose(fit.p_PM, P_PM, atol=0.5e-3)
    assert angle_between(fit.R_PM, R_PM) < 2e-3
    assert fit.shift_s == pytest.approx(61.0 - LATENCY_S - CLOCK_S, abs=3e-3)
    # The residuals are the noise: 50 um and 100 urad RMS (3-D), less the fit's 13 parameters.
    assert fit.rms_m == pytest.approx(50e-6, rel=0.15)
    assert fit.rms_rad == pytest.approx(100e-6, rel=0.15)
    assert fit.words() == (
        f"fitted to registration measured in /d/reg.csv (210 samples, {fit.rms_m * 1e6:.3g} um "
        f"RMS, {fit.rms_rad * 1e6:.3g} urad off the motion once fitted)"
    )
    # Each frame's error against the truth (X_TB's rotation and the base's origin in T, X_PM's)
    # is of the size its standard deviation (the largest of three axes) says: 1.4 to 2.1 of them
    # here, 0.2 to 4.5 over seeds 1 to 5; not ten times more or less.
    errors = (
        angle_between(fit.R_BT, R_BT),
        np.max(np.abs(-fit.R_BT.T @ fit.p_BT - T_TB[:3, 3])),
        angle_between(fit.R_PM, R_PM),
        np.max(np.abs(fit.p_PM - P_PM)),
    )
    sigmas = (*fit.sigma_B, *fit.sigma_M)
    assert 0.1e-3 < sigmas[0] < 1e-3 and 0.05e-3 < sigmas[1] < 0.5e-3
    for error, sigma in zip(errors, sigmas, strict=True):
        assert 0.1 < error / sigma < 5.0


def test_the_frames_standard_deviations_grow_with_the_noise():
    a = fit_registration(REGISTRATION, tracker_run(noise_m=20e-6, seed=2))
    b = fit_registration(REGISTRATION, tracker_run(noise_m=40e-6, seed=2))
    for sa, sb in ((a.sigma_B, b.sigma_B), (a.sigma_M[1:], b.sigma_M[1:])):
        assert np.asarray(sb) == pytest.approx(2 * np.asarray(sa), rel=0.03)
    assert b.rms_m == pytest.approx(2 * a.rms_m, rel=0.01)
    assert a.rms_m == pytest.approx(20e-6, rel=0.15)


def test_a_motion_along_one_line_cannot_register_the_tracker():
    breathing = make_motion("breathing")
    t = CLOCK_S + np.arange(240) / 20.0
    x = breathing.evaluate(t - CLOCK_S)[0]
    p = (T_TB[:3, :3] @ (x[:, 3:] + rpy_matrix(x[:, :3]) @ P_PM).T).T + T_TB[:3, 3]
    y = np.column_stack([np.full((len(t), 3), np.nan), p])
    with pytest.raises(InvalidConfigError) as err:
        fit_registration(breathing, MeasuredMotion("b.csv", "tracker", t, y, XYZ))
    found = re.match(
        r"breathing leaves (\d) of the frames' 9 parameters undetermined", str(err.value)
    )
    assert found and int(found.group(1)) >= 1
    assert str(err.value).endswith(
        "register with the library's motion registration, which moves along and turns about "
        "every axis"
    )


def test_a_marker_that_is_not_this_motion_is_refused():
    run = tracker_run()
    # A motion that turns and moves on every axis, but not the one measured.
    amplitude = np.zeros((6, 6))
    amplitude[range(6), range(6)] = [0.02, 0.02, 0.02, 3e-3, 3e-3, 3e-3]
    other = Harmonics(amplitude, period_s=21.0, centre=REGISTRATION.centre)
    with pytest.raises(InvalidConfigError) as err:
        fit_registration(other, run)
    m = re.fullmatch(
        r"/d/reg.csv: the marker stays (\S+) mm RMS from harmonics once the frames are fitted \(at "
        r"most 1 mm\): not this motion, a marker that slipped, or a tracker that lost it; "
        r"measure the registration again",
        str(err.value),
    )
    assert m and 1.0 < float(m.group(1)) < 10.0  # beyond the bound, within the motion's size


def test_the_samples_past_the_references_end_are_not_fitted():
    # A registration motion that turns and moves on every axis and ends at 9 s; the phantom
    # went on moving after it, as the tracker saw.
    amplitude = np.zeros((6, 6))
    amplitude[range(6), range(6)] = [0.02, 0.02, 0.02, 3e-3, 3e-3, 3e-3]
    going_on = Harmonics(amplitude, period_s=21.0, centre=REGISTRATION.centre, periodic=False)
    ended = Harmonics(
        amplitude, period_s=21.0, centre=REGISTRATION.centre, periodic=False, end_time=9.0
    )
    t = CLOCK_S + np.arange(210) / 20.0
    x = going_on.evaluate(t - CLOCK_S + START_S - LATENCY_S)[0]
    p = (T_TB[:3, :3] @ (x[:, 3:] + rpy_matrix(x[:, :3]) @ P_PM).T).T + T_TB[:3, 3]
    y = np.column_stack([np.full((len(t), 3), np.nan), p])
    fit = fit_registration(ended, MeasuredMotion("e.csv", "tracker", t, y, XYZ), START_S - CLOCK_S)
    # The reference's times 0.44-10.9 s, a step (0.05 s) inside its span 0-9 s: 0.44-8.94 s.
    assert fit.samples == 170
    assert fit.rms_m < 1e-8 and angle_between(fit.R_BT, R_BT) < 1e-8
    np.testing.assert_allclose(fit.p_PM, P_PM, atol=1e-8)


def test_what_a_registration_refuses_before_fitting():
    run = tracker_run()
    cases = [
        (MeasuredMotion("e.csv", "encoders", run.t, run.poses, np.ones(6, bool)), "not an encoder"),
        (MeasuredMotion("z.csv", "tracker", run.t, run.poses, np.eye(6, dtype=bool)[5]), "X, Y"),
        (MeasuredMotion("yz.csv", "tracker", run.t, run.poses, np.arange(6) > 3), "X, Y"),
        (
            MeasuredMotion(
                "r.csv", "tracker", run.t, run.poses, np.array([1, 0, 0, 1, 1, 1], bool)
            ),
            "takes the marker's three rotations or none",
        ),
        (MeasuredMotion("s.csv", "tracker", run.t[:200], run.poses[:200], XYZ), "lasts 9.95 s"),
    ]
    for measured, words in cases:
        with pytest.raises(InvalidConfigError, match=words):
            fit_registration(REGISTRATION, measured)
    with pytest.raises(InvalidConfigError, match="shorter than 10 s: record at least 30 s"):
        fit_registration(REGISTRATION, cases[-1][0])
    gap = np.concatenate([run.t[:100], run.t[100:] + 0.5])
    with pytest.raises(InvalidConfigError, match="stop for 550 ms"):
        fit_registration(REGISTRATION, MeasuredMotion("g.csv", "tracker", gap, run.poses, XYZ))


def test_the_fit_uses_3000_samples_at_most_evenly_picked():
    fit = fit_registration(REGISTRATION, tracker_run(seconds=12.0, rate_hz=400.0))
    assert fit.samples == 3000  # of 4800
    assert fit.rms_m < 1e-8


# -- its pieces ------------------------------------------------------------------------------------


def test_rotations_of_roll_pitch_and_yaw():
    rpy = np.array([[0.1, -0.2, 0.3], [1.0, 0.5, -2.0]])
    poses = np.column_stack([rpy, np.zeros((2, 3))])
    np.testing.assert_allclose(rm._rotations(poses).as_matrix(), rpy_matrix(rpy), atol=1e-15)


def test_the_rotation_error_is_the_sine_of_the_angle_about_the_axis():
    R_ref = rpy_matrix(np.array([[0.1, -0.2, 0.3], [0.0, 0.0, 0.0]]))
    w = np.array([[0.3, -0.1, 0.2], [0.0, 0.0, -0.4]])
    R = R_ref @ Rotation.from_rotvec(w).as_matrix()
    e = rm._rotation_error(R_ref, R)
    angle = np.linalg.norm(w, axis=1, keepdims=True)
    np.testing.assert_allclose(e, np.sin(angle) * w / angle, atol=1e-15)


def test_kabsch_finds_the_rotation_of_most_agreement():
    rng = np.random.default_rng(0)
    y = rng.normal(size=(2, 20, 3))
    R_true = Rotation.from_rotvec([[0.3, -1.0, 0.5], [2.5, 0.1, -0.4]]).as_matrix()
    r = np.einsum("kab,knb->kna", R_true, y)
    H = np.einsum("kna,knb->kab", r, y)
    R, score = lag._kabsch(H)
    np.testing.assert_allclose(R, R_true, atol=1e-12)
    np.testing.assert_allclose(score, np.sum(y * y, axis=(1, 2)), rtol=1e-12)
    # A mirrored set: the best rotation, not the mirror, and no rotation agrees more.
    H = np.einsum("na,nb->ab", -y[0] * [1, 1, 1], y[0])
    R, score = lag._kabsch(H)
    assert np.linalg.det(R) == pytest.approx(1.0) and R @ R.T == pytest.approx(np.eye(3))
    assert score == pytest.approx(np.trace(R.T @ H), rel=1e-12)
    others = Rotation.random(2000, random_state=1).as_matrix()
    assert score >= np.max(np.einsum("kab,ab->k", others, H)) - 1e-12


@dataclass(frozen=True)
class Growing:
    """A motion on X, Y and Z whose size grows with time: the mean squared distance of a shift
    needs each term of its sum (the reference's part in the window varies with the shift)."""

    name: str = "growing"

    def evaluate(self, t):
        t = np.asarray(t, dtype=float)[..., None]
        w = 2 * np.pi * np.array([1 / 3.0, 1 / 4.0, 1 / 5.0])
        p = (1.0 + 0.2 * t) * 1e-3 * np.sin(w * t + [0.0, 1.0, 2.0]) + [0.01, -0.02, 0.3]
        x = np.concatenate([np.zeros(t.shape[:-1] + (3,)), p], axis=-1)
        return x, None, None


@pytest.mark.parametrize("reference", [REGISTRATION, Growing()], ids=["registration", "growing"])
def test_the_shift_of_least_distance_with_the_best_rotation_at_each(reference):
    t = 10.0 + 0.05 * np.arange(300)
    x = reference.evaluate(t + 2.35)[0]
    y = (T_TB[:3, :3] @ x[:, 3:].T).T + T_TB[:3, 3]
    d, R = rigid_shift(t, y, reference, (0.0, 5.0), 0.05)
    assert d == pytest.approx(2.35, abs=1e-9)
    np.testing.assert_allclose(R, R_BT, atol=1e-9)
    # Against every shift's distance, written out (each shift's best rotation by scipy): the
    # least, with noise.
    y = y + np.random.default_rng(3).normal(0.0, 2e-4, y.shape)
    shifts = 0.05 * np.arange(101)
    distances = []
    for s in shifts:
        r = reference.evaluate(t + s)[0][:, 3:]
        rc, yc = r - r.mean(axis=0), y - y.mean(axis=0)
        turn, rssd = Rotation.align_vectors(rc, yc)
        distances.append(rssd**2 / len(t))
    d, R = rigid_shift(t, y, reference, (0.0, 5.0), 0.05)
    assert d == pytest.approx(shifts[int(np.argmin(distances))], abs=1e-9)
    k = int(np.argmin(distances))
    r = reference.evaluate(t + shifts[k])[0][:, 3:]
    turn, _ = Rotation.align_vectors(r - r.mean(axis=0), y - y.mean(axis=0))
    np.testing.assert_allclose(R, turn.as_matrix(), atol=1e-9)


def test_the_shifts_searched_are_the_grid_from_the_first_to_the_last():
    t = 10.0 + 0.05 * np.arange(300)
    x = REGISTRATION.evaluate(t + 2.35)[0]
    y = (T_TB[:3, :3] @ x[:, 3:].T).T + T_TB[:3, 3]
    assert rigid_shift(t, y, REGISTRATION, (0.0, 2.35), 0.05)[0] == pytest.approx(2.35, abs=1e-9)
    assert rigid_shift(t, y, REGISTRATION, (0.0, 2.3), 0.05)[0] == pytest.approx(2.3, abs=1e-9)


@pytest.mark.parametrize("seed", [0, 2])
def test_the_distance_of_each_shift_is_the_one_after_the_best_rotation(seed):
    # Measured positions that are noise alone: the shift of least distance is where the
    # reference's motion in the window happens to fit it best, which every term of the
    # distance decides. Each shift's distance written out: the best rotation by scipy.
    t = 10.0 + 0.05 * np.arange(200)
    y = np.random.default_rng(seed).normal(0.0, 1e-3, (200, 3))
    reference = REGISTRATION
    shifts = 0.05 * np.arange(101)
    distances = []
    for s in shifts:
        r = reference.evaluate(t + s)[0][:, 3:]
        _, rssd = Rotation.align_vectors(r - r.mean(axis=0), y - y.mean(axis=0))
        distances.append(rssd**2 / len(t))
    k = int(np.argmin(distances))
    assert 0 < k < 100
    d, R = rigid_shift(t, y, reference, (0.0, 5.0), 0.05)
    assert d == pytest.approx(shifts[k], abs=1e-9)
    r = reference.evaluate(t + d)[0][:, 3:]
    turn, _ = Rotation.align_vectors(r - r.mean(axis=0), y - y.mean(axis=0))
    np.testing.assert_allclose(R, turn.as_matrix(), atol=1e-9)


def test_the_directions_the_data_leave_undetermined():
    # One column per parameter, its size the change of the residuals per unit (rotations per
    # rad, counted as a point 0.15 m from the axis): known to worse than 1 mm with the residuals'
    # noise, sigma = noise / (size / scale), is undetermined.
    e = np.full(100, 1e-4)  # 0.1 mm: undetermined below 0.1, a rotation below 0.015
    J = np.zeros((100, 9))
    J[:9, :] = np.diag([0.15, 0.014, 0.016, 1.0, 0.09, 1.0, 0.11, 1.0, 1.0])
    assert rm._undetermined(J, e, False) == 2
    J[4, 4] = 0.12
    assert rm._undetermined(J, e, False) == 1
    # The noise assumed is at least 10 um: without residuals, 0.01 and a rotation 0.0015.
    assert rm._undetermined(J, np.zeros(100), False) == 0
    J[1, 1] = 0.0014
    assert rm._undetermined(J, np.zeros(100), False) == 1
    assert rm._undetermined(J, np.full(100, 1e-6), False) == 1
    # A 6-DoF marker's three rotations are counted as rotations too.
    J12 = np.zeros((100, 12))
    J12[:12, :] = np.diag([0.15] * 6 + [0.014, 0.016, 0.15] + [1.0] * 3)
    assert rm._undetermined(J12, e, True) == 1


def test_the_frames_standard_deviations_from_the_fits_covariance():
    # A linear fit of 10 parameters [shift, rotation of T, position, marker] whose residuals'
    # Jacobian is diagonal: each parameter's variance is s^2 / J_jj^2, s^2 the residuals' sum
    # of squares over the degrees of freedom.
    n, k = 40, 10
    J = np.zeros((n, k))
    J[:k, :k] = np.diag([1.0, 0.1, 4.0, 8.0, 0.05, 0.5, 0.25, 3.0, 6.0, 12.0])
    e = np.random.default_rng(0).normal(0.0, 1e-3, n)
    sd = np.sqrt(np.sum(e**2) / (n - k)) / np.diag(J[:k, :k])

    def unpack(p):
        R = Rotation.from_rotvec(p[1:4]).as_matrix()
        return R, p[4:7], np.eye(3), p[7:10]

    # At p = 0: the rotation of B in T is -p[1:4], its origin -p[4:7], the marker's p[7:10].
    sigma_B, sigma_M = rm._frame_sigmas(J, e, np.zeros(k), unpack, False)
    assert sigma_B == pytest.approx((sd[1], sd[4]), rel=1e-5)  # 10 s and 20 s
    assert sigma_M == (0.0, pytest.approx(sd[7], rel=1e-5))
    # With the origin of B 1 m along T's Z, a turn about X or Y of T moves it 1 m per rad:
    # -R^T p_BT changes by -p_BT x w.
    p = np.zeros(k)
    p[4:7] = [0.0, 0.0, 1.0]
    sigma_B, _ = rm._frame_sigmas(J, e, p, unpack, False)
    assert sigma_B[1] == pytest.approx(math.hypot(sd[2], sd[4]), rel=1e-5)

    def unpack_turned(p):  # the marker's rotation a parameter too (a 6-DoF marker)
        R = Rotation.from_rotvec(p[1:4]).as_matrix()
        return R, p[4:7], Rotation.from_rotvec(p[7:10]).as_matrix(), np.zeros(3)

    sigma_B, sigma_M = rm._frame_sigmas(J, e, np.zeros(k), unpack_turned, True)
    assert sigma_M == pytest.approx((sd[7], 0.0), rel=1e-5, abs=1e-12)

    # A 6-DoF marker's rotation and position both parameters: each its own.
    J = np.zeros((n, 13))
    J[:13, :13] = np.diag([1.0, 2.0, 2.0, 2.0, 1.0, 1.0, 1.0, 0.5, 8.0, 4.0, 0.1, 0.2, 0.3])
    sd = np.sqrt(np.sum(e**2) / (n - 13)) / np.diag(J[:13, :13])

    def unpack_6dof(p):
        R = Rotation.from_rotvec(p[1:4]).as_matrix()
        return R, p[4:7], Rotation.from_rotvec(p[7:10]).as_matrix(), p[10:13]

    sigma_B, sigma_M = rm._frame_sigmas(J, e, np.zeros(13), unpack_6dof, True)
    assert sigma_B == pytest.approx((sd[1], sd[4]), rel=1e-5)
    # The marker's turn (2 s) beyond the base's origin (s), each in its own figure.
    assert sigma_M == pytest.approx((sd[7], sd[10]), rel=1e-5)


def test_the_registration_in_words_without_rotations():
    fit = MotionRegistration(
        np.eye(3),
        np.zeros(3),
        np.eye(3),
        np.zeros(3),
        (0, 0),
        (0, 0),
        12.34e-6,
        math.nan,
        0.0,
        500,
        "registration",
        "reg.csv",
    )
    assert fit.words() == (
        "fitted to registration measured in reg.csv (500 samples, 12.3 um RMS off the motion "
        "once fitted)"
    )
