"""Data set labels (paper and best-cost modes), eq. 26 window costs, and training on a synthetic set
where the weights are a known function of the features."""

import numpy as np
import pytest
from conftest import require_extra

require_extra("train")
import torch  # noqa: E402

from stewart_drake.base.errors import InvalidConfigError
from stewart_drake.control.tuner.ann import TunerModel
from stewart_drake.control.tuner.network import load_tuner
from stewart_drake.tuner.training import (
    Dataset,
    build_dataset,
    r2_scores,
    save_tuner,
    train,
    window_cost,
)

GRID = (0.1, 1.0, 10.0)


def synthetic_runs(n=400, seed=0, dt=0.02):
    """9 runs on {0.1, 1, 10}^2 whose feature means shift with log10 omega: learnable labels."""
    rng = np.random.default_rng(seed)
    runs = []
    for q in GRID:
        for r in GRID:
            rho = rng.uniform(0.5, 1.5, (n, 12))
            rho[:, :6] += 0.3 * np.log10(q)
            rho[:, 6:] += 0.3 * np.log10(r)
            runs.append(
                {
                    "omega_Q": q,
                    "omega_R": r,
                    "t": np.arange(n) * dt,
                    "rho": rho,
                    "cost_e": rng.uniform(0, 1, n) / q,
                    "cost_u": rng.uniform(0, 1, n) / r,
                }
            )
    return runs


def test_window_cost_is_eq26_over_windows():
    t = np.arange(10) * 0.1  # windows of 0.3 s: samples 0-2, 3-5, 6-8, 9
    run = {
        "omega_Q": 1.0,
        "omega_R": 1.0,
        "t": t,
        "rho": np.ones((10, 12)),
        "cost_e": np.arange(10.0),
        "cost_u": np.full(10, 0.5),
    }
    J = window_cost(run, 2.0, 4.0, 0.3)
    np.testing.assert_allclose(
        J, [2 * 3 + 4 * 1.5, 2 * 12 + 4 * 1.5, 2 * 21 + 4 * 1.5, 2 * 9 + 4 * 0.5]
    )


def test_paper_labels_are_each_runs_weights():
    runs = synthetic_runs(n=30)
    ds = build_dataset(runs, "paper")
    assert len(ds) == 270 and ds.rho.shape == (270, 12) and ds.y.shape == (270, 2)
    for i, run in enumerate(runs):
        np.testing.assert_allclose(
            ds.y[ds.run_index == i], np.log10([[run["omega_Q"], run["omega_R"]]] * 30)
        )
    assert ds.info["label_counts"] == {f"{q:g},{r:g}": 30 for q in GRID for r in GRID}


def test_best_cost_labels_by_common_weighting():
    # 3 runs, 40 samples at 10 ms, windows of 0.1 s (10 samples). Unit-weight state costs per
    # window: run A (0.1, 10) is cheap in windows 0 and 1, run B (10, 0.1) in window 2, run C
    # (1, 1) in window 3; no torque cost. With each run's *own* weights A would win every window
    # (0.1 x 3 < 1 x 1), so the labels below also show that the common weights decide.
    t = np.arange(40) * 0.01
    cheap, dear = 1.0, 3.0
    cost = {
        "A": [cheap, cheap, dear, dear],
        "B": [dear, dear, cheap, dear],
        "C": [dear, dear, dear, cheap],
    }
    weights = {"A": (0.1, 10.0), "B": (10.0, 0.1), "C": (1.0, 1.0)}
    runs = [
        {
            "omega_Q": weights[name][0],
            "omega_R": weights[name][1],
            "t": t,
            "rho": np.ones((40, 12)),
            "cost_e": np.repeat(cost[name], 10),
            "cost_u": np.zeros(40),
        }
        for name in "ABC"
    ]
    own = np.array([window_cost(run, run["omega_Q"], run["omega_R"], 0.1) for run in runs])
    assert np.all(np.argmin(own, axis=0) == 0)
    ds = build_dataset(runs, "best_cost", window_s=0.1)
    expected = np.repeat([weights["A"], weights["A"], weights["B"], weights["C"]], 10, axis=0)
    for i in range(3):  # every run's samples get the window's winner
        np.testing.assert_allclose(ds.y[ds.run_index == i], np.log10(expected))
    assert ds.info["windows_won"] == [2, 1, 1] and ds.info["n_windows"] == 4
    # Weighting only the torque, which is zero everywhere: all tie, the first run wins.
    ds_torque = build_dataset(runs, "best_cost", window_s=0.1, common_weights=(0.0, 1.0))
    np.testing.assert_allclose(ds_torque.y, np.log10([weights["A"]] * 120))


def test_best_cost_rejects_different_time_bases():
    runs = synthetic_runs(n=20)
    runs[4]["t"] = runs[4]["t"] * 1.5
    with pytest.raises(InvalidConfigError, match="run 4 has a different time base"):
        build_dataset(runs, "best_cost")
    build_dataset(runs, "paper")  # paper mode does not care


def test_malformed_runs_raise():
    runs = synthetic_runs(n=20)
    del runs[2]["cost_u"]
    with pytest.raises(InvalidConfigError, match=r"run 2 lacks keys \['cost_u'\]"):
        build_dataset(runs)
    runs = synthetic_runs(n=20)
    runs[1]["rho"][3, 5] = np.nan
    with pytest.raises(InvalidConfigError, match="run 1: rho has non-finite"):
        build_dataset(runs)
    runs = synthetic_runs(n=20)
    runs[0]["omega_Q"] = 100.0
    with pytest.raises(InvalidConfigError, match=r"omega_Q must be a number in \[0.1, 10\]"):
        build_dataset(runs)
    with pytest.raises(InvalidConfigError, match="mode"):
        build_dataset(synthetic_runs(n=20), "best")


def test_r2_scores():
    y = np.random.default_rng(0).normal(size=(100, 2))
    assert r2_scores(y, y) == {"omega_Q": 1.0, "omega_R": 1.0, "overall": 1.0}
    mean = np.broadcast_to(y.mean(axis=0), y.shape)
    np.testing.assert_allclose(list(r2_scores(y, mean).values()), 0.0, atol=1e-15)
    const = np.c_[y[:, 0], np.ones(100)]
    assert np.isnan(r2_scores(const, const)["omega_R"])


def test_training_learns_synthetic_weights(tmp_path):
    ds = build_dataset(synthetic_runs(n=400), "paper")  # 3600 samples
    threads = torch.get_num_threads()
    model, report = train(ds, seed=0, epochs=60)
    assert torch.get_num_threads() == threads  # restored
    assert report["n_train"] == 2520 and report["n_val"] == 1080
    assert report["train_loss"] < 0.3 * report["train_loss_initial"]
    assert report["val_loss"] < 0.3 * report["val_loss_initial"]
    assert report["loss_history"][-1] < report["loss_history"][0]
    # Noise caps R^2 near 0.85 on this set; a network that ignored the features would get 0.
    assert report["val_r2"]["overall"] > 0.7
    assert report["val_r2"]["omega_Q"] > 0.7 and report["val_r2"]["omega_R"] > 0.7
    # Same seed, same tuner; the saved file predicts the same and carries the report.
    model2, _ = train(ds, seed=0, epochs=60)
    np.testing.assert_array_equal(model.W1, model2.W1)
    loaded = load_tuner(TunerModel, save_tuner(model, tmp_path / "t.npz"))
    np.testing.assert_array_equal(loaded.predict(ds.rho[:50]), model.predict(ds.rho[:50]))
    assert loaded.metadata["val_r2"] == report["val_r2"] and loaded.metadata["mode"] == "paper"


def test_too_few_samples_to_split():
    ds = Dataset(rho=np.ones((2, 12)), y=np.zeros((2, 2)), run_index=np.zeros(2, int), mode="paper")
    with pytest.raises(InvalidConfigError, match="cannot be split"):
        train(ds)
