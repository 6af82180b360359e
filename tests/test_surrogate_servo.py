"""The surrogate's servo on the bus, without a bus: its settings checked, its carriage's units,
its position loop on a plant of its own, its path's check, and the relative latency measured
from encoder samples (stewart_drake/station/surrogate/bus_servo.py,
stewart_drake/live/session_surrogate.py)."""

import math
import re

import numpy as np
import pytest

from stewart_drake.base.errors import InvalidConfigError
from stewart_drake.live.session_surrogate import axis_lag
from stewart_drake.live.session_surrogate import judged_relative_latency as relative_latency
from stewart_drake.station.bus.servo_models import FirstOrderServos
from stewart_drake.station.bus.servos import DynamixelBusConfig, SurrogateServoConfig
from stewart_drake.station.surrogate.bus_servo import SurrogateDrive, check_surrogate_path
from stewart_drake.station.surrogate.linear_stage import LinearStage

PERIOD_S = 0.01


def test_the_default_stage_is_valid_and_its_units_follow_the_belt():
    config = SurrogateServoConfig()
    config.validate([1, 2, 3, 4, 5, 6], PERIOD_S)
    # The cited part: 40 teeth of a 2 mm GT2 belt = 80 mm a turn of 4096 counts, 19.5 um a count.
    lead = 40 * 2e-3
    assert config.metres_per_count == pytest.approx(lead / 4096, rel=1e-12)
    assert 19.5e-6 < config.metres_per_count < 19.6e-6
    assert float(config.counts_to_m(2048 + 4096)) == pytest.approx(lead, rel=1e-12)
    assert float(config.counts_to_m(2048 - 1024)) == pytest.approx(-lead / 4, rel=1e-12)
    flipped = SurrogateServoConfig(direction=-1, zero_counts=-500)
    assert float(flipped.counts_to_m(-500 + 4096)) == pytest.approx(-lead, rel=1e-12)
    for s in (-0.04, 0.0, 0.0123):
        assert abs(float(flipped.counts_to_m(flipped.m_to_counts(s))) - s) <= 0.5 * lead / 4096
    # XM430-W350-T: 46 rpm at no load, 80 % of it through 80 mm a turn = 49.1 mm/s.
    assert config.max_speed_m_s() == pytest.approx(0.8 * 46 / 60 * lead, rel=1e-9)
    assert 0.0490 < config.max_speed_m_s() < 0.0491
    # J: the rotor's 1 g cm^2 through 353.5 : 1, and 0.3 kg through 80 mm / 2 pi.
    j = 1e-7 * 353.5**2 + 0.3 * (lead / (2 * math.pi)) ** 2
    assert config.stage.inertia_at_horn_kg_m2() == pytest.approx(j, rel=1e-9)


def test_the_drive_is_built_from_the_part_the_diagram_uses():
    """What the bus's drive holds, read back from it, against the catalogue's figures by hand:
    J, the friction, the gains, the metres a count and a radian, the speed limit; and the
    Diagram's stage is the same part (one definition: same fields, same figures)."""
    from stewart_drake.station.surrogate.stage import SurrogateStage

    drive = SurrogateDrive(SurrogateServoConfig(), PERIOD_S)
    lead, r = 0.08, 0.08 / (2 * math.pi)
    rotor = 1e-7 * 353.5**2  # 1 g cm^2 through 353.5 : 1, kg m^2
    assert drive.J == pytest.approx(rotor + 0.3 * r * r, rel=1e-9)
    stall, no_load = 4.1, 46 * 2 * math.pi / 60  # N m, rad/s
    assert drive.coulomb == pytest.approx(0.05 * stall, rel=1e-9)  # catalogue: 5 % of stall
    assert drive.viscous == pytest.approx(0.05 * stall / no_load, rel=1e-9)
    w = 2 * math.pi * 5.0
    assert drive.kp == pytest.approx(drive.J * w * w, rel=1e-12)
    assert drive.kd == pytest.approx(2 * drive.J * w, rel=1e-12)
    assert drive.config.metres_per_count == pytest.approx(lead / 4096, rel=1e-12)
    assert drive.config.metres_per_rad == pytest.approx(r, rel=1e-12)
    assert drive.config.max_speed_m_s() * 1e3 == pytest.approx(49.07, abs=0.01)
    diagram = SurrogateStage()
    bus = drive.config.stage
    for name in ("motor", "lead_m_per_rev", "travel_m", "carriage_mass_kg", "efficiency"):
        assert getattr(diagram, name) == getattr(bus, name), name
    assert diagram.moving_mass_kg() * r * r == pytest.approx(drive.J, rel=1e-9)
    assert diagram.no_load_speed_m_s * 0.8 == pytest.approx(drive.config.max_speed_m_s())
    # The horn's viscous friction at the carriage: b / r^2, N s/m (a force b w / r at a speed
    # w r), 0.0426 N m s/rad through 12.7 mm/rad: 263 N s/m.
    assert bus.viscous_N_s_per_m() == pytest.approx(0.05 * stall / no_load / r**2, rel=1e-9)
    assert 262 < bus.viscous_N_s_per_m() < 263


def test_a_stage_at_the_edges_of_its_ranges_is_taken():
    """A metre of travel and 50 kg of carriage are the largest taken; a step past them is
    refused naming the field."""
    LinearStage(travel_m=1.0, carriage_mass_kg=50.0, efficiency=1.0).check()
    for field, value in (("travel_m", 1.01), ("carriage_mass_kg", 50.5)):
        with pytest.raises(InvalidConfigError, match=rf"^stage\.{field} must be a finite number"):
            LinearStage(**{field: value}).check()


@pytest.mark.parametrize(
    "change, words",
    [
        ({"id": 3}, "is a crank's"),
        ({"id": 253}, "bus.surrogate.id"),
        ({"id": 7.0}, "bus.surrogate.id"),
        ({"motor": "XL430-W250-T"}, "no Current Control Mode"),
        ({"motor": "XH430-W350-T"}, "bus.surrogate.stage.motor"),
        ({"motor": "maxon-EC45flat-50W-GP42C-4.3"}, "bus.surrogate.stage.motor"),
        ({"lead_m_per_rev": 0.0}, "bus.surrogate.stage.lead_m_per_rev"),
        ({"lead_m_per_rev": -0.01}, "bus.surrogate.stage.lead_m_per_rev"),
        ({"lead_m_per_rev": float("nan")}, "bus.surrogate.stage.lead_m_per_rev"),
        ({"lead_m_per_rev": 0.6}, "bus.surrogate.stage.lead_m_per_rev"),
        ({"travel_m": 0.0}, "bus.surrogate.stage.travel_m"),
        ({"travel_m": float("inf")}, "bus.surrogate.stage.travel_m"),
        ({"carriage_mass_kg": -1.0}, "bus.surrogate.stage.carriage_mass_kg"),
        ({"efficiency": 0.0}, "bus.surrogate.stage.efficiency"),
        ({"efficiency": 1.2}, "bus.surrogate.stage.efficiency"),
        ({"zero_counts": 2**31}, "zero_counts"),
        ({"direction": 0}, "direction"),
        ({"direction": True}, "direction"),
        ({"current_limit_A": 0.0}, "current_limit_A"),
        ({"current_limit_A": 10.0}, "current_limit_A"),
        ({"bandwidth_hz": 0.0}, "bandwidth_hz"),
        ({"bandwidth_hz": 20.0}, "bandwidth_hz"),  # over a tenth of 100 Hz
    ],
)
def test_a_wrong_stage_is_refused_naming_its_field(change, words):
    change = dict(change)  # the case's own dict, read again when the test runs again
    part = {k: change.pop(k) for k in list(change) if k in LinearStage.__dataclass_fields__}
    config = SurrogateServoConfig(stage=LinearStage(**part), **change)
    with pytest.raises(InvalidConfigError, match=words):
        config.validate([1, 2, 3, 4, 5, 6], PERIOD_S)
    bus = DynamixelBusConfig(surrogate=config)
    with pytest.raises(InvalidConfigError, match=words):
        bus.validate(PERIOD_S, None)


def test_a_bus_without_a_surrogate_is_as_before_and_a_dict_is_refused():
    assert DynamixelBusConfig().surrogate is None
    DynamixelBusConfig().validate(PERIOD_S, None)
    with pytest.raises(InvalidConfigError, match="SurrogateServoConfig"):
        DynamixelBusConfig(surrogate={"id": 7}).validate(PERIOD_S, None)
    with pytest.raises(InvalidConfigError, match="bus.surrogate.stage must be a LinearStage"):
        SurrogateServoConfig(stage={"travel_m": 0.1}).validate([1], PERIOD_S)


def test_the_scenario_file_carries_the_surrogate_section_both_ways(tmp_path):
    from stewart_drake.run.scenario import Scenario, dump_scenario
    from stewart_drake.run.scenario_io import load_scenario

    scenario = Scenario(control_period_s=PERIOD_S, log_period_s=PERIOD_S)
    scenario.hardware = None
    stage = LinearStage(lead_m_per_rev=0.04, travel_m=0.12)
    scenario.bus = DynamixelBusConfig(surrogate=SurrogateServoConfig(id=9, stage=stage))
    text = dump_scenario(scenario)
    assert "surrogate:" in text and "lead_m_per_rev: 0.04" in text
    path = tmp_path / "s.yaml"
    path.write_text(text)
    again = load_scenario(str(path))
    assert again.bus.surrogate == scenario.bus.surrogate
    assert again.bus.surrogate.stage.travel_m == 0.12
    # The stage's fields are the Diagram's (one part): a wrong one is named where it is.
    with pytest.raises(InvalidConfigError, match="bus.surrogate.stage.travel_m"):
        load_scenario(str(path), ["bus.surrogate.stage.travel_m=-1"])
    # Without one, the file is as before: no word of it.
    no_surrogate = Scenario(control_period_s=PERIOD_S, log_period_s=PERIOD_S)
    no_surrogate.hardware = None
    no_surrogate.bus = DynamixelBusConfig()
    assert "surrogate" not in dump_scenario(no_surrogate)


def test_a_path_out_of_the_travel_or_too_fast_is_refused_with_its_figure():
    config = SurrogateServoConfig()
    t = np.linspace(0, 8, 801)
    s = 0.032 * np.sin(2 * np.pi * t / 4)  # 32 mm, 50.3 mm/s peak: over 49.1 mm/s
    v = 0.032 * 2 * np.pi / 4 * np.cos(2 * np.pi * t / 4)
    with pytest.raises(InvalidConfigError, match=r"50\.3 mm/s, over the 49\.1 mm/s") as fast:
        check_surrogate_path(config, s, v)
    assert "bus.surrogate.stage.lead_m_per_rev" in str(fast.value)
    check_surrogate_path(config, 0.97 * s, 0.97 * v)  # 48.8 mm/s: within
    check_surrogate_path(config, 0.5 * s, 0.5 * v)  # half as fast: within
    with pytest.raises(InvalidConfigError, match=r"\+60\.0 mm, outside the stage's travel"):
        check_surrogate_path(config, np.array([0.0, 0.06]), np.zeros(2))
    with pytest.raises(InvalidConfigError, match=r"bus\.surrogate\.stage\.travel_m"):
        check_surrogate_path(config, np.array([0.0, -0.0501]), np.zeros(2))
    with pytest.raises(InvalidConfigError, match="not finite"):
        check_surrogate_path(config, np.array([0.0, np.nan]), np.zeros(2))


def test_the_position_loop_follows_a_breath_on_a_stage_of_its_own():
    """The drive closes its loop on the emulator's first-order stage (the catalogue servo and
    the carriage through the screw), read in whole encoder counts one period late as the bus
    reads it: a 10 mm, 4 s breath (15.7 mm/s peak) is followed within 0.1 mm and less than a
    period late."""
    config = SurrogateServoConfig()
    drive = SurrogateDrive(config, PERIOD_S)
    w = 2 * math.pi / 4

    def command(t):
        return 0.01 * math.sin(w * t), 0.01 * w * math.cos(w * t), -0.01 * w * w * math.sin(w * t)

    drive.command = command
    stage = FirstOrderServos.linear_stage(config.stage)
    from stewart_drake.station.bus.servos import servo_spec

    kt = servo_spec(config.model).torque_constant_Nm_per_A
    r = config.metres_per_rad
    times, read, asked = [], [], []

    def read_stage():
        counts = np.rint(stage.positions_rad()[0] * 4096 / (2 * math.pi))
        drive.reading(counts * config.metres_per_count, stage.velocities_rad_s()[0] * r)
        return counts * config.metres_per_count

    assert drive.torque(0.0)[0] == 0.0  # nothing read yet: no torque
    read_stage()  # the session's first reading, before the loop
    for k in range(1200):
        t = k * PERIOD_S
        # As the driver: the torque from the last period's reading, written; then the read.
        tau, s_c = drive.torque(t)
        times.append(t)
        read.append(read_stage())
        asked.append(s_c)
        stage.advance(PERIOD_S, np.array([tau / kt]))
    t, y, c = np.array(times), np.array(read), np.array(asked)
    late = t > 4.0  # past the start's transient
    assert np.max(np.abs(y[late] - c[late])) < 1e-4
    lag, _ = axis_lag(t[late], y[late], c[late])
    assert -PERIOD_S < lag < PERIOD_S


def _breath(t):
    """A breath of two harmonics (4 s), m: a command with a lag to find."""
    return 0.01 * np.sin(2 * np.pi * t / 4) + 0.003 * np.sin(4 * np.pi * t / 4 + 0.7)


@pytest.mark.parametrize("delay_s", [0.0, 0.0037, 0.021, -0.012])
def test_an_axis_lag_is_the_delay_it_was_given(delay_s):
    t = np.arange(0.0, 20.0, PERIOD_S)
    lag, rms = axis_lag(t, _breath(t - delay_s), _breath(t))
    assert abs(lag - delay_s) < 2e-4, lag
    assert rms < 2e-6


def test_the_relative_latency_is_the_surrogates_lag_less_the_platforms():
    t = np.arange(0.0, 20.0, PERIOD_S)
    x_c = np.zeros((t.size, 6))
    x_c[:, 5] = 0.3 + 0.5 * _breath(t)  # Z moves most
    x_c[:, 3] = 0.1 * _breath(t + 1.0)  # X a little, with another phase
    x_m = x_c.copy()
    x_m[:, 5] = 0.3 + 0.5 * _breath(t - 0.004)
    x_m[:, 3] = 0.1 * _breath(t + 1.0 - 0.5)  # a wrong axis to judge: 0.5 s late
    s_c = _breath(t + 0.4)
    s_m = _breath(t + 0.4 - 0.011)
    judged = relative_latency(t, x_m, x_c, s_m, s_c, tolerance_s=PERIOD_S, t_from=2.0)
    assert judged.platform_axis == "Z"
    assert abs(judged.platform_lag_s - 0.004) < 2e-4
    assert abs(judged.surrogate_lag_s - 0.011) < 2e-4
    assert abs(judged.relative_s + 0.007) < 3e-4  # the platform 4 ms, the surrogate 11 ms
    assert judged.passed and "PASS" in judged.line()
    said = re.search(r"reference's\): ([-+]\d+\.\d\d) ms \(surrogate", judged.line())
    assert said and abs(float(said.group(1)) + 7.0) < 0.3, judged.line()
    assert "the carriage's s against s_cmd, the platform's Z" in judged.line()
    # The surrogate 15 ms behind the platform (-15 ms: the platform's lag less the surrogate's):
    # over one period.
    late = relative_latency(
        t, x_m, x_c, _breath(t + 0.4 - 0.019), s_c, tolerance_s=PERIOD_S, t_from=2.0
    )
    assert abs(late.relative_s + 0.015) < 3e-4 and not late.passed and "FAIL" in late.line()
    # The surrogate ahead of its command, the platform behind: positive, judged on its magnitude.
    ahead = relative_latency(
        t, x_m, x_c, _breath(t + 0.4 + 0.008), s_c, tolerance_s=PERIOD_S, t_from=2.0
    )
    assert abs(ahead.relative_s - 0.012) < 3e-4 and not ahead.passed


def test_a_still_axis_has_no_latency_and_fails_saying_so():
    t = np.arange(0.0, 10.0, PERIOD_S)
    x = np.tile([0, 0, 0, 0, 0, 0.3], (t.size, 1))
    s = _breath(t)
    judged = relative_latency(t, x, x, s, s, tolerance_s=PERIOD_S, x_count_m=1e-5)
    assert math.isnan(judged.relative_s) and not judged.passed
    assert "not measured, the platform did not move; FAIL" in judged.line()
    still = relative_latency(
        t, x, x, np.zeros(t.size), np.zeros(t.size), tolerance_s=PERIOD_S, s_count_m=1e-5
    )
    assert "the surrogate and the platform did not move" in still.line()


@pytest.mark.parametrize(
    "mangle, words",
    [
        (lambda a: a.update(t=a["t"][::-1].copy()), "increas"),
        (lambda a: a["s_measured"].__setitem__(5, np.nan), "not finite"),
        (
            lambda a: a.update(s_commanded=a["s_commanded"][:-1]),
            r"\(n,\) alike|surrogate's samples",
        ),
        (lambda a: a.update(x_measured=a["x_measured"][:, :3]), "poses must be"),
        (lambda a: a.update(tolerance_s=0.0), "tolerance_s"),
        (lambda a: a.update(tolerance_s=float("nan")), "tolerance_s"),
        (lambda a: a.update(t_from=9.5), "too short|longer record"),
        (lambda a: a.update(max_lag_s=0.0), "max_lag_s"),
    ],
)
def test_wrong_samples_are_refused(mangle, words):
    t = np.arange(0.0, 10.0, PERIOD_S)
    x = np.tile([0, 0, 0, 0, 0, 0.3], (t.size, 1))
    x[:, 5] += _breath(t)
    args = dict(
        t=t,
        x_measured=x,
        x_commanded=x.copy(),
        s_measured=_breath(t),
        s_commanded=_breath(t),
        tolerance_s=PERIOD_S,
    )
    mangle(args)
    with pytest.raises(InvalidConfigError, match=words):
        relative_latency(**args)
