"""Fig. 7 shows what its captions say: the zoom holds the largest error with the reference moving
enough for both curves to part, and the feed-forward it subtracts is the one the run used."""

import numpy as np
import pytest

from stewart_drake.paper.run_report import _window_stats, _zoom_window, plot_fig7
from stewart_drake.robot import statics
from stewart_drake.robot.geometry import X_HOME
from stewart_drake.run.plan import make_plan
from stewart_drake.run.scenario import NamedReference, Scenario
from stewart_drake.run.scenario_io import load_scenario
from stewart_drake.run.simulate import run_experiment


def test_the_zoom_holds_the_largest_error_where_the_reference_moves_past_it():
    t = np.arange(0.0, 10.0, 1e-3)
    ref = 0.5 * np.sin(2 * t)
    err = 1e-5 * np.sin(40 * t)
    err[7000] = 3e-4  # the largest error, at t = 7 s
    w = _zoom_window(t, ref, err)
    assert t[w][0] < 7.0 < t[w][-1]
    assert 4 * 3e-4 < np.ptp(ref[w]) < 40 * 3e-4  # apart, and still a zoom
    assert t[w][-1] - t[w][0] < 0.1


def test_window_stats_are_the_means_and_rms_of_each_window():
    t = np.arange(0.0, 0.1, 1e-3)  # 100 samples, two 50 ms windows
    values = np.column_stack([np.where(t < 0.05, 1.0, 3.0), np.tile([1.0, -1.0], 50)])
    t_w, mean, rms = _window_stats(t, values, 0.05)
    np.testing.assert_allclose(t_w, [0.025, 0.075])
    np.testing.assert_allclose(mean, [[1.0, 0.0], [3.0, 0.0]], atol=1e-12)
    np.testing.assert_allclose(rms, [[1.0, 1.0], [3.0, 1.0]])


def test_the_feedforward_is_the_one_the_run_used(tmp_path):
    """Holding home on the ideal robot the feed-forward is gravity's holding torque, and the
    feedback share T - T_ff is what the integral states add: tiny."""
    result = run_experiment(Scenario(duration_s=0.2, reference=NamedReference("home")))
    np.testing.assert_allclose(
        result.T_ff,
        np.tile(
            statics.holding_torques(make_plan(Scenario()).geometry, X_HOME), (len(result.t), 1)
        ),
        rtol=1e-7,  # the logs are float32 (RunResult)
    )
    assert np.abs(result.T - result.T_ff).max() < 1e-3
    assert plot_fig7(result, tmp_path / "f.png").stat().st_size > 20_000


@pytest.mark.parametrize("name", ["paper_hardware", "paper_ideal"])
def test_fig7_draws_every_run_of_the_shipped_scenarios(tmp_path, name):
    result = run_experiment(load_scenario(name, ["duration_s=0.3"]))
    assert result.T_ff.shape == result.T.shape
    assert plot_fig7(result, tmp_path / f"{name}.png").stat().st_size > 20_000
