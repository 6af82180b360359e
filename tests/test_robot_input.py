"""The robot command against hostile input and late signals: a signal as the platform settles
keeps the logs and the end line; non-finite settings, poses and angles are refused in one line
before a port or a process is opened; ``robot --emulate --dry-run`` works as README shows it.

Sessions run in this process against the bus emulator on a pseudo-terminal (``--port``), the
command called through ``main``; only the emulator's own process test spawns one.
"""

import math
import os
import re
import signal
import time
import types

import numpy as np
import pytest
from conftest import HANG_S, LOADED_MACHINE_BUS, bus_emulator, robot_bus_yaml

pytest.importorskip("dynamixel_sdk")

from stewart_drake.base.errors import BusError, InvalidConfigError, MissingExtraError  # noqa: E402
from stewart_drake.cli.main import main  # noqa: E402
from stewart_drake.cli.registry import build_parser  # noqa: E402
from stewart_drake.live import command as live_command  # noqa: E402
from stewart_drake.live.measure import zero_counts_at  # noqa: E402
from stewart_drake.live.session import RobotRun, _drive, end_line  # noqa: E402
from stewart_drake.robot.kinematics import X_HOME  # noqa: E402
from stewart_drake.run.result import load_result  # noqa: E402
from stewart_drake.run.scenario_io import ROBOT_SCENARIO, load_scenario  # noqa: E402
from stewart_drake.station.bus import (
    driver,  # noqa: E402
    vendor_port,  # noqa: E402
)
from stewart_drake.station.bus import protocol as p  # noqa: E402

IDS = [1, 2, 3, 4, 5, 6]
X_REST = X_HOME + np.array([0.0, 0.0, 0.0, 0.0, 0.0, -0.01])  # 10 mm below home


def _emulator(x0=X_REST):
    """The bus emulator in this process (:func:`conftest.bus_emulator`), one control period of
    the shipped bus scenario per torque command."""
    return bus_emulator(x0, load_scenario(ROBOT_SCENARIO).control_period_s)


def _z_mm(summary: str) -> float:
    """The platform's height in a dry run's summary, mm."""
    return float(re.search(r"Z ([-+\d.]+) mm", summary).group(1))


def _home_on_the_emulator(tmp_path) -> tuple[int, list]:
    """(exit code, each servo's torque enable after) of ``robot home`` for 0.3 s on the
    emulator in this process."""
    with _emulator() as emu:
        argv = ["robot", "home", "--scenario", str(robot_bus_yaml(tmp_path)), "--port", emu.port]
        argv += ["--duration", "0.3", "--home-s", "0.5", "--loop-timeout", "5"]
        argv += ["--no-progress", "--out", str(tmp_path)]
        code = main(argv)
        return code, [emu.read_item(i, p.TORQUE_ENABLE) for i in IDS]


def _kill_then(signum, original):
    """``original`` with ``signum`` sent to this process first (the handler runs in it)."""

    def wrapped(*args, **kw):
        os.kill(os.getpid(), signum)
        return original(*args, **kw)

    return wrapped


def _in_read_run(monkeypatch, signum):
    # run.simulate binds read_run when first imported: imported here first, it keeps the
    # original, else a later `stewart-drake run` in this process (the docs' blocks) would be
    # sent the signal long after this test.
    import stewart_drake.run.simulate  # noqa: F401
    from stewart_drake.run import result

    monkeypatch.setattr(result, "read_run", _kill_then(signum, result.read_run))


def _in_yaml_dump(monkeypatch, signum):
    from stewart_drake.run.diagram import StewartDiagram

    monkeypatch.setattr(
        StewartDiagram, "scenario_yaml", _kill_then(signum, StewartDiagram.scenario_yaml)
    )


def _in_final_torque_off(monkeypatch, signum):
    """In the torque-off that follows the run (the ones before the torque is on are spared)."""
    enable, off = driver.DynamixelBus.enable_torque, driver.DynamixelBus._torque_off

    def enabled(self, *args, **kw):
        self.powered_once = True
        return enable(self, *args, **kw)

    def torque_off(self):
        if getattr(self, "powered_once", False):
            os.kill(os.getpid(), signum)
        return off(self)

    monkeypatch.setattr(driver.DynamixelBus, "enable_torque", enabled)
    monkeypatch.setattr(driver.DynamixelBus, "_torque_off", torque_off)


@pytest.mark.parametrize(
    "inject, signum",
    [
        (_in_read_run, signal.SIGINT),
        (_in_yaml_dump, signal.SIGTERM),
        (_in_final_torque_off, signal.SIGTERM),
    ],
    ids=["read_run-SIGINT", "yaml_dump-SIGTERM", "final_torque_off-SIGTERM"],
)
def test_a_signal_after_the_torque_off_keeps_the_logs_and_the_end_line(
    tmp_path, monkeypatch, capsys, ctrl_c, inject, signum
):
    opened = []
    open_bus = driver.DynamixelBus.open

    def recorded_open(self):
        opened.append(self)
        return open_bus(self)

    monkeypatch.setattr(driver.DynamixelBus, "open", recorded_open)
    inject(monkeypatch, signum)
    code, torque = _home_on_the_emulator(tmp_path)
    out, err = capsys.readouterr()
    name = signal.Signals(signum).name
    ends = [line for line in (out + err).splitlines() if line.startswith("stewart-drake robot:")]
    assert code == 128 + signum, ends
    assert len(ends) == 1 and "partial outputs were not written" not in err, (out, err)
    assert ends[0].startswith("stewart-drake robot: the reference ran to its end; "), ends[0]
    assert f"{name} received after the torque went off: held until the logs were saved" in ends[0]
    assert "torque off (confirmed by every servo); logs in" in ends[0]
    assert load_result(tmp_path / "robot_home_bus.npz").t[-1] > 0.5  # the lead-in and the hold
    assert torque == [0] * 6
    assert opened and all(bus._port is None for bus in opened)  # every bus closed


@pytest.mark.filterwarnings("error::tqdm.TqdmWarning")
def test_a_loop_that_misses_every_deadline_says_so_in_a_few_lines(tmp_path, monkeypatch, capsys):
    """A machine too busy for the period, as a bus rehearsal under load met it (1,541 misses,
    a line each, and a TqdmWarning): every period of ``robot home`` starts 1.5 periods late
    (the driver's wait for its period says so), with the progress bar shown, for a duration the
    bar's total once rounded below (0.80000049 s, 0.8 s shown). The misses are said in a line
    when their count reaches a power of two, each with the count, the worst and the causes;
    tqdm does not warn; the run ends as any, the timing counting every miss (at least one a
    period: 0.8 s of the shipped scenario's periods)."""
    from stewart_drake.run.scenario_io import ROBOT_SCENARIO, load_scenario
    from stewart_drake.station.bus.station import DynamixelDriver

    period = load_scenario(ROBOT_SCENARIO).control_period_s
    late = 1.5 * period
    monkeypatch.setattr(DynamixelDriver, "_wait_until", lambda self, due: (due + late, 0.0))
    with _emulator() as emu:
        argv = ["robot", "home", "--scenario", str(robot_bus_yaml(tmp_path)), "--port", emu.port]
        argv += ["--duration", "0.30000049", "--home-s", "0.5", "--loop-timeout", "5"]
        code = main([*argv, "--out", str(tmp_path)])
        torque = [emu.read_item(i, p.TORQUE_ENABLE) for i in IDS]
    out, err = capsys.readouterr()
    assert code == 0 and torque == [0] * 6, (out, err)
    found = re.search(rf"(\d+) periods of {1e3 * period:g} ms, (\d+) deadline misses", out)
    misses = int(found.group(2))
    said = [line for line in re.split(r"[\r\n]", err) if line.startswith("deadline misses: ")]
    assert misses >= round(0.8 / period) and len(said) == int(math.log2(misses)) + 1, (misses, said)
    assert [int(line.split()[2]) for line in said] == [2**k for k in range(len(said))]
    assert f"the worst {1e3 * late:.1f} ms late at t = " in said[0] and "by cause: " in said[-1]
    assert "the period did not hold" in out
    # the session's figures say whose pose they are: the encoders', not the platform's
    assert "\nRMS tracking error of the pose the encoders read over t in [" in "\n" + out


@pytest.mark.parametrize("signum", [signal.SIGINT, signal.SIGQUIT], ids=lambda s: s.name)
def test_a_signal_the_moment_the_torque_is_on_ends_the_run_with_its_end_line(
    tmp_path, monkeypatch, capsys, ctrl_c, signum
):
    """A SIGINT (Ctrl-C) or SIGQUIT (Ctrl-\\) delivered as the torque-enable returns (before the
    announcement): the run ends as any interrupted run, with its end line, the torque off
    confirmed and exit 128 + the signal. Was: the KeyboardInterrupt escaped the session between
    the enable and its ``try`` (no end line, no logs), seen under load in the bus rehearsal; and
    SIGQUIT, handled by no one, ended the process with every servo's torque still on."""
    enable = driver.DynamixelBus.enable_torque

    def enabled_then_signal(self, *args, **kw):
        done = enable(self, *args, **kw)
        os.kill(os.getpid(), signum)
        time.sleep(0.05)  # the handler runs in this thread at the next bytecode
        return done

    monkeypatch.setattr(driver.DynamixelBus, "enable_torque", enabled_then_signal)
    # As in a user's terminal: SIGQUIT at its default (a suite's parent may have set it aside).
    old = signal.signal(signal.SIGQUIT, signal.SIG_DFL)
    try:
        code, torque = _home_on_the_emulator(tmp_path)
    finally:
        signal.signal(signal.SIGQUIT, old)
    out, err = capsys.readouterr()
    ends = [line for line in (out + err).splitlines() if line.startswith("stewart-drake robot:")]
    assert code == 128 + signum, (out, err)
    assert len(ends) == 1, (out, err)
    assert ends[0].startswith(f"stewart-drake robot: interrupted by {signum.name}"), ends[0]
    assert "torque off (confirmed by every servo)" in ends[0], ends[0]
    assert "could not be written" not in ends[0], ends[0]
    assert torque == [0] * 6


def _swallowed(signum):
    """What numba's compiler did to a Ctrl-C: the handler's raise lands in a callback that
    prints "Exception ignored" and goes on."""
    try:
        os.kill(os.getpid(), signum)
        time.sleep(0.05)  # the handler runs in this thread at the next bytecode
    except KeyboardInterrupt:
        pass


@pytest.mark.parametrize("stage", ["compile", "session"])
def test_a_signal_swallowed_before_the_torque_goes_on_stops_the_command_unpowered(
    tmp_path, monkeypatch, capsys, ctrl_c, stage
):
    """A Ctrl-C raised where code swallowed it (in the command's compile step, or once the
    session's own handlers are in place): the servos are never powered, the command ends with
    130 and one line."""
    from stewart_drake.live import session

    enabled = []
    monkeypatch.setattr(driver.DynamixelBus, "enable_torque", lambda self: enabled.append(self))
    if stage == "compile":
        monkeypatch.setattr(live_command, "say_if_compiling", lambda c: _swallowed(signal.SIGINT))
    else:
        build = session.HomingReference

        def homing(*args, **kwargs):  # inside the session, before the torque
            _swallowed(signal.SIGINT)
            return build(*args, **kwargs)

        monkeypatch.setattr(session, "HomingReference", homing)
    with _emulator() as emu:
        argv = ["robot", "home", "--scenario", str(robot_bus_yaml(tmp_path)), "--port", emu.port]
        argv += ["--duration", "0.3", "--home-s", "0.5", "--no-progress", "--out", str(tmp_path)]
        code = main(argv)
        torque = [emu.read_item(i, p.TORQUE_ENABLE) for i in IDS]
    out, err = capsys.readouterr()
    assert code == 130, (out, err)
    assert not enabled and torque == [0] * 6
    ends = [line for line in err.splitlines() if line.startswith("stewart-drake robot:")]
    assert len(ends) == 1 and "SIGINT" in ends[0], err


def test_session_signals_raise_while_the_torque_may_be_on_and_are_held_after():
    from stewart_drake.execution.runners import Interrupted
    from stewart_drake.live.session_signals import SessionSignals

    def kill(signum):
        os.kill(os.getpid(), signum)
        time.sleep(0.01)  # the handler runs in this thread at the next bytecode

    before = signal.getsignal(signal.SIGTERM)
    with SessionSignals() as signals:
        with pytest.raises(Interrupted) as caught:
            kill(signal.SIGTERM)
        assert caught.value.signum == signal.SIGTERM
        kill(signal.SIGTERM)  # a second, while the first one's end runs: held
        assert signals.received == signal.SIGTERM
        with pytest.raises(Interrupted):  # never powered with a signal pending
            signals.arm()
        signals.received = None
        with pytest.raises(Interrupted):  # nor after one raised, even if it was swallowed
            signals.arm()
        signals.raised = None
        signals.arm()
        with pytest.raises(Interrupted):  # armed: the torque is on, a signal ends it
            kill(signal.SIGTERM)
        signals.hold()  # the torque-off
        kill(signal.SIGTERM)
        run = signals.settle(RobotRun("the reference ran to its end", True, True))
        signals.settle(run)  # once
    assert signal.getsignal(signal.SIGTERM) is before  # restored
    assert run.exit_code == 128 + signal.SIGTERM
    assert run.reason == (
        "the reference ran to its end; SIGTERM received after the torque went off: held to the end"
    )
    failed = RobotRun("BusError: bus /dev/ttyUSB0: sync read", False, True, exit_code=1)
    with SessionSignals() as signals:
        signals.hold()
        kill(signal.SIGTERM)
    assert signals.settle(failed).exit_code == 1  # the failure's status stands
    ignored = signal.signal(signal.SIGHUP, signal.SIG_IGN)
    try:
        with SessionSignals():
            assert signal.getsignal(signal.SIGHUP) is signal.SIG_IGN  # nohup stays nohup
    finally:
        signal.signal(signal.SIGHUP, ignored)


def test_the_end_line_gives_one_verdict_on_the_torque_off_after_a_bus_error():
    """The driver's error says the torque-off it attempted as the bus failed was not confirmed;
    the session's last one was: the end line says that one only."""
    failing = types.SimpleNamespace(
        port_name="/dev/ttyUSB0", torque_off=lambda: False, torque_off_confirmed=False
    )
    with pytest.raises(BusError) as caught:
        driver.DynamixelBus._fail(failing, "sync read: no data from servo id 3")
    assert "NOT confirmed" in str(caught.value)

    def body():
        raise caught.value

    simulator = types.SimpleNamespace(
        set_monitor=lambda m: None, set_target_realtime_rate=lambda r: None
    )
    bus = types.SimpleNamespace(torque_off=lambda: True, enable_torque=lambda: None)
    ended = RobotRun("", False, True)
    from stewart_drake.live.session_signals import SessionSignals

    _drive(bus, simulator, 1.0, lambda line: None, "on", body, ended, SessionSignals())
    line = end_line(ended)
    assert ended.exit_code == 1
    assert line == (
        "BusError: bus /dev/ttyUSB0: sync read: no data from servo id 3; "
        "torque off (confirmed by every servo)"
    )
    ended.torque_off_confirmed = False
    assert end_line(ended).count("confirmed") == 1 and "NOT confirmed" in end_line(ended)


@pytest.mark.parametrize(
    "setting",
    [
        "bus.current_limit_A=.nan",
        "bus.current_limit_A=.inf",
        "bus.watchdog_s=.nan",
        "bus.watchdog_s=-.inf",
    ],
)
def test_non_finite_bus_limits_are_refused_in_one_line(setting, capsys, monkeypatch):
    monkeypatch.setattr(driver.DynamixelBus, "open", lambda self: pytest.fail("port opened"))
    assert main(["robot", "--dry-run", "--set", setting]) == 2
    err = capsys.readouterr().err.strip()
    field = setting.split("=")[0]
    assert len(err.splitlines()) == 1 and f"{field} " in err, err
    assert "Traceback" not in err


def test_an_emulated_pose_is_checked_before_a_process_is_spawned(capsys, monkeypatch):
    from stewart_drake.live import emulator_process

    spawn = emulator_process.EmulatorProcess.start
    monkeypatch.setattr(
        emulator_process.EmulatorProcess, "start", lambda self: pytest.fail("spawned")
    )
    with pytest.raises(SystemExit) as stopped:
        main(["robot", "--emulate", "nan,0,0,0,0,0.28", "--dry-run"])
    assert stopped.value.code == 2
    assert "six finite numbers" in capsys.readouterr().err
    assert main(["robot", "--emulate", "0,0,0,0,0,0.5", "--dry-run"]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "--emulate 0,0,0,0,0,0.5: the robot cannot" in err
    assert "__main__" not in err
    monkeypatch.setattr(emulator_process.EmulatorProcess, "start", spawn)


def test_the_emulator_s_start_is_said_before_it_starts(capsys, monkeypatch):
    """``--emulate`` starts a process that loads Drake and builds the robot's plant (seconds,
    and on a loaded machine a minute that showed nothing): said first, in one line."""
    from stewart_drake.live import emulator_process

    def start(self):
        started.append(capsys.readouterr().err)
        raise BusError("the bus emulator did not start: (a test)")

    started = []
    monkeypatch.setattr(emulator_process.EmulatorProcess, "start", start)
    assert main(["robot", "--emulate", "0,0,0,0,0,0.28", "--dry-run"]) == 2
    assert started and started[0].startswith("stewart-drake robot: starting the bus emulator")
    assert capsys.readouterr().err.strip() == (
        "stewart-drake robot: the bus emulator did not start: (a test)"
    )


def test_the_emulator_process_reports_its_failure_in_one_line(capfd):
    from stewart_drake.live.emulator_process import EmulatorProcess

    far = np.array([0.0, 0.0, 0.0, 0.0, 0.0, 0.5])  # out of the rods' reach
    with pytest.raises(BusError, match=r"did not start: UnreachablePoseError: leg") as caught:
        EmulatorProcess(x0=far, start_timeout_s=HANG_S).start()
    assert "__main__" not in str(caught.value) and "\n" not in str(caught.value)
    assert "Traceback" not in capfd.readouterr().err


@pytest.mark.parametrize("angle", ["nan", "1e300", "-inf", "91"])
def test_a_calibration_angle_outside_the_cranks_travel_is_refused(angle, capsys, monkeypatch):
    monkeypatch.setattr(driver.DynamixelBus, "open", lambda self: pytest.fail("port opened"))
    assert main(["robot", f"--calibrate={angle}"]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "the cranks' travel [-90, 90]" in err, err


def test_zero_counts_come_from_finite_angles_within_the_registers_range():
    def bus(counts):
        counts = np.asarray(counts, dtype=float)
        return types.SimpleNamespace(
            ids=IDS,
            zero_counts=np.full(6, 2048),
            directions=np.ones(6),
            read_state=lambda: types.SimpleNamespace(q=p.counts_to_rad(counts, 2048, 1)),
        )

    # Held at +10 deg: 10 / 360 of 4096 counts = 113.8 -> 114 above each zero.
    zeros = zero_counts_at(bus([2162, 2100, 2000, 2500, 1900, 2048]), np.radians(10.0))
    np.testing.assert_array_equal(zeros, [2048, 1986, 1886, 2386, 1786, 1934])
    for angle in (float("nan"), 1e300, 4.0):
        with pytest.raises(InvalidConfigError, match="within half a turn"):
            zero_counts_at(bus([2048] * 6), angle)
    with pytest.raises(BusError, match="servo id 4 reads .*32-bit"):
        zero_counts_at(bus([2048, 2048, 2048, 3e9, 2048, 2048]), 0.0)


def test_the_robot_command_takes_the_shipped_bus_scenario_by_default(tmp_path, capsys):
    assert build_parser().parse_args(["robot"]).scenario == ROBOT_SCENARIO
    scenario = load_scenario(ROBOT_SCENARIO)
    assert scenario.bus is not None and scenario.hardware is None
    with _emulator() as emu:
        # The scenario's own reply timeout (the SDK's 34 ms) is a USB adapter's, not a
        # pseudo-terminal's on a loaded machine (conftest.LOADED_MACHINE_BUS).
        reply = f"bus.reply_timeout_s={LOADED_MACHINE_BUS['reply_timeout_s']}"
        assert main(["robot", "--dry-run", "--port", emu.port, "--set", reply]) == 0
    out = capsys.readouterr().out
    assert out.splitlines()[-1] == "admissible", out
    assert abs(_z_mm(out) - X_REST[5] * 1e3) < 0.2, out  # the pose the emulator rests at


def test_the_robot_extra_is_checked_before_the_emulator_starts(capsys, monkeypatch):
    def missing():
        raise MissingExtraError(
            "the servo driver needs ROBOTIS's dynamixel-sdk: pip install 'stewart-drake[robot]'"
        )

    monkeypatch.setattr(vendor_port, "dynamixel_sdk", missing)
    from stewart_drake.live import emulator_process

    monkeypatch.setattr(
        emulator_process, "start_emulator", lambda *a: pytest.fail("emulator started")
    )
    assert main(["robot", "--emulate", "--dry-run"]) == 2
    err = capsys.readouterr().err
    assert "stewart-drake[robot]" in err and len(err.strip().splitlines()) == 1, err


def test_robot_emulate_dry_run_as_readme_shows_it(capsys):
    """The pose read and judged, each silent stage said before it (the emulator's start, the
    reading: together a minute and more on a first use on a loaded machine)."""
    assert main(["robot", "--emulate", "--dry-run"]) == 0
    out, err = capsys.readouterr()
    assert out.splitlines()[-1] == "admissible", out
    assert abs(_z_mm(out) - 280.0) < 0.2, out  # --emulate's default pose
    said = [line.split(": ", 1)[1] for line in err.splitlines()]
    assert [s.split(",")[0] for s in said] == [
        "starting the bus emulator",
        "reading the servos' angles",
    ], err


# -- the robot command's hostile input: refused before anything is powered ------------------------


@pytest.mark.parametrize("timeout", ["1e-9", "0.0099", "11"])
def test_a_loop_timeout_our_watchdog_could_not_keep_is_refused_before_the_bus_opens(
    tmp_path, capsys, timeout
):
    """Below two control periods (2 x 5 ms on the shipped bus scenario: 0.0099 s is refused)
    our watchdog would remove the torque at the first period; above 10 s it would not guard
    the loop."""
    from stewart_drake.run.scenario_io import ROBOT_SCENARIO, load_scenario

    period = load_scenario(ROBOT_SCENARIO).control_period_s
    opened = []
    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(driver.DynamixelBus, "open", lambda self: opened.append(self))
        argv = ["robot", "home", "--scenario", str(robot_bus_yaml(tmp_path)), "--port", "/dev/null"]
        code = main([*argv, "--loop-timeout", timeout, "--out", str(tmp_path)])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2 and len(err) == 1 and not opened, err
    assert err[0] == (
        f"stewart-drake robot: --loop-timeout {float(timeout):g} s: our watchdog needs at least "
        f"two control periods (2 x {period:g} s) and at most 10 s; give a value in "
        f"[{2 * period:g}, 10] s"
    )


def test_a_trace_of_values_past_any_motion_is_refused_naming_its_line_before_the_bus_opens(
    tmp_path, capsys
):
    trace = tmp_path / "huge.csv"
    rows = [f"{0.1 * i:.1f},{1e300 if i == 7 else 0.0}" for i in range(40)]
    trace.write_text("t [s],SI [mm]\n" + "\n".join(rows) + "\n")
    argv = ["robot", str(trace), "--scenario", str(robot_bus_yaml(tmp_path)), "--port", "/dev/null"]
    code = main([*argv, "--out", str(tmp_path)])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2 and len(err) == 1, err
    assert err[0] == (
        f"stewart-drake robot: {trace}, line 9: SI = 1e+300 mm, beyond the 1000 m any motion "
        "of a platform reaches; check the value and the column's unit"
    )


def test_a_session_whose_logs_could_not_be_written_does_not_exit_0(tmp_path, monkeypatch, capsys):
    """The run ends as it should, the torque off, but without its record it is no success: the
    end line names the log and why, and the exit status is 1."""
    from stewart_drake.run import result

    def full_disk(res, path):
        raise OSError(28, "No space left on device", str(path))

    monkeypatch.setattr(result, "save_result", full_disk)
    with _emulator() as emu:
        argv = ["robot", "home", "--scenario", str(robot_bus_yaml(tmp_path)), "--port", emu.port]
        argv += ["--duration", "0.3", "--home-s", "0.5", "--loop-timeout", "5"]
        code = main([*argv, "--no-progress", "--out", str(tmp_path)])
        torque = [emu.read_item(i, p.TORQUE_ENABLE) for i in IDS]
    out, err = capsys.readouterr()
    ends = [line for line in (out + err).splitlines() if line.startswith("stewart-drake robot:")]
    assert code == 1 and len(ends) == 1, (out, err)
    assert (
        "the reference ran to its end; the logs could not be written: [Errno 28] No space"
        in (ends[0])
    )
    assert f"{tmp_path / 'robot_home_bus.npz'}" in ends[0] and torque == [0] * 6


@pytest.mark.parametrize("samples", [0, 1])
def test_a_run_ended_within_its_first_logged_period_says_so_and_writes_nothing(
    tmp_path, monkeypatch, samples
):
    """Interrupted as the torque came on (Ctrl-C at once, under load): zero or one logged
    sample has no metrics, so there is nothing to keep, and the end line says so, not that the
    logs "could not be written" (one sample made the metrics refuse it)."""
    from stewart_drake.live.session import RobotRun, _keep_logs
    from stewart_drake.run import result as run_result

    logs = types.SimpleNamespace(result=types.SimpleNamespace(t=np.zeros(samples)))
    monkeypatch.setattr(run_result, "read_run", lambda sd, context: logs)
    ended = RobotRun("interrupted by SIGINT", False, True, exit_code=130)
    simulator = types.SimpleNamespace(get_context=lambda: None)
    _keep_logs(ended, None, simulator, 0.1, tmp_path / "run.npz", None)
    assert ended.reason == (
        "interrupted by SIGINT; it ended within its first logged period: there are no logs to write"
    )
    assert ended.exit_code == 130 and ended.logs is None and not list(tmp_path.iterdir())


def test_the_emulator_outlives_a_signal_to_the_process_group():
    """A Ctrl-C, Ctrl-\\ or SIGTERM to the job's process group reaches the emulator's process
    too: it ignores them (the session turns the torque off through it and must find it
    answering), answers the bus after them, and ends when its parent stops it."""
    from stewart_drake.live.emulator_process import EmulatorProcess

    with EmulatorProcess(x0=X_HOME, start_timeout_s=HANG_S) as emu:
        child = emu._process
        for signum in (signal.SIGINT, signal.SIGTERM, signal.SIGHUP, signal.SIGQUIT):
            os.kill(child.pid, signum)
        child.join(1.0)  # wait-kept: a signal not ignored ends it well within a second
        assert child.is_alive()
        bus = driver.DynamixelBus.from_config(
            driver.DynamixelBusConfig(port=emu.port, reply_timeout_s=1.0)
        )
        with bus:  # opened: every servo pinged and answering, then the torque off, confirmed
            assert bus.read_state() is not None
        assert bus.torque_off_confirmed
    assert not child.is_alive()
    t, x = emu.truth()
    assert len(t) > 0 and x.shape[1] == 12


def test_a_run_of_another_scenario_never_replaces_the_default_robots_files():
    from stewart_drake.live.command import _scenario_suffix
    from stewart_drake.run.scenario_io import ROBOT_SCENARIO

    assert _scenario_suffix(ROBOT_SCENARIO) == ""
    assert _scenario_suffix("phantom_bus") == "_phantom_bus"
    assert _scenario_suffix("/lab/robots/my bot.v2.yaml") == "_my_bot_v2"
    assert _scenario_suffix("bus.yml") == "_bus"


def test_a_bus_is_said_emulated_only_while_an_emulator_this_process_started_serves_it():
    """What a run's encoder log says of its bus (``emulator_process.bus_words``): a port this
    process's ``start_emulator`` serves is the emulator's, with its servos in words (the same
    words the run prints); once it is closed, or for any other port, the servos on that port,
    not emulated by this run."""
    from stewart_drake.live.emulator_process import bus_words, start_emulator
    from stewart_drake.station.bus.servos import DynamixelBusConfig
    from stewart_drake.verification.measured_motion import EMULATED_BUS

    scenario = load_scenario(ROBOT_SCENARIO)
    scenario.bus = DynamixelBusConfig(**LOADED_MACHINE_BUS)
    assert bus_words("/dev/ttyUSB0") == "the servos on /dev/ttyUSB0, not emulated by this run"
    emulator = start_emulator(scenario, X_HOME)
    try:
        port = scenario.bus.port
        assert port == emulator.port and port != LOADED_MACHINE_BUS.get("port")
        assert bus_words(port) == EMULATED_BUS + emulator.servos.summary()
        assert bus_words("/dev/ttyUSB0").startswith("the servos on /dev/ttyUSB0")
    finally:
        emulator.close()
    assert bus_words(port) == f"the servos on {port}, not emulated by this run"
