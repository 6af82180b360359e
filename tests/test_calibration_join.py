"""The measurements joined from a session's files (stewart_drake.calibration.join): the encoder
log, the tracker's file and the planned windows, into the file ``calibrate`` reads; the
emulated tracker; the reference's clock the encoder log records."""

import numpy as np
import pytest

from stewart_drake.calibration import files, join, poses
from stewart_drake.calibration.tracker import MeasurementNoise, emulated_setup, track
from stewart_drake.cli import main as cli
from stewart_drake.references.homing import HomingReference
from stewart_drake.robot.geometry import StewartGeometry
from stewart_drake.robot.kinematics import X_HOME

GEOMETRY = StewartGeometry()
EPOCH = 1.7e9  # the shared clock: s since the epoch


@pytest.fixture(scope="module")
def session(tmp_path_factory):
    """A planned path through 3 poses and the files of a session that drove it exactly: an
    encoder log at 100 Hz (its t_path the path's clock from 4 s of run time on, readings that
    are a function of the pose) and a tracker file at 50 Hz on the same clock, noiseless."""
    folder = tmp_path_factory.mktemp("session")
    x = poses.candidate_poses(GEOMETRY, 3, 5)
    path = poses.pose_path(GEOMETRY, x, dwell_s=1.5)
    poses_csv, windows_csv = files.write_path(folder / "poses.csv", path)
    t_run = np.arange(0.0, 4.0 + path.t[-1], 0.01)
    t_path = np.where(t_run >= 4.0, t_run - 4.0, np.nan)
    x_run = np.array([np.interp(np.nan_to_num(t_path), path.t, path.x[:, i]) for i in range(6)]).T
    q = x_run @ np.arange(36.0).reshape(6, 6) * 1e-2  # readings that follow the pose
    log = join.write_encoder_log(folder / "robot_encoders.csv", EPOCH + t_run, t_run, t_path, q)
    t_tracker = np.arange(0.0, t_run[-1], 0.02)
    x_tracker = np.array([np.interp(t_tracker, t_run, x_run[:, i]) for i in range(6)]).T
    tracker = join.write_tracker_file(folder / "tracker.csv", EPOCH + t_tracker, x_tracker)
    return path, poses_csv, windows_csv, log, tracker


def test_the_join_averages_each_planned_window_on_the_shared_clock(session):
    path, _, windows_csv, log, tracker = session
    joined = join.join(log, tracker, windows_csv)
    np.testing.assert_allclose(joined.planned, path.poses, atol=1e-12)
    np.testing.assert_allclose(joined.poses, path.poses, atol=1e-9)  # at rest in each window
    np.testing.assert_allclose(joined.readings, path.poses @ np.arange(36.0).reshape(6, 6) * 1e-2)
    # Each window on the shared clock: the path's, 4 s of lead-in later, within a period.
    np.testing.assert_allclose(joined.windows - EPOCH, path.windows + 4.0, atol=0.011)
    assert np.all(joined.readings_used >= 49) and np.all(joined.tracker_used >= 24)
    assert np.max(joined.reading_spread) < 1e-9


def test_the_cli_joins_into_a_measurements_file_calibrate_reads(session, tmp_path, capsys):
    path, poses_csv, _, log, tracker = session
    out = tmp_path / "measurements.csv"
    argv = ["calibrate", "--join", str(log), str(tracker), "--plan-file", str(poses_csv)]
    assert cli.main(argv + ["--out", str(out)]) == 0
    assert "joined 3 poses" in capsys.readouterr().out
    text = out.read_text().splitlines()
    assert text[0].startswith("q0 [rad],") and len(text) == 4
    values = np.loadtxt(out, delimiter=",", skiprows=1)
    np.testing.assert_allclose(values[:, 6:], path.poses, atol=1e-9)


@pytest.mark.parametrize(
    "change, match",
    [
        ("clock", "must be on the robot computer's clock"),
        ("frames", "must measure the platform frame E in the base frame B"),
        ("short", "no reading in the window of pose 2"),
        ("header", "lacks the column Z"),
        ("cell", "line 3, column X: 'x' is not a finite number"),
    ],
)
def test_a_bad_session_file_is_refused_in_one_line_before_anything_is_written(
    session, tmp_path, capsys, change, match
):
    _, poses_csv, _, log, tracker = session
    log_text, tracker_text = log.read_text(), tracker.read_text()
    lines = tracker_text.splitlines()
    if change == "clock":  # the tracker's own clock, an hour off
        t, x = (a := np.loadtxt(tracker, delimiter=",", skiprows=1))[:, 0], a[:, 1:]
        join.write_tracker_file(tmp_path / "t.csv", t + 3600.0, x)
        tracker_text = (tmp_path / "t.csv").read_text()
    elif change == "frames":  # the tracker's frames, not B and E: 2 cm off
        a = np.loadtxt(tracker, delimiter=",", skiprows=1)
        a[:, 4] += 0.02
        join.write_tracker_file(tmp_path / "t.csv", a[:, 0], a[:, 1:])
        tracker_text = (tmp_path / "t.csv").read_text()
    elif change == "short":  # the run ended before the last window
        log_lines = log_text.splitlines()
        log_text = "\n".join(log_lines[: len(log_lines) * 2 // 3]) + "\n"
    elif change == "header":
        tracker_text = "\n".join([lines[0].replace(",Z [m]", ",height [m]")] + lines[1:])
    else:
        cells = lines[2].split(",")
        cells[4] = "x"
        tracker_text = "\n".join(lines[:2] + [",".join(cells)] + lines[3:])
    (tmp_path / "log.csv").write_text(log_text)
    (tmp_path / "tracker.csv").write_text(tracker_text)
    out = tmp_path / "m.csv"
    argv = ["calibrate", "--join", str(tmp_path / "log.csv"), str(tmp_path / "tracker.csv")]
    assert cli.main(argv + ["--plan-file", str(poses_csv), "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip()
    assert match in err and len(err.splitlines()) == 1, err
    assert not out.exists()


def test_a_tracker_in_its_own_frame_is_joined_through_its_registration(session, tmp_path, capsys):
    # The tracker measured its marker in its own frame, 1 m and 30 deg from the base, on its
    # own clock (100 s late): the windows' gaps and the clock's estimate compare its poses
    # with the path in the base frame, and the measurements keep its frame for calibrate.
    path, poses_csv, _, log, tracker = session
    setup = emulated_setup(GEOMETRY)
    a = np.loadtxt(tracker, delimiter=",", skiprows=1)
    seen = join.write_tracker_file(
        tmp_path / "t.csv", a[:, 0] - 100.0, setup.tracker_poses(a[:, 1:])
    )
    reg = files.write_registration(
        tmp_path / "reg.yaml", setup.fiducials(MeasurementNoise(1e-7, 1e-6), 0, 1e-7)
    )
    out = tmp_path / "m.csv"
    argv = ["calibrate", "--join", str(log), str(seen), "--plan-file", str(poses_csv)]
    argv += ["--tracker-clock-offset", "estimate", "--out", str(out)]
    assert cli.main(argv) == 2
    err = capsys.readouterr().err  # the poses are not B and E: said, and nothing written
    assert "mm RMS from the planned path" in err and "--registration" in err and not out.exists()
    assert cli.main(argv + ["--registration", str(reg)]) == 0
    printed = capsys.readouterr().out
    assert "the tracker's clock + 100.0000 s" in printed and "--registration" in printed
    values = np.loadtxt(out, delimiter=",", skiprows=1)
    np.testing.assert_allclose(values[:, 6:], setup.tracker_poses(path.poses), atol=1e-9)


def test_join_mode_refuses_a_missing_plan_file_or_a_stray_option(tmp_path, capsys):
    base = ["calibrate", "--join", "a.csv", "b.csv", "--out", str(tmp_path / "m.csv")]
    assert cli.main(base) == 2
    assert "--join and --plan-file go together" in capsys.readouterr().err
    assert cli.main(["calibrate", "--plan", "12", "--bus", str(tmp_path), "--out", "p.csv"]) == 2
    assert "--bus is for --rehearse" in capsys.readouterr().err
    assert cli.main(["calibrate", "--rehearse", "--bus", str(tmp_path), "--out", "r.yaml"]) == 2
    assert "leave out --out" in capsys.readouterr().err


def test_the_emulated_tracker_samples_the_record_at_its_rate_with_its_noise():
    t = np.arange(0.0, 10.0, 0.002)
    x = np.tile(X_HOME, (len(t), 1))
    x[:, 3] = 0.01 * t  # moving along X at 10 mm/s
    noise = MeasurementNoise(5e-6, 20e-6)
    times, tracked = track(t, x, noise, seed=1, rate_hz=50.0)
    np.testing.assert_allclose(np.diff(times), 0.02)
    truth = np.tile(X_HOME, (len(times), 1))
    truth[:, 3] = 0.01 * t[np.searchsorted(t, times, side="right") - 1]
    e = tracked - truth
    assert abs(np.std(e[:, 3:]) / 5e-6 - 1) < 0.1 and abs(np.std(e[:, :3]) / 20e-6 - 1) < 0.1
    assert abs(np.mean(e[:, 3:])) < 1e-6


def test_the_encoder_log_s_path_clock_is_the_homed_reference_s_own():
    x0 = X_HOME
    ref = type("Held", (), {"evaluate": lambda self, t: (np.tile(x0, (np.size(t), 1)),) * 3})()
    homed = HomingReference(ref, x0, home_s=3.0, t_end=20.0, ramp_s=1.0)
    tau = homed.reference_time(np.array([0.0, 2.9, 5.0, 10.0]))
    assert np.all(np.isnan(tau[:2]))
    # Past the ramp, the reference's clock runs at its own rate, half the ramp behind.
    np.testing.assert_allclose(tau[2:], [5.0 - 3.5, 10.0 - 3.5])


def test_the_robot_command_drives_a_planned_path_whole_unless_told(session):
    from stewart_drake.cli.registry import build_parser
    from stewart_drake.live.command import _robot_reference
    from stewart_drake.run.scenario import Scenario

    path, poses_csv, *_ = session
    args = build_parser().parse_args(["robot", str(poses_csv)])
    _robot_reference(args, Scenario())
    assert args.duration == pytest.approx(path.t[-1])
    args = build_parser().parse_args(["robot", str(poses_csv), "--duration", "5"])
    _robot_reference(args, Scenario())
    assert args.duration == 5.0


def test_an_encoder_logs_bus_line_is_read_back_and_bounded(tmp_path):
    """The ``# bus:`` line written under the header comes back as written (whitespace and a
    newline inside folded to one line); a log without it says "" and is read the same; a file of
    a thousand comments keeps only the first 16 for its reader, the rows all read."""
    t = np.arange(5) * 0.01
    q = np.zeros((5, 6))
    path = join.write_encoder_log(tmp_path / "a.csv", t, t, t, q, bus="emulated: ideal\n  servos")
    log = join.read_encoder_log(path)
    assert log["bus"] == "emulated: ideal servos" and len(log["time"]) == 5
    plain = join.write_encoder_log(tmp_path / "b.csv", t, t, t, q)
    assert join.read_encoder_log(plain)["bus"] == ""
    text = plain.read_text().splitlines()
    many = tmp_path / "c.csv"
    many.write_text("\n".join([text[0]] + [f"# note {k}" for k in range(1000)] + text[1:]) + "\n")
    comments: list = []
    out = join.read_table(
        many, "encoder log", join.ENCODER_LOG_COLUMNS, "", ("t_path",), comments=comments
    )
    assert comments == [f"note {k}" for k in range(16)] and len(out["time"]) == 5
