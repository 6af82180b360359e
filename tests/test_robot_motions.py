"""The robot command drives what ``reproduce`` drives: the organ-motion library's motions with
their ``--param`` and ``--add``, and trace files with the trace options, chosen by the one
conversion both commands use (:func:`~stewart_drake.organ_motion.command.motion_reference`),
and checked like every reference before the torque goes on.

Sessions run in this process against the bus emulator on the commanded clock
(:func:`conftest.bus_emulator`), the command called through ``main``.
"""

import numpy as np
import pytest
from conftest import bus_emulator, robot_bus_yaml, write_trace

pytest.importorskip("dynamixel_sdk")

from stewart_drake.calibration.files import READING_COLUMNS  # noqa: E402
from stewart_drake.calibration.join import (  # noqa: E402
    ENCODER_LOG_COLUMNS,
    ENCODER_LOG_REMEDY,
    read_table,
)
from stewart_drake.cli.main import main  # noqa: E402
from stewart_drake.references.organ.library import make_motion  # noqa: E402
from stewart_drake.robot.kinematics import X_HOME  # noqa: E402
from stewart_drake.run.plan import robot_geometry  # noqa: E402
from stewart_drake.run.scenario_io import ROBOT_SCENARIO, load_scenario  # noqa: E402
from stewart_drake.station.bus import driver  # noqa: E402
from stewart_drake.station.bus import protocol as p  # noqa: E402
from stewart_drake.verification.measured_motion import encoder_motion  # noqa: E402

IDS = [1, 2, 3, 4, 5, 6]
X_REST = X_HOME + np.array([0.0, 0.0, 0.0, 0.0, 0.0, -0.01])  # 10 mm below home
#: A faster, smaller breath than the library's default (15 mm, 4 s): two whole cycles in 4 s.
BREATH = {"amplitude": "10mm", "period": "2s"}


def _emulator():
    """The bus emulator in this process, one control period of the shipped bus scenario per
    torque command."""
    return bus_emulator(X_REST, load_scenario(ROBOT_SCENARIO).control_period_s)


def _robot(emu, tmp_path, *args) -> tuple[int, list]:
    """(exit code, each servo's Torque Enable writes of 1) of ``robot ARGS`` on ``emu``, with
    the shipped bus scenario's settings for a loaded machine and a 0.5 s homing."""
    argv = ["robot", *args, "--scenario", str(robot_bus_yaml(tmp_path)), "--port", emu.port]
    argv += ["--home-s", "0.5", "--loop-timeout", "5", "--no-progress", "--out", str(tmp_path)]
    code = main(argv)
    enables = [
        packet.servo_id
        for _, packet in emu.received
        if packet.instruction == p.WRITE
        and packet.params[:1] == bytes([p.TORQUE_ENABLE[0]])
        and packet.params[2:3] == b"\x01"
    ]
    return code, enables


def _params(values: dict) -> list:
    return [a for k, v in values.items() for a in ("--param", f"{k}={v}")]


def test_the_robot_follows_a_library_breathing_motion_with_its_parameters(tmp_path, capsys):
    """``robot breathing --param ...`` runs to its end with the timing summary, and the pose
    its encoders logged (forward kinematics of the log beside the run, on the reference's
    clock, from 0.5 s on) is the library's breathing with those parameters: 1.16 mm RMS from
    it (a platform resting at the breath's middle would be 3.6 mm off), its SI displacement
    correlated 0.985 with the reference's, swinging 13.2 mm for the 10 mm asked (the shipped
    bus scenario's controller, omega_Q = 0.01 at 10 ms, overshoots a 2 s breath). The
    commanded clock makes these figures the same on a loaded machine; the bounds leave room
    for another machine's arithmetic, not for another motion."""
    with _emulator() as emu:
        code, enables = _robot(emu, tmp_path, "breathing", *_params(BREATH), "--duration", "4")
        torque = [emu.read_item(i, p.TORQUE_ENABLE) for i in IDS]
    out, err = capsys.readouterr()
    assert code == 0, (out, err)
    assert enables and torque == [0] * 6
    assert "control loop timing:" in out and "deadline misses" in out, out
    assert "stewart-drake robot: the reference ran to its end; torque off (confirmed" in out

    log_path = tmp_path / "robot_breathing_bus_encoders.csv"
    log = read_table(
        log_path, "encoder log", ENCODER_LOG_COLUMNS, ENCODER_LOG_REMEDY, nan_ok=("t_path",)
    )
    readings = np.column_stack([log[n] for n in READING_COLUMNS])
    geometry = robot_geometry(load_scenario(ROBOT_SCENARIO))
    measured = encoder_motion(log_path, log["t_path"], readings, geometry)
    on_path = measured.t > 0.5  # the first half second of the path: the loop catching up
    t, x = measured.t[on_path], measured.poses[on_path]
    assert t[-1] > 3.5, t[-1]  # the whole path was logged
    x_ref = make_motion("breathing", BREATH).evaluate(t)[0]
    error_m = np.linalg.norm(x[:, 3:] - x_ref[:, 3:], axis=1)
    rms_m = float(np.sqrt(np.mean(error_m**2)))
    assert rms_m < 1.5e-3, f"RMS {rms_m * 1e3:.3f} mm from the breathing reference"
    # The breath is along SI, the platform's X.
    assert np.corrcoef(x[:, 3], x_ref[:, 3])[0, 1] > 0.95
    assert 8e-3 < np.ptp(x[:, 3]) < 15e-3, f"the platform swung {np.ptp(x[:, 3]) * 1e3:.2f} mm"


@pytest.mark.parametrize(
    "motion",
    [
        ["breathing", "--param", "amplitude=12mm", "--param", "period=3s"],
        ["breathing_heartbeat", "--param", "heart_rate=80bpm", "--add", "baseline_drift"],
        ["TRACE", "--map", "SI=-Z", "--lowpass-hz", "2", "--centre-on", "first"],
        ["TRACE", "--add", "heartbeat", "--param", "amplitude=1mm"],
    ],
    ids=["library", "library+add", "trace", "trace+add"],
)
def test_robot_and_reproduce_choose_the_same_reference_for_a_motion(tmp_path, motion):
    from stewart_drake.cli.registry import build_parser
    from stewart_drake.live.command import _robot_reference
    from stewart_drake.organ_motion.command import motion_scenario

    t = np.arange(0.0, 8.0, 0.05)
    trace = write_trace(tmp_path / "patient.csv", t, {"SI [mm]": 5 * np.sin(t)})
    motion = [str(trace) if a == "TRACE" else a for a in motion]
    reproduced, _ = motion_scenario(build_parser().parse_args(["reproduce", *motion]))
    args = build_parser().parse_args(["robot", *motion])
    scenario = load_scenario(ROBOT_SCENARIO)
    _robot_reference(args, scenario)
    assert scenario.reference == reproduced.reference
    scenario.validate()


@pytest.mark.parametrize(
    "motion, params, says",
    [
        ("breathing", {"amplitude": "ten mm"}, "parameter amplitude: 'ten mm' is not a finite"),
        ("breathing", {"depth": "5mm"}, "breathing has no parameter 'depth'"),
        ("paper", {"amplitude": "5mm"}, "--param: for a library motion or a trace file, not"),
    ],
    ids=["value", "name", "not-a-motion"],
)
def test_a_bad_param_is_refused_in_one_line_before_the_bus_opens(
    tmp_path, capsys, monkeypatch, motion, params, says
):
    monkeypatch.setattr(driver.DynamixelBus, "open", lambda self: pytest.fail("port opened"))
    argv = ["robot", motion, *_params(params), "--scenario", str(robot_bus_yaml(tmp_path))]
    code = main([*argv, "--port", "/dev/null", "--out", str(tmp_path)])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2 and len(err) == 1, err
    assert err[0].startswith("stewart-drake robot: ") and says in err[0], err[0]


def test_a_motion_beyond_the_motors_is_refused_by_the_checks_before_the_torque_goes_on(
    tmp_path, capsys
):
    """The reference's checks (reach, joint ranges, the motors' torque and speed) apply to a
    library motion as to every reference: an 80 mm breath in 0.5 s is refused before any
    servo is powered."""
    with _emulator() as emu:
        big = {"amplitude": "80mm", "period": "0.5s"}
        code, enables = _robot(emu, tmp_path, "breathing", *_params(big), "--duration", "2")
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2 and not enables, err
    assert len(err) == 1 and err[0].startswith("stewart-drake robot: "), err
    assert "motor" in err[0] and "torque" in err[0], err[0]
    assert not (tmp_path / "robot_breathing_bus.npz").exists()
