"""The emulator's truth (live/emulator_process): its true pose and the encoders' pose paired
with the reference on the run's clock (a known motion, known offsets: the errors come back as
put in), and the lines a rehearsal prints."""

from types import SimpleNamespace

import numpy as np
import pytest

from stewart_drake.live.emulator_process import truth_and_reading, truth_lines


class Ramp:
    """x(t) = [0, 0, 0, v t, 0, 0.3]."""

    v = 0.01

    def evaluate(self, t):
        t = np.atleast_1d(np.asarray(t, dtype=float))
        x = np.zeros((t.size, 6))
        x[:, 3], x[:, 5] = self.v * t, 0.3
        return x, np.zeros_like(x), np.zeros_like(x)


def _run(period=0.01, n=300, wall0=100.0, read_offset=(0.0, 0.0, 0.0, 2e-4, 0.0, 0.0)):
    t = np.arange(n) * period
    walls = wall0 + t  # the periods on the wall clock, on time
    ramp = Ramp()
    readings = ramp.evaluate(t)[0] + np.asarray(read_offset)
    driver = SimpleNamespace(
        readings=lambda: (t, walls, None),
        timing=SimpleNamespace(rows=lambda: np.column_stack([walls, np.zeros(n)])),
        pose_readings=lambda: readings,
    )
    sd = SimpleNamespace(station=SimpleNamespace(driver=driver), trajectory=ramp)
    return sd, ramp, walls


def test_the_true_pose_is_paired_on_the_runs_clock_and_the_reading_at_its_period():
    sd, ramp, walls = _run()
    # the plant's steps every 2 ms on the wall clock, 50 um behind on X
    t_true = np.arange(walls[0], walls[-1], 0.002)
    x_true = np.zeros((t_true.size, 12))
    x_true[:, :6] = ramp.evaluate(t_true - walls[0])[0]
    x_true[:, 3] -= 5e-5
    e_true, e_read = truth_and_reading(sd, (t_true, x_true), (1.0, 2.0))
    assert e_true.shape[0] == pytest.approx(500, abs=2)
    np.testing.assert_allclose(e_true[:, 3], -5e-5, atol=1e-12)
    np.testing.assert_allclose(np.delete(e_true, 3, axis=1), 0.0, atol=1e-15)
    assert e_read.shape[0] == 101
    np.testing.assert_allclose(e_read[:, 3], 2e-4, atol=1e-15)


def test_a_wrong_clock_shows_as_error():
    """The truth paired one period off the run's clock would read v h of error: the pairing
    sees it (a test that could not see a wrong clock would pass anything)."""
    sd, ramp, walls = _run()
    t_true = np.arange(walls[0], walls[-1], 0.002)
    x_true = np.zeros((t_true.size, 12))
    x_true[:, :6] = ramp.evaluate(t_true - walls[0] - 0.01)[0]  # 10 ms late
    e_true, _ = truth_and_reading(sd, (t_true, x_true), (1.0, 2.0))
    np.testing.assert_allclose(e_true[:, 3], -ramp.v * 0.01, atol=1e-12)


def test_the_lines_give_true_read_and_floor_per_axis_in_mrad_and_mm():
    sd, ramp, walls = _run()
    t_true = np.arange(walls[0], walls[-1], 0.002)
    x_true = np.zeros((t_true.size, 12))
    x_true[:, :6] = ramp.evaluate(t_true - walls[0])[0]
    floor = np.array([4.6e-4, 4.6e-4, 8.6e-4, 1.34e-4, 1.34e-4, 2e-5])
    lines = truth_lines(sd, (t_true, x_true), (1.0, 2.0), floor)
    x_line = next(line for line in lines if line.split()[:1] == ["X"])
    cells = x_line.split()[1:]
    assert float(cells[0]) < 1e-9 and cells[2:] == ["0.2", "(0.2)", "0.134"]
    assert "cannot see a crank within its count" in lines[-1]
    empty = truth_lines(sd, (np.zeros(0), np.zeros((0, 12))), (1.0, 2.0), floor)
    assert empty == ["the emulator's true pose: no step of its plant inside the measured window"]


def test_on_the_loops_clock_the_truth_is_paired_on_its_own_times_not_the_wall_clock():
    """The emulator on the loop's clock records the loop's time since its first command: the
    truth is paired at those times (here 20 um behind on X), whatever the wall clock did; read
    as wall-clock times it would pair nothing."""
    sd, ramp, walls = _run()
    t_true = np.arange(0.0, 2.99, 0.001)
    x_true = np.zeros((t_true.size, 12))
    x_true[:, :6] = ramp.evaluate(t_true)[0]
    x_true[:, 3] -= 2e-5
    e_true, _ = truth_and_reading(sd, (t_true, x_true), (1.0, 2.0), loop_clock=True)
    assert e_true.shape[0] == pytest.approx(1000, abs=2)
    np.testing.assert_allclose(e_true[:, 3], -2e-5, atol=1e-12)
    on_the_wall, _ = truth_and_reading(sd, (t_true, x_true), (1.0, 2.0))
    assert on_the_wall.shape[0] == 0


def test_the_lines_say_the_emulators_clock_and_a_wall_clock_that_slipped():
    sd, ramp, walls = _run()
    t_true = np.arange(walls[0], walls[-1], 0.002)
    x_true = np.zeros((t_true.size, 12))
    x_true[:, :6] = ramp.evaluate(t_true - walls[0])[0]
    floor = np.full(6, 1e-4)
    slipped = SimpleNamespace(period_s=None, slipped_s=0.325)
    lines = truth_lines(sd, (t_true, x_true), (1.0, 2.0), floor, slipped)
    assert "fell 0.325 s behind the wall clock" in lines[-1]
    assert "figures are the emulator's, not a robot's" in lines[-1]
    kept = SimpleNamespace(period_s=None, slipped_s=0.0)
    assert "behind" not in truth_lines(sd, (t_true, x_true), (1.0, 2.0), floor, kept)[-1]
    loop = SimpleNamespace(period_s=0.01, slipped_s=float("nan"))
    t_loop = t_true - walls[0]
    lines = truth_lines(sd, (t_loop, x_true), (1.0, 2.0), floor, loop)
    assert "on the loop's clock" in lines[-1]
    x_line = next(line for line in lines if line.split()[:1] == ["X"])
    assert float(x_line.split()[1]) < 1e-9  # paired on the loop's times: no error
