"""``verify`` right at the edges, each edge with a right motion and a wrong one on either side:
a motion smaller than the tolerance (CANNOT JUDGE, its own exit status, where a platform at
rest would pass too; at a tolerance that tells them apart, the right one PASSes and the one at
rest FAILs); a pair whose motions are smaller than the tolerance (the right one PASSes, "did
not move" only of one that did not); a swapped pair at a bound wide enough to hold it; times
since 1970 keeping the latency's digits; a phantom 41 mm off its place under a registration
(the clock not pulled, the offset named); a tracker turned 10, 45, 90 and 180 deg named at
each angle; a mirrored tracker or reversed rotations refused by calibrate --register; a clock
offset of 1e10 s refused in bounded memory; and what a newcomer reads (the option a refusal
names, figures per axis in mm, an earlier report or registration never replaced silently)."""

import math
import tracemalloc

import numpy as np
import pytest
from test_verify import (
    CLOCK_OFFSET_S,
    LATENCY_S,
    MARKER_COLUMNS,
    PARAMS,
    REFERENCE,
    SEEN_XYZ,
    SETUP,
    phantom_run,
    registration_run,
    tracker_view,
    write_marker_export,
)

from stewart_drake.base.errors import InvalidConfigError
from stewart_drake.cli.main import main
from stewart_drake.references.organ.library import make_motion
from stewart_drake.verification.measured_motion import MeasuredMotion
from stewart_drake.verification.registration_motion import fit_registration
from stewart_drake.verification.verify import verify

TOLERANCE = (1e-4, math.radians(0.1))


def small_run(amplitude="0.2mm", at_rest=False, noise_m=2e-6, seconds=40.0):
    """(reference, MeasuredMotion): a breathing of ``amplitude`` along X, as a tracker aligned
    with the base saw it 60 ms late with ``noise_m`` per axis (the platform at rest at its
    first pose with ``at_rest``)."""
    reference = make_motion("breathing", {"amplitude": amplitude})
    t = 100.0 + np.arange(int(seconds * 100)) / 100.0
    x = reference.evaluate(t - 100.0 + 2.0 - LATENCY_S)[0]
    if at_rest:
        x = np.tile(x[0], (len(x), 1))
    x[:, 3:] += np.random.default_rng(3).normal(0.0, noise_m, x[:, 3:].shape)
    x[:, :3] = np.nan
    return reference, MeasuredMotion("m.csv", "tracker", t, x, SEEN_XYZ)


@pytest.mark.parametrize("at_rest", [False, True])
def test_a_motion_within_the_tolerance_cannot_be_judged_and_never_passes(at_rest):
    reference, measured = small_run(at_rest=at_rest)
    judgement = verify(reference, measured, tolerance=TOLERANCE).judgement
    # The reference moves 0.2 mm peak to peak: about 70 um RMS, within 0.1 mm.
    rest = float(np.std(reference.evaluate(np.arange(0, 40, 0.01))[0][:, 3]))
    assert 50e-6 < rest < 90e-6
    assert judgement.verdict == "CANNOT JUDGE" and not judgement.passed, judgement.line
    assert judgement.line.startswith("CANNOT JUDGE: m.csv")
    assert "the phantom at rest would pass too" in judgement.cannot_judge
    assert "judge at a tolerance below X's" in judgement.cannot_judge


@pytest.mark.parametrize("at_rest, verdict", [(False, "PASS"), (True, "FAIL")])
def test_at_a_tolerance_that_tells_motion_from_none_the_right_passes_and_rest_fails(
    at_rest, verdict
):
    reference, measured = small_run(at_rest=at_rest)
    judgement = verify(reference, measured, tolerance=(20e-6, math.radians(0.1))).judgement
    assert judgement.verdict == verdict, judgement.line
    assert judgement.cannot_judge == ""


def test_cannot_judge_has_its_own_exit_status(tmp_path, capsys):
    _, measured = small_run()
    export = write_marker_export(tmp_path / "m.csv", measured.t, measured.poses[:, 3:])
    code = main(
        ["verify", "breathing", "--param", "amplitude=0.2mm", "--measured", str(export)]
        + ["--measured-columns", MARKER_COLUMNS, "--out", str(tmp_path / "out")]
    )
    out = capsys.readouterr().out
    assert code == 3, out
    assert out.startswith("CANNOT JUDGE: m.csv (X, Y, Z; each axis's offset removed)")


def test_a_heartbeat_at_the_depth_cameras_tolerance_cannot_be_judged():
    reference = make_motion("heartbeat")
    t = np.arange(3000) / 100.0
    x = reference.evaluate(t)[0]
    x[:, :3] = np.nan
    judgement = verify(
        reference, MeasuredMotion("m.csv", "tracker", t, x, SEEN_XYZ), tolerance=(1e-3, 0.0175)
    ).judgement
    assert judgement.verdict == "CANNOT JUDGE", judgement.line


def test_a_failing_motion_still_fails_whatever_its_size():
    # A 2x breathing of 0.2 mm errs by its own amplitude: beyond 20 um, it FAILs (not CANNOT
    # JUDGE), and at 0.1 mm cannot be told from the right one.
    reference, measured = small_run()
    poses = measured.poses.copy()
    poses[:, 3:] = poses[:, 3:].mean(axis=0) + 3.0 * (poses[:, 3:] - poses[:, 3:].mean(axis=0))
    wrong = MeasuredMotion("m.csv", "tracker", measured.t, poses, SEEN_XYZ)
    assert verify(reference, wrong, tolerance=(20e-6, 0.0017)).judgement.verdict == "FAIL"


# -- times since 1970, a constant offset, a turned tracker --------------------------------------


@pytest.mark.parametrize("start_s", [123.456, 1.7e9 + 0.123])
def test_times_since_1970_keep_the_latency_to_a_millisecond(start_s):
    t, x = phantom_run(seconds=30.0)
    seen = tracker_view(x, aligned=True)
    t_shifted = t - t[0] + start_s
    measured = MeasuredMotion("m.csv", "tracker", t_shifted, seen, SEEN_XYZ)
    offset = CLOCK_OFFSET_S + t[0] - start_s  # the same relation on the new clock
    ver = verify(REFERENCE, measured, clock_offset_s=offset, tolerance=(2e-4, 0.0017))
    assert ver.latency_s == pytest.approx(LATENCY_S, abs=1e-3)
    assert ver.judgement.verdict == "PASS", ver.judgement.line


@pytest.fixture(scope="module")
def registration():
    import tempfile
    from pathlib import Path

    from stewart_drake.calibration import files, tracker
    from stewart_drake.calibration.registration_file import read_registration

    folder = Path(tempfile.mkdtemp())
    return read_registration(
        files.write_registration(
            folder / "REG.yaml", SETUP.fiducials(tracker.MeasurementNoise(5e-6, 20e-6), seed=1)
        )
    )


@pytest.mark.parametrize("clock_given", [True, False])
def test_a_constant_offset_does_not_pull_the_clock_and_is_named(registration, clock_given):
    t, x = phantom_run(seconds=40.0)
    off = x.copy()
    off[:, 3] += 0.041  # the phantom set down 41 mm off its place along X
    offset = CLOCK_OFFSET_S if clock_given else None
    ver = verify(
        REFERENCE,
        MeasuredMotion("m.csv", "tracker", t, tracker_view(off, seed=4), SEEN_XYZ),
        clock_offset_s=offset,
        registration=registration,
        tolerance=TOLERANCE,
    )
    right = verify(
        REFERENCE,
        MeasuredMotion("m.csv", "tracker", t, tracker_view(x, seed=4), SEEN_XYZ),
        clock_offset_s=offset,
        registration=registration,
        tolerance=(2e-4, 0.0017),
    )
    assert right.judgement.verdict == "PASS", right.judgement.line
    assert ver.judgement.verdict == "FAIL"
    # The shift is the right one (the latency with the clock given; the whole shift without).
    assert ver.shift_s == pytest.approx(right.shift_s, abs=2e-3)
    causes = ver.judgement.causes
    assert any("a constant offset of X +41" in c for c in causes), causes
    assert not any("shape" in c or "amplitude" in c for c in ver.judgement.causes)


@pytest.mark.parametrize("angle_deg", [10.0, 45.0, 90.0, 180.0])
def test_a_turned_tracker_is_named_at_any_angle(angle_deg):
    from scipy.spatial.transform import Rotation

    t, x = phantom_run(seconds=40.0)
    seen = tracker_view(x, aligned=True, seed=5)
    turn = Rotation.from_rotvec(math.radians(angle_deg) * np.array([0.0, 0.0, 1.0]))
    seen[:, 3:] = turn.apply(seen[:, 3:])
    ver = verify(REFERENCE, MeasuredMotion("m.csv", "tracker", t, seen, SEEN_XYZ))
    assert ver.judgement.verdict == "FAIL"
    causes = ver.judgement.causes
    if angle_deg == 180.0:
        # A half turn about the vertical of a motion along X is X reversed, and said so.
        assert causes[0].startswith("X runs the wrong way"), causes
        return
    named = [c for c in causes if c.startswith("the measured motion is turned")]
    if angle_deg == 90.0 and not named:
        # A quarter turn about the vertical of a motion along X is X moved onto Y: said as the
        # axis it follows, with the turned frame among its causes.
        assert any(
            c.startswith("Y moves") and "follows the reference's X" in c and "frame turned" in c
            for c in causes
        ), causes
        return
    assert named, causes
    got = float(named[0].split("turned ")[1].split(" deg")[0])
    assert got == pytest.approx(angle_deg, abs=1.0)


# -- a registration fitted wrong -------------------------------------------------------------


def test_a_mirrored_tracker_is_refused_and_the_right_one_registers():
    reference = make_motion("registration")
    t, seen = registration_run()
    poses = np.full((len(t), 6), np.nan)
    poses[:, 3:] = seen
    fit = fit_registration(reference, MeasuredMotion("r.csv", "tracker", t, poses, SEEN_XYZ))
    assert fit.rms_m < 1e-4
    mirrored = poses.copy()
    mirrored[:, 3] = -mirrored[:, 3]
    with pytest.raises(InvalidConfigError, match="a mirrored tracker's frame .* explains"):
        fit_registration(reference, MeasuredMotion("r.csv", "tracker", t, mirrored, SEEN_XYZ))


def test_reversed_rotations_of_a_6dof_marker_are_refused():
    reference = make_motion("registration")
    t = 500.0 + np.arange(4000) / 100.0
    x = reference.evaluate(t - 500.0 + 0.5 - LATENCY_S)[0]
    seen = SETUP.tracker_poses(x)
    seen[:, 3:] += np.random.default_rng(8).normal(0.0, 30e-6, seen[:, 3:].shape)
    everything = np.ones(6, dtype=bool)
    fit = fit_registration(reference, MeasuredMotion("r.csv", "tracker", t, seen, everything))
    assert fit.rms_m < 1e-4 and fit.rms_rad < 1e-3
    wrong = seen.copy()
    wrong[:, :3] = -wrong[:, :3]
    with pytest.raises(InvalidConfigError, match=r"rotations run the other way|deg RMS from"):
        fit_registration(reference, MeasuredMotion("r.csv", "tracker", t, wrong, everything))


# -- bounded, and what a newcomer reads ------------------------------------------------------


def test_a_clock_offset_of_1e10_is_refused_in_bounded_memory():
    t, x = phantom_run(seconds=20.0)
    measured = MeasuredMotion("m.csv", "tracker", t, tracker_view(x, aligned=True), SEEN_XYZ)
    tracemalloc.start()
    try:
        with pytest.raises(InvalidConfigError, match="check the offset's sign and unit"):
            verify(REFERENCE, measured, clock_offset_s=1e10)
        _, peak = tracemalloc.get_traced_memory()
    finally:
        tracemalloc.stop()
    assert peak < 50e6


def test_a_headerless_measured_file_names_the_option_verify_takes(tmp_path, capsys):
    path = tmp_path / "m.csv"
    path.write_text("\n".join(f"{i},{i * 10},{i * 0.1}" for i in range(50)) + "\n")
    code = main(["verify", "breathing", "--measured", str(path), "--out", str(tmp_path / "o")])
    err = capsys.readouterr().err
    assert code == 2
    assert "--measured-columns" in err and " --columns" not in err and "--format" not in err


def test_figures_are_per_axis_in_units_people_read_and_a_replaced_report_is_said(tmp_path, capsys):
    t, x = phantom_run(seconds=30.0)
    big = x.copy()
    centre = big[:, 3:].mean(axis=0)
    big[:, 3:] = centre + 3.0 * (big[:, 3:] - centre)  # 3x the amplitude: mm of error
    export = write_marker_export(tmp_path / "m.csv", t, tracker_view(big, aligned=True)[:, 3:])
    options = ["--measured", str(export), "--measured-columns", MARKER_COLUMNS]
    out_dir = ["--out", str(tmp_path / "out")]
    assert main(["verify", "breathing", *PARAMS, *options, *out_dir]) == 2
    first = capsys.readouterr().out
    summary = next(line for line in first.splitlines() if line.startswith("m.csv: latency"))
    assert "e+0" not in first
    assert "RMS error per axis" in summary and " mm (peak " in summary
    x_rms = float(summary.split(": X ")[1].split(" mm")[0])
    assert 2.0 < x_rms < 20.0  # twice a breathing's RMS along X, in mm
    assert "(replacing" not in first
    assert main(["verify", "breathing", *PARAMS, *options, *out_dir]) == 2
    second = capsys.readouterr().out
    assert "(replacing an earlier report of this name, its verdict FAIL)" in second


def test_save_registration_never_replaces_a_file(tmp_path, capsys):
    t, seen = registration_run()
    reg_csv = write_marker_export(tmp_path / "reg.csv", t, seen)
    reg = tmp_path / "REG.yaml"
    reg.write_text("kept\n")
    code = main(
        ["calibrate", "--register", str(reg_csv), "--measured-columns", MARKER_COLUMNS]
        + ["--out", str(reg)]
    )
    err = capsys.readouterr().err
    assert code == 2 and reg.read_text() == "kept\n"
    assert "exists: a registration is never replaced" in err


def test_a_long_follow_says_how_far_it_is(monkeypatch):
    """The follower tells its progress every PROGRESS_S of wall clock (a stream at 1 kHz
    follows for minutes): at 0 s, every 256 arrivals, each count below the whole and rising."""
    from stewart_drake.references import stream as streams

    monkeypatch.setattr(streams, "PROGRESS_S", 0.0)
    motion = make_motion("breathing")
    s = streams.stream_of(motion, 0.2, 100.0, 20.0)
    said = []
    streams.follow(s, "linear", progress=lambda i, n: said.append((i, n)))
    n = s.t.size
    assert len(said) == len(range(0, n, 256))  # every 256th arrival of 2,000
    assert all(b[0] > a[0] for a, b in zip(said, said[1:]))
    assert all(i < total == n for i, total in said)


def test_an_encoder_log_with_a_value_no_run_makes_is_one_line(tmp_path):
    from stewart_drake.calibration.join import read_encoder_log, write_encoder_log

    t = np.arange(50) * 0.01
    q = np.zeros((50, 6))
    path = write_encoder_log(tmp_path / "run_encoders.csv", t, t, t, q)
    lines = path.read_text().splitlines()
    row = lines[20].split(",")
    row[3] = "1e308"  # the first crank's reading, after time, t_run and t_path
    lines[20] = ",".join(row)
    path.write_text("\n".join(lines) + "\n")
    with pytest.raises(InvalidConfigError, match=r"line 21: .* = 1e\+308 rad, beyond the 1e\+07"):
        read_encoder_log(path)
