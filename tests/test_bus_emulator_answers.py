"""The bus emulator's answers, packet by packet, as the DYNAMIXEL Protocol 2.0 e-Manual gives them
(station/bus/emulator.py): each instruction's status, its errors (CRC, length, range, an unknown
instruction), what a broadcast is not answered, a disconnected servo's silence, the Alert bit of a
hardware error; the Present values in the e-Manual's units from a motion written here; and the
emulator's own process entry serving the ids it is given. No thread but ``main``'s: each packet
is handed to the emulator as its bus thread would."""

import math
import os
import select
import sys
import time

import numpy as np
import pytest
from conftest import HANG_S

from stewart_drake.station.bus import protocol as p
from stewart_drake.station.bus.emulator import BusEmulator, main
from stewart_drake.station.bus.servo_models import ServoBackend

#: XM430-W350's units (e-Manual): 4096 counts a turn, 0.229 rpm, 2.69 mA.
COUNTS_PER_RAD = 4096 / (2 * math.pi)
VELOCITY_UNIT_RAD_S = 0.229 * 2 * math.pi / 60
CURRENT_UNIT_A = 2.69e-3


class Held(ServoBackend):
    """Horns held at the angles and rates given (and driving the currents given, when given)."""

    def __init__(self, q, v, currents=None):
        self.q, self.v = np.asarray(q, float), np.asarray(v, float)
        if currents is not None:
            self.currents_A = lambda: np.asarray(currents, float)

    def advance(self, dt_s, current_A):
        pass

    def positions_rad(self):
        return self.q

    def velocities_rad_s(self):
        return self.v


@pytest.fixture
def emu():
    emulator = BusEmulator([1, 2, 3], backend=Held(np.zeros(3), np.zeros(3)))
    yield emulator
    emulator.close()


def _answer(emulator, servo_id, instruction, params=b"", crc_ok=True):
    """The statuses the emulator sends for one instruction packet: [(id, error, params)]."""
    packet, used, ok = p.parse_packet(p.build_packet(servo_id, instruction, params))
    assert packet is not None and ok
    reply = bytearray(emulator._answer(packet, crc_ok))
    out = []
    while reply:
        status, used, ok = p.parse_packet(reply)
        assert status is not None and ok and status.instruction == p.STATUS
        out.append((status.servo_id, status.params[0], bytes(status.params[1:])))
        del reply[:used]
    return out


def _le(value: int, size: int) -> bytes:
    return p.to_unsigned(value, size).to_bytes(size, "little")


def test_a_ping_answers_the_model_number_and_firmware_and_a_broadcast_ping_each_servo(emu):
    model, firmware = emu.read_item(1, p.MODEL_NUMBER), emu.read_item(1, p.FIRMWARE_VERSION)
    assert model == 1020  # XM430-W350's model number (e-Manual)
    assert _answer(emu, 2, p.PING) == [(2, 0, _le(model, 2) + bytes([firmware]))]
    assert [s[:2] for s in _answer(emu, p.BROADCAST_ID, p.PING)] == [(1, 0), (2, 0), (3, 0)]
    assert _answer(emu, 9, p.PING) == []  # no servo 9 on the bus: silence


def test_a_packet_whose_crc_fails_gets_a_crc_error_unless_it_was_broadcast(emu):
    assert _answer(emu, 3, p.READ, _le(132, 2) + _le(4, 2), crc_ok=False) == [(3, p.ERR_CRC, b"")]
    assert _answer(emu, p.BROADCAST_ID, p.PING, crc_ok=False) == []


def test_a_read_returns_the_table_or_names_its_length_or_range_error(emu):
    emu.servos[2].put(p.PRESENT_POSITION, 3000)
    assert _answer(emu, 2, p.READ, _le(132, 2) + _le(4, 2)) == [(2, 0, _le(3000, 4))]
    assert _answer(emu, 2, p.READ, _le(132, 2)) == [(2, p.ERR_DATA_LENGTH, b"")]
    size = emu.servos[2].items.size
    assert _answer(emu, 2, p.READ, _le(size - 1, 2) + _le(2, 2)) == [(2, p.ERR_DATA_RANGE, b"")]
    assert _answer(emu, 2, p.READ, _le(size - 2, 2) + _le(2, 2))[0][1] == 0  # the last item
    assert _answer(emu, p.BROADCAST_ID, p.READ, _le(132, 2) + _le(4, 2)) == []


def test_a_write_is_acknowledged_and_kept_a_short_one_refused_a_broadcast_one_silent(emu):
    assert _answer(emu, 1, p.WRITE, _le(102, 2) + _le(-200, 2)) == [(1, 0, b"")]
    assert p.to_signed(emu.read_item(1, p.GOAL_CURRENT), 2) == -200
    assert _answer(emu, 1, p.WRITE, _le(102, 2)) == [(1, p.ERR_DATA_LENGTH, b"")]
    assert _answer(emu, p.BROADCAST_ID, p.WRITE, _le(102, 2) + _le(77, 2)) == []
    assert [emu.read_item(i, p.GOAL_CURRENT) for i in (1, 2, 3)] == [77, 77, 77]
    assert _answer(emu, p.BROADCAST_ID, p.WRITE, _le(9, 2) + bytes([40])) == []  # one byte
    assert [emu.read_item(i, p.RETURN_DELAY_TIME) for i in (1, 2, 3)] == [40, 40, 40]
    # A broadcast READ writes nothing, whatever its parameters.
    assert _answer(emu, p.BROADCAST_ID, p.READ, _le(102, 2) + _le(9, 2)) == []
    assert [emu.read_item(i, p.GOAL_CURRENT) for i in (1, 2, 3)] == [77, 77, 77]


def test_a_sync_write_writes_each_row_to_its_servo_only_and_is_not_answered(emu):
    """Each row is an id and ``size`` bytes: servo 1's goal of 2 (a byte that is also an id)
    is not read as a row of servo 2, and no row writes past its item."""
    rows = bytes([1]) + _le(2, 2) + bytes([3]) + _le(-30, 2)
    assert _answer(emu, p.BROADCAST_ID, p.SYNC_WRITE, _le(102, 2) + _le(2, 2) + rows) == []
    goals = [p.to_signed(emu.read_item(i, p.GOAL_CURRENT), 2) for i in (1, 2, 3)]
    assert goals == [2, 0, -30]
    assert [emu.read_item(i, (104, 1)) for i in (1, 2, 3)] == [0, 0, 0]  # the byte after


def test_a_sync_read_answers_each_servo_asked_in_its_order(emu):
    for i, counts in ((1, 1000), (2, 2000), (3, 3000)):
        emu.servos[i].put(p.PRESENT_POSITION, counts)
    statuses = _answer(emu, p.BROADCAST_ID, p.SYNC_READ, _le(132, 2) + _le(4, 2) + bytes([3, 1]))
    assert statuses == [(3, 0, _le(3000, 4)), (1, 0, _le(1000, 4))]
    size = emu.servos[1].items.size
    beyond = _answer(emu, p.BROADCAST_ID, p.SYNC_READ, _le(size - 1, 2) + _le(4, 2) + bytes([2]))
    assert beyond == [(2, p.ERR_DATA_RANGE, b"")]
    last = _answer(emu, p.BROADCAST_ID, p.SYNC_READ, _le(size - 1, 2) + _le(1, 2) + bytes([2]))
    assert last[0][:2] == (2, 0)  # the table's last byte is in range


def test_a_sync_read_across_two_models_answers_each_by_its_own_table():
    """A P-series servo beside X-series ones: an address past the X table but inside the P
    table gives the P servo its bytes and the X servo its range error, in the order asked."""
    with BusEmulator([1, 3], models={3: "PM42-010-S260-R"}) as mixed:
        assert (
            mixed.read_item(3, p.MODEL_NUMBER) == 2100
            and mixed.read_item(1, p.MODEL_NUMBER) == 1020
        )
        address = mixed.servos[1].items.size + 10
        assert mixed.servos[3].items.size > address + 4
        statuses = _answer(
            mixed, p.BROADCAST_ID, p.SYNC_READ, _le(address, 2) + _le(4, 2) + bytes([3, 1])
        )
        assert [s[:2] for s in statuses] == [(3, 0), (1, p.ERR_DATA_RANGE)]


def test_an_instruction_the_servo_does_not_know_is_refused_unless_broadcast(emu):
    assert _answer(emu, 2, p.REBOOT) == [(2, p.ERR_INSTRUCTION, b"")]
    assert _answer(emu, p.BROADCAST_ID, p.REBOOT) == []


def test_a_disconnected_servo_is_silent_until_reconnected(emu):
    emu.disconnect(2)
    assert _answer(emu, 2, p.PING) == []
    assert [s[0] for s in _answer(emu, p.BROADCAST_ID, p.PING)] == [1, 3]
    emu.disconnect(2, cut=False)
    assert [s[0] for s in _answer(emu, p.BROADCAST_ID, p.PING)] == [1, 2, 3]
    emu.mute()
    assert emu.muted
    emu.mute(False)
    assert not emu.muted


def test_a_hardware_error_removes_the_torque_and_sets_the_alert_bit_in_every_status(emu):
    for i in (1, 2):
        emu.servos[i].put(p.OPERATING_MODE, p.CURRENT_CONTROL_MODE)
        emu.servos[i].put(p.TORQUE_ENABLE, 1)
        emu.servos[i].put(p.GOAL_CURRENT, 100)
    emu.set_hardware_error(1, 0x04)  # overheating
    emu.set_hardware_error(1, 0x20)  # overload: the bits add
    assert emu.read_item(1, p.HARDWARE_ERROR_STATUS) == 0x24
    assert emu.read_item(1, p.TORQUE_ENABLE) == 0
    assert _answer(emu, 1, p.PING)[0][1] == p.ALERT
    assert _answer(emu, 2, p.PING)[0][1] == 0
    np.testing.assert_allclose(emu.applied_current_A(), [0.0, 100 * CURRENT_UNIT_A, 0.0])


def test_a_fresh_emulator_holds_the_documented_defaults():
    """Stepped every 2 ms, at most 20 ms a step, 30 deg C, a Return Delay Time of 0, on the wall
    clock with no catch-up; nothing slipped, dropped, muted or failed yet; a servo without a
    current mode (the XL430-W250) is emulated (the driver, not the bus, refuses it)."""
    fresh = BusEmulator([1, 2], backend=Held(np.zeros(2), np.zeros(2)))  # not started
    try:
        assert (fresh.tick_s, fresh.max_step_s) == (0.002, 0.02)
        assert fresh.command_step_s is None and fresh.catch_up is False
        assert fresh.read_item(1, p.PRESENT_TEMPERATURE) == 30
        assert fresh.read_item(2, p.RETURN_DELAY_TIME) == 0
        assert (fresh.slipped_s, fresh.dropped_bytes, fresh.muted) == (0.0, 0, False)
        assert fresh.model_error is None and fresh.timing is None
    finally:
        fresh.close()
    with BusEmulator([4], model="XL430-W250-T", models={4: "XL430-W250-T"}) as xl:
        assert xl.read_item(4, p.MODEL_NUMBER) == 1060
        assert xl.read_item(4, p.PRESENT_CURRENT) == 0  # no current unit: nothing reported


def test_the_packets_received_are_kept_with_their_time_and_bounded(emu):
    """Every instruction packet is logged with its arrival time, newest last; past 10,000 the
    oldest 5,000 go, so a long session's log stays bounded."""
    packet = p.parse_packet(p.build_packet(1, p.PING))[0]
    for _ in range(10_000):
        emu._log(packet)
    assert len(emu.received) == 10_000
    times = [t for t, _ in emu.received]
    assert all(logged is packet for _, logged in emu.received)
    assert isinstance(times[0], float) and times == sorted(times)  # arrival order, newest last
    emu._log(packet)
    assert len(emu.received) == 5_001


@pytest.mark.parametrize(
    "ids, kw",
    [([], {}), ([1, 1], {}), ([-1], {}), ([253], {}), ([1], {"command_step_s": 0.0}),
     ([1], {"command_step_s": math.inf})],
)  # fmt: skip
def test_bad_ids_or_a_bad_command_step_are_refused(ids, kw):
    from stewart_drake.base.errors import InvalidConfigError

    with pytest.raises(InvalidConfigError, match="ids|command_step_s"):
        BusEmulator(ids, **kw)


def test_the_ids_at_the_ends_of_the_range_are_taken():
    with BusEmulator([0, 252], backend=Held(np.zeros(2), np.zeros(2))) as ends:
        assert [s[0] for s in _answer(ends, p.BROADCAST_ID, p.PING)] == [0, 252]


def test_its_threads_are_named_and_never_hold_the_interpreter_at_exit():
    """A stack dump names them (``dynamixel-bus-emulator``, ``dynamixel-bus-model``), and they
    are daemons: an emulator left open never keeps a process from ending."""
    import threading

    with BusEmulator([1], backend=Held(np.zeros(1), np.zeros(1))):
        threads = {t.name: t for t in threading.enumerate()}
        for name in ("dynamixel-bus-emulator", "dynamixel-bus-model"):
            assert name in threads and threads[name].daemon, name


def test_the_present_values_are_the_motion_in_the_e_manuals_units():
    q, v = np.array([0.1, -0.2, 0.0]), np.array([1.0, -0.5, 0.03])
    zeros = [2048, 1000, 0]
    with BusEmulator([4, 5, 6], backend=Held(q, v), zero_counts=zeros) as emulator:
        positions = [p.to_signed(emulator.read_item(i, p.PRESENT_POSITION), 4) for i in (4, 5, 6)]
        velocities = [p.to_signed(emulator.read_item(i, p.PRESENT_VELOCITY), 4) for i in (4, 5, 6)]
        assert positions == [round(z + a * COUNTS_PER_RAD) for z, a in zip(zeros, q)]
        assert positions == [2113, 870, 0]
        assert velocities == [round(w / VELOCITY_UNIT_RAD_S) for w in v] == [42, -21, 1]
        np.testing.assert_array_equal(emulator.state()[0], q)
    currents = np.array([0.5, -0.25, 0.0])
    with BusEmulator([1, 2, 3], backend=Held(np.zeros(3), np.zeros(3), currents)) as emulator:
        present = [p.to_signed(emulator.read_item(i, p.PRESENT_CURRENT), 2) for i in (1, 2, 3)]
        assert present == [round(a / CURRENT_UNIT_A) for a in currents] == [186, -93, 0]
    # A backend that drives fewer windings than it has servos (a surrogate's stage last): the
    # last reports what its own table drives (its torque off: 0).
    with BusEmulator([1, 2, 3], backend=Held(np.zeros(3), np.zeros(3), currents[:2])) as short:
        present = [p.to_signed(short.read_item(i, p.PRESENT_CURRENT), 2) for i in (1, 2, 3)]
        assert present == [186, -93, 0]


def _status_within(fd, wait_s):
    """The first whole status packet read from ``fd`` within ``wait_s``, else None."""
    reply, deadline = bytearray(), time.monotonic() + wait_s
    while time.monotonic() < deadline:
        if select.select([fd], [], [], 0.1)[0]:
            reply += os.read(fd, 64)
            status = p.parse_packet(reply)[0]
            if status is not None:
                return status
    return None


@pytest.mark.parametrize(
    "argv, there, absent, model",
    [
        (["--ids", "3", "7"], 7, 1, 1020),
        ([], 6, 7, 1020),  # the default ids, 1 to 6
        ([], 1, 0, 1020),
        (["--ids", "2", "--model", "XM540-W270-T"], 2, 1, 1120),
    ],
)
def test_the_emulators_own_process_entry_serves_the_ids_it_is_given(
    capsys, monkeypatch, argv, there, absent, model
):
    """``python -m stewart_drake.station.bus.emulator --ids 3 7`` (docs/hardware_bus.md) run in
    this process: it prints its port first, answers a ping of a servo it serves with its model
    and not of another, and ends when its stdin closes."""
    pings = {}

    class Stdin:
        def read(self, n):
            port = capsys.readouterr().out.splitlines()[0]
            fd = os.open(port, os.O_RDWR | os.O_NOCTTY)
            try:
                # Servo 7 answers within the hang guard; servo 1 is not there: a second of
                # silence is its answer.
                for servo, wait_s in ((there, HANG_S), (absent, 1.0)):
                    os.write(fd, p.build_packet(servo, p.PING))
                    pings[servo] = _status_within(fd, wait_s)
            finally:
                os.close(fd)
            return ""  # stdin closed: the entry stops serving

    monkeypatch.setattr(sys, "stdin", Stdin())
    main(argv)
    assert pings[there] is not None and pings[there].servo_id == there
    assert pings[there].params[0] == 0
    assert int.from_bytes(pings[there].params[1:3], "little") == model
    assert pings[absent] is None
