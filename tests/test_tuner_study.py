"""The tuner study's pieces (tasks, cost, hindsight, our tuner, verdict) and a small
study end to end, resumed."""

import json

import numpy as np
import pytest
from conftest import needs_torch

from stewart_drake.base.errors import InvalidConfigError, MissingFileError
from stewart_drake.control.tuner.network import load_tuner, save_tuner
from stewart_drake.control.tuner.ratio import N_RATIO_INPUTS, RatioTunerModel, ratio_tuner_inputs
from stewart_drake.control.tuning import RatioTunerDriver, WeightSchedule
from stewart_drake.execution.runners import SerialRunner
from stewart_drake.run.metrics import window_means
from stewart_drake.run.scenario import Scenario
from stewart_drake.tuner import ratio_training, study_verdict
from stewart_drake.tuner import study_runs as sr
from stewart_drake.tuner import tuner_study as ts
from stewart_drake.tuner.tuner_report import plot_tuner_tradeoff, render_tuner_markdown

# -- tasks -----------------------------------------------------------------------------------------


# -- cost, schedules, verdict ----------------------------------------------------------------------


def test_window_means_average_each_window():
    t = np.arange(0.0, 1.0, 1e-3)
    values = np.floor(t / 0.2 + 1e-9)  # 0, 1, 2, 3, 4 per window (t = 0.6 is in the 4th)
    np.testing.assert_allclose(window_means(t, values, 1.0, sr.WINDOW_S), [0, 1, 2, 3, 4])


def _records(costs_e, costs_u):
    """{ratio: record} with window costs (13, n) for e2 and u2."""
    return {
        r: {
            "e2_w": np.asarray(e),
            "u2_w": np.asarray(u),
            "e2": float(np.mean(e)),
            "u2": float(np.mean(u)),
        }
        for r, e, u in zip(sr.RATIOS, costs_e, costs_u)
    }


def test_hindsight_picks_the_best_ratio_of_each_window_and_skips_lost_runs():
    rng = np.random.default_rng(0)
    e, u = rng.uniform(1, 2, (13, 5)), rng.uniform(1, 2, (13, 5))
    records = _records(e, u)
    best = e + 0.1 * u
    lost = int(np.argmin(best[:, 0]))
    records[sr.RATIOS[lost]] = {"lost": "fell"}
    best[lost] = np.inf
    t, ratios = sr.hindsight_schedule(records, 0.1)
    np.testing.assert_allclose(t, np.arange(5) * sr.WINDOW_S)
    assert ratios == [sr.RATIOS[k] for k in best.argmin(axis=0)]


def test_verdict_is_the_paired_difference_to_the_best_fixed_ratio_of_each_task():
    tasks = [("dash_hold", 100 + k) for k in range(5)]
    records = {}
    Arm = sr.StudyArm
    for k, task in enumerate(tasks):
        fixed = {
            Arm("fixed", ratio=r): {"e2": 1.0 + abs(np.log10(r) - 0.5 * k % 2), "u2": 0.0}
            for r in sr.RATIOS
        }
        best = min(v["e2"] for v in fixed.values())
        records[task] = {
            **fixed,
            Arm("ours", lam=0.1): {"e2": 0.7 * best, "u2": 0.0},
            Arm("hindsight", lam=0.1): {"e2": (0.9 + 0.02 * k) * best, "u2": 0.0},
            Arm("paper tuner"): {"e2": np.inf, "u2": np.inf},
        }
    v = study_verdict.verdict(records, tasks, 0.1)
    ours, head = v["controllers"]["ours 0.1"], v["controllers"]["hindsight 0.1"]
    assert ours["arm"] == {"kind": "ours", "ratio": None, "lam": 0.1, "shift": None}
    assert ours["mean"] == pytest.approx(-0.3) and ours["std"] == pytest.approx(0.0, abs=1e-12)
    assert ours["beats"]  # 30 % below, beyond a zero spread
    assert head["mean"] == pytest.approx(-0.06) and not head["beats"]  # not 15 %
    assert not v["controllers"]["paper tuner"]["beats"]  # lost: infinite J


# -- our tuner -------------------------------------------------------------------------------------


@needs_torch
def test_ratio_tuner_learns_the_cost_minimizing_ratio_from_the_reference_speed():
    """Synthetic windows whose best ratio is 10 when the reference moves and 0.01 when it holds:
    trained on the interpolated cost, the network picks each side's ratio."""
    rng = np.random.default_rng(1)
    n_w, log_r = 40, np.log10(sr.RATIOS)
    moving = rng.uniform(size=n_w) < 0.5
    runs = {}
    for task in range(2):
        target = np.where(moving, 1.0, -2.0)
        e2_w = np.array([(lr - target) ** 2 + 0.1 for lr in log_r])  # (13, n_w)
        records = {}
        for r in sr.RATIOS:
            x_d = np.zeros((n_w, 18))
            x_d[:, 6] = np.where(moving, 1.0, 0.0)  # |rpy_dot| = 1 rad/s
            records[r] = {
                "e2_w": e2_w[sr.RATIOS.index(r)],
                "u2_w": np.zeros(n_w),
                "inputs": ratio_tuner_inputs(rng.uniform(0, 2, (n_w, 12)), x_d),
                "input_window": np.arange(n_w),
            }
        runs[task] = records
    model = ratio_training.train_ratio_tuner(runs, 0.1, epochs=400)
    x_move, x_hold = np.zeros(18), np.zeros(18)
    x_move[6] = 1.0
    rho = np.ones(12)
    assert model.predict_log10(ratio_tuner_inputs(rho, x_move)) == pytest.approx(1.0, abs=0.3)
    assert model.predict_log10(ratio_tuner_inputs(rho, x_hold)) == pytest.approx(-2.0, abs=0.3)


def test_ratio_tuner_file_round_trips_and_refuses_other_files(tmp_path):
    rng = np.random.default_rng(2)
    model = RatioTunerModel(
        rng.normal(size=(4, N_RATIO_INPUTS)),
        rng.normal(size=4),
        rng.normal(size=(1, 4)),
        rng.normal(size=1),
        np.zeros(N_RATIO_INPUTS),
        np.ones(N_RATIO_INPUTS),
        {"lambda": 0.1},
    )
    path = save_tuner(model, tmp_path / "r.npz")
    again = load_tuner(RatioTunerModel, path)
    inputs = rng.normal(size=(7, N_RATIO_INPUTS))
    np.testing.assert_array_equal(again.predict(inputs), model.predict(inputs))
    assert np.all(again.predict(inputs)[:, 1] == 1.0) and again.metadata == {"lambda": 0.1}
    np.savez(tmp_path / "other.npz", W1=np.zeros(3))
    with pytest.raises(InvalidConfigError, match="is not a valid ratio tuner weights file"):
        load_tuner(RatioTunerModel, tmp_path / "other.npz")
    with pytest.raises(MissingFileError, match="no ratio tuner weights"):
        Scenario(tuner=RatioTunerDriver(weights=str(tmp_path / "none.npz"))).validate()


def test_weight_schedules_are_checked_by_field():
    with pytest.raises(InvalidConfigError, match="tuner.t must be increasing times"):
        Scenario(tuner=WeightSchedule(t=[0.0, 0.0], omega_Q=[1, 1], omega_R=[1, 1])).validate()
    with pytest.raises(InvalidConfigError, match=r"tuner.omega_Q must be in \[0.001, 1000\]"):
        Scenario(tuner=WeightSchedule(t=[0.0], omega_Q=[1e4], omega_R=[1])).validate()


# -- a small study end to end ----------------------------------------------------------------------


@needs_torch
def test_a_small_study_runs_resumes_and_reports(tmp_path, monkeypatch):
    # two ratios, a decade either side of 1, are enough for a best and a worse fixed ratio;
    # each module of the study that reads the ratios holds its own name for them
    for module in (ts, sr, study_verdict, ratio_training):
        monkeypatch.setattr(module, "RATIOS", (0.1, 10.0))
    monkeypatch.setattr(ts, "LAMBDAS", (0.1,))
    monkeypatch.setattr(ts, "SHIFTS", (-1.0, 0.0, 1.0))  # quick keeps (-1, 1)
    monkeypatch.setattr(ts, "train_tasks", lambda quick=False: [("dash_hold", 0)])
    monkeypatch.setattr(ts, "test_tasks", lambda quick=False: [("dash_hold", 100)])
    summary = ts.run_tuner_study(tmp_path, SerialRunner(), quick=True, progress=False)
    v = summary["verdicts"]["0.1"]
    labels = set(v["controllers"])
    assert labels == {
        "hindsight 0.1",
        "ours 0.1",
        "ours closed-loop 0.1",
        "paper tuner",
        "speed schedule",
        "fixed chosen 0.1",
        "fixed gain 1",
    }
    assert v["best_fixed"]["dash_hold_s100"][0] in (0.1, 10.0)
    # fixed: 2 tasks x 2; test baselines 3; hindsight + ours 2; shifts 2 on the training task;
    # ours closed-loop 1. "fixed chosen" reuses the fixed runs.
    assert summary["n_runs"] == 2 * 2 + 3 + 2 + 2 + 1 and summary["lost"] == []
    chosen = summary["chosen"]["0.1"]
    assert chosen["shift"] in (-1.0, 1.0) and chosen["fixed_ratio"] in (0.1, 10.0)
    # the chosen fixed ratio is the training task's best one (one training task), and its
    # verdict on the test task is that ratio's own run
    assert chosen["fixed_means"][str(chosen["fixed_ratio"])] == pytest.approx(1.0)
    point = summary["points"]["dash_hold_s100"][f"fixed {chosen['fixed_ratio']:.3g}"]
    J_best = v["best_fixed"]["dash_hold_s100"][1]
    assert v["controllers"]["fixed chosen 0.1"]["per_task"]["dash_hold_s100"] == pytest.approx(
        (point["e2"] + 0.1 * point["u2"]) / J_best - 1.0
    )
    assert v["controllers"]["fixed chosen 0.1"]["per_task"]["dash_hold_s100"] >= 0.0
    assert (tmp_path / "weights" / "ratio_tuner_lambda0.1.npz").is_file()
    shipped = load_tuner(
        RatioTunerModel, tmp_path / "weights" / "chosen" / "ratio_tuner_lambda0.1.npz"
    )
    assert shipped.metadata["shift"] == chosen["shift"]  # the closed-loop choice
    data = shipped.metadata["data"]
    assert data["training_tasks"] == ["dash_hold_s0"] and data["base_scenario"] == "paper_hardware"
    assert len(data["base_scenario_sha256"]) == 64 and data["quick"] is True
    assert json.loads((tmp_path / "tuner_study.json").read_text())["verdicts"] == json.loads(
        json.dumps(summary["verdicts"])
    )
    monkeypatch.setattr(ts, "study_job", lambda job: pytest.fail("ran again"))
    again = ts.run_tuner_study(tmp_path, SerialRunner(), quick=True, progress=False)
    assert again["verdicts"] == summary["verdicts"]
    md = render_tuner_markdown(again)
    assert "QUICK mode" in md and "| ours |" in md and "**Verdict**" in md
    assert "| ours closed-loop (shift " in md and "| fixed chosen (" in md
    assert plot_tuner_tradeoff(again, tmp_path / "t.png").stat().st_size > 10_000


# -- the shipped tuners ----------------------------------------------------------------------------


def test_the_shipped_ratio_tuners_name_the_data_they_came_from():
    from stewart_drake.control.tuner.ratio import (
        DEFAULT_RATIO_TUNER_PATH,
        RATIO_TUNER_LAMBDAS,
        ratio_tuner_path,
    )

    assert DEFAULT_RATIO_TUNER_PATH == ratio_tuner_path(0.1)
    for lam in RATIO_TUNER_LAMBDAS:
        model = load_tuner(RatioTunerModel, ratio_tuner_path(lam))
        data = model.metadata["data"]
        assert model.metadata["lambda"] == lam and model.metadata["shift"] in sr.SHIFTS
        assert data["base_scenario"] == "paper_hardware" and data["quick"] is False
        assert data["training_tasks"] == [f"{f}_s{s}" for f, s in sr.train_tasks()]
        assert data["task_duration_s"] == sr.TASK_DURATION_S
        assert model.metadata["samples"] > 1000


def test_run_with_our_tuner_uses_the_shipped_weights(tmp_path, capsys):
    """`run --tuner ratio` builds the RatioTuner from the shipped lambda = 0.1 file, and the
    weights it uses move away from the initial [1, 1]."""
    from stewart_drake.cli.main import main
    from stewart_drake.cli.registry import build_parser
    from stewart_drake.control.tuner.ratio import DEFAULT_RATIO_TUNER_PATH, RatioTuner
    from stewart_drake.paper.command import run_scenario
    from stewart_drake.run.diagram import make_stewart_diagram
    from stewart_drake.run.result import load_result

    args = build_parser().parse_args(["run", "--tuner", "ratio", "--duration", "0.3"])
    sd = make_stewart_diagram(run_scenario(args))
    assert isinstance(sd.tuner, RatioTuner)
    assert sd.tuner.model.metadata == load_tuner(RatioTunerModel, DEFAULT_RATIO_TUNER_PATH).metadata
    assert (
        main(
            [
                "run",
                "--tuner",
                "ratio",
                "--duration",
                "0.3",
                "--no-progress",
                "--out",
                str(tmp_path),
            ]
        )
        == 0
    )
    assert f"ratio tuner weights: {DEFAULT_RATIO_TUNER_PATH}" in capsys.readouterr().out
    result = load_result(tmp_path / "run_paper_ratio.npz")
    ratio = result.omega[:, 0] / result.omega[:, 1]
    assert np.all((1e-3 <= ratio) & (ratio <= 1e3)) and np.any(ratio != 1.0)
    assert result.metrics["finite"] and result.metrics["max_closure_m"] < 1e-5
