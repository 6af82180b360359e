"""Every way a session on the robot ends removes the torque, says why in one line and keeps the
logs: runs of :func:`~stewart_drake.live.session.run_on_robot` against the bus emulator
(a pseudo-terminal, the robot's Drake plant behind it at real time), each ended by one cause.

The loop runs at 10 ms with the bus's and our watchdog's longest waits (conftest's
LOADED_MACHINE_BUS, a 5 s loop timeout): the emulator and the loop share this process and the
machine may be loaded (a load of 20 on 2 cores stalls a thread for a second), and what is tested
is where each path ends, not how fast. A test that needs a short wait sets it, and says why.
"""

import os
import re
import signal
import threading
import time

import numpy as np
import pytest
from conftest import HANG_S, LOADED_MACHINE_BUS, on_bus_read, require_extra, wait_for

require_extra("robot")

from stewart_drake.base.errors import StartPoseError  # noqa: E402
from stewart_drake.control.lqi.driver import LqiDriver  # noqa: E402
from stewart_drake.live.plant_backend import (  # noqa: E402
    StationServos,
    dynamixel_scenario,
)
from stewart_drake.live.session import end_line, run_on_robot  # noqa: E402
from stewart_drake.references.trajectories import NamedReference  # noqa: E402
from stewart_drake.robot.kinematics import X_HOME  # noqa: E402
from stewart_drake.run.result import load_result  # noqa: E402
from stewart_drake.run.scenario import Scenario
from stewart_drake.station.bus import protocol as p  # noqa: E402
from stewart_drake.station.bus.emulator import BusEmulator  # noqa: E402
from stewart_drake.station.bus.servos import DynamixelBusConfig  # noqa: E402

IDS = [1, 2, 3, 4, 5, 6]
CONTROL_PERIOD_S = 0.01
X_REST = X_HOME + np.array([0.0, 0.0, 0.0, 0.0, 0.0, -0.01])  # 10 mm below home


def _emulator(x0=X_REST):
    """The bus emulator in this process, the robot's plant behind it stepping at 2 ms (half
    the CPU of 1 ms: the loop and the plant share this process's GIL), on the commanded clock:
    one control period of :func:`_scenario` per torque command. These tests check where each
    path ends, not how fast: on a loaded machine the loop runs late, and a plant on the wall
    clock would move on without it (a guard trip that is the machine's, not the robot's)."""
    from pydrake.multibody.plant import MultibodyPlantConfig

    robot = Scenario(
        plant=MultibodyPlantConfig(time_step=0.002, discrete_contact_approximation="sap"),
        control_period_s=0.002,
        log_period_s=0.002,
    )
    backend = StationServos(dynamixel_scenario(scenario=robot), x0=x0)
    return BusEmulator(IDS, backend=backend, command_step_s=CONTROL_PERIOD_S)


def _scenario(emu, tmp_path, **bus):
    """Holding home at a 10 ms period with low LQI weights (omega_Q = 0.01): the loop's
    delay varies by milliseconds on a loaded machine, which this controller tolerates
    (tests/test_hardware_station.py)."""
    scenario = Scenario(controller=LqiDriver(omega_Q=0.01))
    scenario.hardware = None  # derived from the bus's servos
    scenario.reference = NamedReference("home")
    scenario.control_period_s = CONTROL_PERIOD_S
    scenario.log_period_s = CONTROL_PERIOD_S
    scenario.duration_s = 1.0
    scenario.guard.divergence_dir = str(tmp_path / "diverged")
    scenario.bus = DynamixelBusConfig(port=emu.port, **(LOADED_MACHINE_BUS | bus))
    return scenario


#: A ``before_torque`` hook: ``action()`` at the n-th bus read of the run.
_on_call = on_bus_read


def _torque_enabled(emu):
    return [emu.read_item(i, p.TORQUE_ENABLE) for i in IDS]


def _torque_off_times(emu, since):
    """Times of the WRITEs of Torque Enable = 0 received after ``since`` (perf_counter)."""
    return [
        t
        for t, packet in emu.received
        if t > since
        and packet.instruction == p.WRITE
        and packet.params[:1] == bytes([p.TORQUE_ENABLE[0]])
        and packet.params[2:3] == b"\x00"
    ]


def _run(scenario, tmp_path, **kw):
    lines = []
    kw = {"home_s": 1.0, "loop_timeout_s": 5.0, "out": tmp_path, "say": lines.append} | kw
    run = run_on_robot(scenario, **kw)
    return run, lines


def _compiled_signatures() -> dict:
    """Every signature compiled so far of the loop's kernels (the bus's, the LQI's step)."""
    from stewart_drake.control.lqi import kernels as lqi
    from stewart_drake.station.bus import kernels as bus

    dispatchers = {
        name: getattr(bus, name)
        for name in ("measure_pose", "plant_state", "parse_status", "crank_state")
        + ("torque_command", "fill_sync_write")
    } | {f"lqi.{name}": getattr(lqi.step, name) for name in ("step", "act", "newton")}
    return {name: list(f.signatures) for name, f in dispatchers.items()}


def test_a_run_homes_from_the_measured_pose_holds_and_ends_with_the_torque_off(tmp_path):
    with _emulator() as emu:
        compiled = _compiled_signatures()
        run, lines = _run(_scenario(emu, tmp_path), tmp_path)
        # Nothing compiled during the run: every call had the types compiled before it.
        assert _compiled_signatures() == compiled
        z_end = emu.with_backend(
            lambda b: b.station.GetOutputPort("platform_state").Eval(
                b.station.GetMyContextFromRoot(b.simulator.get_context())
            )[5]
        )
        assert _torque_enabled(emu) == [0] * 6
    assert run.ok and run.exit_code == 0 and run.torque_off_confirmed, end_line(run)
    assert "torque on" in lines[0]
    # Homed: the plant (the emulator's ground truth) ends at home's height, not at rest's.
    assert abs(z_end - X_HOME[5]) < 1e-3, z_end
    result = load_result(run.logs)  # the file a simulated run writes
    assert result.t[-1] > 1.5 and np.all(np.isfinite(result.T))
    assert run.start is not None and abs(run.start.x[5] - X_REST[5]) < 1e-3


def test_ctrl_c_ends_the_run_with_the_torque_off_and_the_logs_kept(tmp_path, ctrl_c):
    with _emulator() as emu:
        scenario = _scenario(emu, tmp_path)
        scenario.duration_s = 30.0
        run, _ = _run(
            scenario,
            tmp_path,
            before_torque=_on_call(50, lambda: os.kill(os.getpid(), signal.SIGINT)),
        )
        assert _torque_enabled(emu) == [0] * 6
    assert not run.ok and run.exit_code == 128 + signal.SIGINT
    assert run.reason == "interrupted by SIGINT" and run.torque_off_confirmed
    assert run.logs is not None and load_result(run.logs).t[-1] < 10.0
    assert "torque off (confirmed by every servo)" in end_line(run)


def test_our_watchdog_removes_the_torque_when_the_loop_stalls(tmp_path):
    """The loop stalls until our watchdog's torque off reaches the bus (a hang fails the test):
    the torque goes off while the loop is stalled. Our watchdog's limit is 2 s, under the
    servos' own (2.54 s), so that ours acts first, and long enough that a loaded machine does
    not trip it before the stall. That it never goes before the limit is tested on the
    watchdog's own clock (tests/test_robot_session.py)."""
    stalled = []

    def stall():
        stalled.append(time.perf_counter())
        wait_for(lambda: _torque_off_times(emu, stalled[0]), HANG_S, "our watchdog's torque off")

    with _emulator() as emu:
        scenario = _scenario(emu, tmp_path)
        scenario.duration_s = 30.0
        run, _ = _run(scenario, tmp_path, loop_timeout_s=2.0, before_torque=_on_call(50, stall))
        offs = _torque_off_times(emu, stalled[0])
    assert run.reason.startswith("LoopStalledError") and run.exit_code == 1, run.reason
    assert "no period completed" in run.reason
    assert len(offs) >= 1  # sent while the loop was stalled (the stall ended on it)
    assert run.torque_off_confirmed and run.logs is not None


def test_a_bus_that_stops_answering_mid_run_ends_it_with_the_torque_off(tmp_path):
    def cut_for_a_moment():
        emu.mute()
        threading.Timer(0.3, emu.mute, args=(False,)).start()

    with _emulator() as emu:
        # A reply timeout of 1 s, under our watchdog's 5 s: the bus error first (a reply that a
        # loaded machine delays past it is a bus error too, the path under test).
        scenario = _scenario(emu, tmp_path, reply_timeout_s=1.0)
        scenario.duration_s = 30.0
        run, _ = _run(
            scenario, tmp_path, loop_timeout_s=5.0, before_torque=_on_call(50, cut_for_a_moment)
        )
        assert _torque_enabled(emu) == [0] * 6
    assert run.reason.startswith("BusError") and run.exit_code == 1, run.reason
    assert run.torque_off_confirmed and run.logs is not None


def test_a_guard_trip_ends_the_run_with_the_torque_off_and_its_dump(tmp_path):
    with _emulator() as emu:
        scenario = _scenario(emu, tmp_path)
        scenario.duration_s = 30.0
        scenario.guard.max_tracking_error = [1e-9, 1e-9]  # trips at its first check
        run, _ = _run(scenario, tmp_path)
        assert _torque_enabled(emu) == [0] * 6
    assert run.reason.startswith("SimulationDivergedError") and run.exit_code == 1, run.reason
    assert run.torque_off_confirmed
    assert list((tmp_path / "diverged").glob("diverged_*.npz"))


def test_a_start_pose_outside_the_admissible_set_powers_nothing(tmp_path):
    low = np.array([0.0, 0.0, 0.0, 0.0, 0.0, 0.198])  # the cranks near their dead point
    with _emulator(low) as emu:
        t0 = time.perf_counter()
        with pytest.raises(StartPoseError, match="singularity"):
            _run(_scenario(emu, tmp_path), tmp_path)
        enables = [
            pk
            for t, pk in emu.received
            if t > t0
            and pk.instruction == p.WRITE
            and pk.params[:1] == bytes([p.TORQUE_ENABLE[0]])
            and pk.params[2:3] == b"\x01"
        ]
        assert enables == [] and _torque_enabled(emu) == [0] * 6


def test_too_many_late_periods_end_the_run_with_the_torque_off(tmp_path):
    with _emulator() as emu:
        scenario = _scenario(emu, tmp_path, max_deadline_misses=0)
        scenario.duration_s = 30.0
        run, _ = _run(scenario, tmp_path, before_torque=_on_call(50, lambda: time.sleep(0.05)))
        assert _torque_enabled(emu) == [0] * 6
    assert run.reason.startswith("DeadlineMissError") and run.exit_code == 1, run.reason
    assert run.torque_off_confirmed


@pytest.mark.slow
def test_sigterm_to_the_robot_command_ends_with_the_torque_off_one_line_and_the_logs(tmp_path):
    """The command as a user runs it (``robot home --emulate``), ended by SIGTERM while it
    holds: exit status 128 + 15, the one line, the logs."""
    import subprocess
    import sys

    from stewart_drake.run.scenario import dump_scenario

    scenario = Scenario(controller=LqiDriver(omega_Q=0.01), control_period_s=0.01)
    scenario.log_period_s = 0.01
    scenario.hardware = None
    scenario.bus = DynamixelBusConfig(**LOADED_MACHINE_BUS)
    (tmp_path / "bus.yaml").write_text(dump_scenario(scenario))
    command = [
        sys.executable, "-m", "stewart_drake.cli.main", "robot", "home",
        "--scenario", str(tmp_path / "bus.yaml"), "--emulate", "0,0,0,0,0,0.3",
        "--home-s", "0.5", "--hold", "120", "--loop-timeout", "5", "--out", str(tmp_path),
    ]  # fmt: skip
    process = subprocess.Popen(command, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    # stderr read in a thread: the one-line messages, and the progress bar's "n.nn/total sim s"
    # (tqdm rewrites its line with carriage returns), the run's own clock.
    seen = []
    reader = threading.Thread(target=lambda: seen.extend(iter(lambda: process.stderr.read(1), "")))
    reader.start()

    def simulated_s():
        text = "".join(seen)
        if "torque on" not in text:
            return 0.0
        times = re.findall(r"(\d+\.\d+)/\d+\.\d+ sim s", text.split("torque on", 1)[1])
        return float(times[-1]) if times else 0.0

    try:
        # Signalled once the run is 0.6 s in by its own clock, however loaded the machine.
        wait_for(lambda: simulated_s() >= 0.6 or process.poll() is not None, HANG_S, "0.6 s on")
        assert process.poll() is None, "".join(seen)
        process.send_signal(signal.SIGTERM)
        process.wait(timeout=HANG_S)
        reader.join(timeout=HANG_S)
        out = process.stdout.read()
    finally:
        process.kill()
    err = "".join(seen)
    assert process.returncode == 128 + signal.SIGTERM, (out, err)
    said = [line for line in err.splitlines() if line.startswith("stewart-drake robot: ")]
    # What it does first (loading, the emulator's start), then one end line, last.
    last = [line for line in said if "torque off" in line]
    assert len(last) == 1 and said[-1] == last[0] and len(said) == 3, err
    assert "interrupted by SIGTERM; torque off (confirmed by every servo); logs in" in last[0]
    assert load_result(tmp_path / "robot_home_bus.npz").t[-1] > 0.5


def test_teleop_on_the_robot_holds_where_it_rests_and_ends_with_the_torque_off(tmp_path):
    from pydrake.geometry import Meshcat

    from stewart_drake.live.session import teleop_on_robot

    with _emulator() as emu:
        scenario = _scenario(emu, tmp_path)
        lines = []
        run = teleop_on_robot(
            scenario, Meshcat(), duration_s=1.0, loop_timeout_s=5.0, say=lines.append
        )
        z_end = emu.with_backend(
            lambda b: b.station.GetOutputPort("platform_state").Eval(
                b.station.GetMyContextFromRoot(b.simulator.get_context())
            )[5]
        )
        assert _torque_enabled(emu) == [0] * 6
    assert run.ok and run.torque_off_confirmed and run.reason == "the session ran its duration"
    assert "sliders" in lines[0]
    # The sliders start at the measured pose: the robot holds where it rested.
    assert abs(z_end - X_REST[5]) < 2e-3, z_end


def test_a_realtime_loop_the_os_refuses_is_one_line_and_the_run_goes_on(tmp_path, monkeypatch):
    """``--realtime`` where the OS refuses the priority, the memory lock and the idle states
    (simulated: the calls fail as they do without the privilege, the PM QoS device missing):
    one line saying what and how to grant it, the run to its end, the summary saying what the
    loop was given, and the thread as it was."""
    import gc

    from stewart_drake.live import realtime

    def refused(*args):
        raise PermissionError(1, "Operation not permitted")

    monkeypatch.setattr(realtime.os, "sched_setscheduler", refused)
    monkeypatch.setattr(realtime, "_memory_lock_refusal", lambda: "the memory lock limit is 8 kB")
    missing = tmp_path / "no-pm-qos" / "cpu_dma_latency"
    monkeypatch.setattr(realtime, "PM_QOS_DEVICE", str(missing))
    cores = os.sched_getaffinity(0)
    with _emulator() as emu:
        run, lines = _run(_scenario(emu, tmp_path), tmp_path, realtime=True)
    assert run.ok and run.exit_code == 0 and run.torque_off_confirmed, end_line(run)
    said = [line for line in lines if line.startswith("realtime")]
    assert len(said) == 1 and lines[0] == said[0], lines  # before the torque goes on
    assert "not granted: SCHED_FIFO priority 50 (Operation not permitted: run as root" in said[0]
    assert "ulimit -r 50" in said[0] and "ulimit -l unlimited" in said[0]
    assert f"shallow idle states (no {missing}: a kernel without PM QoS)" in said[0]
    assert run.timing_lines[0] == (
        f"realtime: the normal policy (SCHED_OTHER), pinned to core {max(cores)}, memory not "
        "locked, garbage collected between periods"
    )
    assert run.timing["cpu"]["n"] == run.timing["periods"] - 1 > 100
    # Given back: the cores, the collector.
    assert os.sched_getaffinity(0) == cores and gc.isenabled()
