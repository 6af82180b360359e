"""The DYNAMIXEL driver end to end against the bus emulator on a pseudo-terminal, and the
protocol's packets against the vendor's own packet builder."""

import math
import os
import pickle
import sys
import time

import numpy as np
import pytest
from conftest import HANG_S, LOADED_MACHINE_BUS, require_extra, wait_for

require_extra("robot")
import dynamixel_sdk as sdk  # noqa: E402

from stewart_drake.base.errors import (  # noqa: E402
    BusError,
    InvalidConfigError,
    MissingExtraError,
    MissingServoError,
    ServoConfigMismatchError,
)
from stewart_drake.station.bus import protocol as p  # noqa: E402
from stewart_drake.station.bus import servos  # noqa: E402
from stewart_drake.station.bus.driver import DynamixelBus  # noqa: E402
from stewart_drake.station.bus.emulator import BusEmulator  # noqa: E402
from stewart_drake.station.bus.servo_models import FirstOrderServos  # noqa: E402
from stewart_drake.station.bus.vendor_port import dynamixel_sdk  # noqa: E402

IDS = [1, 2, 3, 4, 5, 6]
XM430 = servos.SERVO_SPECS["XM430-W350-T"]


class _CapturePort:
    """What the SDK's txPacket needs of a port; keeps the bytes it writes."""

    is_using = False

    def clearPort(self):
        pass

    def writePort(self, packet):
        self.sent = bytes(packet)
        return len(packet)


# --- the protocol against the SDK ------------------------------------------------------------


def test_crc_agrees_with_the_sdk():
    rng = np.random.default_rng(0)
    handler = sdk.PacketHandler(2.0)
    for n in (1, 7, 64, 300):
        data = rng.integers(0, 256, n).tolist()
        assert p.crc16(bytes(data)) == handler.updateCRC(0, data, n)
    # The e-Manual's example: a PING to id 1 ends in CRC 0x4E19 (bytes 19 4E).
    assert p.build_packet(1, p.PING) == bytes.fromhex("FFFFFD0001030001194E")


@pytest.mark.parametrize(
    "params",
    [
        [0x66, 0x00, 0x10, 0x02],  # Goal Current = 0x0210
        [0x74, 0x00, 0xFF, 0xFF, 0xFD, 0x00],  # needs stuffing
        [0x74, 0x00, 0xFF, 0xFF, 0xFD, 0xFF, 0xFF, 0xFD],  # twice
    ],
)
def test_instruction_packets_match_the_sdk_byte_for_byte(params):
    handler, port = sdk.PacketHandler(2.0), _CapturePort()
    tx = [0xFF, 0xFF, 0xFD, 0, 3, (len(params) + 3) & 0xFF, 0, p.WRITE] + params + [0, 0]
    # The SDK's stuffing (its txPacket drops addStuffing's result when the length grows, so
    # stuffing is compared on addStuffing itself; the driver never sends FF FF FD: ids <= 252).
    stuffed = handler.addStuffing(list(tx))
    n = stuffed[5] + 7
    crc = handler.updateCRC(0, stuffed, n - 2)
    expected = bytes(stuffed[: n - 2]) + crc.to_bytes(2, "little")
    ours = p.build_packet(3, p.WRITE, bytes(params))
    assert ours == expected
    if b"\xff\xff\xfd" not in bytes(params):
        assert handler.txPacket(port, list(tx)) == sdk.COMM_SUCCESS
        assert ours == port.sent
    packet, used, crc_ok = p.parse_packet(b"\x00\xff" + ours + b"\xff")
    assert crc_ok and used == len(ours) + 2
    assert (packet.servo_id, packet.instruction, packet.params) == (3, p.WRITE, bytes(params))


def test_a_corrupted_packet_is_flagged_and_a_partial_one_waits():
    good = p.build_status(5, 0, bytes([0xFF, 0xFF, 0xFD, 0x01]))
    bad = bytearray(good)
    bad[-3] ^= 0x01
    assert p.parse_packet(bytes(bad))[2] is False
    assert p.parse_packet(good[:-1]) == (None, 0, True)
    # The SDK's own receiver takes our status packet (stuffing removed): same parameters.
    handler = sdk.PacketHandler(2.0)
    assert handler.removeStuffing(list(good))[9:13] == [0xFF, 0xFF, 0xFD, 0x01]


def test_conversions_invert_and_use_the_datasheet_torque_constant():
    assert XM430.torque_constant_Nm_per_A == pytest.approx(4.1 / 2.3)
    assert servos.SERVO_SPECS["XM540-W270-T"].torque_constant_Nm_per_A == pytest.approx(
        2.409, abs=1e-3
    )
    tau = np.array([-1.0, -0.01, 0.0, 0.5, 3.0])
    units = servos.torque_to_current_units(tau, XM430, direction=-1)
    step = XM430.torque_constant_Nm_per_A * 2.69e-3  # one current unit, N m
    back = servos.current_units_to_torque(units, XM430, direction=-1)
    assert np.all(np.abs(back - tau) <= step / 2 + 1e-12)
    assert units[3] == -round(0.5 / (4.1 / 2.3) / 2.69e-3)
    q = np.array([-3.0, 0.0, 1.234])
    counts = p.rad_to_counts(q, zero_counts=1000, direction=-1)
    assert np.all(np.abs(p.counts_to_rad(counts, 1000, -1) - q) <= math.pi / 4096 + 1e-12)
    assert p.velocity_units_to_rad_s(100) == pytest.approx(22.9 * 2 * math.pi / 60)


def test_a_servo_without_current_control_is_refused_for_torque():
    with pytest.raises(InvalidConfigError, match="XL430-W250-T has no Current Control Mode"):
        servos.servo_spec("XL430-W250-T")
    with pytest.raises(InvalidConfigError, match="XM430-W350-T"):
        DynamixelBus("/dev/null", 1_000_000, IDS, model="XL430-W250-T")


@pytest.mark.parametrize(
    "kw, match",
    [
        (dict(baud_rate=12345), "baud_rate"),
        (dict(watchdog_s=0.03), "watchdog_s"),
        (dict(ids=[1, 1]), "distinct"),
        (dict(current_limit_A=9.0), "current_limit_A"),
        (dict(zero_counts=[0, 0]), "one entry per id"),
    ],
)
def test_bad_settings_are_refused_before_the_port_is_opened(kw, match):
    args = dict(port="/nonexistent/port", baud_rate=1_000_000, ids=IDS) | kw
    with pytest.raises(InvalidConfigError, match=match):
        DynamixelBus(**args)


def test_the_bus_its_check_and_its_scenario_section_default_alike():
    """A bus built without a model, a temperature limit or a watchdog writes what a scenario's
    ``bus:`` section without them would: the driver's, the check's and the section's defaults
    are the same values."""
    import dataclasses
    import inspect

    names = ("model", "temperature_limit_C", "watchdog_s")
    config = {f.name: f.default for f in dataclasses.fields(servos.DynamixelBusConfig)}
    for function in (DynamixelBus.__init__, servos.check_bus_settings):
        parameters = inspect.signature(function).parameters
        assert {n: parameters[n].default for n in names} == {n: config[n] for n in names}
    assert (config["model"], config["temperature_limit_C"], config["watchdog_s"]) == (
        "XM430-W350-T",
        70,
        0.1,
    )


def test_a_missing_sdk_names_the_extra(monkeypatch):
    monkeypatch.setitem(sys.modules, "dynamixel_sdk", None)
    with pytest.raises(MissingExtraError, match=r"stewart-drake\[robot\]"):
        dynamixel_sdk()


# --- the driver against the emulator ---------------------------------------------------------


@pytest.fixture
def emulator():
    with BusEmulator(IDS, zero_counts=[2048, 1000, 3000, 2048, 2048, 2048]) as emu:
        yield emu


def _bus(emu, **kw):
    # A generous reply timeout: the emulator's thread may wait long for a core on a loaded
    # machine, and its pseudo-terminal delays a reply by up to a second (the SDK's own ~34 ms
    # is what a robot runs with; benchmarks/bus_round_trip.py measures the round trips).
    kw = (
        dict(
            zero_counts=[2048, 1000, 3000, 2048, 2048, 2048],
            current_limit_A=1.5,
            reply_timeout_s=LOADED_MACHINE_BUS["reply_timeout_s"],
            # The servos' watchdog at its longest (2.54 s), where the test does not time it:
            # a loaded machine may pause the test's thread past a shorter one between two
            # instructions, and the current it checks would already be off.
            watchdog_s=LOADED_MACHINE_BUS["watchdog_s"],
        )
        | kw
    )
    return DynamixelBus(emu.port, 1_000_000, IDS, **kw)


def test_configure_writes_the_limits_and_reads_them_back(emulator):
    with _bus(emulator, temperature_limit_C=65, position_limits_counts=(500, 3500)) as bus:
        # A Goal Current left by an earlier run: configure zeroes it before any torque.
        bus._packets.write2ByteTxRx(bus._port, 2, p.GOAL_CURRENT[0], 300)
        assert emulator.read_item(2, p.GOAL_CURRENT) == 300
        bus.configure()
        for i in IDS:
            assert emulator.read_item(i, p.OPERATING_MODE) == 0
            assert emulator.read_item(i, p.CURRENT_LIMIT) == math.floor(1.5 / 2.69e-3) == 557
            assert emulator.read_item(i, p.TEMPERATURE_LIMIT) == 65
            assert emulator.read_item(i, p.MIN_POSITION_LIMIT) == 500
            assert emulator.read_item(i, p.MAX_POSITION_LIMIT) == 3500
            assert emulator.read_item(i, p.BUS_WATCHDOG) == 127  # 2.54 s in 20 ms units
            assert emulator.read_item(i, p.TORQUE_ENABLE) == 0
            assert emulator.read_item(i, p.GOAL_CURRENT) == 0
        state = bus.read_state()
        np.testing.assert_allclose(state.q, 0, atol=1e-12)  # the zero offsets applied
    # Closing removed the torque and let the port go.
    assert all(emulator.read_item(i, p.TORQUE_ENABLE) == 0 for i in IDS)


def test_a_setting_that_does_not_read_back_is_refused_with_the_torque_off(emulator):
    servo = emulator.servos[3]
    write = servo.write
    # Servo 3 acknowledges an Operating Mode write without storing it (another firmware).
    servo.write = lambda address, data: 0 if address == 11 else write(address, data)
    with _bus(emulator) as bus:
        with pytest.raises(ServoConfigMismatchError, match="servo id 3: Operating Mode") as e:
            bus.configure()
        assert (e.value.wrote, e.value.read) == (0, 3)
        assert bus.torque_off_confirmed
    assert pickle.loads(pickle.dumps(e.value)).item == "Operating Mode"


def test_the_servo_refuses_eeprom_writes_with_torque_on_and_goals_over_the_limit(emulator):
    with _bus(emulator) as bus:
        bus.configure()
        bus.enable_torque()
        handler, port = bus._packets, bus._port
        _, error = handler.write2ByteTxRx(port, 1, p.CURRENT_LIMIT[0], 100)
        assert error == p.ERR_ACCESS
        _, error = handler.write2ByteTxRx(port, 1, p.GOAL_CURRENT[0], 600)  # limit 557
        assert error == p.ERR_DATA_LIMIT
        # either sign: -600 units (two's complement) is over the limit too, -557 is not
        _, error = handler.write2ByteTxRx(port, 1, p.GOAL_CURRENT[0], -600 & 0xFFFF)
        assert error == p.ERR_DATA_LIMIT
        _, error = handler.write2ByteTxRx(port, 1, p.GOAL_CURRENT[0], -557 & 0xFFFF)
        assert error == 0
        # The driver clips instead: the torque sent is the limit's.
        sent = bus.write_torques(np.full(6, 100.0))
        np.testing.assert_allclose(sent, 557 * 2.69e-3 * 4.1 / 2.3)


def test_a_constant_current_accelerates_the_horn_at_kt_i_over_j():
    """75 commands of 2 ms each on the model's own clock (the emulator's commanded clock: the
    horns move 2 ms per command, so a loaded machine cannot stretch or drop the model's time
    between two reads), each read after its step."""
    J, i_goal, dt = 0.0125, 0.2, 0.002  # kg m^2; A: a = K_t i / J = 28.5 rad/s^2; s
    backend = FirstOrderServos(J, XM430.torque_constant_Nm_per_A, q0=np.zeros(6))
    emu = BusEmulator(IDS, backend=backend, command_step_s=dt)
    with emu, _bus(emu, zero_counts=None) as bus:
        bus.configure()
        bus.enable_torque()
        tau = XM430.torque_constant_Nm_per_A * i_goal
        v = []
        for _ in range(75):  # 0.15 s of the model's time
            bus.write_torques(np.array([tau, -tau, tau, -tau, tau, tau]))
            s = bus.read_state()
            v.append(s.v)
        bus.torque_off()
    t, v = dt * np.arange(1, len(v) + 1), np.array(v)
    expected = XM430.torque_constant_Nm_per_A * (round(i_goal / 2.69e-3) * 2.69e-3) / J
    moving = v[:, 0] > 0.2  # the first write starts the motion; fit past it
    slope = np.polyfit(t[moving], v[moving], 1)[0]
    np.testing.assert_allclose(slope, expected * np.array([1, -1, 1, -1, 1, 1]), rtol=0.1)
    assert np.allclose(s.tau, tau * np.array([1, -1, 1, -1, 1, 1]), rtol=0.01)


def test_a_commanded_clock_moves_the_model_one_period_per_torque_command_whatever_the_wall_time():
    """With ``command_step_s`` the model advances exactly one period at each torque command and
    not otherwise: the same state as the model stepped by hand with the currents the servos
    drive, however long the driver takes between commands. The bus watchdog still counts wall
    time."""
    J, dt = 0.0125, 0.01
    backend = FirstOrderServos(J, XM430.torque_constant_Nm_per_A, q0=np.zeros(6))
    by_hand = FirstOrderServos(J, XM430.torque_constant_Nm_per_A, q0=np.zeros(6))
    signs = np.array([1, -1, 1, -1, 1, 1])
    tau = XM430.torque_constant_Nm_per_A * 0.2 * signs
    emu = BusEmulator(IDS, backend=backend, command_step_s=dt)
    # The watchdog at 1 s: longer than the test's pauses (0.05 s) however loaded the machine.
    with emu, _bus(emu, zero_counts=None, watchdog_s=1.0) as bus:
        bus.configure()
        bus.enable_torque()
        for k in range(8):
            bus.write_torques(tau)
            if k == 3:
                time.sleep(0.05)  # a late period: the model does not move meanwhile
        state = bus.read_state()  # answered after the last command's step
        for _ in range(8):  # the currents the servos drove for every command
            by_hand.advance(dt, emu.applied_current_A())
        q_commanded = emu.state()[0]
        time.sleep(0.05)  # no command: no motion
        np.testing.assert_array_equal(emu.state()[0], q_commanded)
        np.testing.assert_array_equal(q_commanded, by_hand.positions_rad())
        np.testing.assert_array_equal(emu.state()[1], by_hand.velocities_rad_s())
        assert np.all(np.sign(state.v) == signs) and np.all(state.v != 0)
        # Watched without bus traffic: every instruction packet restarts a servo's watchdog.
        wait_for(lambda: np.all(emu.applied_current_A() == 0), HANG_S, "the bus watchdog's trip")
        assert bus.watchdog_tripped() == IDS
    with pytest.raises(InvalidConfigError, match="command_step_s"):
        BusEmulator(IDS, command_step_s=0.0)


def test_torque_off_is_idempotent_and_stops_the_current(emulator):
    with _bus(emulator) as bus:
        bus.configure()
        bus.enable_torque()
        bus.write_torques(np.full(6, 0.5))
        bus.read_state()
        assert np.all(emulator.applied_current_A() > 0)
        assert bus.torque_off() and bus.torque_off()
        assert np.all(emulator.applied_current_A() == 0)
        assert all(emulator.read_item(i, p.TORQUE_ENABLE) == 0 for i in IDS)
    assert bus.torque_off()  # closed: nothing to do, still safe


def test_the_bus_watchdog_removes_torque_when_commands_stop(emulator):
    with _bus(emulator, watchdog_s=0.1) as bus:
        bus.configure()
        bus.enable_torque()
        bus.write_torques(np.full(6, 0.5))
        # Read until the servos report the current (the model's next step): each read is an
        # instruction that restarts the watchdog, so none trips while the test waits.
        wait_for(lambda: np.all(bus.read_state().tau > 0), HANG_S, "the current driven")
        # Each servo's trip is due 5 units of 20 ms after its last instruction: read from the
        # emulator's own watch (its times, not the test's), where a wrong unit would show.
        for expiry, servo in emulator._armed():
            assert expiry - servo.last_instruction == pytest.approx(0.1, abs=1e-9)
        t_last = time.perf_counter()
        off = lambda: np.all(emulator.applied_current_A() == 0)  # noqa: E731
        wait_for(off, HANG_S, "the bus watchdog's trip", poll_s=0.005)
        elapsed = time.perf_counter() - t_last
        print(f"watchdog 0.1 s: current off {elapsed * 1e3:.0f} ms after the last command")
        assert bus.watchdog_tripped() == IDS
        # Goal Current is read-only until the trip is cleared; configure clears it.
        _, error = bus._packets.write2ByteTxRx(bus._port, 1, p.GOAL_CURRENT[0], 10)
        assert error == p.ERR_DATA_RANGE
        bus.configure()
        assert bus.watchdog_tripped() == []


def test_a_hardware_error_removes_the_servos_torque_and_is_reported(emulator):
    with _bus(emulator) as bus:
        bus.configure()
        bus.enable_torque()
        bus.write_torques(np.full(6, 0.5))
        assert bus.hardware_errors() == {}
        emulator.set_hardware_error(4, p.HW_OVERHEATING | p.HW_OVERLOAD)
        assert bus.hardware_errors() == {4: 0x24}
        current = emulator.applied_current_A()
        assert current[3] == 0 and np.all(np.delete(current, 3) > 0)
        # Its status packets carry the Alert bit, which the driver's reads tolerate.
        _, _, error = bus._packets.read1ByteTxRx(bus._port, 4, p.TORQUE_ENABLE[0])
        assert error == p.ALERT


def test_a_missing_id_is_named(emulator):
    bus = DynamixelBus(emulator.port, 1_000_000, [1, 2, 9], reply_timeout_s=0.2)
    with pytest.raises(MissingServoError, match="servo id 9 does not answer") as info:
        bus.open()
    assert info.value.servo_id == 9
    assert pickle.loads(pickle.dumps(info.value)).servo_id == 9


def test_a_bus_that_stops_answering_mid_run_raises_and_tries_torque_off(emulator):
    with _bus(emulator, reply_timeout_s=0.2) as bus:  # 7 transfers will time out
        bus.configure()
        bus.enable_torque()
        for _ in range(20):
            bus.read_state()
            bus.write_torques(np.full(6, 0.2))
        emulator.mute()
        t_mute = time.perf_counter()
        with pytest.raises(BusError, match="sync read.*NOT confirmed") as info:
            bus.read_state()
        assert not bus.torque_off_confirmed
        assert pickle.loads(pickle.dumps(info.value)).args == info.value.args
    # The driver sent Torque Enable = 0 after the link failed (broadcast first).
    sent = [pk for t, pk in emulator.received if t > t_mute and pk.instruction == p.WRITE]
    assert sent and sent[0].servo_id == p.BROADCAST_ID
    assert sent[0].params == bytes([p.TORQUE_ENABLE[0], 0, 0])


def test_the_robots_drake_plant_behind_the_bus_holds_lifts_and_lowers_the_platform():
    from stewart_drake.live.plant_backend import StationServos
    from stewart_drake.robot.kinematics import X_HOME
    from stewart_drake.robot.statics import holding_torques

    backend = StationServos()
    T_hold = holding_torques(backend.station.plan.geometry, X_HOME)
    station = backend.station
    station_context = station.GetMyContextFromRoot(backend.simulator.get_context())

    def plant_time():  # read with the emulator's thread held: it steps the same context
        return emu.with_backend(lambda b: b.simulator.get_context().get_time())

    def height():  # Z of the platform, m
        port = station.GetOutputPort("platform_state")
        return emu.with_backend(lambda b: port.Eval(station_context)[5])

    # A long watchdog: a loaded machine may pause this loop for more than the default 0.1 s.
    emu = BusEmulator(IDS, backend=backend)
    with emu, _bus(emu, zero_counts=None, watchdog_s=1.0) as bus:
        bus.configure()
        start = bus.read_state()
        # The plant's crank angles at home, through the bus: within one count.
        home = emu.with_backend(lambda b: b.positions_rad())
        np.testing.assert_allclose(start.q, home, atol=2 * math.pi / 4096)
        bus.enable_torque()
        moves, z = [], [height()]
        for scale in (
            1.0,
            2.0,
            -0.5,
        ):  # hold; lift; push down (beyond the gears' friction: 0.2 N m)
            # 0.2 s of the plant's time: on a loaded machine the plant slips behind the wall
            # clock (emu.slipped_s), so a phase is timed by the plant, bounded by the wall. The
            # damper stops the previous phase's motion quickly (a lift that ran on would carry
            # into the push down); it does not change a phase's direction.
            q0, t0 = bus.read_state().q, plant_time()
            wall_end = time.perf_counter() + HANG_S
            while plant_time() < t0 + 0.2 and time.perf_counter() < wall_end:
                bus.write_torques(scale * T_hold - 0.2 * bus.read_state().v)
            moves.append(bus.read_state().q - q0)
            z.append(height())
        assert bus.watchdog_tripped() == []
    assert np.all(np.abs(moves[0]) <= 3 * 2 * math.pi / 4096)  # held within 3 counts
    assert np.all(moves[1] > 0.02) and z[2] > z[1] + 1e-3, (moves, z)  # lifted
    assert np.all(moves[2] < -0.02) and z[3] < z[2] - 1e-3, (moves, z)  # lowered


def test_the_emulator_never_blocks_on_a_port_nobody_reads_and_stops_on_close():
    emu = BusEmulator([1]).start()
    fd = os.open(emu.port, os.O_RDWR | os.O_NOCTTY | os.O_NONBLOCK)
    try:
        ping = p.build_packet(1, p.PING)
        deadline = time.perf_counter() + HANG_S
        while emu.dropped_bytes == 0 and time.perf_counter() < deadline:
            try:
                os.write(fd, ping * 50)  # ~700 bytes of replies each; never read
            except BlockingIOError:
                pass
            time.sleep(0.001)
        assert emu.dropped_bytes > 0
    finally:
        os.close(fd)
        thread, t0 = emu._thread, time.perf_counter()
        emu.close()
        print(f"emulator closed in {1e3 * (time.perf_counter() - t0):.1f} ms")
    assert not thread.is_alive()
