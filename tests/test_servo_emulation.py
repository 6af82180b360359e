"""The bus emulator's servos as a built robot's (stewart_drake/station/bus/emulator_config.py,
bus_timing.py, live/plant_backend.py's RealisticServos): what a scenario's ``emulator`` section
draws, each figure against the catalogue and the e-Manual by hand; the bus's time per packet;
corrupt and lost replies ending a run's read; and the drive, the friction budget and the
encoders read back from the Drake plant the emulator steps."""

import math

import numpy as np
import pytest

from stewart_drake.base.errors import BusError, InvalidConfigError
from stewart_drake.live.robot_options import EmulateChoice, emulate_choice
from stewart_drake.robot.motor_catalogue import catalogue_motor
from stewart_drake.station.bus import protocol as p
from stewart_drake.station.bus.bus_timing import BusTiming
from stewart_drake.station.bus.emulator_config import EmulatorConfig
from stewart_drake.station.bus.servo_physics import FRICTION
from stewart_drake.station.bus.servos import servo_spec

XM430, PM42 = servo_spec("XM430-W350-T"), servo_spec("PM42-010-S260-R")


# -- what a section draws ---------------------------------------------------------------------


def test_ideal_servos_are_the_controllers_own_model():
    s = EmulatorConfig(servos="ideal").draw(XM430)
    assert not s.departs() and s.summary() == "ideal servos (the controller's own model)"
    np.testing.assert_allclose(s.k_Nm_per_A, 4.1 / 2.3)  # the bus's stall ratio
    assert s.supply_V == math.inf and s.current_time_constant_s == 0.0
    assert np.all(s.friction[:, FRICTION["coulomb_Nm"]] == pytest.approx(0.05 * 4.1))
    assert np.all(s.friction[:, FRICTION["load_motor"]] == 0.0)
    assert (s.backlash_rad, s.encoder_noise_counts, s.return_delay_us) == (0.0, 0.0, 0.0)


def test_one_departure_given_to_ideal_servos_is_the_only_one():
    s = EmulatorConfig(servos="ideal", kt_scale=0.7).draw(XM430)
    assert s.departs()
    np.testing.assert_allclose(s.k_Nm_per_A, 0.7 * 4.1 / 2.3)
    assert s.rotor_inertia_scale == 1.0 and s.mass_scale == 1.0 and s.backlash_rad == 0.0


def test_realistic_xm430_servos_by_hand():
    """The XM430-W350-T at 12 V: the back-EMF constant its no-load speed gives, 12 / (46 rpm) =
    2.491 V s/rad, against its stall ratio 1.783 N m/A: a gear train of efficiency 0.716; so
    the drawn motor constants lie within 10 % (and the winding's warmth) of 2.491, the
    load-dependent friction is 0.284 of the motor's torque, the winding 12 / 2.3 ohm."""
    s = EmulatorConfig().draw(XM430)
    back_emf = 12.0 / (46.0 * 2 * math.pi / 60)
    efficiency = (4.1 / 2.3) / back_emf
    assert efficiency == pytest.approx(0.716, abs=1e-3)
    warm = 1 - 0.0012 * s.temperature_rise_K
    assert np.all(s.k_Nm_per_A >= 0.9 * back_emf * warm - 1e-12)
    assert np.all(s.k_Nm_per_A <= 1.1 * back_emf * warm + 1e-12)
    assert np.ptp(s.k_Nm_per_A) > 0  # each servo its own
    np.testing.assert_allclose(s.friction[:, FRICTION["load_motor"]], 1 - efficiency)
    np.testing.assert_allclose(
        s.resistance_ohm, 12.0 / 2.3 * (1 + 0.0039 * s.temperature_rise_K), rtol=1e-12
    )
    stall = catalogue_motor("XM430-W350-T").servo.peak_torque_Nm
    c = s.friction[:, FRICTION["coulomb_Nm"]] / (0.01 * stall)
    assert np.all((c >= 0.5 * 0.8) & (c <= 2.0 * 1.2))
    assert 0.5 <= s.rotor_inertia_scale <= 2.0 and 0.97 <= s.mass_scale <= 1.03
    assert 0.25 * math.radians(0.25) <= s.backlash_rad <= math.radians(0.25)
    assert np.all(s.inl_counts <= 0.5 / (360 / 4096)) and s.encoder_noise_counts == 0.34
    assert s.current_time_constant_s == pytest.approx(1e-3 * s.current_time_constant_s / 1e-3)
    assert 0.5e-3 <= s.current_time_constant_s <= 2e-3
    assert (s.return_delay_us, s.latency_timer_ms, s.reply_jitter_us) == (500.0, 1.0, 100.0)
    assert s.supply_V == 12.0 and 0.0 <= s.temperature_rise_K <= 5.0


def test_the_p_series_reads_its_motor_and_is_supplied_at_24_volts():
    s = EmulatorConfig().draw(PM42)
    assert s.family == "P" and s.supply_V == 24.0
    np.testing.assert_allclose(s.friction[:, FRICTION["load_motor"]], 0.3)  # 1 - 0.7
    assert np.all(s.inl_counts == 0.0) and s.encoder_noise_counts == 1.0
    assert s.backlash_rad <= math.radians(0.1)


def test_a_seed_draws_the_same_robot_and_another_seed_another():
    a, b = EmulatorConfig(seed=3).draw(XM430), EmulatorConfig(seed=3).draw(XM430)
    np.testing.assert_array_equal(a.k_Nm_per_A, b.k_Nm_per_A)
    assert a.backlash_rad == b.backlash_rad
    c = EmulatorConfig(seed=4).draw(XM430)
    assert not np.array_equal(a.k_Nm_per_A, c.k_Nm_per_A)


def test_a_departure_given_leaves_the_others_as_drawn():
    a = EmulatorConfig(seed=5).draw(XM430)
    b = EmulatorConfig(seed=5, kt_scale=1.3).draw(XM430)
    assert b.backlash_rad == a.backlash_rad and b.rotor_inertia_scale == a.rotor_inertia_scale
    np.testing.assert_array_equal(b.inl_phase, a.inl_phase)
    assert np.all(b.kt_scale == 1.3)


@pytest.mark.parametrize(
    "change, words",
    [
        ({"servos": "real"}, "emulator.servos must be one of realistic, ideal"),
        ({"seed": -1}, "emulator.seed"),
        ({"kt_scale": 0.0}, "emulator.kt_scale must be a finite number in [0.2, 5]"),
        ({"friction_scale": -1.0}, "emulator.friction_scale"),
        ({"backlash_rad": 0.5}, "emulator.backlash_rad"),
        ({"latency_timer_ms": 300.0}, "emulator.latency_timer_ms"),
        ({"crc_error_rate": 2.0}, "emulator.crc_error_rate"),
        ({"return_delay_us": float("nan")}, "emulator.return_delay_us"),
    ],
)
def test_a_departure_out_of_range_is_named(change, words):
    with pytest.raises(InvalidConfigError) as err:
        EmulatorConfig(**change).draw(XM430)
    assert words in str(err.value)


def test_the_scenarios_section_takes_set_and_refuses_a_bad_value():
    from stewart_drake.run.scenario_io import load_scenario

    s = load_scenario("phantom_bus", ["emulator.servos=ideal", "emulator.kt_scale=0.7"])
    assert (s.emulator.servos, s.emulator.kt_scale) == ("ideal", 0.7)
    with pytest.raises(InvalidConfigError, match="emulator.kt_scale"):
        load_scenario("phantom_bus", ["emulator.kt_scale=9"])


@pytest.mark.parametrize(
    "text, choice",
    [
        ("ideal", EmulateChoice("ideal", (0.0, 0.0, 0.0, 0.0, 0.0, 0.28))),
        ("realistic", EmulateChoice("realistic", (0.0, 0.0, 0.0, 0.0, 0.0, 0.28))),
        ("0,0,0,0,0,0.3", EmulateChoice(None, (0.0, 0.0, 0.0, 0.0, 0.0, 0.3))),
        ("ideal@0,0,0,0.01,0,0.3", EmulateChoice("ideal", (0.0, 0.0, 0.0, 0.01, 0.0, 0.3))),
    ],
)
def test_emulate_takes_the_servos_a_pose_or_both(text, choice):
    assert emulate_choice(text) == choice


@pytest.mark.parametrize("text", ["ideel", "ideal@1,2", "fast@0,0,0,0,0,0.3", "1,2,3"])
def test_emulate_refuses_what_it_does_not_take(text):
    import argparse

    with pytest.raises(argparse.ArgumentTypeError):
        emulate_choice(text)


# -- the bus's time ---------------------------------------------------------------------------


def test_a_packets_time_on_the_wire_and_through_the_adapter_by_hand():
    t = BusTiming(1_000_000, latency_timer_ms=0.0, jitter_us=0.0)
    assert t.wire_s(146) == pytest.approx(1.46e-3)  # 10 bits a byte
    # six status packets of 15 bytes, each after a 500 us Return Delay Time
    assert t.reply_s([(15, 500e-6)] * 6) == pytest.approx(6 * (500e-6 + 150e-6))
    held = BusTiming(1_000_000, latency_timer_ms=16.0, jitter_us=0.0, seed=1)
    waits = [held.reply_s([(15, 0.0)]) - 150e-6 for _ in range(2000)]
    assert 0.0 <= min(waits) and max(waits) <= 16e-3
    assert np.mean(waits) == pytest.approx(8e-3, rel=0.05)  # uniform over the timer
    # 124 bytes fill two USB packets: nothing waits for the timer
    assert held.reply_s([(62, 0.0), (62, 0.0)]) == pytest.approx(1.24e-3)


def test_replies_are_corrupt_or_lost_at_their_rates():
    t = BusTiming(1_000_000, crc_error_rate=0.2, timeout_rate=0.1, seed=2)
    fates = [t.fate() for _ in range(20000)]
    assert fates.count("lost") / 20000 == pytest.approx(0.1, abs=0.01)
    assert fates.count("corrupt") / 20000 == pytest.approx(0.2, abs=0.015)
    assert BusTiming(1_000_000).fate() == "sent"


def _bus_on(emulator, reply_timeout_s: float | None = None):
    pytest.importorskip("dynamixel_sdk", reason="the robot extra: pip install -e '.[robot]'")
    from stewart_drake.station.bus.driver import DynamixelBus

    return DynamixelBus(
        emulator.port, 1_000_000, [1, 2, 3, 4, 5, 6], reply_timeout_s=reply_timeout_s
    )


def test_a_sync_read_takes_its_bytes_and_return_delays_and_the_driver_writes_them_to_zero():
    """The emulator's servos start at the factory's 500 us; before the driver configures them
    a sync read of six takes at least six of those and its 146 bytes at 1 Mbps (4.5 ms), after
    it (Return Delay Time written 0, read back) its bytes' 1.46 ms. Lower bounds only: a busy
    machine only adds."""
    from stewart_drake.station.bus.emulator import BusEmulator

    timing = BusTiming(1_000_000, latency_timer_ms=0.0, jitter_us=0.0)
    with BusEmulator([1, 2, 3, 4, 5, 6], timing=timing, return_delay_us=500.0) as emu:
        assert emu.read_item(1, p.RETURN_DELAY_TIME) == 250
        bus = _bus_on(emu)
        bus.open()
        before = min(_read_time(bus) for _ in range(5))
        bus.configure()
        assert all(emu.read_item(i, p.RETURN_DELAY_TIME) == 0 for i in range(1, 7))
        after = min(_read_time(bus) for _ in range(5))
        bus.close()
    assert before >= 6 * 500e-6 + 1.46e-3
    assert after >= 1.46e-3 and before - after >= 2.5e-3


def _read_time(bus) -> float:
    import time

    t0 = time.perf_counter()
    bus.read_state()
    return time.perf_counter() - t0


@pytest.mark.parametrize(
    "fate, words",
    [("crc_error_rate", "incorrect status packet"), ("timeout_rate", "no status packet")],
)
def test_a_read_whose_retries_fail_too_ends_with_a_bus_error(fate, words):
    """Every status packet corrupt: the read and its one retry fail, and the error names what
    and how often it was sent; every one lost: the read fails at once, not sent again."""
    from stewart_drake.station.bus.emulator import BusEmulator

    timing = BusTiming(1_000_000, 0.0, 0.0, **{fate: 1.0})
    with BusEmulator([1, 2, 3, 4, 5, 6]) as emu:
        bus = _bus_on(emu, reply_timeout_s=0.2)  # wait-kept: a lost reply must time out
        bus.open()
        bus.configure()
        emu.timing = timing  # from here every status packet is corrupt, or lost
        with pytest.raises(BusError) as err:
            bus.read_state()
        bus.close()
    said = str(err.value)
    assert "sync read" in said and words in said.lower()
    if fate == "crc_error_rate":  # sent again once, corrupt again
        assert "(sent 2 times)" in said and bus.reads_retried == {"corrupt": 1}
    else:  # a silent bus is not waited out twice
        assert "(sent" not in said and bus.reads_retried == {}


class _Scripted(BusTiming):
    """A bus whose status packets meet the fates of ``script`` in turn, then arrive."""

    def __init__(self, script):
        super().__init__(1_000_000, 0.0, 0.0)
        self.script = list(script)

    def fate(self) -> str:
        return self.script.pop(0) if self.script else "sent"


def test_a_corrupt_reply_is_read_again_and_the_retry_is_the_reading():
    """One servo's status packet corrupt, then (the next period) another: each read is sent
    again once and answers with the servos' true positions, the retries counted; one lost
    ends the read at once; with no retry allowed a corrupt packet ends it too."""
    from stewart_drake.station.bus.emulator import BusEmulator

    with BusEmulator([1, 2, 3, 4, 5, 6]) as emu:
        bus = _bus_on(emu, reply_timeout_s=0.2)  # wait-kept: a lost reply must time out
        bus.open()
        bus.configure()
        truth = bus.read_state().q
        emu.timing = _Scripted(["sent", "sent", "corrupt"])
        np.testing.assert_array_equal(bus.read_state().q, truth)
        assert bus.reads_retried == {"corrupt": 1}
        emu.timing = _Scripted(["sent", "corrupt"])
        np.testing.assert_array_equal(bus.read_state().q, truth)
        assert bus.reads_retried == {"corrupt": 2}
        emu.timing = _Scripted(["lost"])
        with pytest.raises(BusError, match="no status packet") as lost:
            bus.read_state()
        assert "(sent" not in str(lost.value) and bus.reads_retried == {"corrupt": 2}
        bus.read_retries = 0
        emu.timing = _Scripted(["corrupt"])
        with pytest.raises(BusError, match="sync read") as err:
            bus.read_state()
        assert "sent 1 times" not in str(err.value) and "(sent" not in str(err.value)
        bus.close()


# -- the servos behind the bus, read back from the plant ----------------------------------------


@pytest.fixture(scope="module")
def realistic_xm430():
    """paper_bus's robot behind the bus with realistic servos of seed 2, resting at home."""
    from stewart_drake.live.plant_backend import RealisticServos, behind_the_bus, dynamixel_scenario
    from stewart_drake.run.scenario_io import load_scenario

    scenario = load_scenario("paper_bus", ["emulator.seed=2"])
    servos = scenario.emulator.draw(XM430)
    robot = dynamixel_scenario("XM430-W350-T", behind_the_bus(scenario, servos))
    x0 = np.array([0.0, 0.0, 0.0, 0.0, 0.0, 0.28])
    return RealisticServos(robot, "XM430-W350-T", x0, servos), servos, scenario


def test_the_plant_behind_the_bus_is_the_drawn_robot(realistic_xm430):
    """Read back from the Drake plant: each motor joint's reflected rotor inertia the
    catalogue's times the drawn scale, the gear play the drawn one, the platform's mass the
    drawing's times the drawn scale, its rods at the warm robot's length."""
    backend, servos, scenario = realistic_xm430
    plant, context = backend.station.plant, backend._plant_context
    catalogue = catalogue_motor("XM430-W350-T").servo
    for index in plant.GetJointActuatorIndices():
        actuator = plant.get_joint_actuator(index)
        if actuator.name().startswith("friction_"):
            reflected = actuator.calc_reflected_inertia(context)
            assert reflected == pytest.approx(
                catalogue.reflected_inertia * servos.rotor_inertia_scale, rel=1e-9
            )
    play = plant.GetJointByName("play_0")
    assert play.position_upper_limits()[0] == pytest.approx(servos.backlash_rad / 2)
    platform = plant.GetBodyByName("platform")
    drawn = scenario.robot.build().platform_mass * servos.mass_scale
    assert platform.get_mass(context) == pytest.approx(drawn, rel=1e-9)
    warm = backend.station.plan.plant_geometry
    cold = scenario.robot.build()
    assert warm.lengths_at_c == pytest.approx(cold.lengths_at_c + servos.temperature_rise_K)


def test_the_current_lags_and_the_budget_is_set_on_the_plant(realistic_xm430):
    """One 1 ms step of 0.3 A from rest: each servo's current 0.3 (1 - e^-(1 ms / tau)), its
    friction actuator's effort limit the budget at rest by hand, K_c + K_cs + (K_lm + K_lms) k i;
    the plant's current read back as Present Current."""
    backend, servos, _ = realistic_xm430
    backend.advance(1e-3, np.full(6, 0.3))
    i = 0.3 * (1 - math.exp(-1e-3 / servos.current_time_constant_s))
    np.testing.assert_allclose(backend.currents_A(), i, rtol=1e-9)
    f = servos.friction
    budget = (
        f[:, FRICTION["coulomb_Nm"]]
        + f[:, FRICTION["stribeck_Nm"]]
        + (f[:, FRICTION["load_motor"]] + f[:, FRICTION["load_motor_stribeck"]])
        * servos.k_Nm_per_A
        * i
    )
    plant = backend.station.plant
    limits = [
        plant.get_joint_actuator(index).effort_limit()
        for index in plant.GetJointActuatorIndices()
        if plant.get_joint_actuator(index).name().startswith("friction_")
    ]
    np.testing.assert_allclose(limits, budget, rtol=1e-6)


def _without_friction(servos_kind: str):
    from stewart_drake.live.plant_backend import RealisticServos, behind_the_bus, dynamixel_scenario
    from stewart_drake.run.scenario_io import load_scenario

    settings = ["emulator.seed=2", "emulator.friction_scale=0", f"emulator.servos={servos_kind}"]
    scenario = load_scenario("paper_bus", settings)
    servos = scenario.emulator.draw(XM430)
    robot = dynamixel_scenario("XM430-W350-T", behind_the_bus(scenario, servos))
    backend = RealisticServos(robot, "XM430-W350-T", np.array([0, 0, 0, 0, 0, 0.28]), servos)
    plant = backend.station.plant
    friction = [
        plant.get_joint_actuator(i)
        for i in plant.GetJointActuatorIndices()
        if plant.get_joint_actuator(i).name().startswith("friction_")
    ]
    return backend, servos, friction


def test_realistic_servos_without_friction_keep_their_gears_load_friction():
    """``emulator.friction_scale: 0`` (the emulated budget's "without its friction") takes the
    dry, Stribeck and viscous friction away and leaves what the gears' efficiency loses under
    load: the friction actuators stay; after a 1 ms step of 0.3 A on five servos each of those
    holds the load terms' (K_lm + K_lms) k i by hand, and the sixth, unloaded, none (Drake's
    least limit, 1e-12 N m: a limit of 0 it refuses)."""
    backend, servos, friction = _without_friction("realistic")
    f = servos.friction
    assert not np.any(f[:, [FRICTION["coulomb_Nm"], FRICTION["stribeck_Nm"]]])
    assert len(friction) == 6
    backend.advance(1e-3, np.array([0.3, 0.3, 0.3, 0.3, 0.3, 0.0]))
    i = 0.3 * (1 - math.exp(-1e-3 / servos.current_time_constant_s))
    loads = f[:, FRICTION["load_motor"]] + f[:, FRICTION["load_motor_stribeck"]]
    budget = loads[:5] * servos.k_Nm_per_A[:5] * i
    assert np.all(budget > 1e-3)
    limits = [a.effort_limit() for a in friction]
    np.testing.assert_allclose(limits[:5], budget, rtol=1e-6)
    assert limits[5] == 1e-12


def test_ideal_servos_without_friction_run_on_a_plant_without_its_actuators():
    """The controller's own servos with ``friction_scale: 0``: no friction term at all, no
    friction actuator on the plant, and a step of current moves every crank by more than a
    count."""
    backend, servos, friction = _without_friction("ideal")
    assert not np.any(servos.friction[:, FRICTION["coulomb_Nm"]]) and friction == []
    before = backend.positions_rad()
    for _ in range(50):
        backend.advance(1e-3, np.full(6, 0.5))
    assert np.all(np.abs(backend.positions_rad() - before) > XM430.rad_per_count)


def test_the_encoders_read_their_non_linearity_on_the_output(realistic_xm430):
    """With the noise off: each reading less the crank's true angle (and its zero error) is the
    drawn first harmonic less its value at angle 0 (where the zero was calibrated), A (sin(theta
    + phase) - sin(phase)) counts."""
    import dataclasses

    backend, servos, _ = realistic_xm430
    quiet = dataclasses.replace(servos, encoder_noise_counts=0.0)
    backend.servos = quiet
    from stewart_drake.plant.backlash import crank_angles

    station = backend.station
    theta = crank_angles(station.plant, backend._plant_context, station.handles)
    read = backend.positions_rad() - station.plan.plant_geometry.encoder_offsets
    count = 2 * math.pi / 4096
    np.testing.assert_allclose(
        read - theta,
        quiet.inl_counts * (np.sin(theta + quiet.inl_phase) - np.sin(quiet.inl_phase)) * count,
        atol=1e-15,
    )
    assert np.max(np.abs(read - theta)) > 0.05 * count  # the cranks are off 0: it shows
    backend.servos = servos


def test_the_realistic_servos_pwm_drives_each_ones_own_winding(realistic_xm430):
    """Position Control Mode's drive: a duty of the servos' 12 V through each one's own
    winding, less its back-EMF at its motor's rate (at rest, none): by hand."""
    backend, servos, _ = realistic_xm430
    duty = np.array([0.1, -0.1, 0.2, 0.0, -0.3, 0.05])
    rates = backend._motor_rates()
    expected = (duty * 12.0 - servos.k_Nm_per_A * rates) / servos.resistance_ohm
    np.testing.assert_allclose(backend.pwm_currents(duty), expected, rtol=1e-12)
    assert servos.supply_V == 12.0 and np.all(np.abs(rates) < 1e-3)
    np.testing.assert_allclose(
        backend.pwm_currents(duty), duty * 12.0 / servos.resistance_ohm, atol=1e-3
    )
