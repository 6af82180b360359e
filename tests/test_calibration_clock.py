"""A tracker on its own clock (stewart_drake.calibration.clock): its offset found from the
motion the robot and the tracker both saw, and the join on the robot's clock with it."""

import numpy as np
import pytest

from stewart_drake.base.errors import InvalidConfigError
from stewart_drake.calibration import files, join, poses
from stewart_drake.calibration.clock import estimate_clock_offset
from stewart_drake.calibration.tracker import MeasurementNoise, noisy_poses
from stewart_drake.cli import main as cli
from stewart_drake.robot.geometry import StewartGeometry

GEOMETRY = StewartGeometry()
EPOCH = 1.7e9  # the robot computer's clock: s since the epoch
#: The tracker stamps the time since it started, 12.3456 s before the robot's run.
OFFSET = EPOCH - 12.3456
NOISE = MeasurementNoise(5e-6, 20e-6)


def _session(folder, seed: int, tracker_offset: float = OFFSET, still: bool = False):
    """A path through 4 poses driven exactly: an encoder log at 100 Hz (the path's clock from
    4 s of run time on) and a tracker at 50 Hz with 5 um / 20 urad of noise whose clock is the
    robot's minus ``tracker_offset``; ``still``: the platform never leaves the path's start.
    Returns (poses.csv, windows.csv, log, tracker)."""
    x = poses.candidate_poses(GEOMETRY, 4, seed)
    path = poses.pose_path(GEOMETRY, x, dwell_s=1.5)
    poses_csv, windows_csv = files.write_path(folder / "poses.csv", path)
    t_run = np.arange(0.0, 4.0 + path.t[-1], 0.01)
    t_path = np.where(t_run >= 4.0, t_run - 4.0, np.nan)
    x_run = np.array([np.interp(np.nan_to_num(t_path), path.t, path.x[:, i]) for i in range(6)]).T
    if still:
        x_run[:] = x_run[0]
    q = x_run @ np.arange(36.0).reshape(6, 6) * 1e-2
    log = join.write_encoder_log(folder / "robot_encoders.csv", EPOCH + t_run, t_run, t_path, q)
    # The tracker samples the platform's pose at its own instants, off the log's.
    t_tracker = np.arange(0.0037, t_run[-1], 0.02)
    exact = np.array([np.interp(t_tracker, t_run, x_run[:, i]) for i in range(6)]).T
    x_tracker = noisy_poses(exact, NOISE, np.random.default_rng(seed))
    t_tracker = EPOCH + t_tracker
    tracker = join.write_tracker_file(folder / "tracker.csv", t_tracker - tracker_offset, x_tracker)
    return poses_csv, windows_csv, log, tracker


@pytest.fixture(scope="module")
def session(tmp_path_factory):
    return _session(tmp_path_factory.mktemp("clock"), seed=3)


def test_a_tracker_on_its_own_clock_is_put_on_the_robots_to_a_tenth_of_a_millisecond(session):
    """3 us off here (16 us at most on seeds 3, 5 and 11): the coarse step alone is up to half
    its 0.1 s grid off, a fine step that did not refine would be seen."""
    poses_csv, windows_csv, log, tracker = session
    estimated = join.join(log, tracker, windows_csv, "estimate", poses_csv)
    assert abs(estimated.clock_offset_s - OFFSET) < 1e-4
    assert estimated.clock.samples > 1000
    assert estimated.clock.residual_m < 3e-5  # the tracker's noise: 5 um, 20 urad x 0.15 m
    # The measurements are the join's on the true offset, given.
    given = join.join(log, tracker, windows_csv, OFFSET)
    assert given.clock is None and given.clock_offset_s == OFFSET
    np.testing.assert_allclose(estimated.poses, given.poses, atol=2e-6)
    np.testing.assert_array_equal(estimated.readings, given.readings)
    np.testing.assert_allclose(estimated.windows, given.windows)


def test_without_its_offset_a_tracker_on_its_own_clock_is_refused_with_the_way_out(session):
    poses_csv, windows_csv, log, tracker = session
    with pytest.raises(InvalidConfigError, match="--tracker-clock-offset"):
        join.join(log, tracker, windows_csv)
    with pytest.raises(InvalidConfigError, match="needs the path file"):
        join.join(log, tracker, windows_csv, "estimate")
    with pytest.raises(InvalidConfigError, match="number of seconds or 'estimate'"):
        join.join(log, tracker, windows_csv, float("nan"))


def test_a_tracker_that_saw_another_path_or_no_motion_is_refused(tmp_path, session):
    poses_csv, windows_csv, log, _ = session
    for name in ("other", "still"):
        (tmp_path / name).mkdir()
    other = _session(tmp_path / "other", seed=8)[3]
    with pytest.raises(InvalidConfigError, match="did not see this path"):
        join.join(log, other, windows_csv, "estimate", poses_csv)
    still = _session(tmp_path / "still", seed=3, still=True)[3]
    with pytest.raises(InvalidConfigError, match="tracker never moves"):
        join.join(log, still, windows_csv, "estimate", poses_csv)


def test_the_estimate_refuses_a_span_it_would_not_sample():
    t = np.array([0.0, 1.0, 2.0 * 86400])
    x = np.zeros((3, 6))
    with pytest.raises(InvalidConfigError, match="spans"):
        estimate_clock_offset(t, x, t, x)


def test_the_cli_estimates_the_offset_and_says_it(session, tmp_path, capsys):
    poses_csv, _, log, tracker = session
    out = tmp_path / "measurements.csv"
    argv = ["calibrate", "--join", str(log), str(tracker), "--plan-file", str(poses_csv)]
    assert cli.main([*argv, "--out", str(out), "--tracker-clock-offset", "estimate"]) == 0
    printed = capsys.readouterr().out
    offset = float(printed.split("the tracker's clock + ")[1].split(" s")[0])
    assert abs(offset - OFFSET) < 1e-3
    assert len(out.read_text().splitlines()) == 1 + 4  # the header, a line per pose
    for bad, message in (
        (["--tracker-clock-offset", "soon"], "number of seconds or estimate"),
        (["--tracker-clock-offset", "inf"], "number of seconds or estimate"),
    ):
        assert cli.main([*argv, "--out", str(tmp_path / "m2.csv"), *bad]) == 2
        err = capsys.readouterr().err
        assert message in err and len(err.strip().splitlines()) == 1
        assert not (tmp_path / "m2.csv").exists()
    assert cli.main(["calibrate", "--plan", "12", "--out", str(tmp_path / "p.csv"),
                     "--tracker-clock-offset", "1"]) == 2  # fmt: skip
    assert "is for --join" in capsys.readouterr().err
