"""What the servo driver and the bus emulator need of DYNAMIXEL Protocol 2.0 and the X series.

Packets (ROBOTIS e-Manual, "DYNAMIXEL Protocol 2.0",
<https://emanual.robotis.com/docs/en/dxl/protocol2/>): header ``FF FF FD 00``, id, length
(little endian; instruction or status byte + parameters + 2 CRC bytes, after stuffing), the
instruction (or 0x55 and an error byte for a status packet), the parameters, and a CRC-16
(polynomial 0x8005, initial 0, no reflection) over everything before it. Byte stuffing: in the
instruction, error and parameters, every ``FF FF FD`` becomes ``FF FF FD FD``.

Control table of the X series servos this module knows (the e-Manual page of each model,
section "Control Table": XM430-W350 <https://emanual.robotis.com/docs/en/dxl/x/xm430-w350/>,
XM540-W270 <https://emanual.robotis.com/docs/en/dxl/x/xm540-w270/>, XL430-W250
<https://emanual.robotis.com/docs/en/dxl/x/xl430-w250/>): the addresses below are common to
the three. Goal Current (102) and Present Current (126) count 2.69 mA on the XM430 and XM540;
**the XL430-W250 has no current sensing and no Current Control Mode** (its address 126 is
Present Load, in 0.1 % of the maximum torque), so it cannot be driven by torque: a bus of
XL430s is refused for torque control. Positions count 4096 per turn of the horn (12-bit
absolute encoder on the output); velocities 0.229 rpm per unit. In Current Control Mode the
position is multi-turn (a signed 32-bit count) and the Min/Max Position Limits are not enforced
by the servo (they apply in Position Control Mode only): a crank's range is for our guard to
keep; the limits are still written, so that a mode change cannot leave them at the factory's.

The DYNAMIXEL-P series (PM42-010-S260-R, PH42-020-S300-R; e-Manual,
<https://emanual.robotis.com/docs/en/dxl/p/pm42-010-s260-r/>, "Control Table") speaks the same
protocol with another table (:data:`P_SERIES`): its EEPROM ends at 512, Torque Enable is at 512,
Goal Current at 550 (1 mA), Present Current, Velocity and Position at 574, 576 and 580 (contiguous
again, 10 bytes: 1 mA, 0.01 rpm and the encoder's pulses, hundreds of thousands a turn, signed about
0), its Operating Mode 0 Current (Torque) Control Mode. A model's table, counts and units are its
:class:`~.servos.ServoSpec`'s; the constants below are the X series' (:data:`X_SERIES`).

The models' specs and torque <-> current (the servo's torque constant at the horn):
:mod:`.servos`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

# Instructions and the status packet (e-Manual, Protocol 2.0, "Instruction").
PING = 0x01
READ = 0x02
WRITE = 0x03
REBOOT = 0x08
STATUS = 0x55
SYNC_READ = 0x82
SYNC_WRITE = 0x83
FAST_SYNC_READ = 0x8A
BROADCAST_ID = 0xFE
MAX_ID = 252

# The status packet's error byte (e-Manual, Protocol 2.0, "Status Packet"): bit 7 is the
# Alert (a Hardware Error Status is set), bits 0..6 the error number.
ERR_RESULT_FAIL = 0x01
ERR_INSTRUCTION = 0x02
ERR_CRC = 0x03
ERR_DATA_RANGE = 0x04
ERR_DATA_LENGTH = 0x05
ERR_DATA_LIMIT = 0x06
ERR_ACCESS = 0x07
ALERT = 0x80

# Control table, X series (e-Manual, each model's "Control Table"): (address, size in bytes).
MODEL_NUMBER = (0, 2)
FIRMWARE_VERSION = (6, 1)
ID = (7, 1)
RETURN_DELAY_TIME = (9, 1)  # 2 us units, 0..254 (factory 250): both families' address
RETURN_DELAY_UNIT_S = 2e-6
OPERATING_MODE = (11, 1)  # 0: Current Control Mode (not on the XL430)
TEMPERATURE_LIMIT = (31, 1)  # deg C, 0..100
CURRENT_LIMIT = (38, 2)  # current units, 0..model's maximum
MAX_POSITION_LIMIT = (48, 4)  # counts, 0..4095
MIN_POSITION_LIMIT = (52, 4)  # counts, 0..4095
TORQUE_ENABLE = (64, 1)
HARDWARE_ERROR_STATUS = (70, 1)
BUS_WATCHDOG = (98, 1)  # 20 ms units, 1..127; 0 off; -1 (0xFF) tripped
GOAL_CURRENT = (102, 2)  # signed, current units
PRESENT_CURRENT = (126, 2)  # signed, current units
PRESENT_VELOCITY = (128, 4)  # signed, 0.229 rpm
PRESENT_POSITION = (132, 4)  # signed, counts
PRESENT_TEMPERATURE = (146, 1)  # deg C
#: Bytes 0..63 are EEPROM: writable only with the torque off (e-Manual, "Control Table").
EEPROM_END = 64
#: One read of the state: Present Current, Velocity and Position are contiguous (126..135).
STATE_BLOCK = (PRESENT_CURRENT[0], 10)

CURRENT_CONTROL_MODE = 0
#: Position Control Mode (both families): the servo's own position loop (docs/robot.md).
POSITION_CONTROL_MODE = 3
#: The servos' supply by family, V: the X series at 12 V (the catalogue's figures), the P
#: series at 24 V.
SUPPLY_V = {"X": 12.0, "P": 24.0}
WATCHDOG_UNIT_S = 0.020
WATCHDOG_TRIPPED = 0xFF
#: Counts per turn of the X-series servos' absolute encoder (on the horn, the crank's axis).
COUNTS_PER_REV = 4096
VELOCITY_UNIT_RAD_S = 0.229 * 2 * math.pi / 60
#: Hardware Error Status bits (e-Manual, "Hardware Error Status(70)").
HW_INPUT_VOLTAGE, HW_OVERHEATING, HW_ENCODER, HW_ELECTRICAL_SHOCK, HW_OVERLOAD = (
    0x01,
    0x04,
    0x08,
    0x10,
    0x20,
)


@dataclass(frozen=True)
class ControlTable:
    """Where a family of servos keeps the items the bus uses: (address, size in bytes) each.

    Attributes:
        family: "X" or "P". eeprom_end: the first RAM address (EEPROM below it is writable
            only with the torque off). goals: [start, end) of the Goal items, read-only after a
            bus watchdog trip. read_only: [start, end) ranges no WRITE may touch. size: the
            table's length the emulator keeps, bytes.
        position_gains: the Position D, I and P Gains and the Feedforward 1st Gain, in that
            order (2 bytes each). profile_velocity, goal_position: contiguous in both families
            (one sync write streams both). pwm_full: the PWM's 100 %, in Goal PWM's units (the
            PWM Limit's largest value).
    """

    family: str
    operating_mode: tuple[int, int]
    temperature_limit: tuple[int, int]
    current_limit: tuple[int, int]
    max_position_limit: tuple[int, int]
    min_position_limit: tuple[int, int]
    torque_enable: tuple[int, int]
    hardware_error_status: tuple[int, int]
    bus_watchdog: tuple[int, int]
    goal_current: tuple[int, int]
    present_current: tuple[int, int]
    present_velocity: tuple[int, int]
    present_position: tuple[int, int]
    present_temperature: tuple[int, int]
    eeprom_end: int
    goals: tuple[int, int]
    read_only: tuple[tuple[int, int], ...]
    size: int
    position_gains: tuple[tuple[int, int], ...] = ()
    profile_velocity: tuple[int, int] = (0, 0)
    goal_position: tuple[int, int] = (0, 0)
    pwm_full: int = 0

    @property
    def state_block(self) -> tuple[int, int]:
        """(address, 10): Present Current (2), Velocity (4) and Position (4), contiguous in
        both families: one sync read a period."""
        return (self.present_current[0], 10)


#: The X series' table (the module constants above).
X_SERIES = ControlTable(
    family="X",
    operating_mode=OPERATING_MODE,
    temperature_limit=TEMPERATURE_LIMIT,
    current_limit=CURRENT_LIMIT,
    max_position_limit=MAX_POSITION_LIMIT,
    min_position_limit=MIN_POSITION_LIMIT,
    torque_enable=TORQUE_ENABLE,
    hardware_error_status=HARDWARE_ERROR_STATUS,
    bus_watchdog=BUS_WATCHDOG,
    goal_current=GOAL_CURRENT,
    present_current=PRESENT_CURRENT,
    present_velocity=PRESENT_VELOCITY,
    present_position=PRESENT_POSITION,
    present_temperature=PRESENT_TEMPERATURE,
    eeprom_end=EEPROM_END,
    goals=(100, 120),  # Goal PWM .. Goal Position
    read_only=((0, 7), (70, 71), (120, 147)),
    size=147,
    position_gains=((80, 2), (82, 2), (84, 2), (90, 2)),
    profile_velocity=(112, 4),  # 0.229 rpm; 0: no profile
    goal_position=(116, 4),
    pwm_full=885,
)
#: The DYNAMIXEL-P series' table (e-Manual, PM42-010-S260-R / PH42-020-S300-R "Control Table").
P_SERIES = ControlTable(
    family="P",
    operating_mode=(11, 1),
    temperature_limit=(31, 1),
    current_limit=(38, 2),  # 1 mA
    max_position_limit=(48, 4),  # pulses, signed
    min_position_limit=(52, 4),
    torque_enable=(512, 1),
    hardware_error_status=(518, 1),
    bus_watchdog=(546, 1),  # 20 ms units, as the X series'
    goal_current=(550, 2),  # signed, 1 mA
    present_current=(574, 2),  # signed, 1 mA
    present_velocity=(576, 4),  # signed, 0.01 rpm
    present_position=(580, 4),  # signed, pulses
    present_temperature=(594, 1),
    eeprom_end=512,
    goals=(548, 568),  # Goal PWM .. Goal Position
    read_only=((0, 7), (517, 519), (568, 600)),
    size=608,
    position_gains=((528, 2), (530, 2), (532, 2), (538, 2)),
    profile_velocity=(560, 4),  # 0.01 rpm; 0: no profile
    goal_position=(564, 4),
    pwm_full=2009,
)


# --- conversions (one servo or arrays alike; ``direction`` is +1 or -1) ----------------------


def counts_to_rad(counts, zero_counts=0, direction=1, counts_per_rev: int = COUNTS_PER_REV):
    """Crank angle, rad, for a Present Position (counts) and the count at the crank's zero;
    ``counts_per_rev`` the model's (default the X series')."""
    return (
        (np.asarray(counts) - np.asarray(zero_counts)) * (2 * math.pi / counts_per_rev) * direction
    )


def rad_to_counts(q_rad, zero_counts=0, direction=1, counts_per_rev: int = COUNTS_PER_REV):
    """The Present Position (counts, rounded) at crank angle ``q_rad``; inverse of
    :func:`counts_to_rad`."""
    return np.rint(
        np.asarray(q_rad) * direction * counts_per_rev / (2 * math.pi) + np.asarray(zero_counts)
    ).astype(np.int64)


def velocity_units_to_rad_s(units, direction=1, unit_rad_s: float = VELOCITY_UNIT_RAD_S):
    """Crank rate, rad/s, for a Present Velocity in units of ``unit_rad_s`` (the X series'
    0.229 rpm by default)."""
    return np.asarray(units) * unit_rad_s * direction


# --- packets ---------------------------------------------------------------------------------


def _crc_table() -> list[int]:
    table = []
    for i in range(256):
        crc = i << 8
        for _ in range(8):
            crc = ((crc << 1) ^ 0x8005) if crc & 0x8000 else (crc << 1)
        table.append(crc & 0xFFFF)
    return table


_CRC_TABLE = _crc_table()


def crc16(data: bytes | bytearray) -> int:
    """The Protocol 2.0 CRC-16 (polynomial 0x8005, initial value 0, MSB first) of ``data``."""
    crc = 0
    for b in data:
        crc = ((crc << 8) ^ _CRC_TABLE[((crc >> 8) ^ b) & 0xFF]) & 0xFFFF
    return crc


def stuff(body: bytes) -> bytes:
    """``body`` (instruction/error and parameters) with ``FD`` added after each ``FF FF FD``.
    The two bytes before the body are the length's, never ``FF FF``: the search starts in it."""
    out = bytearray()
    for b in body:
        out.append(b)
        if b == 0xFD and out[-3:-1] == b"\xff\xff":
            out.append(0xFD)
    return bytes(out)


def unstuff(body: bytes) -> bytes:
    """The inverse of :func:`stuff`."""
    out = bytearray()
    i = 0
    while i < len(body):
        out.append(body[i])
        if body[i] == 0xFD and out[-3:-1] == b"\xff\xff" and i + 1 < len(body):
            if body[i + 1] == 0xFD:
                i += 1  # drop the stuffed FD
        i += 1
    return bytes(out)


def build_packet(servo_id: int, instruction: int, params: bytes = b"") -> bytes:
    """A whole packet: header, id, length, ``instruction`` and ``params`` (stuffed), CRC.

    For a status packet pass ``instruction=STATUS`` and the error byte as ``params[0]``.
    """
    body = stuff(bytes([instruction]) + bytes(params))
    head = bytes([0xFF, 0xFF, 0xFD, 0x00, servo_id]) + (len(body) + 2).to_bytes(2, "little")
    packet = head + body
    return packet + crc16(packet).to_bytes(2, "little")


def build_status(servo_id: int, error: int, params: bytes = b"") -> bytes:
    """A status packet from ``servo_id`` with error byte ``error``."""
    return build_packet(servo_id, STATUS, bytes([error]) + bytes(params))


@dataclass(frozen=True)
class Packet:
    """A parsed packet: ``instruction`` (STATUS for a status packet) and unstuffed ``params``
    (a status packet's error byte first)."""

    servo_id: int
    instruction: int
    params: bytes


def parse_packet(buf: bytes | bytearray) -> tuple[Packet | None, int, bool]:
    """The first whole packet in ``buf``: (packet or None, bytes consumed, crc_ok).

    Bytes before a header are skipped (consumed). An incomplete packet gives (None, n_skipped,
    True): keep the rest and wait for more bytes. A packet with a wrong CRC is consumed and
    returned with ``crc_ok`` False (a servo answers it with a CRC error).
    """
    start = bytes(buf).find(b"\xff\xff\xfd\x00")
    if start < 0:
        keep = min(len(buf), 3)  # a header may be arriving
        return None, len(buf) - keep, True
    if len(buf) < start + 7:
        return None, start, True
    length = int.from_bytes(buf[start + 5 : start + 7], "little")
    end = start + 7 + length
    if length < 3 or length > 1024:
        return None, start + 4, True  # not a packet: look further
    if len(buf) < end:
        return None, start, True
    frame = bytes(buf[start:end])
    crc_ok = crc16(frame[:-2]) == int.from_bytes(frame[-2:], "little")
    body = unstuff(frame[7:-2])
    return Packet(frame[4], body[0], body[1:]), end, crc_ok


def to_signed(value: int, size: int) -> int:
    """A little-endian unsigned ``size``-byte value as the signed integer it encodes."""
    bits = 8 * size
    return value - (1 << bits) if value >= 1 << (bits - 1) else value


def to_unsigned(value: int, size: int) -> int:
    """The ``size``-byte two's complement of ``value``."""
    return int(value) & ((1 << (8 * size)) - 1)


@dataclass(frozen=True)
class BusState:
    """One read of the bus; arrays (n,) in the order of the bus's ids, at the cranks.

    Attributes:
        q: crank angles, rad (zero offsets and directions applied).
        v: crank rates, rad/s.  tau: the torques the servos drive (Present Current x K_t), N m.
        t: perf_counter time, s, halfway through the read.  round_trip_s: the read's duration.
        s, s_dot, s_tau: the surrogate's carriage (a bus with one,
            :class:`~.servos.SurrogateServoConfig`): its position m, rate m/s and the
            torque its servo drives, N m in the carriage's sense; NaN without a surrogate.
    """

    q: np.ndarray
    v: np.ndarray
    tau: np.ndarray
    t: float
    round_trip_s: float
    s: float = float("nan")
    s_dot: float = float("nan")
    s_tau: float = float("nan")
