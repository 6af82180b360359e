"""The robot's own encoder log as both measurements of ``verify INTERNAL --surrogate EXTERNAL``:
the platform by forward kinematics of its crank readings, the surrogate's carriage by its
servo's encoder (the log's ``s [m]``, never its command ``s_cmd [m]``), both on the log's
``t_path``, the lead-in left out.

The log is written by ``write_encoder_log`` from a known motion: the cranks the robot's inverse
kinematics of the library's breathing (4 s) ``LAG_I`` late, plus the encoders' zero errors,
17-bit counts; the carriage a 4 mm sine of 4 s with a quarter of its second harmonic (a
breath's asymmetry: reversed, a pure sine would be the same sine half a period late), 0.3 s ahead
of the breath, ``LAG_S`` late. The figures are held to that arithmetic: each latency the lag it
was made with, the relative latency their difference, a carriage 5 % too large an RMS error of
0.05 of its RMS, A sqrt((1 + 1/16) / 2). The battery of wrong
carriages (at rest, reversed, 0.3 s late, its command written where its reading is missing)
FAILs or is refused naming the cause."""

import json

import numpy as np
import pytest

from stewart_drake.base.errors import InvalidConfigError
from stewart_drake.calibration import tracker
from stewart_drake.calibration.join import write_encoder_log
from stewart_drake.cli.main import main
from stewart_drake.references.organ.library import make_motion
from stewart_drake.references.traces import load_trace
from stewart_drake.robot.kinematics import ik
from stewart_drake.run.plan import robot_geometry
from stewart_drake.run.scenario_io import load_scenario
from stewart_drake.verification.external_reference import model_reference
from stewart_drake.verification.pair_command import read_encoder_pair
from stewart_drake.verification.pair_judgement import verify_pair

GEOMETRY = robot_geometry(load_scenario("phantom_hardware"))
INTERNAL = make_motion("breathing", {})
#: The carriage's sine: amplitude m, period s, its lead on the breath s.
AMPLITUDE_M, PERIOD_S, LEAD_S = 4e-3, 4.0, 0.3
#: The platform's and the carriage's lags behind their commands, s.
LAG_I, LAG_S = 0.015, 0.015
#: The log: its lead-in's lines (no t_path), then SECONDS at 100 Hz.
LEAD_IN, SECONDS, STEP_S = 50, 20.0, 0.01
COUNTS = 2**17


def sine(t, lag_s=0.0):
    """The carriage's displacement, m, ``lag_s`` late: A (sin phi + sin(2 phi) / 4)."""
    phi = 2 * np.pi * (np.asarray(t) - lag_s + LEAD_S) / PERIOD_S
    return AMPLITUDE_M * (np.sin(phi) + 0.25 * np.sin(2 * phi))


@pytest.fixture(scope="module")
def cranks():
    """(t_path (n,) s, q (n, 6) rad): the encoders' readings of the breathing LAG_I late."""
    t_path = np.arange(0.0, SECONDS, STEP_S)
    x = INTERNAL.evaluate(t_path - LAG_I)[0]
    return t_path, tracker.quantize(ik(GEOMETRY, x) + GEOMETRY.encoder_offsets, COUNTS)


@pytest.fixture(scope="module")
def resp(tmp_path_factory):
    """The surrogate's recorded trace: a 2-column file (t s, displacement mm), 5 Hz, 40 s."""
    path = tmp_path_factory.mktemp("resp") / "resp.txt"
    t = np.arange(0.0, 40.0, 0.2)
    path.write_text("\n".join(f"{a:.1f} {b * 1e3:.6f}" for a, b in zip(t, sine(t))) + "\n")
    return path


def write_log(path, cranks, s=None, s_cmd=None):
    """An encoder log at ``path`` of the cranks and the carriage's ``s`` and ``s_cmd`` (each a
    function of t_path, m; default the sine LAG_S late and on time), held over the lead-in."""
    t_path, q = cranks
    s = sine(t_path, LAG_S) if s is None else s(t_path)
    s_cmd = sine(t_path) if s_cmd is None else s_cmd(t_path)
    n = len(t_path) + LEAD_IN

    def held(v):
        return np.concatenate([np.repeat(v[:1], LEAD_IN, axis=0), v])

    return write_encoder_log(
        path,
        1.7e9 + np.arange(n) * STEP_S,
        np.arange(n) * STEP_S,
        np.concatenate([np.full(LEAD_IN, np.nan), t_path]),
        held(q),
        surrogate=(held(s), held(s_cmd)),
    )


def judge(log, resp, surrogate_log=None, axis_map=None):
    """The pair judged from the log (for both measurements unless ``surrogate_log``)."""
    surrogate = load_trace(resp, axis_map)
    internal, carriage = read_encoder_pair(log, surrogate_log or log, GEOMETRY, surrogate)
    return verify_pair(INTERNAL, surrogate, internal, carriage)


def causes(pair) -> str:
    return "; ".join(pair.judgement.causes)


@pytest.mark.parametrize("lag_i, lag_s", [(LAG_I, LAG_S), (0.06, 0.0), (0.0, 0.08)])
def test_the_right_pair_passes_its_relative_latency_the_two_lags_difference(
    tmp_path, cranks, resp, lag_i, lag_s
):
    t_path, _ = cranks
    if lag_i != LAG_I:
        x = INTERNAL.evaluate(t_path - lag_i)[0]
        cranks = (t_path, tracker.quantize(ik(GEOMETRY, x) + GEOMETRY.encoder_offsets, COUNTS))
    log = write_log(tmp_path / "run_encoders.csv", cranks, s=lambda t: sine(t, lag_s))
    pair = judge(log, resp)
    assert pair.passed, pair.judgement.line
    # Both on t_path: each latency is its lag, their difference the relative latency.
    assert pair.internal.latency_s == pytest.approx(lag_i, abs=1e-3)
    assert pair.surrogate.latency_s == pytest.approx(lag_s, abs=1e-3)
    assert pair.relative_latency_s == pytest.approx(lag_i - lag_s, abs=1e-3)
    assert pair.internal.clock_offset_s == 0.0 and pair.surrogate.clock_offset_s == 0.0
    # The lead-in left out of both: the first sample of each is t_path's first, 0.
    assert pair.internal.measured.t[0] == 0.0 and pair.surrogate.measured.t[0] == 0.0
    assert pair.internal.measured.kind == "encoders"
    assert pair.surrogate.measured.kind == "carriage"
    assert pair.surrogate.fidelity["measured"] == ["X"]  # a 2-column file is on SI, X
    # The carriage's error is the spline through the file's 5 Hz samples: microns.
    assert np.nanmax(pair.surrogate.fidelity["rms"]) < 5e-6
    assert pair.internal.fidelity["rms_translation_m"] < 10e-6


def test_the_carriage_is_read_on_the_surrogates_axis_with_its_sign(tmp_path, cranks, resp):
    """A trace mapped to -AP (Z, reversed): ``s`` is the file's own displacement, so the
    carriage goes on Z reversed and the right log still passes, as on +SI."""
    named = tmp_path / "chest.csv"
    rows = np.loadtxt(resp)
    named.write_text("t [s],chest [mm]\n" + "\n".join(f"{a:.1f},{b:.6f}" for a, b in rows) + "\n")
    log = write_log(tmp_path / "run_encoders.csv", cranks)
    pair = judge(log, named, axis_map={"chest": "-AP"})
    assert pair.surrogate.fidelity["measured"] == ["Z"]
    assert pair.passed and pair.relative_latency_s == pytest.approx(0.0, abs=1e-3)
    # The carriage's s put on Z is -s: it matches a reference of -file on Z.
    np.testing.assert_allclose(
        pair.surrogate.measured.poses[:, 5], -sine(pair.surrogate.measured.t, LAG_S), atol=1e-12
    )


def test_a_carriage_5_percent_too_large_is_its_fidelitys_error(tmp_path, cranks, resp):
    """RMS of 0.05 of the carriage's motion: 0.05 A sqrt((1 + 1/16) / 2) = 146 um, beyond
    0.1 mm: the surrogate's own verdict FAILs; its clock means something, so the relative
    latency still PASSes."""
    log = write_log(tmp_path / "run_encoders.csv", cranks, s=lambda t: 1.05 * sine(t, LAG_S))
    pair = judge(log, resp)
    expected = 0.05 * AMPLITUDE_M * np.sqrt((1 + 1 / 16) / 2)
    assert np.nanmax(pair.surrogate.fidelity["rms"]) == pytest.approx(expected, rel=0.03)
    assert not pair.surrogate.judgement.passed and not pair.passed
    assert pair.judgement.passed and pair.judgement.meaningful


def test_a_carriage_at_rest_fails(tmp_path, cranks, resp):
    log = write_log(tmp_path / "run_encoders.csv", cranks, s=lambda t: np.full(len(t), 1e-3))
    pair = judge(log, resp)
    assert not pair.judgement.passed and not pair.judgement.meaningful
    assert "the surrogate did not move" in causes(pair)
    assert not pair.surrogate.judgement.passed and not pair.passed


def test_a_reversed_carriage_fails(tmp_path, cranks, resp):
    log = write_log(tmp_path / "run_encoders.csv", cranks, s=lambda t: -sine(t, LAG_S))
    pair = judge(log, resp)
    assert not pair.judgement.passed and not pair.passed
    assert "the surrogate runs the wrong way on X" in causes(pair)


def test_a_carriage_0_3_s_late_fails_naming_it_late(tmp_path, cranks, resp):
    log = write_log(tmp_path / "run_encoders.csv", cranks, s=lambda t: sine(t, LAG_S + 0.3))
    pair = judge(log, resp)
    assert pair.relative_latency_s == pytest.approx(LAG_I - LAG_S - 0.3, abs=1e-3)
    assert not pair.judgement.passed and pair.judgement.meaningful
    assert "beyond --max-relative-latency 100 ms: the surrogate late" in causes(pair)
    # Its fidelity is judged with its latency known (t_path): 0.3 s is within verify's 0.5 s.
    assert pair.surrogate.latency_s == pytest.approx(LAG_S + 0.3, abs=1e-3)


def test_the_reading_is_judged_never_the_command(tmp_path, cranks, resp):
    """A carriage read 0.3 s late beside a command on time FAILs (its command would pass); a
    log whose reading equals its command exactly passes."""
    late = write_log(tmp_path / "late_encoders.csv", cranks, s=lambda t: sine(t, 0.3), s_cmd=sine)
    pair = judge(late, resp)
    assert pair.relative_latency_s == pytest.approx(LAG_I - 0.3, abs=1e-3)
    assert not pair.judgement.passed
    exact = write_log(tmp_path / "exact_encoders.csv", cranks, s=sine, s_cmd=sine)
    pair = judge(exact, resp)
    assert pair.passed and pair.relative_latency_s == pytest.approx(LAG_I, abs=1e-3)


def test_other_columns_are_read_past(tmp_path, cranks, resp):
    """A column after the carriage's (its reference, ``s_ref [m]``) and the columns in another
    order change nothing: ``s`` is taken by its name."""
    log = write_log(tmp_path / "run_encoders.csv", cranks, s=lambda t: sine(t, 0.05))
    cells = [line.split(",") for line in log.read_text().splitlines()]
    order = [0, 1, 2, 10, 9] + list(range(3, 9))  # s_cmd before s, the readings last
    extra = ["s_ref [m]"] + ["0.5"] * (len(cells) - 1)
    wider = tmp_path / "wider_encoders.csv"
    wider.write_text(
        "\n".join(",".join([c[k] for k in order] + [e]) for c, e in zip(cells, extra)) + "\n"
    )
    first = judge(log, resp)
    second = judge(wider, resp)
    assert second.relative_latency_s == pytest.approx(first.relative_latency_s, abs=1e-9)
    assert second.relative_latency_s == pytest.approx(LAG_I - 0.05, abs=1e-3)


@pytest.mark.parametrize(
    "header, words",
    [
        ("s_ref", "the header lacks the column s; give the <stem>_encoders.csv of a run with"),
        (None, "the header lacks the column s; give the <stem>_encoders.csv of a run with"),
    ],
)
def test_a_log_without_the_carriages_reading_is_refused(tmp_path, cranks, resp, header, words):
    """Its command alone (``s`` renamed ``s_ref``) or no surrogate columns at all: refused in
    one line naming the column and the file."""
    log = write_log(tmp_path / "run_encoders.csv", cranks)
    text = log.read_text().split("\n", 1)
    if header is None:
        t_path, q = cranks
        n = len(t_path)
        log = write_encoder_log(log, np.arange(n) * STEP_S, np.arange(n) * STEP_S, t_path, q)
    else:
        log.write_text(text[0].replace(",s [m],", f",{header} [m],") + "\n" + text[1])
    with pytest.raises(InvalidConfigError) as refused:
        judge(log, resp)
    line = str(refused.value)
    assert "\n" not in line and line.startswith(f"{log}: ") and words in line, line


def run(tmp_path, internal, surrogate, *options):
    """``verify breathing --surrogate resp.txt`` in process: (exit code, the pair's JSON)."""
    out = tmp_path / "out"
    argv = ["verify", "breathing", "--surrogate", str(options[0]), "--measured", str(internal)]
    argv += ["--measured-surrogate", str(surrogate), "--out", str(out), *options[1:]]
    code = main(argv)
    found = sorted(out.glob("verify_*_pair.json"))
    return code, (json.loads(found[0].read_text()) if found else None)


def test_the_command_takes_one_log_for_both(tmp_path, cranks, resp, capsys):
    log = write_log(tmp_path / "run_encoders.csv", cranks, s=lambda t: sine(t, LAG_S + 0.03))
    code, figures = run(tmp_path, log, log, resp)
    out = capsys.readouterr().out.splitlines()
    assert code == 0, out
    assert out[0].startswith("PASS: run_encoders.csv (phi, theta, psi, X, Y, Z; the encoders")
    assert out[1].startswith("PASS: run_encoders.csv (X; each axis's offset removed) against")
    assert figures["relative_latency_s"] == pytest.approx(-0.03, abs=1e-3)
    assert figures["internal"]["latency_s"] == pytest.approx(LAG_I, abs=1e-3)
    assert figures["surrogate"]["latency_s"] == pytest.approx(LAG_S + 0.03, abs=1e-3)
    report = json.loads((tmp_path / "out" / "verify_resp_run_encoders.json").read_text())
    assert report["measured"]["kind"] == "carriage"
    assert "the surrogate's carriage s of the encoder log" in " ".join(report["removed"])


@pytest.mark.parametrize(
    "which, options, words",
    [
        ("camera", [], "is an encoder log, on the reference's clock (t_path), and"),
        ("log", ["--measured-surrogate-map", "s=SI"], "an encoder log's columns are its own"),
    ],
)
def test_options_refused_in_one_line(tmp_path, cranks, resp, capsys, which, options, words):
    log = write_log(tmp_path / "run_encoders.csv", cranks)
    other = log
    if which == "camera":
        other = tmp_path / "depth.csv"
        other.write_text("t [s],depth [mm]\n" + "\n".join(f"{k},{k}" for k in range(10)) + "\n")
    code, _ = run(tmp_path, log, other, resp, *options)
    err = capsys.readouterr().err.strip().splitlines()[-1]
    assert code == 2 and words in err, err


# -- a library motion's external signal made by a correlation model ---------------------------


def breath_x(t):
    """The breathing's X (SI, its only axis), m."""
    return INTERNAL.evaluate(np.asarray(t, float))[0][:, 3]


@pytest.mark.parametrize("drift", [None, "drift=0.06mm/s"])
def test_the_models_reference_is_the_breath_through_the_model(drift):
    """e(t) = k s(t + tau) + drift t, s the breath along its only axis (X), about its mean;
    repeating with the breath without a drift, made over the breath's two periods."""
    params = ["ratio=0.5", "lead=0.4s"] + ([drift] if drift else [])
    ref = model_reference(INTERNAL, params, 30.0)
    t = np.arange(0.0, 29.0, 0.01)
    e = ref.evaluate(t)[0]
    expected = 0.5 * breath_x(t + 0.4) + (0.06e-3 * t if drift else 0.0)
    np.testing.assert_allclose(e[:, 3] - e[:, 3].mean(), expected - expected.mean(), atol=1e-7)
    assert not np.any(np.delete(e, 3, axis=1))
    assert ref.carriage_axis == (3, 1.0)
    assert (ref.repeat_period_s, ref.end_time) == ((None, 30.0) if drift else (4.0, None))


@pytest.mark.parametrize(
    "lead, lag_s, expected",
    [("0.4s", LAG_S, LAG_I - LAG_S), ("0.4s", 0.3, LAG_I - 0.3), ("0s", LAG_S, 0.4)],
)
def test_the_command_judges_a_carriage_against_the_model(
    tmp_path, cranks, capsys, lead, lag_s, expected
):
    """The carriage made as the model asks (0.5 of the breath, 0.4 s ahead) LAG_S late PASSes;
    0.3 s late it FAILs, the surrogate late; judged against a model without the lead, it is
    0.4 s early: the internal target late against it."""
    log = write_log(
        tmp_path / "run_encoders.csv", cranks, s=lambda t: 0.5 * breath_x(t + 0.4 - lag_s)
    )
    out = tmp_path / "out"
    code = main(
        ["verify", "breathing", "--surrogate", "model", "--surrogate-param", "ratio=0.5"]
        + [f"lead={lead}", "--measured", str(log), "--measured-surrogate", str(log)]
        + ["--out", str(out)]
    )
    figures = json.loads((out / "verify_breathing_pair.json").read_text())
    assert figures["relative_latency_s"] == pytest.approx(expected, abs=2e-3)
    assert figures["surrogate"]["reference"] == "model"
    passed = abs(expected) <= 0.1
    assert code == (0 if passed else 2) and figures["relative"]["passed"] is passed
    assert figures["surrogate"]["passed"], figures["surrogate"]["line"]
    capsys.readouterr()


@pytest.mark.parametrize(
    "options, words",
    [
        (["--surrogate", "S.txt", "--surrogate-param", "ratio=2"], "give --surrogate model"),
        (["--surrogate", "model", "--surrogate-param", "gain=2"], "the keys are ratio, lead"),
        (["--surrogate", "model", "--surrogate-map", "x=SI"], "leave --surrogate-map out"),
    ],
)
def test_model_options_refused_in_one_line(tmp_path, cranks, capsys, options, words):
    log = write_log(tmp_path / "run_encoders.csv", cranks)
    argv = ["verify", "breathing", "--measured", str(log), "--measured-surrogate", str(log)]
    code = main(argv + options + ["--out", str(tmp_path / "out")])
    err = capsys.readouterr().err.strip().splitlines()[-1]
    assert code == 2 and words in err, err
    assert not (tmp_path / "out").exists()


# -- end to end: the log of a run on the emulated robot ----------------------------------------


@pytest.mark.slow
def test_the_log_of_a_run_on_the_emulated_robot_gives_the_runs_own_relative_latency(
    tmp_path, monkeypatch
):
    """``robot breathing --surrogate RESP`` on the bus emulator (the robot's plant and the
    surrogate's lead-screw stage behind one bus, on the commanded clock), then ``verify`` with its
    encoder log for both: the relative latency agrees with the one the run measured from the
    same encoders (``live.session_surrogate.judged_relative_latency``: each lag a delay of the
    reading behind its command, on the reference's clock) to 0.5 ms (2.7897 against 2.7901 ms
    when written; 16.0 against 17.1 ms when verify searched a clock of its own).

    And the robot's session and the simulated Diagram pick one direction and one relative
    latency: the session's lag matching and its verdict judge the platform along the direction
    the Diagram's surrogate signal carries (the principal direction of the breathing's
    translations, X: its superior-inferior axis), and the Diagram's pair report
    (``base.pair_figures.relative_latency``, the same definition) on the session's own samples
    gives each lag and their difference within 0.5 ms."""
    from stewart_drake.base.pair_figures import relative_latency
    from stewart_drake.live import session_surrogate
    from stewart_drake.station.surrogate.axis import SurrogateAxis

    judged, matched = [], []
    measure, lag_match = session_surrogate.judged_relative_latency, session_surrogate.lag_match

    def measure_and_keep(*args, **kwargs):
        judged.append((args, kwargs))
        return measure(*args, **kwargs)

    def lag_match_and_keep(*args):
        matched.append(lag_match(*args))
        return matched[-1]

    monkeypatch.setattr(session_surrogate, "judged_relative_latency", measure_and_keep)
    monkeypatch.setattr(session_surrogate, "lag_match", lag_match_and_keep)
    from conftest import LOADED_MACHINE_BUS, bus_emulator, extra_missing

    if extra_missing("robot"):
        pytest.skip(extra_missing("robot"))
    from stewart_drake.control.lqi.driver import LqiDriver
    from stewart_drake.live.session import end_line, run_on_robot
    from stewart_drake.references.organ.library import OrganMotionReference
    from stewart_drake.robot.kinematics import X_HOME
    from stewart_drake.run.scenario import Scenario
    from stewart_drake.station.bus.servos import DynamixelBusConfig, SurrogateServoConfig
    from stewart_drake.station.surrogate.carriage import load_surrogate

    stage, period = SurrogateServoConfig(), 0.01
    resp = tmp_path / "resp.txt"
    t = np.arange(0.0, 40.0, 0.2)
    resp.write_text("\n".join(f"{a:.1f} {b * 1e3:.6f}" for a, b in zip(t, sine(t))) + "\n")
    with bus_emulator(X_HOME, period, surrogate=stage, s0_m=0.0) as emu:
        scenario = Scenario(controller=LqiDriver(omega_Q=0.01))
        scenario.hardware = None
        scenario.reference = OrganMotionReference("breathing")
        scenario.control_period_s = scenario.log_period_s = period
        scenario.duration_s = 10.0
        scenario.guard.divergence_dir = str(tmp_path / "diverged")
        scenario.bus = DynamixelBusConfig(port=emu.port, surrogate=stage, **LOADED_MACHINE_BUS)
        run = run_on_robot(
            scenario,
            home_s=1.0,
            loop_timeout_s=5.0,
            out=tmp_path,
            say=lambda line: None,
            surrogate=load_surrogate(resp),
        )
    assert run.ok and run.relative_latency is not None, end_line(run)
    out = tmp_path / "out"
    argv = ["verify", "breathing", "--surrogate", str(resp), "--measured", str(run.encoder_log)]
    argv += ["--measured-surrogate", str(run.encoder_log), "--tolerance", "1mm,1deg"]
    main(argv + ["--out", str(out)])
    figures = json.loads((out / "verify_breathing_pair.json").read_text())
    # One relative latency: verify's from the log, measured on the reference's clock as the
    # session measures it, within 0.5 ms (a clock search of its own put it 1.1 ms away).
    assert figures["relative_latency_s"] == pytest.approx(
        run.relative_latency.relative_s, abs=5e-4
    ), (figures["relative"]["line"], run.relative_latency.line())
    assert figures["relative"]["meaningful"], figures["relative"]["line"]
    # One direction: the Diagram's signal's (its lag matching follows it), the session's lag
    # matching's and its verdict's.
    motion = scenario.reference.make(None, scenario.duration_s, None)  # as the Diagram makes it
    diagram_u = SurrogateAxis(trace=str(resp)).signal(motion, scenario.duration_s).direction
    assert len(matched) == 1 and len(judged) == 1
    np.testing.assert_allclose(diagram_u, (1, 0, 0), atol=1e-6)
    np.testing.assert_allclose(matched[0].direction, diagram_u, atol=1e-6)
    np.testing.assert_allclose(run.relative_latency.platform_direction, diagram_u, atol=1e-6)
    assert run.relative_latency.platform_axis == "X"
    # One relative latency: the Diagram's report's function on the session's samples.
    (t, x_m, x_c, s_m), kw = judged[0][0][:4], judged[0][1]
    diagram = relative_latency(t, x_c, x_m, kw["s_reference"], s_m)
    np.testing.assert_allclose(diagram.direction, diagram_u, atol=1e-6)
    assert abs(diagram.relative_s - run.relative_latency.relative_s) < 5e-4, (
        diagram,
        run.relative_latency.line(),
    )
    # Each lag alike, and lags to agree on (the platform's about 17 ms), not zeros.
    assert abs(diagram.internal_lag_s - run.relative_latency.platform_lag_s) < 5e-4
    assert abs(diagram.external_lag_s - run.relative_latency.surrogate_lag_s) < 5e-4
    assert run.relative_latency.platform_lag_s > 5e-3
