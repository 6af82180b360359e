"""What moves the bus emulator's plant, and when a command acts: the loop's clock (each command
first carries the model to its own instant under the commands before it), a goal written during
a wall-clock step acting from the firmware period it arrived in, and the step a 1 ms firmware
period on a 2 ms plant costs (none but the currents')."""

import numpy as np
import pytest

from stewart_drake.station.bus.servo_firmware import FirmwareLoops
from stewart_drake.station.bus.servo_models import FirstOrderServos
from stewart_drake.station.bus.servos import servo_spec

XM430 = servo_spec("XM430-W350-T")
HANG_BUS_S = 5.0
PERIOD = 0.01


def _positions_after_commands(catch_up: bool, currents) -> list:
    """A first-order XM430 in Current Control Mode on the commands' clock: its angle read after
    each Goal Current of ``currents`` is written (one sync write each), counts."""
    pytest.importorskip("dynamixel_sdk", reason="the robot extra: pip install -e '.[robot]'")
    from stewart_drake.station.bus.driver import DynamixelBus
    from stewart_drake.station.bus.emulator import BusEmulator

    backend = FirstOrderServos.from_catalogue(XM430.name, [0.0], load_inertia=0.002)
    reads = []
    with BusEmulator(
        [1], XM430.name, backend=backend, command_step_s=PERIOD, catch_up=catch_up
    ) as emu:
        bus = DynamixelBus(emu.port, 1_000_000, [1], XM430.name, reply_timeout_s=HANG_BUS_S)
        with bus:
            bus.configure()
            bus.enable_torque()
            for amps in currents:
                bus.write_torques([amps * XM430.torque_constant_Nm_per_A])
                reads.append(bus.read_state().q[0] / XM430.rad_per_count)
            bus.torque_off()
    return reads


def test_on_the_loops_clock_a_read_finds_the_robot_where_it_is_when_the_command_arrives():
    """Catching up, the first command moves nothing before its read, and each later read is
    where the commands before it left the robot: the same motion as the plain commanded
    clock's, one command later (a torque acts from when it is written, as on a wall clock,
    not before the read that follows it)."""
    currents = [1.0] * 6 + [-1.0] * 4
    plain = _positions_after_commands(False, currents)
    caught = _positions_after_commands(True, currents)
    assert caught[0] == pytest.approx(0.0, abs=0.5)
    assert plain[0] >= 1.0 and plain[5] > 50  # the plain clock moved under the first already
    np.testing.assert_allclose(caught[1:], plain[:-1], atol=1.0)


class _Recorded(FirmwareLoops):
    """The firmware's part alone on a first-order servo, each period's command kept."""

    def __init__(self):
        from stewart_drake.station.bus.servo_firmware import PositionFirmware, PositionGains

        self.ids, self.zero_counts = [1], np.zeros(1)
        self.backend = FirstOrderServos.from_catalogue(XM430.name, [0.0], load_inertia=0.002)
        self._firmware, self._pwm_currents, self.seen = {}, {}, []
        self._loop = PositionFirmware(PositionGains(0.0, 0.0, 0.0, 0.0, 12.0), 1e-3, [0.0])

    def _firmware_of(self, k, command, read_rad):
        self.seen.append(command[:2])
        return self._loop


def test_a_goal_written_during_a_wall_clock_step_acts_from_the_period_it_arrived_in():
    """A step of 4 ms from t0 with a goal written at t0 + 2.5 ms: the firmware's periods at
    t0, +1 and +2 ms run on the goal before it, the one at +3 ms on the new goal; on the
    commands' clock (no start instant) every period runs on the goal written."""
    loops = _Recorded()
    t0 = 1000.0
    command = ((400, 7, (1, 2, 3, 4)), (100, 3), t0 + 0.0025)
    loops._advance(0.004, np.zeros(1), {0: command}, t0)
    assert loops.seen == [(100, 3)] * 3 + [(400, 7)]
    loops.seen.clear()
    loops._advance(0.004, np.zeros(1), {0: command})
    assert loops.seen == [(400, 7)] * 4
    loops.seen.clear()
    loops._advance(0.0, np.zeros(1), {0: command}, t0)  # no time: no firmware period
    assert loops.seen == []


def test_the_model_thread_never_waits_for_the_tables_a_catching_up_command_holds():
    """A command catching up holds the tables until the model thread has made its step: the
    thread's look at the watchdogs must not wait for them (it would never make the step: the
    emulator went silent under load), only come back a tick later."""
    import threading

    from conftest import HANG_S

    from stewart_drake.station.bus.emulator import BusEmulator

    backend = FirstOrderServos.from_catalogue(XM430.name, [0.0], load_inertia=0.002)
    emu = BusEmulator([1], XM430.name, backend=backend, command_step_s=PERIOD, catch_up=True)
    waits = []
    with emu._lock:  # as the bus thread holds it while a command catches up
        looker = threading.Thread(target=lambda: waits.append(emu._trip_watchdogs()))
        looker.start()
        looker.join(timeout=HANG_S)
        assert not looker.is_alive()
    assert waits == [emu.tick_s]
    emu.close()
