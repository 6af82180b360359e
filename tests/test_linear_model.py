"""The linear models of the robot and the LQI at a pose, their loop figures, and their agreement
with the nonlinear Drake plant."""

from pathlib import Path

import numpy as np
import pytest
from conftest import extra_missing

from stewart_drake.analysis.loop_analysis import (
    axis_figures,
    frequency_grid,
    loop_models,
    margins,
    measure_tracking,
    tracking_response,
)
from stewart_drake.base.errors import InvalidConfigError
from stewart_drake.control.linear_model import (
    closed_loop,
    loop_at_a_time,
    lqi_design,
    lqi_model,
    plant_model,
)
from stewart_drake.control.lqi.driver import LqiDriver
from stewart_drake.control.lqi.gain import error_model, input_matrix
from stewart_drake.robot import kinematics
from stewart_drake.robot.geometry import X_HOME, reference_geometry
from stewart_drake.run.scenario_io import load_scenario

H = 1e-3
# This checkout's scenarios (a shipped name resolves to the installed package's).
SCENARIOS = Path(__file__).resolve().parents[1] / "scenarios"
IDEAL, BUILT = SCENARIOS / "paper_ideal.yaml", SCENARIOS / "paper_hardware.yaml"


def test_without_gravity_friction_or_delay_the_plant_is_the_lqi_s_design_model():
    g = reference_geometry().replace(gravity=0.0)
    x0 = X_HOME + np.array([0.1, -0.05, 0.08, 0.01, -0.02, 0.0])
    plant = plant_model(g, x0, H, integrator="zoh")
    A, B = error_model(input_matrix(g, x0), H)
    np.testing.assert_allclose(plant.A, A[:12, :12], atol=1e-12)
    np.testing.assert_allclose(plant.B, B[:12], rtol=1e-9, atol=1e-15)
    # The loop closed on it has the design's closed-loop eigenvalues (eq. 34's A - B K).
    _, _, K = lqi_design(g, x0, H)
    loop = closed_loop(plant, lqi_model(g, x0, H), kinematics.jacobian(g, x0))
    ours = np.sort_complex(np.linalg.eigvals(loop.A))
    np.testing.assert_allclose(ours, np.sort_complex(np.linalg.eigvals(A - B @ K)), atol=1e-9)
    # SAP steps the position with the new velocity: h^2 instead of h^2 / 2 per unit of input.
    sap = plant_model(g, x0, H)
    np.testing.assert_allclose(sap.B[:6], 2 * plant.B[:6], rtol=1e-9)


def test_delay_and_current_loop_shape_the_plant_input():
    g = reference_geometry()
    base = plant_model(g, X_HOME, H)
    late = plant_model(g, X_HOME, H, delay_periods=2)
    lag = plant_model(g, X_HOME, H, current_time_constant_s=0.385e-3)

    def impulse(m, n=6):
        x, out = np.zeros(m.A.shape[0]), []
        for k in range(n):
            x = m.A @ x + m.B @ (np.eye(6)[5] if k == 0 else np.zeros(6))
            out.append((m.C @ x)[5])
        return np.array(out)

    np.testing.assert_allclose(impulse(late)[2:], impulse(base)[:4], rtol=1e-12)
    assert np.all(impulse(late)[:2] == 0)
    # The current loop passes the whole torque at DC (the step's impulse is kept) but spreads it.
    assert (
        abs(
            lag.frequency_response([1e-3])[0, 11, 5] / base.frequency_response([1e-3])[0, 11, 5] - 1
        )
        < 1e-3
    )
    assert impulse(lag)[0] < impulse(base)[0]
    assert plant_model(g, X_HOME, H, delay_periods=1).to_drake().time_period() == H
    with pytest.raises(InvalidConfigError, match="integrator"):
        plant_model(g, X_HOME, H, integrator="euler")


def test_margins_of_a_known_loop():
    # L = w_c / (i w) exp(-i w T): crossover w_c, phase margin 90 deg - w_c T, phase -180 deg at
    # w_180 = pi / (2 T), gain margin w_180 / w_c.
    f = np.geomspace(0.1, 400, 20000)
    w, w_c, T = 2 * np.pi * f, 2 * np.pi * 10.0, 5e-3
    fc, pm, delay, gm, gm_low = margins(f, w_c / (1j * w) * np.exp(-1j * w * T))
    assert fc == pytest.approx(10.0, rel=1e-4)
    assert pm == pytest.approx(90 - np.degrees(w_c * T), abs=0.01)
    assert delay == pytest.approx(np.radians(pm) / w_c, rel=1e-6)
    assert gm == pytest.approx(20 * np.log10(np.pi / (2 * T) / w_c), abs=0.01)
    assert gm_low == -np.inf


def test_loop_figures_of_the_ideal_and_the_built_robot_at_home():
    ideal = axis_figures(loop_models(load_scenario(IDEAL)))
    built = axis_figures(loop_models(load_scenario(BUILT)))
    for a in ideal:  # the LQI's loops: phase margins above 50 deg, Ms below 1.3
        assert a.phase_margin_deg > 50 and a.Ms < 1.3 and a.gain_margin_db == np.inf
    z = ideal[5]
    assert z.crossover_hz == pytest.approx(22.6, abs=0.2)
    assert z.bandwidth.hz == pytest.approx(31.7, abs=0.3)
    # The delay, the current loop and the 100 Hz rate filter cost roll and pitch most of their
    # margin on the robot as built (crossover near 60 Hz).
    assert built[0].phase_margin_deg < 20 and built[0].Ms > 4
    assert built[5].phase_margin_deg == pytest.approx(44.0, abs=1.0)


def test_the_loop_in_python_control_has_the_same_margins():
    if extra_missing("analysis"):
        pytest.skip(extra_missing("analysis"))
    import control

    models = loop_models(load_scenario(BUILT))
    loop = loop_at_a_time(models.open, 5).to_control()
    assert loop.dt == H and loop.nstates == models.open.A.shape[0]
    # On the frequency response of its StateSpace (its polynomial route is ill-conditioned on
    # 42 states): the same crossover, phase margin and both gain margins as ours.
    w = 2 * np.pi * frequency_grid(H)
    gm, pm, _, wpc, wgc, _ = control.stability_margins(
        control.frequency_response(loop, w), returnall=True
    )
    ours = axis_figures(models)[5]
    assert pm[0] == pytest.approx(ours.phase_margin_deg, abs=0.05)
    assert wgc[0] / (2 * np.pi) == pytest.approx(ours.crossover_hz, rel=1e-3)
    assert 20 * np.log10(gm.max()) == pytest.approx(ours.gain_margin_db, abs=0.05)
    assert 20 * np.log10(gm[gm < 1].max()) == pytest.approx(ours.lower_gain_margin_db, abs=0.05)


def test_lqi_model_needs_an_lqi():
    with pytest.raises(InvalidConfigError, match="needs an LQI"):
        loop_models(load_scenario(IDEAL, ["controller=!PdDriver {}"]))
    driver = LqiDriver(omega_Q=10.0)
    soft, stiff = (
        axis_figures(loop_models(load_scenario(IDEAL), driver=d))[5] for d in (LqiDriver(), driver)
    )
    assert stiff.crossover_hz > soft.crossover_hz


def test_the_model_matches_the_drake_plant_at_home():
    # Sines of 0.05 mm on Z at 0.5 to 20 Hz around home on the ideal robot: the nonlinear SAP
    # plant and the linear model agree within 0.02 dB and 0.2 deg (measured: 0.001 dB, 0.01 deg).
    scenario = load_scenario(IDEAL)
    f, G = measure_tracking(scenario, 5, frequencies_hz=(0.5, 2.0, 5.0, 10.0, 20.0))
    model = tracking_response(loop_models(scenario), f)[:, 5]
    np.testing.assert_allclose(20 * np.log10(np.abs(G / model)), 0.0, atol=0.02)
    np.testing.assert_allclose(np.degrees(np.angle(G / model)), 0.0, atol=0.2)
    assert 20 * np.log10(abs(G[3])) > 2.5  # the loop's 3 dB peak near 10 Hz is really there


@pytest.mark.slow
@pytest.mark.parametrize("axis", [0, 3])
@pytest.mark.parametrize("pose", ["tilted", "edge"])
def test_the_model_matches_the_drake_plant_away_from_home(axis, pose):
    # tilted: 8.6, -5.7, 5.7 deg and 20, -15 mm off home; edge: rolled 0.5 rad (29 deg of the
    # 37.5 deg the robot tilts at Z = 0.30 m, docs/workspace.md)
    x0 = X_HOME + (
        np.array([0.15, -0.1, 0.1, 0.02, -0.015, 0.0])
        if pose == "tilted"
        else np.array([0.5, 0.0, 0.0, 0.0, 0.0, 0.0])
    )
    scenario = load_scenario(IDEAL)
    f, G = measure_tracking(scenario, axis, x0=x0)
    model = tracking_response(loop_models(scenario, x0), f)[:, axis]
    np.testing.assert_allclose(20 * np.log10(np.abs(G / model)), 0.0, atol=0.05)
    np.testing.assert_allclose(np.degrees(np.angle(G / model)), 0.0, atol=0.5)


def test_analyze_prints_the_margins_and_writes_the_plots(tmp_path, capsys):
    from stewart_drake.cli.main import main

    out = tmp_path / "an"
    assert main(["analyze", "--scenario", str(IDEAL), "--out", str(out)]) == 0
    text = capsys.readouterr().out
    z = next(line for line in text.splitlines() if line.startswith("| Z |")).split("|")
    assert float(z[2]) == pytest.approx(22.6, abs=0.1) and float(z[3]) == pytest.approx(61.2, 0.1)
    for name in ("bode.png", "sensitivity.png"):
        assert (out / name).stat().st_size > 20_000
    assert "| phi |" in (out / "loop.md").read_text()
    assert main(["analyze", "--scenario", str(IDEAL), "--pose", "0,0,0", "--out", str(out)]) == 2
    assert "--pose takes six numbers" in capsys.readouterr().err


def test_the_weights_and_the_workspace_map_name_the_weak_loops():
    from stewart_drake.analysis.loop_analysis import loop_map, tilt_grid, weakest_pose, weight_sweep

    built = load_scenario(BUILT)
    rows = {r["ratio"]: r for r in weight_sweep(built, ratios=(0.01, 1.0, 100.0))}
    # Stiffer weights raise the bandwidth and spend the roll loop's margin; at 100 the loop
    # the delay, the current loop and the rate filter add to is unstable.
    assert rows[0.01]["stable"] and rows[1.0]["stable"] and not rows[100.0]["stable"]
    pm = {r: min(a["phase_margin_deg"] for a in rows[r]["axes"]) for r in rows}
    assert pm[0.01] > 35 and 10 < pm[1.0] < 20
    assert rows[0.01]["axes"][5]["bandwidth_hz"] < rows[1.0]["axes"][5]["bandwidth_hz"]
    grid = tilt_grid(0.55, 3)
    mapped = loop_map(built, grid)
    assert 0 < len(mapped) <= 9
    weakest = weakest_pose(mapped)
    home = next(r for r in mapped if r["pose"] == [0, 0, 0, 0, 0, 0.3])
    assert weakest["phase_margin_deg"] < home["phase_margin_deg"] - 1
    assert weakest["Ms"] > home["Ms"] + 0.3 and weakest["spectral_radius"] < 1
    assert abs(weakest["pose"][1]) == pytest.approx(0.55)  # pitched to the edge
