"""The session on the robot: homing lead-in, our watchdog, the measured pose and its verdict.

The end-to-end safety paths (a run on the bus emulator ended by each cause) are in
tests/test_robot_safety.py.
"""

import math
import os
import threading
import time
from pathlib import Path

import numpy as np
import pytest
from conftest import HANG_S, LOADED_MACHINE_BUS, require_extra

require_extra("robot")

from stewart_drake.base.errors import InvalidConfigError, StartPoseError  # noqa: E402
from stewart_drake.live.measure import measure_pose, pose_verdict  # noqa: E402
from stewart_drake.live.watchdog import LoopWatchdog  # noqa: E402
from stewart_drake.references.homing import HomingReference  # noqa: E402
from stewart_drake.references.trajectories import paper_manoeuvre  # noqa: E402
from stewart_drake.robot.kinematics import X_HOME  # noqa: E402
from stewart_drake.run.plan import make_plan  # noqa: E402
from stewart_drake.station.bus.driver import DynamixelBus  # noqa: E402
from stewart_drake.station.bus.emulator import BusEmulator  # noqa: E402

IDS = [1, 2, 3, 4, 5, 6]
#: The bus's wait for a reply: a loaded machine's pseudo-terminal delays one by up to a second.
REPLY_S = LOADED_MACHINE_BUS["reply_timeout_s"]


def test_the_homing_lead_in_and_the_warped_reference_start_and_end_at_rest_on_its_path():
    reference = paper_manoeuvre()  # starts moving: phi_dot = 2 pi / 6 rad/s
    x_rest = X_HOME + np.array([0.02, -0.01, 0.0, 0.003, -0.002, -0.01])
    homed = HomingReference(reference, x_rest, home_s=2.0, t_end=3.0, ramp_s=1.0)
    assert homed.duration_s == 6.0
    x, v, a = homed.evaluate(np.array([0.0, 2.0, 6.0, 9.0]))
    np.testing.assert_allclose(x[0], x_rest, atol=1e-15)
    np.testing.assert_allclose(x[1], reference.evaluate(0.0)[0], atol=1e-12)  # homed
    np.testing.assert_allclose(x[2:], np.tile(reference.evaluate(3.0)[0], (2, 1)), atol=1e-12)
    np.testing.assert_allclose(np.abs(v) + np.abs(a), 0.0, atol=1e-12)  # at rest at each end
    # The rate and acceleration it reports are its pose's derivatives (central differences),
    # across the lead-in, both ramps and the joins.
    t = np.linspace(0.05, 6.5, 131)
    h = 1e-5
    xp, vp, _ = homed.evaluate(t + h)
    xm, vm, _ = homed.evaluate(t - h)
    _, v, a = homed.evaluate(t)
    np.testing.assert_allclose((xp - xm) / (2 * h), v, atol=1e-6)
    np.testing.assert_allclose((vp - vm) / (2 * h), a, atol=1e-4)
    # Between the ramps: the reference itself, half a ramp late, at its own rate.
    t_mid = np.array([3.6, 4.0, 4.4])
    for part, ref in zip(homed.evaluate(t_mid), reference.evaluate(t_mid - 2.0 - 0.5)):
        np.testing.assert_allclose(part, ref, atol=1e-12)
    # Never faster than the reference (on its path, at most its rate).
    speeds = np.abs(homed.evaluate(np.linspace(2.0, 6.0, 401))[1]).max(axis=0)
    assert np.all(
        speeds <= np.abs(reference.evaluate(np.linspace(0, 3, 301))[1]).max(axis=0) + 1e-12
    )
    with pytest.raises(InvalidConfigError, match="must be > 0"):
        HomingReference(reference, x_rest, home_s=0.0)


def test_our_watchdog_removes_the_torque_when_periods_stop_and_the_next_step_raises(monkeypatch):
    """On the watchdog's own clock, set by the test: quiet up to the limit, the torque off
    once past it."""
    import types

    from conftest import wait_for

    from stewart_drake.base.errors import LoopStalledError
    from stewart_drake.live import watchdog as robot
    from stewart_drake.live.watchdog import watchdog_monitor

    now = [100.0]
    monkeypatch.setattr(robot, "time", types.SimpleNamespace(perf_counter=lambda: now[0]))
    calls = []
    watchdog = LoopWatchdog(lambda: calls.append(now[0]) or True, timeout_s=0.2)
    monitor = watchdog_monitor(watchdog)
    with watchdog:
        monitor(None)  # a step completed at 100 s
        now[0] = 100.19
        time.sleep(0.3)  # six of its checks (every 0.05 s) at 0.19 s without a period
        assert calls == [] and watchdog.tripped is None  # never before the limit
        now[0] = 100.21
        wait_for(lambda: watchdog.tripped, HANG_S, "the watchdog tripping")
    assert calls == [100.21]  # once
    assert "no period completed for 210 ms" in watchdog.tripped
    assert "(confirmed)" in watchdog.tripped
    with pytest.raises(LoopStalledError, match="no period completed"):
        monitor(None)  # the loop's next step ends the run


def test_our_watchdog_stays_quiet_while_periods_complete(monkeypatch):
    """A period completed every 10 ms of the watchdog's own clock (set by the test: a loaded
    machine cannot stretch a period here) for 2 s of it, over a score of its checks: it never
    trips."""
    import types

    from stewart_drake.live import watchdog as robot

    now = [100.0]
    monkeypatch.setattr(robot, "time", types.SimpleNamespace(perf_counter=lambda: now[0]))
    calls = []
    watchdog = LoopWatchdog(lambda: calls.append(1) or True, timeout_s=0.2)
    with watchdog:
        for _ in range(200):
            now[0] += 0.01
            watchdog.kick()
            time.sleep(0.005)  # its checks come every 0.05 s: a score of them
    assert calls == [] and watchdog.tripped is None
    with pytest.raises(InvalidConfigError, match="loop timeout"):
        LoopWatchdog(lambda: True, timeout_s=0.0)


def test_the_bus_lock_makes_a_watchdogs_torque_off_wait_for_the_transfer_in_progress():
    with BusEmulator(IDS) as emu:
        bus = DynamixelBus(emu.port, 1_000_000, IDS, reply_timeout_s=REPLY_S).open()
        try:
            bus.configure()
            done = []
            with bus.lock:  # a transfer in progress in the main thread
                other = threading.Thread(target=lambda: done.append(bus.torque_off()))
                other.start()
                time.sleep(0.05)
                assert done == []  # waits
            other.join(HANG_S)
            assert done == [True]
        finally:
            bus.close()


@pytest.fixture(scope="module")
def dynamixel_plan():
    from stewart_drake.live.plant_backend import dynamixel_scenario

    return make_plan(dynamixel_scenario(), with_reference=False)


def test_the_measured_pose_is_the_plants_within_the_encoders_resolution(dynamixel_plan):
    from stewart_drake.live.plant_backend import StationServos

    x0 = X_HOME + np.array([0.03, -0.02, 0.01, 0.004, -0.003, 0.01])
    backend = StationServos(dynamixel_plan.scenario, x0=x0)
    with BusEmulator(IDS, backend=backend) as emu:
        bus = DynamixelBus(emu.port, 1_000_000, IDS, reply_timeout_s=REPLY_S).open()
        try:
            measured = measure_pose(dynamixel_plan, bus=bus)
        finally:
            bus.close()
    # One count (2 pi / 4096 rad) on each crank moves the platform by at most |J^-1| counts.
    from stewart_drake.robot.kinematics import jacobian

    count = 2 * math.pi / 4096
    bound = np.abs(np.linalg.inv(jacobian(dynamixel_plan.geometry, x0))).sum(axis=1) * count
    assert np.all(np.abs(measured.x - x0) <= bound), (measured.x - x0, bound)
    assert measured.problem is None and measured.flags["admissible"]
    assert "admissible" in measured.summary()


def test_a_pose_outside_the_admissible_set_is_named(dynamixel_plan):
    geometry = dynamixel_plan.geometry
    # Reachable poses (the angles exist) that the admissible set refuses, each for its reason.
    for x, why in (
        (np.array([0.0, 0.0, 0.0, 0.0, 0.0, 0.198]), "singularity"),  # cranks near their dead point
        (np.array([0.8, 0.0, 0.0, 0.0, 0.0, 0.3]), "joint's range"),  # rolled 46 deg
    ):
        verdict = pose_verdict(dynamixel_plan, _angles(geometry, x))
        np.testing.assert_allclose(verdict.x, x, atol=1e-9)  # the FK finds the pose back
        assert not verdict.flags["admissible"] and why in verdict.problem
        assert "NOT admissible" in verdict.summary()
    assert pose_verdict(dynamixel_plan, _angles(geometry, X_HOME)).problem is None
    with pytest.raises(StartPoseError, match="zero_counts"):
        pose_verdict(dynamixel_plan, np.full(6, 3.0))  # no pose has these angles


def _angles(geometry, x):
    """The crank angles of pose x by the closed-form IK, unchecked (x may be outside a range)."""
    from stewart_drake.robot.kinematics import ik_unchecked

    theta, _ = ik_unchecked(geometry, x)
    assert np.all(np.isfinite(theta))
    return theta


def test_calibration_finds_the_zero_counts_the_servos_were_mounted_with():
    from stewart_drake.live.measure import zero_counts_at
    from stewart_drake.station.bus.servo_models import FirstOrderServos

    q_held = np.radians([-3.8, -3.8, 10.0, -20.0, 0.0, 45.0])  # the jig's angles
    mounted = [2048, 1000, 3000, 2500, 100, 4000]
    backend = FirstOrderServos.from_catalogue("XM430-W350-T", q_held)
    with BusEmulator(IDS, backend=backend, zero_counts=mounted) as emu:
        # Configured with a wrong guess of the zeros (the factory mid-turn, 2048).
        directions = [1, 1, 1, 1, 1, 1]
        bus = DynamixelBus(
            emu.port,
            1_000_000,
            IDS,
            zero_counts=[2048] * 6,
            directions=directions,
            reply_timeout_s=REPLY_S,
        ).open()
        try:
            found = [zero_counts_at(bus, a)[k] for k, a in enumerate(q_held)]
        finally:
            bus.close()
    assert np.all(np.abs(np.array(found) - mounted) <= 1), (found, mounted)


def test_a_granted_realtime_loop_holds_its_core_and_priority_and_gives_them_back():
    """Where the OS grants it (root, or an rtprio limit): in the thread that entered it,
    SCHED_FIFO at priority 50 on one core, the collector off; all given back on exit. Run in a
    thread of its own, which does nothing while it holds the priority."""
    import gc
    import os

    from stewart_drake.live.realtime import PRIORITY, RealtimeLoop, loop_core

    seen = {}

    def inside():
        before = (os.sched_getscheduler(0), os.sched_getaffinity(0))
        with RealtimeLoop() as loop:
            seen["inside"] = (
                os.sched_getscheduler(0),
                os.sched_getparam(0).sched_priority,
                os.sched_getaffinity(0),
                gc.isenabled(),
                loop.policy,
                loop.refusals,
            )
        seen["after"] = (os.sched_getscheduler(0), os.sched_getaffinity(0)) == before

    thread = threading.Thread(target=inside)
    thread.start()
    thread.join(HANG_S)
    policy, priority, cores, collecting, named, refusals = seen["inside"]
    if named != "SCHED_FIFO":
        pytest.skip(f"the OS grants no real-time priority here: {refusals}")
    assert (policy, priority, cores) == (os.SCHED_FIFO, PRIORITY, {loop_core()})
    assert not collecting and seen["after"] and gc.isenabled()


def _held_qos_files() -> int:
    """How many of this process's open files are the PM QoS device (read from /proc)."""
    from stewart_drake.live.realtime import PM_QOS_DEVICE

    fds = Path("/proc/self/fd")
    return sum(1 for fd in fds.iterdir() if os.path.realpath(fd) == PM_QOS_DEVICE)


def test_a_granted_realtime_loop_holds_the_cores_idle_states_shallow_and_gives_them_back():
    """Where the OS grants it (root, or write access to /dev/cpu_dma_latency): inside the loop
    the kernel reads back a wake-up latency of 0 us in force, the loop holding the device open
    once; on exit the file is closed (so the request is gone: the kernel holds it only while
    the file is open)."""
    from stewart_drake.live.realtime import IDLE_LATENCY_US, RealtimeLoop, idle_latency_in_force

    if not os.path.exists("/proc/self/fd"):
        pytest.skip("no /proc to read the open files from")
    before = _held_qos_files()
    with RealtimeLoop() as loop:
        inside = (loop.idle_latency_us, idle_latency_in_force(), _held_qos_files())
        refusals = list(loop.refusals)
    if inside[0] is None:
        pytest.skip(f"the OS grants no PM QoS request here: {refusals}")
    assert IDLE_LATENCY_US == 0
    assert inside == (0, 0, before + 1), inside
    assert _held_qos_files() == before and loop.idle_latency_us is None
    assert "idle states held to 0 us wake-up" not in loop.granted()
