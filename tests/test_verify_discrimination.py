"""``stewart-drake verify`` can say no: a battery of wrong motions, each FAILs with its cause
named, in the base frame's axes (a tracker aligned with the base, its offsets removed) and
through a registration (a tracker 1 m and 30 deg away, registered by fiducials); the right
motion with realistic tracker noise PASSes (specificity); the smallest scale and tilt errors
that fail at the tolerance (sensitivity) are those computed from the reference alone, checked
independently and by the verdicts just either side of them; the issue's five false PASS cases,
through the command, now exit 2; and a right irregular motion on the tracker's own clock is
found and passes."""

import re

import numpy as np
import pytest
from test_verify import (
    ALIGNED_ORIGIN_M,
    CLOCK_OFFSET_S,
    LATENCY_S,
    MARKER_COLUMNS,
    NOISE_RMS_M,
    PARAMS,
    REFERENCE,
    SEEN_XYZ,
    SETUP,
    phantom_run,
    tracker_view,
    write_marker_export,
)

from stewart_drake.calibration import files, tracker
from stewart_drake.calibration.registration_file import read_registration
from stewart_drake.cli.main import main
from stewart_drake.references.organ.library import make_motion
from stewart_drake.verification.measured_motion import MeasuredMotion
from stewart_drake.verification.verdict_sensitivity import sensitivity
from stewart_drake.verification.verify import verify

#: The tolerance of the battery: verify's default, 0.1 mm and 0.1 deg RMS per axis.
TOLERANCE = (1e-4, np.radians(0.1))


@pytest.fixture(scope="module")
def registration(tmp_path_factory):
    """SETUP's tracker registered by fiducials measured at 2 um."""
    reg = files.write_registration(
        tmp_path_factory.mktemp("reg") / "REG.yaml",
        SETUP.fiducials(tracker.MeasurementNoise(5e-6, 20e-6), seed=1),
    )
    return read_registration(reg)


def about_centre(x, scale):
    """Poses (n, 6) scaled about their mean pose by ``scale`` (n, 6) or a number."""
    c = x.mean(axis=0)
    return c + scale * (x - c)


def tilted(x, angle_rad, axis=(0.0, 1.0, 0.0)):
    """The platform's poses (n, 6) with the whole phantom turned by ``angle_rad`` about
    ``axis`` through the base frame's origin (set down tilted)."""
    from scipy.spatial.transform import Rotation

    turn = Rotation.from_rotvec(angle_rad * np.asarray(axis))
    R = turn * Rotation.from_euler("ZYX", x[:, 2::-1])
    return np.column_stack([R.as_euler("ZYX")[:, ::-1], turn.apply(x[:, 3:])])


def wrong(case: str, t, x):
    """(the platform's true poses (n, 6), the latency's bound s) of a wrong phantom."""
    other = REFERENCE.evaluate
    if case == "right":
        return x, 0.5
    if case == "at rest":
        return np.tile(x[0], (len(x), 1)), 0.5
    if case == "0.5x amplitude":
        return about_centre(x, 0.5), 0.5
    if case == "2x amplitude":
        return about_centre(x, 2.0), 0.5
    if case == "SI reversed":
        return about_centre(x, np.array([1, 1, 1, -1, 1, 1.0])), 0.5
    if case == "SI and LR swapped":
        c = x.mean(axis=0)
        y = x.copy()
        y[:, 3], y[:, 4] = c[3] + x[:, 4] - c[4], c[4] + x[:, 3] - c[3]
        return y, 0.5
    if case == "another period":
        other = make_motion("breathing", {"tilt": "2deg", "period": "5s"}).evaluate
    elif case == "another motion":
        other = make_motion("sawtooth").evaluate
    elif case == "pure noise":
        y = np.tile(x.mean(axis=0), (len(x), 1))
        y[:, 3:] += np.random.default_rng(11).normal(0.0, 2e-3, (len(x), 3))
        return y, 0.5
    elif case == "3 deg tilt":
        return tilted(x, np.radians(3.0)), 0.5
    elif case == "1 s late":
        return REFERENCE.evaluate(t + CLOCK_OFFSET_S - 1.0)[0], 0.5
    return other(t + CLOCK_OFFSET_S - LATENCY_S)[0], 0.5


#: Each wrong motion and the words its FAIL gives, in the base's axes and through a
#: registration.
#: Through the registration, a marker of positions only 50 mm off the platform is taken off
#: along the reference's rotation: a platform that does not turn as asked shows a little motion
#: of that lever (0.2 mm at rest), so that "the phantom did not move" is said of X alone there.
BATTERY = {
    "at rest": (r"the phantom did not move", r"X did not move"),
    "0.5x amplitude": (r"X moves 0\.5x", r"X moves 0\.4[89]\d*x"),
    "2x amplitude": (r"X moves 2x", r"X moves 2\.0\d*x"),
    "SI reversed": (r"X runs the wrong way", r"X runs the wrong way"),
    "SI and LR swapped": (r"it follows the reference's X", r"it follows the reference's X"),
    "another period": (r"another period", r"another period"),
    "another motion": (r"another motion", r"another motion"),
    "pure noise": (r"X does not follow the reference", r"X does not follow the reference"),
    "3 deg tilt": (r"turned (2\.9|3\.0)\d* deg", r"a constant offset of X \+1[5-7]\.\d mm"),
    "1 s late": (r"latency 1 s beyond --max-latency 500 ms", r"latency 1 s beyond"),
}


def judged(case: str, registered, seed=0):
    """The verification of ``case`` (:func:`wrong`) as the tracker saw it 60 ms late with 0.12
    mm RMS of 3-D noise, clocks known: through ``registered`` (SETUP's tracker) or, with None,
    by a tracker aligned with the base, each axis's offset removed."""
    t, x = phantom_run(seconds=40.0)
    truth, bound = wrong(case, t, x)
    seen = tracker_view(truth, seed=seed, aligned=registered is None)
    measured = MeasuredMotion("m.csv", "tracker", t, seen, SEEN_XYZ)
    return verify(
        REFERENCE,
        measured,
        clock_offset_s=CLOCK_OFFSET_S,
        registration=registered,
        max_latency_s=bound,
        tolerance=TOLERANCE,
    )


@pytest.mark.parametrize("frames", ["axes", "registration"])
@pytest.mark.parametrize("case", list(BATTERY))
def test_a_wrong_motion_fails_naming_its_cause(case, frames, registration):
    ver = judged(case, registration if frames == "registration" else None)
    words = BATTERY[case][frames == "registration"]
    assert not ver.judgement.passed, ver.judgement.line
    assert ver.judgement.line.startswith("FAIL: m.csv (X, Y, Z; ")
    assert any(re.search(words, cause) for cause in ver.judgement.causes), ver.judgement.causes
    assert "; cause: " in ver.judgement.line


@pytest.mark.parametrize("frames", ["axes", "registration"])
@pytest.mark.parametrize("seed", [0, 1, 2])
def test_the_right_motion_with_realistic_tracker_noise_passes(seed, frames, registration):
    ver = judged("right", registration if frames == "registration" else None, seed=seed)
    assert ver.judgement.passed, ver.judgement.line
    assert ver.judgement.causes == []
    assert ver.latency_s == pytest.approx(LATENCY_S, abs=0.010)
    # Each axis's RMS error is the tracker's noise on it, 0.12 mm / sqrt(3) = 69 um.
    rms = np.array(ver.fidelity["rms"][3:])
    assert rms == pytest.approx(np.full(3, NOISE_RMS_M / np.sqrt(3)), rel=0.15)


def _noise_free(x_true, frame_axes: bool):
    """The verification of platform poses x_true (n, 6) measured exactly, on the reference's
    clock shifted as phantom_run's: 6-DoF in the base frame (``frame_axes``: its offsets
    removed)."""
    t, _ = phantom_run(seconds=40.0)
    measured = MeasuredMotion("m.csv", "tracker", t, x_true, np.ones(6, bool))
    return verify(
        REFERENCE,
        measured,
        clock_offset_s=CLOCK_OFFSET_S,
        frame="axes" if frame_axes else "base",
        tolerance=TOLERANCE,
    )


@pytest.mark.parametrize("frame_axes", [True, False])
def test_the_smallest_scale_and_tilt_that_fail_are_those_computed(frame_axes):
    t, x = phantom_run(seconds=40.0)
    ver = _noise_free(x, frame_axes)
    s = ver.judgement.sensitivity
    w0, w1 = ver.fidelity["window_s"]
    r = ver.result
    inside = (r.t >= w0 - 1e-9) & (r.t <= w1 + 1e-9)
    x_d = r.x_d[inside]
    # Independently: a scale error e moves X by e (x_X - its mean): it fails at 0.1 mm over the
    # RMS of the reference's X about its mean.
    assert s["amplitude_axis"] == "X"
    assert s["amplitude_fraction"] == pytest.approx(1e-4 / np.std(x_d[:, 3]), rel=1e-9)
    # A small tilt a about the base's X or Y moves the platform by a Z (0.3 m up) across it and
    # turns it by a: without the offsets removed, 0.1 mm / RMS(Z) fails first (0.1 deg of turn
    # needs more). With them removed, only the motion about the mean shows: a tilt about Y or
    # Z moves Z or Y by a (X - its mean), the breathing's 5.4 mm RMS.
    if frame_axes:
        expected = 1e-4 / np.std(x_d[:, 3])
    else:
        expected = 1e-4 / np.sqrt(np.mean(x_d[:, 5] ** 2))
        assert expected < np.radians(0.1)
    assert s["tilt_rad"] == pytest.approx(expected, rel=1e-6)
    # The verdicts either side of each: 0.8 of it passes, 1.25 of it fails.
    e = s["amplitude_fraction"]
    assert _noise_free(about_centre(x, 1 + 0.8 * e), frame_axes).judgement.passed
    assert not _noise_free(about_centre(x, 1 + 1.25 * e), frame_axes).judgement.passed
    assert not _noise_free(about_centre(x, 1 - 1.25 * e), frame_axes).judgement.passed
    axis = {"X": (1.0, 0, 0), "Y": (0, 1.0, 0), "Z": (0, 0, 1.0)}[s["tilt_about"]]
    a = s["tilt_rad"]
    assert _noise_free(tilted(x, 0.8 * a, axis), frame_axes).judgement.passed
    assert not _noise_free(tilted(x, 1.25 * a, axis), frame_axes).judgement.passed


def test_the_sensitivity_of_a_single_axis_sensor_is_on_its_axis():
    t, x = phantom_run(seconds=40.0)
    x_d = x[400:]
    only_x = np.array([False] * 3 + [True, False, False])
    s = sensitivity(t[400:], x_d, only_x, TOLERANCE, True)
    assert s["amplitude_axis"] == "X"
    assert s["amplitude_fraction"] == pytest.approx(1e-4 / np.std(x_d[:, 3]), rel=1e-9)
    # Along Z the breathing does not move: a sensor there sees no scale, and no tilt about Z.
    only_z = np.array([False] * 5 + [True])
    s = sensitivity(t[400:], x_d, only_z, TOLERANCE, True)
    assert s["amplitude_axis"] == "" and np.isnan(s["amplitude_fraction"])


def test_a_sensor_along_an_axis_the_motion_does_not_move_is_refused():
    # A Z-only sensor on a breathing along X would pass the phantom at rest: refused, saying so.
    from stewart_drake.base.errors import InvalidConfigError

    t, x = phantom_run(seconds=40.0)
    seen = np.full_like(x, np.nan)
    seen[:, 5] = x[:, 5]
    only_z = np.array([False] * 5 + [True])
    with pytest.raises(InvalidConfigError, match="measures Z, along which breathing does not"):
        verify(REFERENCE, MeasuredMotion("z.csv", "tracker", t, seen, only_z))


#: The issue's five false PASS cases: the docs' setup (a positions-only marker in the tracker's
#: frame, breathing with a 2 deg tilt), the default frames; each now exits 2.
ISSUE_CASES = ["at rest", "0.5x amplitude", "2x amplitude", "SI reversed", "at rest, clocks given"]


@pytest.mark.parametrize("case", ISSUE_CASES)
def test_the_issues_false_passes_now_fail_through_the_command(tmp_path, case, capsys):
    t, x = phantom_run(seconds=40.0)
    truth, _ = wrong(case.split(",")[0], t, x)
    export = write_marker_export(tmp_path / "m.csv", t, tracker_view(truth)[:, 3:])
    options = ["--measured", str(export), "--measured-columns", MARKER_COLUMNS]
    if case.endswith("clocks given"):
        options.append(f"--clock-offset={CLOCK_OFFSET_S!r}")
    code = main(["verify", "breathing", *PARAMS, "--out", str(tmp_path / "out"), *options])
    out = capsys.readouterr().out
    assert code == 2, out
    assert out.startswith("FAIL: m.csv (X, Y, Z; each axis's offset removed) against breathing")


def test_a_right_irregular_motion_on_the_trackers_clock_is_found_and_passes(registration):
    """90 s of irregular breathing, the tracker's clock 123 s off and not given, registered by
    fiducials, 60 ms late, 0.05 mm of noise: the clock search once took a shift 42 s off."""
    reference = make_motion("irregular_breathing")
    t = 123.456 + np.arange(9000) / 100.0
    x = reference.evaluate(t - 123.456 + 2.0 - LATENCY_S)[0]
    seen = SETUP.tracker_poses(x)
    seen[:, 3:] += np.random.default_rng(0).normal(0.0, 0.05e-3 / np.sqrt(3), seen[:, 3:].shape)
    seen[:, :3] = np.nan
    ver = verify(
        reference,
        MeasuredMotion("m.csv", "tracker", t, seen, SEEN_XYZ),
        registration=registration,
        tolerance=TOLERANCE,
    )
    assert ver.shift_s == pytest.approx(2.0 - 123.456 - LATENCY_S, abs=0.005)
    assert ver.judgement.passed, ver.judgement.line
    assert ver.fidelity["rms_translation_m"] == pytest.approx(0.05e-3, rel=0.25)


def test_an_offset_of_the_whole_phantom_is_judged_with_a_registration_only(registration):
    # The phantom set down 0.3 mm off along LR: through the registration it fails naming the
    # offset; in the base's axes the offset is removed (and reported), as the words say.
    t, x = phantom_run(seconds=40.0)
    off = x.copy()
    off[:, 4] += 0.3e-3
    seen = tracker_view(off, seed=4)
    ver = verify(
        REFERENCE,
        MeasuredMotion("m.csv", "tracker", t, seen, SEEN_XYZ),
        clock_offset_s=CLOCK_OFFSET_S,
        registration=registration,
        tolerance=TOLERANCE,
    )
    assert not ver.judgement.passed
    assert any("a constant offset of Y +0.3" in c for c in ver.judgement.causes)
    aligned = verify(
        REFERENCE,
        MeasuredMotion("m.csv", "tracker", t, tracker_view(off, seed=4, aligned=True), SEEN_XYZ),
        clock_offset_s=CLOCK_OFFSET_S,
        tolerance=TOLERANCE,
    )
    assert aligned.judgement.passed
    assert aligned.offsets[4] - ALIGNED_ORIGIN_M[1] == pytest.approx(0.3e-3, abs=5e-6)
