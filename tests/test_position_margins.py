"""The servos' own position loop's margins (station/bus/position_margins) held to the loop run in
time: the firmware the emulator runs (PositionFirmware) on a crank integrated apart, in steps a
hundred times finer than its period, grows past the range's ends and settles within them."""

import math

import pytest

from stewart_drake.station.bus.position_margins import (
    GAIN_RANGE,
    delay_margin_s,
    gain_range,
    position_closed_loop,
    position_margin_lines,
    spectral_radius,
)
from stewart_drake.station.bus.servo_firmware import PositionFirmware, position_gains

#: The phantom's crank on its PM42 (reflected rotor and its share of the platform), the PM42's
#: constant and winding at 24 V, its loop at 30 Hz, damping 1.4.
J, K, R, V = 0.0162, 2.8333, 20.0, 24.0
GAINS = position_gains(J, K, R, V, 30.0, 1.4)


def _simulated_growth(gain: float, delay_s: float = 0.0, periods: int = 1500) -> float:
    """|q| at the end over |q| at the start of the loop run in time: the firmware each 1 ms on
    the crank (a 0.1 mrad offset, far below any saturation; its encoder read exactly), the
    crank ``J q'' = g (k / R)(u - k q')`` by semi-implicit Euler at 10 us, the voltage acting
    ``delay_s`` after it is computed."""
    firmware = PositionFirmware(GAINS, 1e-12, [0.0])
    q, v, dt = 1e-4, 0.0, 1e-5
    sub = round(GAINS.period_s / dt)
    late = round(delay_s / dt)
    pending = [0.0] * (late + 1)  # the voltage over the last ``late`` fine steps
    start = abs(q)
    for _ in range(periods):
        u = float(firmware.duty([q])[0]) * V
        for _ in range(sub):
            pending.append(u)
            acting = pending.pop(0)
            v += dt * gain * (K / (R * J)) * (acting - K * v)
            q += dt * v
    return abs(q) / start


def test_the_design_is_stable_and_its_range_ends_where_the_loop_run_in_time_turns():
    lo, hi = gain_range(GAINS, J, K, R)
    assert lo < GAIN_RANGE[0] and hi > GAIN_RANGE[1]
    assert spectral_radius(GAINS, J, K, R, 1.0) < 1.0
    assert _simulated_growth(1.0) < 1e-3
    assert _simulated_growth(0.93 * hi) < 1.0 < _simulated_growth(1.07 * hi)
    assert _simulated_growth(1.07 * lo, periods=6000) < 1.0
    assert _simulated_growth(0.93 * lo, periods=6000) > 1.0


def test_a_delay_inside_the_servo_past_its_margin_breaks_the_loop_run_in_time():
    margin = delay_margin_s(GAINS, J, K, R)
    assert 2e-4 < margin < 5e-3
    assert _simulated_growth(1.0, 0.9 * margin) < 1.0
    assert _simulated_growth(1.0, 1.1 * margin) > 1.0


def test_the_state_holds_every_voltage_still_to_act():
    """With 2.5 ms of delay the state keeps the three voltages computed before this one."""
    assert position_closed_loop(GAINS, J, K, R, 1.0, 0.0).shape == (6, 6)
    assert position_closed_loop(GAINS, J, K, R, 1.0, 0.0025).shape == (8, 8)


def test_the_lines_say_the_range_and_whether_it_holds_the_shipped_one():
    lines = position_margin_lines(GAINS, J, K, R)
    lo, hi = gain_range(GAINS, J, K, R)
    assert f"{lo:.2f} to {hi:.2f}" in lines[0]
    assert lines[1].startswith("  holds")
    weak = position_gains(J, K, R, V, 30.0, 0.05)  # barely damped: little gain room
    assert "does NOT hold" in position_margin_lines(weak, J, K, R)[1]


def test_refusals():
    from stewart_drake.base.errors import InvalidConfigError

    for kw, match in (({"gain": 0.0}, "gain"), ({"extra_delay_s": -1e-3}, "extra_delay_s")):
        with pytest.raises(InvalidConfigError, match=match):
            position_closed_loop(GAINS, J, K, R, **kw)
    with pytest.raises(InvalidConfigError, match="inertia"):
        position_closed_loop(GAINS, 0.0, K, R)
    assert math.isfinite(gain_range(GAINS, J, K, R)[0])


def test_the_shipped_phantoms_loop_survives_what_the_catalogue_does_not_know():
    """phantom_bus's servos' loop, on the gains its bus writes (the table's, rounded), stays
    stable for a plant gain of 0.5 to 2, and with 1 ms more delay inside the servo from 0.5."""
    from stewart_drake.run.scenario_io import load_scenario
    from stewart_drake.station.bus.position_mode import crank_inertia
    from stewart_drake.station.bus.servo_firmware import table_position_gains
    from stewart_drake.station.bus.servos import servo_spec

    scenario = load_scenario("phantom_bus")
    spec = servo_spec(scenario.bus.model, torque_control=False)
    inertia = crank_inertia(scenario.robot.build(), spec.name)
    gains = table_position_gains(scenario.bus.position_loop.raw_gains(spec, inertia), spec, 24.0)
    k, r = spec.torque_constant_Nm_per_A, 24.0 / spec.stall_current_A
    lo, hi = gain_range(gains, inertia, k, r)
    assert lo <= GAIN_RANGE[0] and hi >= GAIN_RANGE[1], (lo, hi)
    assert gain_range(gains, inertia, k, r, 1e-3)[0] <= GAIN_RANGE[0]
    assert position_margin_lines(gains, inertia, k, r)[1].startswith("  holds")


def test_analyze_states_the_phantoms_loop_and_refuses_a_budget_it_cannot_simulate(tmp_path, capsys):
    """``analyze --scenario phantom_bus`` prints the servos' loop's range (the figures of the
    test above) and says why there is no error budget; asked for one, it refuses in one line."""
    from stewart_drake.cli import main as cli

    out = tmp_path / "an"
    assert cli.main(["analyze", "--scenario", "phantom_bus", "--out", str(out)]) == 0
    printed = capsys.readouterr().out
    assert "the servos' own loop's margins instead" in printed
    assert "the servos' position loop (1 ms on each servo's encoder): stable for" in printed
    assert "  holds the shipped range 0.5 to 2" in printed
    assert "no error budget: phantom_bus's servos run their own position loop" in printed
    code = cli.main(["analyze", "--scenario", "phantom_bus", "--budget", "breathing"])
    assert code != 0
    assert "--budget: phantom_bus's servos run their own position loop" in capsys.readouterr().err
