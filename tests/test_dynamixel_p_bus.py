"""The DYNAMIXEL-P series on the bus (station/bus): the driver addresses the P series' control
table (Torque Enable at 512, Goal Current at 550 in mA, the state at 574..583) as the e-Manual
gives it, configures and reads back its signed Position Limits, converts its encoder's 526,374
counts a turn and its 0.01 rpm velocity, and refuses a surrogate's servo of the other family;
the emulator answers as a P-series servo does; phantom_bus derives its robot from them."""

import math

import numpy as np
import pytest
from conftest import HANG_S, LOADED_MACHINE_BUS, require_extra, wait_for

require_extra("robot")

from stewart_drake.base.errors import InvalidConfigError  # noqa: E402
from stewart_drake.station.bus import protocol as p  # noqa: E402
from stewart_drake.station.bus.driver import DynamixelBus  # noqa: E402
from stewart_drake.station.bus.emulator import BusEmulator  # noqa: E402
from stewart_drake.station.bus.servo_models import FirstOrderServos  # noqa: E402
from stewart_drake.station.bus.servos import (  # noqa: E402
    SurrogateServoConfig,
    check_bus_settings,
    servo_spec,
)
from stewart_drake.station.surrogate.linear_stage import LinearStage  # noqa: E402

IDS = [1, 2, 3, 4, 5, 6]
MODEL = "PM42-010-S260-R"
#: The e-Manual's PM42-010-S260-R (its control table and specification table), written out here.
EMANUAL = {
    "model_number": 2100,
    "torque_enable": 512,
    "hardware_error_status": 518,
    "bus_watchdog": 546,
    "goal_current": 550,
    "present_current": 574,
    "present_velocity": 576,
    "present_position": 580,
    "counts_per_rev": 526_374,
    "current_limit_max_mA": 1461,
}


def test_the_p_series_table_and_units_are_the_emanuals():
    spec = servo_spec(MODEL)
    t = spec.table
    assert spec.model_number == EMANUAL["model_number"]
    for item in ("torque_enable", "hardware_error_status", "bus_watchdog", "goal_current"):
        assert getattr(t, item)[0] == EMANUAL[item], item
    assert t.state_block == (EMANUAL["present_current"], 10)
    assert t.present_velocity[0] == EMANUAL["present_velocity"]
    assert t.present_position[0] == EMANUAL["present_position"]
    assert spec.counts_per_rev == EMANUAL["counts_per_rev"]
    assert spec.current_unit_A == 1e-3 and spec.current_limit_max == EMANUAL["current_limit_max_mA"]
    assert spec.velocity_unit_rad_s == pytest.approx(0.01 * 2 * math.pi / 60)
    # K_t: the table's continuous torque over its continuous current (1.7 N m at 0.6 A)
    assert spec.torque_constant_Nm_per_A == pytest.approx(1.7 / 0.6)
    # the X series' are unchanged
    x = servo_spec("XM430-W350-T")
    assert x.table.goal_current == (102, 2) and x.counts_per_rev == 4096


def test_the_p_series_position_limits_are_signed_about_zero_and_checked_as_such():
    settings = check_bus_settings(1_000_000, IDS, MODEL)
    assert settings.position_limits_counts == (-263_187, 263_187)
    np.testing.assert_array_equal(settings.zero_counts, 0)
    with pytest.raises(InvalidConfigError, match="-263187 <= min < max <= 263187"):
        check_bus_settings(1_000_000, IDS, MODEL, position_limits_counts=(-300_000, 0))
    with pytest.raises(InvalidConfigError, match="0 <= min < max <= 4095"):
        check_bus_settings(1_000_000, IDS, "XM430-W350-T", position_limits_counts=(-10, 100))
    # 10.5 Mbps is a P-series rate, not an X-series one
    check_bus_settings(10_500_000, IDS, MODEL)
    with pytest.raises(InvalidConfigError, match="baud_rate 10500000"):
        check_bus_settings(10_500_000, IDS, "XM430-W350-T")


@pytest.fixture
def emulator():
    """On the commanded clock: the model moves only with a torque command, so what a test
    puts in it stays until read."""
    backend = FirstOrderServos.from_catalogue(MODEL, np.zeros(6))
    with BusEmulator(IDS, model=MODEL, backend=backend, command_step_s=0.01) as emu:
        yield emu


def _bus(emu, **kw):
    kw = (
        dict(
            current_limit_A=1.2,
            reply_timeout_s=LOADED_MACHINE_BUS["reply_timeout_s"],
            watchdog_s=LOADED_MACHINE_BUS["watchdog_s"],
            position_limits_counts=(-200_000, 200_000),
        )
        | kw
    )
    return DynamixelBus(emu.port, 1_000_000, IDS, model=MODEL, **kw)


def test_configure_writes_the_p_series_items_and_reads_the_signed_limits_back(emulator):
    t = servo_spec(MODEL).table
    with _bus(emulator) as bus:
        bus.configure()
        for i in IDS:
            assert emulator.read_item(i, t.operating_mode) == 0
            assert emulator.read_item(i, t.current_limit) == 1200  # mA
            assert p.to_signed(emulator.read_item(i, t.min_position_limit), 4) == -200_000
            assert p.to_signed(emulator.read_item(i, t.max_position_limit), 4) == 200_000
            assert emulator.read_item(i, t.bus_watchdog) == 127
        bus.enable_torque()
        assert all(emulator.read_item(i, (EMANUAL["torque_enable"], 1)) == 1 for i in IDS)
        sent = bus.write_torques(np.array([0.5, -0.5, 1.0, 0.0, 0.2, -4.0]))

        def goal():
            at = (EMANUAL["goal_current"], 2)
            return [p.to_signed(emulator.read_item(i, at), 2) for i in IDS]

        # a sync write has no status packet: wait for the emulator's thread to take it
        wait_for(lambda: goal()[5] != 0, HANG_S, "the sync write to reach the emulator")
        # mA = torque / K_t; the last clipped to the Current Limit (1.2 A)
        want = np.rint(np.array([0.5, -0.5, 1.0, 0.0, 0.2, -4.0]) / (1.7 / 0.6) * 1e3)
        want[5] = -1200
        np.testing.assert_array_equal(goal(), want)
        np.testing.assert_allclose(sent, want * 1e-3 * 1.7 / 0.6)
    assert all(emulator.read_item(i, (EMANUAL["torque_enable"], 1)) == 0 for i in IDS)


def test_a_reading_converts_the_p_series_counts_and_velocity_units(emulator):
    """The horns put at known angles and rates in the emulator's model: the driver reads them
    back to within one count and one velocity unit."""
    q = np.array([0.1, -0.2, 0.3, 0.0, 1.0, -1.0])
    v = np.array([0.01, -0.02, 0.5, 0.0, 1.0, -1.5])

    def put(backend):
        backend._q, backend._v = q.copy(), v.copy()

    emulator.with_backend(put)
    with emulator._lock:
        emulator._update_present()
    with _bus(emulator) as bus:
        state = bus.read_state()
        raw = [p.to_signed(emulator.read_item(1, (EMANUAL["present_position"], 4)), 4)]
    assert raw[0] == round(0.1 * 526_374 / (2 * math.pi))
    np.testing.assert_allclose(state.q, q, atol=2 * math.pi / 526_374)
    np.testing.assert_allclose(state.v, v, atol=0.01 * 2 * math.pi / 60)


def test_a_surrogate_of_the_other_family_is_refused_naming_why():
    """One sync read and write serve every servo of a bus, at one address: an X-series stage
    beside P-series cranks cannot share them."""
    with pytest.raises(InvalidConfigError, match="other addresses"):
        DynamixelBus("/dev/null", 1_000_000, IDS, model=MODEL, surrogate=SurrogateServoConfig())
    beside = SurrogateServoConfig.beside(MODEL)
    assert servo_spec(beside.model).table.family == "P" and beside.zero_counts == 0
    assert beside.stage == LinearStage(motor=MODEL, lead_m_per_rev=0.12)
    assert SurrogateServoConfig.beside("XM430-W350-T") == SurrogateServoConfig()


def test_phantom_bus_is_the_robot_of_the_p_series_servos():
    from stewart_drake.run.plan import make_plan
    from stewart_drake.run.scenario_io import load_scenario

    scenario = load_scenario("phantom_bus", [])
    plan = make_plan(scenario, with_reference=False)
    assert scenario.bus.model == MODEL
    assert plan.scenario.hardware.encoders.counts_per_rev == 526_374
    assert plan.servo.name == f"ROBOTIS DYNAMIXEL-P {MODEL} (24 V)"
    assert plan.torque_limit_Nm == pytest.approx(1.2 * 1.7 / 0.6)


def test_each_servos_counts_a_turn_have_one_source_the_catalogue_and_are_the_emanuals():
    """The bus's counts a turn are the motor catalogue's (the planner's encoders and the
    driver's conversions cannot disagree), and those are the e-Manual's: 4096 on the X series,
    526,374 pulses on the PM42-010, 607,500 on the PH42-020 (their specification tables)."""
    from stewart_drake.robot.motor_catalogue import catalogue_motor
    from stewart_drake.station.bus.servos import SERVO_SPECS

    emanual = {"PM42-010-S260-R": 526_374, "PH42-020-S300-R": 607_500}
    for name, spec in SERVO_SPECS.items():
        assert spec.counts_per_rev == catalogue_motor(name).encoder_counts_per_rev, name
        assert spec.counts_per_rev == emanual.get(name, 4096), name
