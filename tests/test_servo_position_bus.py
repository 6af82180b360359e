"""The servos' own position loop over the bus: the control table's gains in SI and back, the
driver's Position Control Mode (its gains written and read back, the servo held where it is at
torque on, goals streamed with their profile) against the emulator's servos running the loop."""

import math

import pytest

from stewart_drake.base.errors import InvalidConfigError
from stewart_drake.station.bus.servo_firmware import (
    position_gains,
    raw_position_gains,
    table_position_gains,
)
from stewart_drake.station.bus.servos import servo_spec

XM430 = servo_spec("XM430-W350-T")
#: The emulated bus's reply timeout: a guard against a hang, not a measure of speed.
HANG_BUS_S = 5.0


def test_the_tables_gains_are_the_emanuals_divisors_in_si():
    """XM430 at 12 V, 1 ms: P 800 is 800 / 128 PWM units a count, 885 units the supply, 4096
    counts a turn; I 1000 is 1000 / 65536 a count each millisecond; D 160 is 160 / 16 a count
    a millisecond; FF 40 is 40 / 4 a count a millisecond: each by hand, and back to the raw."""
    g = table_position_gains((160, 1000, 800, 40), XM430, 12.0)
    per_count = 12.0 / 885 * 4096 / (2 * math.pi)  # V per (PWM unit x count), over rad
    assert g.p_V_per_rad == pytest.approx(800 / 128 * per_count, rel=1e-12)
    assert g.i_V_per_rad_s == pytest.approx(1000 / 65536 * per_count / 1e-3, rel=1e-12)
    assert g.d_V_s_per_rad == pytest.approx(160 / 16 * per_count * 1e-3, rel=1e-12)
    assert g.ff_V_s_per_rad == pytest.approx(40 / 4 * per_count * 1e-3, rel=1e-12)
    assert raw_position_gains(g, XM430) == (160, 1000, 800, 40)


def test_a_gain_past_the_table_is_refused_naming_it():
    """A 35 Hz loop on a 4096-count servo at 1 ms (damped by the back-EMF alone, no D Gain)
    needs an I Gain of K_P w / 4 over (12 V / 885 a count, over 1 ms, / 65536): by hand 891356,
    past the table's 16383."""
    w = 2 * math.pi * 35
    k_i = 0.02 * w * w * 5.2 / 2.3 * w / 4
    unit = 12.0 / 885 * 4096 / (2 * math.pi) / 1e-3 / 65536
    fast = position_gains(0.02, 2.3, 5.2, 12.0, position_hz=35.0, damping=0.1)
    with pytest.raises(InvalidConfigError) as err:
        raw_position_gains(fast, XM430)
    assert f"Position I Gain would be {round(k_i / unit)} " in str(err.value)
    assert "past its table's 16383" in str(err.value)


def _loop_gains():
    """An XM430 with a light crank, as the emulator's first-order servo holds it: 8 Hz."""
    from stewart_drake.robot.motor_catalogue import catalogue_motor

    servo = catalogue_motor("XM430-W350-T").servo
    inertia = servo.rotor_inertia * servo.gear_ratio**2 + 0.002
    r = 12.0 / XM430.stall_current_A
    return inertia, raw_position_gains(
        position_gains(inertia, XM430.torque_constant_Nm_per_A, r, 12.0, 8.0, 1.0), XM430
    )


def _bus(emu, raw):
    pytest.importorskip("dynamixel_sdk", reason="the robot extra: pip install -e '.[robot]'")
    from stewart_drake.station.bus.driver import DynamixelBus

    return DynamixelBus(
        emu.port,
        1_000_000,
        [1],
        XM430.name,
        reply_timeout_s=HANG_BUS_S,
        position_gains_raw=raw,
        watchdog_s=2.54,  # a loaded machine's pause between two writes is not a trip
    )


def _ramp(raw) -> tuple[float, float, float]:
    """The emulated servo (a first-order XM430 with a light crank, resting at 0.3 rad) in
    Position Control Mode with gains ``raw``, on the commands' clock (10 ms a write): (its
    largest departure over 0.2 s of holding after torque on; its largest lag behind its
    trajectory while a 0.5 rad/s ramp is streamed, a goal and its profile a period, after the
    first 0.2 s; its error 0.3 s after the ramp's end), in counts. The gains read back as
    written, the mode as Position Control Mode."""
    from stewart_drake.station.bus import protocol as p
    from stewart_drake.station.bus.emulator import BusEmulator
    from stewart_drake.station.bus.servo_models import FirstOrderServos

    backend = FirstOrderServos.from_catalogue(XM430.name, [0.3], load_inertia=0.002)
    count = XM430.rad_per_count
    with BusEmulator([1], XM430.name, backend=backend, command_step_s=0.01) as emu:
        bus = _bus(emu, raw)
        with bus:
            bus.configure()
            table = XM430.table
            assert [emu.read_item(1, item) for item in table.position_gains] == list(raw)
            assert emu.read_item(1, table.operating_mode) == p.POSITION_CONTROL_MODE
            start = bus.read_state().q[0]
            bus.enable_torque()
            held = 0.0
            for _ in range(20):
                bus.write_goals([start], [0.0])
                held = max(held, abs(bus.read_state().q[0] - start))
            lag = 0.0
            for k in range(1, 101):
                goal = start + 0.005 * k  # each profile reaches its goal within the period
                bus.write_goals([goal], [0.5])
                if k > 20:
                    lag = max(lag, abs(bus.read_state().q[0] - goal))
            for _ in range(30):
                bus.write_goals([start + 0.5], [0.5])
            end = abs(bus.read_state().q[0] - (start + 0.5))
    return held / count, lag / count, end / count


def test_the_servo_holds_where_it_is_then_follows_streamed_goals():
    """At torque on the servo holds where it rests (within a count); streamed a ramp, it
    keeps within a count and a half of its trajectory (the reading in whole counts, the goal
    not) and ends within as much of the ramp's end: its integral carries what the P term
    would lag. Without the integral (I Gain 0) it lags by what its P and D terms need to push
    the load along, several counts."""
    _, raw = _loop_gains()
    held, lag, end = _ramp(raw)
    assert held <= 1.0 and lag <= 1.5 and end <= 1.5
    _, lag_without_i, _ = _ramp((raw[0], 0, raw[2], raw[3]))
    assert lag_without_i >= 3.0


def test_goals_are_refused_in_current_mode_or_of_the_wrong_shape():
    from stewart_drake.station.bus.emulator import BusEmulator

    _, raw = _loop_gains()
    with BusEmulator([1], XM430.name) as emu:
        current = _bus(emu, None)
        with pytest.raises(InvalidConfigError, match="runs Current Control Mode"):
            current.write_goals([0.0], [0.0])
        position = _bus(emu, raw)
        with pytest.raises(InvalidConfigError, match="1 finite angles and rates"):
            position.write_goals([0.0, 0.1], [0.0, 0.0])
        with pytest.raises(InvalidConfigError, match="1 finite angles and rates"):
            position.write_goals([math.nan], [0.0])


def test_a_goal_whose_bytes_would_form_a_header_reaches_the_servo_stuffed():
    """A Profile Velocity of 0xFDFFFF units is the bytes FF FF FD 00: sent as they are, a servo
    would take them for a packet's start. The driver stuffs that write (Protocol 2.0); the
    emulated servo's table reads back the profile and the goal as written, and a goal written
    after it is taken too (the bus still in step)."""
    from stewart_drake.station.bus.emulator import BusEmulator

    _, raw = _loop_gains()
    table = XM430.table
    with BusEmulator([1], XM430.name, command_step_s=0.01, zero_counts=[2048]) as emu:
        bus = _bus(emu, raw)
        with bus:
            bus.configure()
            bus.write_goals([0.25], [0xFDFFFF * XM430.velocity_unit_rad_s])
            bus.read_state()  # answered after the write is taken
            assert emu.read_item(1, table.profile_velocity) == 0xFDFFFF
            assert emu.read_item(1, table.goal_position) == 2048 + round(0.25 / XM430.rad_per_count)
            bus.write_goals([-0.25], [1.0])
            bus.read_state()
            assert emu.read_item(1, table.profile_velocity) == round(
                1.0 / XM430.velocity_unit_rad_s
            )
            assert emu.read_item(1, table.goal_position) == 2048 - round(0.25 / XM430.rad_per_count)


@pytest.mark.parametrize(
    "raw", [(1, 2, 3), (0, 0, 20000, 0), (0, -1, 800, 0), (0.5, 0, 800, 0)], ids=str
)
def test_wrong_raw_gains_are_refused_before_the_port(raw):
    from stewart_drake.station.bus.emulator import BusEmulator

    with BusEmulator([1], XM430.name) as emu:
        with pytest.raises(InvalidConfigError, match="position_gains_raw must be 4 integers"):
            _bus(emu, raw)


def test_a_held_goal_gives_the_same_reading_as_the_firmware_run_by_hand():
    """The emulator's servo and the firmware with the same gains closed by hand on the same
    first-order servo, a step of 0.1 rad without profile: the same angle after 0.2 s, to a
    count (the emulator steps its model in the commands' 10 ms, the firmware its 1 ms)."""
    from stewart_drake.station.bus.emulator import BusEmulator
    from stewart_drake.station.bus.servo_firmware import PositionFirmware
    from stewart_drake.station.bus.servo_models import FirstOrderServos

    _, raw = _loop_gains()
    gains = table_position_gains(raw, XM430, 12.0)
    by_hand = FirstOrderServos.from_catalogue(XM430.name, [0.0], load_inertia=0.002)
    firmware = PositionFirmware(gains, XM430.rad_per_count, [0.0])
    firmware.set_goal([0.1])
    for _ in range(200):
        by_hand.advance(1e-3, by_hand.pwm_currents(firmware.duty(by_hand.positions_rad())))
    backend = FirstOrderServos.from_catalogue(XM430.name, [0.0], load_inertia=0.002)
    with BusEmulator([1], XM430.name, backend=backend, command_step_s=0.01) as emu:
        bus = _bus(emu, raw)
        with bus:
            bus.configure()
            bus.enable_torque()
            for _ in range(20):
                bus.write_goals([0.1])  # no profile: the goal at once
            emulated = bus.read_state().q[0]
    assert by_hand.positions_rad()[0] > 0.09  # it moved to the goal
    assert emulated == pytest.approx(by_hand.positions_rad()[0], abs=XM430.rad_per_count)


def test_a_surrogate_beside_cranks_in_their_own_loop_keeps_current_mode_and_its_own_write():
    """The cranks in Position Control Mode with a surrogate's stage on the same bus: the stage
    is configured in Current Control Mode without the cranks' position gains (read back); its
    torque goes in a sync write of its own Goal Current (0.5 N m on the default stage's XM430:
    round(0.5 / 1.7826 / 2.69 mA) = 104 units by hand), which does not move the commands' clock;
    the cranks' goals do."""
    from stewart_drake.station.bus import protocol as p
    from stewart_drake.station.bus.emulator import BusEmulator
    from stewart_drake.station.bus.servo_models import FirstOrderServos, StackedServos
    from stewart_drake.station.bus.servos import SurrogateServoConfig

    pytest.importorskip("dynamixel_sdk", reason="the robot extra: pip install -e '.[robot]'")
    from stewart_drake.station.bus.driver import DynamixelBus

    _, raw = _loop_gains()
    stage = SurrogateServoConfig(id=7)
    crank = FirstOrderServos.from_catalogue(XM430.name, [0.3], load_inertia=0.002)
    backend = StackedServos(crank, FirstOrderServos.linear_stage(stage.stage, 0.0))
    with BusEmulator(
        [1, 7], XM430.name, backend=backend, command_step_s=0.01, zero_counts=[2048, 2048]
    ) as emu:
        bus = DynamixelBus(
            emu.port, 1_000_000, [1], XM430.name, reply_timeout_s=HANG_BUS_S,
            position_gains_raw=raw, watchdog_s=2.54, surrogate=stage,
        )  # fmt: skip
        with bus:
            bus.configure()
            table = XM430.table
            assert emu.read_item(1, table.operating_mode) == p.POSITION_CONTROL_MODE
            assert emu.read_item(7, table.operating_mode) == p.CURRENT_CONTROL_MODE
            assert [emu.read_item(7, item) for item in table.position_gains] != list(raw)
            bus.enable_torque()
            before = bus.read_state()
            bus.write_surrogate_torque(0.5)
            after = bus.read_state()  # answered after the write is taken
            assert p.to_signed(emu.read_item(7, table.goal_current), 2) == 104
            assert (after.q[0], after.s) == (before.q[0], before.s)  # no step of the model
            bus.write_goals([before.q[0] + 0.02], [2.0])
            moved = bus.read_state()
            assert moved.s != before.s and moved.q[0] != before.q[0]
            with pytest.raises(InvalidConfigError, match="finite"):
                bus.write_surrogate_torque(float("nan"))
            bus.torque_off()
