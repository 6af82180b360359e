"""Baselines behind the same ports, robustness conditions, metrics and the report."""

import json
import re
from pathlib import Path

import numpy as np
import pytest

from stewart_drake.base.errors import InvalidConfigError
from stewart_drake.cli.main import main
from stewart_drake.evaluation.evaluation_grid import RATIO_LQI, cases, grid_controller
from stewart_drake.evaluation.evaluation_report import ann_verdict
from stewart_drake.references.trajectories import StepTrajectory, make_trajectory
from stewart_drake.run.diagram import make_stewart_diagram
from stewart_drake.run.metrics import frequency_response, settling_time
from stewart_drake.run.scenario import LqiDriver, NamedReference, PdDriver, Scenario
from stewart_drake.run.simulate import run_experiment
from stewart_drake.station.station import SensorNoise

REPO = Path(__file__).resolve().parent.parent


def test_pd_baseline_tracks_the_paper_manoeuvre():
    """Through t = 2.4 s (phi = -0.52 rad, Z = 0.25 m), where gains fixed at home diverge: one
    mode's joint-space inertia is 24x smaller there (docs of CrankPdController)."""
    r = run_experiment(Scenario(controller=PdDriver(), duration_s=3.0))
    m = r.metrics
    assert m["max_closure_m"] < 1e-5 and m["finite"]
    assert m["rms_error"][0] < 5e-4 and m["rms_error"][5] < 5e-5  # phi < 0.5 mrad, Z < 50 um
    assert m["status"] == {"inertia_reschedules": 300, "failures": 0}  # every 10 ms
    assert "gain_solves" not in m and r.omega is None


def test_unknown_payload_sags_the_pd_but_not_the_lqi():
    """+20 % platform mass the feed-forward does not know: the PD (no integral) holds home with a
    steady sag close to the statics' prediction; the LQI's integral removes it."""
    from stewart_drake.control.pd import CrankPdController
    from stewart_drake.robot import kinematics
    from stewart_drake.robot.geometry import X_HOME, StewartGeometry
    from stewart_drake.robot.statics import crank_inertia_matrix

    g = StewartGeometry()
    cfg = dict(reference=NamedReference("home"), duration_s=1.5, payload_scale=1.2)
    sd = make_stewart_diagram(Scenario(**cfg))
    assert sd.plant.GetBodyByName("platform").default_mass() == pytest.approx(1.2)
    assert sd.controller.geometry.platform_mass == pytest.approx(1.0)
    pd = run_experiment(Scenario(controller=PdDriver(), **cfg))
    lqi = run_experiment(Scenario(**cfg))
    sag_pd = pd.x[-1, 5] - X_HOME[5]
    # Predicted: extra weight 0.2 g through the crank stiffness K_p = w^2 M_theta, mapped to Z.
    pd_ctrl = CrankPdController(g)
    J = kinematics.jacobian(g, X_HOME)
    K_x = J.T @ pd_ctrl.K_p @ J
    predicted = -np.linalg.solve(K_x, np.r_[0, 0, 0, 0, 0, 0.2 * g.gravity])[5]
    assert sag_pd == pytest.approx(predicted, rel=0.1)
    assert abs(lqi.x[-1, 5] - X_HOME[5]) < 0.01 * abs(sag_pd)
    assert crank_inertia_matrix(g).shape == (6, 6)


def test_torque_saturation_limits_the_applied_torque():
    """The 5 mm Z step asks the LQI (1, 1) for 1.5 N m; limited to 0.6 N m it still settles,
    later than unsaturated (0.103 s)."""
    r = run_experiment(
        Scenario(reference=NamedReference("step_Z"), duration_s=1.5, torque_limit_Nm=0.6)
    )
    assert np.abs(r.T).max() <= 0.6 + 1e-12
    assert np.abs(r.T).max() == pytest.approx(0.6)
    t_s = settling_time(r.t, r.x[:, 5] - r.x_d[:, 5], 0.005, 0.5)
    assert 0.103 < t_s < 0.3


def test_sensor_noise_is_seeded_and_metrics_use_the_true_pose():
    noise = (1e-4,) * 3 + (5e-5,) * 3 + (1e-2,) * 3 + (5e-3,) * 3
    a = run_experiment(Scenario(duration_s=0.5, sensor_noise=SensorNoise(list(noise))))
    b = run_experiment(Scenario(duration_s=0.5, sensor_noise=SensorNoise(list(noise))))
    c = run_experiment(Scenario(duration_s=0.5, sensor_noise=SensorNoise(list(noise), seed=1)))
    clean = run_experiment(Scenario(duration_s=0.5))
    np.testing.assert_array_equal(a.x, b.x)
    assert not np.array_equal(a.T, c.T) and not np.array_equal(a.T, clean.T)
    # The logged pose is the plant's, not the measurement: the step-to-step change of a white
    # 0.05 mm measurement noise would have a std of 0.05 mm sqrt 2 = 71 um.
    assert np.std(np.diff(a.x[:, 5] - a.x_d[:, 5])) < 0.5 * 5e-5 * np.sqrt(2)
    with pytest.raises(InvalidConfigError, match="sensor_noise.std"):
        Scenario(sensor_noise=SensorNoise([-1.0] * 12))


def test_the_sweep_s_acceleration_cap_has_its_derivatives_and_keeps_the_gain():
    """The shipped sweeps: the full amplitude below the corner, a constant acceleration above
    it, rate and acceleration the derivatives of the pose (finite differences away from the
    corner's kink and the end of the sweep), and the same low-pass read back through the
    envelope as through a constant amplitude."""
    from stewart_drake.references.trajectories import SWEEP_AMPLITUDE, SWEEP_MAX_ACCELERATION, sweep

    chirp = sweep("Z")
    corner = np.sqrt(SWEEP_MAX_ACCELERATION[1] / SWEEP_AMPLITUDE[1]) / (2 * np.pi)
    assert corner == pytest.approx(31.6, abs=0.1)
    t = np.arange(0.01, 9.9, 2.5e-5)
    x, x_dot, x_ddot = (v[:, 5] for v in chirp.evaluate(t))
    assert np.max(np.abs(x - chirp.offset[5])) == pytest.approx(2e-4, rel=1e-6)
    late = t > 8.0  # held at 50 Hz: 0.08 mm, 7.9 m/s^2
    assert np.max(np.abs(x[late] - chirp.offset[5])) == pytest.approx(8e-5, rel=1e-3)
    assert np.max(np.abs(x_ddot)) == pytest.approx(SWEEP_MAX_ACCELERATION[1], rel=1e-3)
    t_corner = chirp.duration_s * np.log(corner / chirp.f0_hz) / np.log(chirp.f1_hz / chirp.f0_hz)
    away = (np.abs(t - t_corner) > 2e-3) & (np.abs(t - chirp.duration_s) > 2e-3)
    for value, rate in ((x, x_dot), (x_dot, x_ddot)):
        error = np.abs(np.gradient(value, t) - rate)[away][2:-2]
        assert error.max() < 2e-3 * np.abs(rate).max()

    f_c = 10.0  # the low-pass again, through the envelope
    t = np.arange(0, 8, 1e-3)
    f_t = chirp.frequency(t)
    g = 1 / np.sqrt(1 + (f_t / f_c) ** 2)
    y = chirp.offset[5] + chirp.envelope(t)[0] * g * np.sin(chirp.phase(t) - np.arctan(f_t / f_c))
    f, gain, _ = frequency_response(t, y, chirp)
    np.testing.assert_allclose(gain, 1 / np.sqrt(1 + (f / f_c) ** 2), rtol=0.02)


def test_scenarios_are_reachable_and_named():
    from stewart_drake.robot.geometry import StewartGeometry
    from stewart_drake.run.plan import validate_reference as validate

    g = StewartGeometry()
    for name in ("helix", "step_phi", "step_Z", "sweep_Z", "sweep_phi"):
        traj = make_trajectory(name)
        assert traj.name == name
        assert validate(traj, g, 10.0).ok
    s = make_trajectory("step_X")
    assert isinstance(s, StepTrajectory) and s.axis == 3
    x, xd, _ = make_trajectory("sweep_Z").evaluate(np.array([0.0, 1e-3]))
    assert xd[0, 5] == pytest.approx((x[1, 5] - x[0, 5]) / 1e-3, rel=1e-3)
    with pytest.raises(InvalidConfigError, match="axis"):
        StepTrajectory(axis="W")


def test_grid_and_controller_names():
    grid = cases()
    # 10 nominal scenarios + 7 conditions (payload +-20 %, noise, saturation, 3 tool
    # disturbances) each, + 5 encoder resolutions for the 5 weight ratios (hardware base)
    assert len(grid) == 12 * (10 + 7) + 5 * 5
    assert {c.condition for c in grid if c.reference == "home" and c.condition != "nominal"} == {
        "push 5 N",
        "twist 0.2 N m",
        "contact 2 Hz",
    }
    assert {c.controller.name for c in grid if c.condition.startswith("encoders")} == set(RATIO_LQI)
    assert {(c.reference, c.condition) for c in grid if c.condition.startswith("saturation")} == {
        ("step_Z", "saturation 0.6 N m")
    }
    assert {c.controller.name for c in grid} >= {"lqi_0.1_10", "pd", "ann_best_cost", "ann_paper"}
    # typed: a fixed LQI keeps the base's LQI options at its weights; the ANN tunes the base's
    base = Scenario(controller=LqiDriver(riccati="cold"))
    lqi = grid_controller("lqi_10_0.1", base)
    assert (
        (lqi.controller.omega_Q, lqi.controller.omega_R, lqi.controller.riccati)
        == (10.0, 0.1, "cold")
        and lqi.ratio == 100.0
        and lqi.tuner is None
    )
    ann = grid_controller("ann_paper", base)
    assert ann.controller == base.controller and ann.tuner.weights.endswith("ann_tuner_paper.npz")
    assert isinstance(grid_controller("pd", base).controller, PdDriver)
    with pytest.raises(InvalidConfigError, match="unknown controller"):
        grid_controller("lqr", Scenario())


def test_verdict_compares_at_no_more_feedback_effort():
    # the total Sum T^2 dt (gravity's) is the same for all and must not decide admissibility
    def row(c, nrms, effort):
        return {
            "case": {"controller": c, "scenario": "paper", "condition": "nominal"},
            "normalized_rms": nrms,
            "sum_dT2_dt": effort,
            "sum_T2_dt": 4.3 - 0.001 * nrms,
        }

    rows = [
        row("lqi_1_1", 1.0, 1.0),
        row("lqi_10_0.1", 0.1, 2.0),
        row("ann_best_cost", 0.5, 1.5),
        row("ann_paper", 2.0, 0.9),
    ]
    v = ann_verdict(rows)
    assert (
        v["ann_best_cost"]["beats"]
        and v["ann_best_cost"]["best_fixed"]["case"]["controller"] == "lqi_1_1"
    )
    assert v["ann_best_cost"]["ratio"] == pytest.approx(0.5)
    assert v["ann_paper"]["best_fixed"] is None and not v["ann_paper"]["beats"]


#: The cases of the default tier's report: one for each panel of its figures (the trade-off's
#: paper run nominal and with noise, the bandwidth's two sweeps, the steps' Z step) and the
#: push the motors cannot hold. The slow tier's report runs every case.
REPORT_CASES = {("paper", "nominal"), ("paper", "noise"), ("step_Z", "nominal")}
REPORT_CASES |= {("sweep_Z", "nominal"), ("sweep_phi", "nominal"), ("home", "push 5 N")}


@pytest.mark.parametrize(
    "controllers, every_case",
    [
        pytest.param(("pd",), False, id="pd"),
        # Every case of the grid: the PD's 17 and the LQI's 22 (its encoders' 5 among them).
        pytest.param(("lqi_1_1", "pd"), True, id="lqi-and-pd", marks=pytest.mark.slow),
    ],
)
def test_evaluate_writes_the_report_under_out_and_never_over_the_docs(
    tmp_path, capsys, controllers, every_case, monkeypatch
):
    import dataclasses

    from stewart_drake.evaluation import evaluation

    # The report needs its cases whole, not --quick's 1 s of each: the 1 s runs (paper, helix,
    # steps, payload, noise, saturation) are cut to 0.6 s, still past the Z step's settling and
    # the saturated transient; the sweeps and the held disturbances keep their 2 s.
    full_grid = evaluation.cases
    monkeypatch.setattr(
        evaluation,
        "cases",
        lambda *a, **k: [
            dataclasses.replace(c, duration_s=0.6) if c.duration_s == 1.0 else c
            for c in full_grid(*a, **k)
            if every_case or (c.reference, c.condition) in REPORT_CASES
        ],
    )
    committed = (REPO / "docs" / "results.md").read_bytes()
    out = tmp_path / "out"
    assert (
        main(
            [
                "evaluate",
                "--quick",
                "--controllers",
                ",".join(controllers),
                "--runner",
                "serial",
                "--out",
                str(out),
                "--no-progress",
            ]
        )
        == 0
    )
    assert (REPO / "docs" / "results.md").read_bytes() == committed
    md = (out / "results.md").read_text()
    assert "QUICK mode" in md and all(f"| {c} |" in md for c in controllers)
    for name in ("results_tradeoff.png", "results_bandwidth.png", "results_steps.png"):
        assert (out / name).stat().st_size > 10_000
    rows = json.loads((out / "rows.json").read_text())["rows"]
    encoders = 5 if "lqi_1_1" in controllers else 0  # lqi_1_1: the encoders
    per_controller = 10 + 7 if every_case else len(REPORT_CASES)
    assert len(rows) == len(controllers) * per_controller + encoders
    assert f"wrote {out / 'results.md'}" in capsys.readouterr().out
    # The 5 N push at the tool tip needs 0.91 N m at the cranks, beyond the servos' 0.70 N m:
    # it is lost, and only it; the report says why.
    lost = {(r["case"]["controller"], r["case"]["condition"]) for r in rows if "error" in r}
    assert lost == {(c, "push 5 N") for c in controllers}
    assert "push 5 N 0.907 N m (beyond the motors' limit: no controller can hold it)" in md
    step = next(
        r for r in rows if r["case"]["scenario"] == "step_Z" and r["case"]["controller"] == "pd"
    )
    assert 0.01 < step["settling_time_s"] < 0.3


def test_evaluate_cli_refuses_unknown_controllers(capsys, tmp_path):
    code = main(
        ["evaluate", "--controllers", "lqi_1_1,magic", "--docs", str(tmp_path), "--no-progress"]
    )
    err = capsys.readouterr().err
    assert code == 2 and "unknown controller 'magic'" in err and len(err.splitlines()) == 1


def test_the_evaluation_says_which_failures_the_sizing_explains():
    from stewart_drake.evaluation.command import _why_failed
    from stewart_drake.evaluation.evaluation_report import disturbance_holding_torques

    needs, limit = disturbance_holding_torques("paper_hardware")
    assert needs["push 5 N"] > limit > needs["twist 0.2 N m"]  # 0.907 > 0.702 > 0.443 N m
    rows = [{"case": {"condition": "push 5 N"}, "error": "lost"}] * 2 + [
        {"case": {"condition": "nominal"}, "error": "a bug"}
    ]
    why = _why_failed(rows, "paper_hardware")
    assert why.startswith(": 2 under push 5 N, which needs more holding torque than the motors'")
    assert why.endswith("; 1 for other reasons")
    assert _why_failed([], "paper_hardware") == ""


def _paper_rows_and_tuner_of(md: str):
    """The paper table's rows and the tuner study's paper-tuner entries, read back from a
    report's text (the figures as printed)."""
    lines = md.splitlines()
    (i,) = [
        k for k, ln in enumerate(lines) if ln.startswith("| controller | phi |") and "nRMS" in ln
    ]
    header = [h.strip() for h in lines[i].strip("|").split("|")]
    rows = []
    for line in lines[i + 2 :]:
        if not line.startswith("|"):
            break
        cell = dict(zip(header, (c.strip() for c in line.strip("|").split("|"))))
        rows.append(
            {
                "case": dict(controller=cell["controller"], scenario="paper", condition="nominal"),
                "normalized_rms": float(cell["nRMS"]),
                "sum_dT2_dt": float(cell["feedback Sum dT^2 dt"]),
                "sum_T2_dt": float(cell["Sum T^2 dt"]),
            }
        )
    verdicts = {}
    for lam, mean, std in re.findall(
        r"^### lambda = (\S+)\n(?:.*\n)*?\| paper tuner \| ([+-]\d+) % \+- (\d+) % \|", md, re.M
    ):
        entry = {"mean": int(mean) / 100, "std": int(std) / 100, "beats": False}
        verdicts[lam] = {"controllers": {"paper tuner": entry}}
    return rows, {"settings": {"quick": False}, "verdicts": verdicts}


def test_the_ann_section_leads_with_the_held_out_verdict_not_one_run():
    """docs/results.md's ANN section, as the generator writes it for the report's own figures:
    the tuner study's answer first, and no one-run "beats"."""
    from stewart_drake.evaluation.evaluation_grid import index_rows
    from stewart_drake.evaluation.evaluation_report import _verdict_lines

    md = (REPO / "docs" / "results.md").read_text()
    rows, tuner = _paper_rows_and_tuner_of(md)
    assert len(rows) == 12 and set(tuner["verdicts"]) == {"0.01", "0.1", "1"}
    section = "\n".join(_verdict_lines(index_rows(rows), [], tuner))
    assert section in md
    first = section.split("\n\n")[1]
    assert first.startswith("**No**, over the held-out tasks of the tuner study")
    assert "lambda = 0.01: +1785 % +- 2185 %" in first
    assert "beats" not in section
    assert "- **ann_best_cost** tracks better on this one run than" in section  # its one run
    alone = "\n".join(_verdict_lines(index_rows(rows), [], None))
    assert alone.split("\n\n")[1].startswith("**Not decided here**")


def test_the_bandwidth_table_and_figure_say_below_and_above_the_sweep(tmp_path):
    from stewart_drake.evaluation.evaluation_grid import index_rows
    from stewart_drake.evaluation.evaluation_plots import plot_results
    from stewart_drake.evaluation.evaluation_report import _bandwidth_table

    f = np.geomspace(2.43, 49.4, 30)

    def sweep_row(controller, reference, gain_db, lag_s=0.01):
        return {
            "case": {"controller": controller, "scenario": reference, "condition": "nominal"},
            # what a row stored before the bandwidth said "below the sweep" held: f[0]
            "bandwidth_hz": float(f[0]),
            "peak_gain_db": float(np.max(gain_db)),
            "response": {
                "f": f.tolist(),
                "gain": (10 ** (np.asarray(gain_db) / 20)).tolist(),
                "phase": (-2 * np.pi * f * lag_s).tolist(),
            },
        }

    rows = [
        sweep_row("lqi_0.1_10", "sweep_Z", np.full(30, -3.8)),
        sweep_row("lqi_0.1_10", "sweep_phi", np.full(30, 1.4)),
    ]
    by = index_rows(rows)
    table = _bandwidth_table(by, ["lqi_0.1_10"])
    line = next(row for row in table if row.startswith("| lqi_0.1_10"))
    assert line.split("|")[2].strip() == "< 2.43 (below the sweep)"
    assert line.split("|")[4].strip() == "> 49.4 (above the sweep)"
    assert "measured from 2.43 to 49.4 Hz" in "\n".join(_bandwidth_table(by, []))
    paths = plot_results(rows, tmp_path)
    assert paths[1].name == "results_bandwidth.png" and paths[1].stat().st_size > 10_000
