"""The surrogate's figures, stage and options, each against an independent computation: sine
pairs whose lead, loop area and correlation are known in closed form, the carriage's step against
a fine Euler integration, the command's refusals before any run."""

import math

import numpy as np
import pytest

from stewart_drake.base import pair_figures as sf
from stewart_drake.base.errors import InvalidConfigError
from stewart_drake.cli import main as cli
from stewart_drake.execution.trace_options import correlation_model
from stewart_drake.organ_motion.surrogate_pair import pair_report
from stewart_drake.station.surrogate.correlation import CorrelationModel
from stewart_drake.station.surrogate.stage import SurrogateStage

H = 1e-3
T = np.arange(0.0, 16.0, H)
W = 2 * math.pi / 4.0  # a 4 s breath


def _sines(lead=0.3, a_i=5e-3, a_e=8e-3):
    return a_i * np.sin(W * T), a_e * np.sin(W * (T + lead))


@pytest.mark.parametrize("lead", [-0.65, -0.2, 0.0, 0.137, 0.5])
def test_lead_is_the_shift_of_a_sine_pair(lead):
    i, e = _sines(lead)
    assert sf.lead_s(T, i, e, 1.0) == pytest.approx(lead, abs=2e-4)
    # axes pointing opposite ways: the same lead, not half a breath off
    assert sf.lead_s(T, i, -e, 1.95) == pytest.approx(lead, abs=2e-4)


@pytest.mark.parametrize("lead", [0.1, 0.4, -0.3])
def test_hysteresis_area_is_pi_ai_ae_sin_phi(lead):
    a_i, a_e = 5e-3, 8e-3
    i, e = _sines(lead, a_i, a_e)
    expected = math.pi * a_i * a_e * math.sin(W * lead)  # closed form, not the code's
    assert sf.hysteresis_area(i, e) == pytest.approx(expected, rel=2e-3)


@pytest.mark.parametrize("lead", [0.0, 0.3, 1.0])
def test_correlation_of_a_sine_pair_is_the_cosine_of_its_phase(lead):
    i, e = _sines(lead)
    assert sf.correlation(i, e) == pytest.approx(math.cos(W * lead), abs=2e-3)


def test_drift_of_the_external_alone_is_found():
    i, e = _sines(0.3)
    drift = 2e-3 / 60  # 2 mm a minute
    assert sf.baseline_drift(T, i, e + drift * T, 0.3) == pytest.approx(drift, rel=1e-3)
    assert sf.baseline_drift(T, i + drift * T, e, 0.3) < 0  # the internal's drift: the other sign


@pytest.mark.parametrize("d", [0.0, 0.004, -0.012, 0.0375])
def test_delay_is_the_shift_of_the_measured_signal(d):
    commanded = 5e-3 * np.sin(W * T) + 1e-3 * np.sin(3 * W * T)
    measured = np.interp(T - d, T, commanded) + 2e-4  # late by d, with an offset removed
    assert sf.lag_s(T, commanded, measured, 0.1) == pytest.approx(d, abs=1e-4)


def test_relative_latency_is_internal_delay_less_external_delay():
    c = 5e-3 * np.sin(W * T)
    late = np.interp(T - 0.02, T, c)
    rl = sf.relative_latency(T, c, np.interp(T - 0.005, T, c), 0.8 * c, 0.8 * late)
    assert rl.relative_s == pytest.approx(-0.015, abs=2e-4)  # the surrogate late


def _pair(external_measured=None, lead=0.4):
    x_d = np.zeros((len(T), 6))
    x_d[:, 3] = 5e-3 * np.sin(W * T)
    asked = 0.8 * 5e-3 * np.sin(W * (T + lead))
    measured = asked if external_measured is None else external_measured(asked)
    return pair_report(T, x_d, x_d, measured, asked, (4.0, 15.0))


def test_the_right_pair_matches_to_5_percent_and_wrong_ones_do_not():
    good = _pair()
    assert abs(good["latency"]["relative_latency_s"]) < 1e-4
    assert all(v < 0.05 for v in good["match"].values())
    wrong = {
        "at rest": lambda a: np.zeros_like(a) + 1e-9 * np.sin(W * T),
        "scaled": lambda a: 1.2 * a,
        "reversed": lambda a: -a,
        "shifted 20 ms": lambda a: np.interp(T - 0.02, T, a),
        "another motion": lambda a: 4e-3 * np.sin(1.5 * W * T),
    }
    for name, f in wrong.items():
        fig = _pair(f)
        latency_off = abs(fig["latency"]["relative_latency_s"]) > 0.01
        figure_off = any(v > 0.05 for v in fig["match"].values())
        rms_off = fig["external_rms_m"] > 1e-4
        assert latency_off or figure_off or rms_off, name


def test_carriage_step_agrees_with_a_fine_euler_integration():
    stage = SurrogateStage()
    A, B = stage.carriage_matrices(1e-3)
    m, b, F = stage.moving_mass_kg(), stage.viscous_N_s_per_m(), 10.0
    p, v = 0.0, 0.01
    for _ in range(10000):  # 1 ms in 0.1 us steps
        p, v = p + v * 1e-7, v + (F - b * v) / m * 1e-7
    x = A @ [0.0, 0.01] + B[:, 0] * F
    assert x == pytest.approx([p, v], rel=1e-5)


def test_default_stage_is_the_catalogue_servo_on_its_belt():
    stage = SurrogateStage()
    # XM430-W350-T: 46 rpm, 4.1 N m stall (0.82 continuous), 4096 counts; 80 mm a turn
    assert stage.no_load_speed_m_s == pytest.approx(46 / 60 * 0.08)
    assert stage.metres_per_count == pytest.approx(0.08 / 4096)
    assert stage.continuous_force_N == pytest.approx(0.82 * 2 * math.pi / 0.08 * 0.9)
    # the figures the docs give: 61.3 mm/s, 58 N, 19.5 um
    assert 61.3e-3 < stage.no_load_speed_m_s < 61.4e-3
    assert 57.9 < stage.continuous_force_N < 58.0
    assert 19.5e-6 < stage.metres_per_count < 19.6e-6
    # reflected rotor: 1 g cm^2 x 353.5^2 x (2 pi / 0.08)^2, plus the carriage
    assert stage.moving_mass_kg() == pytest.approx(
        1e-7 * 353.5**2 * (2 * math.pi / 0.08) ** 2 + 0.3
    )


def test_what_drake_builds_is_the_catalogue_part_on_its_belt():
    """The Drake systems of the default stage, read back from the built Diagram, against the
    catalogue's figures by hand (XM430-W350-T: 4.1 N m stall, 0.82 N m continuous, 46 rpm,
    1 g cm^2 rotor, 353.5 : 1, 4096 counts; dry friction 5 % of stall and as much again viscous
    at no load; the belt 80 mm a turn at 0.9; 0.3 kg): the force limit, the carriage's exact
    discrete step (closed form of the mass-damper), the control law's row and the goals'
    step."""
    from pydrake.systems.framework import DiagramBuilder

    from stewart_drake.station.surrogate.stage import add_surrogate_stage

    k = 2 * math.pi / 0.08  # rad a metre of belt
    m = 1e-7 * 353.5**2 * k * k + 0.3  # 77.4 kg
    b = 0.05 * 4.1 / (46 * 2 * math.pi / 60) * k * k  # N s/m
    force = 0.82 * 0.9 * k  # 58.0 N
    count = 0.08 / 4096
    h, period = 1e-3, 0.01
    t = np.arange(0.0, 1.0, period)
    p = 0.0123 + 0.004 * np.sin(t)
    builder = DiagramBuilder()
    add_surrogate_stage(
        builder, SurrogateStage(), (t, p, 0.004 * np.cos(t), -0.004 * np.sin(t)), period, 0, h
    )
    diagram = builder.Build()
    sat = diagram.GetSubsystemByName("surrogate_force_limit")
    context = sat.CreateDefaultContext()
    for asked, given in ((1e9, force), (-1e9, -force), (10.0, 10.0)):
        sat.get_input_port().FixValue(context, [asked])
        assert sat.get_output_port().Eval(context)[0] == pytest.approx(given, rel=1e-9)
    assert 57.9 < force < 58.0
    carriage = diagram.GetSubsystemByName("surrogate_carriage")
    e = math.exp(-b / m * h)
    assert carriage.A() == pytest.approx(np.array([[1, (1 - e) * m / b], [0, e]]), rel=1e-9)
    step = np.array([[(h - (1 - e) * m / b) / b], [(1 - e) / b]])
    assert carriage.B() == pytest.approx(step, rel=1e-6)
    law = diagram.GetSubsystemByName("surrogate_pd").D()
    w = 2 * math.pi * 8.0  # critically damped at 8 Hz
    kp, kd = m * w * w, 2 * m * w - b
    assert law == pytest.approx(np.array([[kp, kd + b, m, -kp, -kd]]), rel=1e-9)
    goal = diagram.GetSubsystemByName("surrogate_goal")
    gctx = goal.CreateDefaultContext()
    for q in (0.0, 0.33, 0.71):
        gctx.SetTime(q)
        got = goal.get_output_port().Eval(gctx)[0]
        assert got / count == pytest.approx(round(got / count), abs=1e-6)  # whole counts
        assert abs(got - np.interp(q, t, p, left=p[0])) <= 0.5 * count + 0.004 * period


def test_stage_refuses_what_it_cannot_do():
    stage = SurrogateStage()
    with pytest.raises(InvalidConfigError, match="unstable"):
        SurrogateStage(bandwidth_hz=60.0).validate(0.01)
    for wrong, field in (
        (dict(motor="XM999"), "surrogate.stage.motor"),
        (dict(lead_m_per_rev=0.0), "surrogate.stage.lead_m_per_rev"),
        (dict(travel_m=-0.1), "surrogate.stage.travel_m"),
        (dict(carriage_mass_kg=float("nan")), "surrogate.stage.carriage_mass_kg"),
        (dict(efficiency=1.5), "surrogate.stage.efficiency"),
        (dict(damping_ratio=0.0), "surrogate.stage.damping_ratio"),
    ):
        with pytest.raises(InvalidConfigError, match=field):
            SurrogateStage(**wrong).validate()
    t = np.linspace(0, 1, 11)
    for p, v, a, what in (
        (np.full(11, 0.06), np.zeros(11), np.zeros(11), "travel"),
        (np.zeros(11), np.full(11, 0.07), np.zeros(11), "speed"),
        (np.zeros(11), np.zeros(11), np.full(11, 5.0), "force"),
    ):
        with pytest.raises(InvalidConfigError, match=what):
            stage.check_signal(t, p, v, a)
    stage.check_signal(t, np.full(11, 0.04), np.full(11, 0.05), np.full(11, 0.1))


def test_correlation_model_blends_its_change_and_is_read_from_words():
    model = correlation_model(["lead=300ms", "ratio=0.8", "change_at=10s", "lead_after=-0.2s"])
    assert model.lead(np.array([0.0, 9.0, 11.0, 20.0])) == pytest.approx([0.3, 0.3, -0.2, -0.2])
    assert correlation_model(["drift=2mm/min"]).drift_m_per_s == pytest.approx(2e-3 / 60)
    for bad in (["speed=1"], ["lead=3 parsecs"], ["ratio=0"], ["lead_after=1s"]):
        with pytest.raises(InvalidConfigError):
            correlation_model(bad)
    with pytest.raises(InvalidConfigError):
        CorrelationModel(lead_s=9.0).validate()


def _refused(capsys, argv, words):
    assert cli.main(argv + ["--no-progress"]) != 0
    _, err = capsys.readouterr()
    assert words in err, err


def test_command_refuses_a_bad_surrogate_before_the_run(tmp_path, capsys):
    out = ["--out", str(tmp_path)]
    _refused(capsys, ["reproduce", "breathing", "--surrogate-param", "lead=1s", *out], "need")
    _refused(
        capsys,
        ["reproduce", "breathing", "--surrogate", "model", "--surrogate-param", "nope=1", *out],
        "keys",
    )
    _refused(
        capsys,
        ["reproduce", "breathing", "--surrogate", str(tmp_path / "none.txt"), *out],
        "no file",
    )


def test_one_file_holding_both_is_read_twice_by_the_one_reader(tmp_path):
    from stewart_drake.references.traces import load_trace
    from stewart_drake.station.surrogate.pairs import load_external

    t = np.arange(0.0, 20.0, 0.1)
    si, chest = 5.0 * np.sin(W * t), 8.0 * np.sin(W * (t + 0.3))
    path = tmp_path / "pair.csv"
    rows = "\n".join(f"{a:.3f},{b:.6f},{c:.6f}" for a, b, c in zip(t, si, chest))
    path.write_text("t [s],SI [mm],chest [mm]\n" + rows + "\n")
    # the external's column named by the axis it moves (a header's names are the platform's)
    external = load_external(path, columns="t [s], -, SI [mm]")
    q = np.arange(2.0, 18.0, 0.01)
    assert external(q) == pytest.approx(8e-3 * np.sin(W * (q + 0.3)), abs=5e-5)
    internal = load_trace(path, columns="t [s], SI [mm], -")
    moving = np.ptp(internal.evaluate(q)[0], axis=0) > 0
    assert moving.tolist() == [False, False, False, True, False, False]  # SI is the platform's X
    for columns in ("t [s], LR [mm], SI [mm]", "t [s], rot_SI [deg], -"):
        with pytest.raises(InvalidConfigError, match="along one line") as refused:
            load_external(path, columns=columns)
        assert f"--surrogate {path}" in str(refused.value)
        assert "name the other columns '-' (--surrogate-columns)" in str(refused.value)


def test_scenario_section_round_trips_through_yaml(tmp_path):
    from dataclasses import replace

    from stewart_drake.run.scenario import dump_scenario
    from stewart_drake.run.scenario_io import load_scenario
    from stewart_drake.station.surrogate.axis import SurrogateAxis

    axis = SurrogateAxis(
        stage=SurrogateStage(travel_m=0.05, lead_m_per_rev=0.06, bandwidth_hz=5.0),
        correlation=CorrelationModel(lead_s=0.3, change_at_s=10.0, lead_after_s=-0.1),
    )
    scenario = replace(load_scenario("phantom_hardware"), surrogate=axis).validate()
    path = tmp_path / "s.yaml"
    dump_scenario(scenario, path)
    back = load_scenario(str(path)).surrogate
    assert back == axis
    assert "lead_m_per_rev: 0.06" in path.read_text()  # the part's field, as the bus's
    assert back.stage.no_load_speed_m_s == pytest.approx(46 / 60 * 0.06)  # derived again
    with pytest.raises(InvalidConfigError, match="surrogate.stage.travel_m"):
        load_scenario(str(path), ["surrogate.stage.travel_m=-1"])


def test_hysteresis_of_a_single_cycle_and_of_a_pair_at_rest():
    one = (T >= 2.0) & (T < 6.0)  # exactly one 4 s breath
    i, e = _sines(0.4)
    expected = math.pi * 5e-3 * 8e-3 * math.sin(W * 0.4)
    assert sf.hysteresis_area(i[one], e[one]) == pytest.approx(expected, rel=5e-3)
    with pytest.raises(InvalidConfigError, match="crosses its mean"):
        sf.hysteresis_area(np.ones_like(T), e)
