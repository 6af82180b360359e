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


def test_a_sync_write_writes_each_row_to_its_servo_only_and_is_not_answered(emu):
    rows = bytes([1]) + _le(10, 2) + bytes([3]) + _le(-30, 2)
    assert _answer(emu, p.BROADCAST_ID, p.SYNC_WRITE, _le(102, 2) + _le(2, 2) + rows) == []
    goals = [p.to_signed(emu.read_item(i, p.GOAL_CURRENT), 2) for i in (1, 2, 3)]
    assert goals == [10, 0, -30]


def test_a_sync_read_answers_each_servo_asked_in_its_order(emu):
    for i, counts in ((1, 1000), (2, 2000), (3, 3000)):
        emu.servos[i].put(p.PRESENT_POSITION, counts)
    statuses = _answer(emu, p.BROADCAST_ID, p.SYNC_READ, _le(132, 2) + _le(4, 2) + bytes([3, 1]))
    assert statuses == [(3, 0, _le(3000, 4)), (1, 0, _le(1000, 4))]
    size = emu.servos[1].items.size
    beyond = _answer(emu, p.BROADCAST_ID, p.SYNC_READ, _le(size - 1, 2) + _le(4, 2) + bytes([2]))
    assert beyond == [(2, p.ERR_DATA_RANGE, b"")]


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


def test_the_emulators_own_process_entry_serves_the_ids_it_is_given(capsys, monkeypatch):
    """``python -m stewart_drake.station.bus.emulator --ids 3 7`` (docs/hardware_bus.md) run in
    this process: it prints its port first, answers a ping of servo 7 there and not of servo 1,
    and ends when its stdin closes."""
    pings = {}

    class Stdin:
        def read(self, n):
            port = capsys.readouterr().out.splitlines()[0]
            fd = os.open(port, os.O_RDWR | os.O_NOCTTY)
            try:
                # Servo 7 answers within the hang guard; servo 1 is not there: a second of
                # silence is its answer.
                for servo, wait_s in ((7, HANG_S), (1, 1.0)):
                    os.write(fd, p.build_packet(servo, p.PING))
                    pings[servo] = _status_within(fd, wait_s)
            finally:
                os.close(fd)
            return ""  # stdin closed: the entry stops serving

    monkeypatch.setattr(sys, "stdin", Stdin())
    main(["--ids", "3", "7"])
    assert pings[7] is not None and pings[7].servo_id == 7 and pings[7].params[0] == 0
    assert int.from_bytes(pings[7].params[1:3], "little") == 1020  # XM430-W350, the default
    assert pings[1] is None
