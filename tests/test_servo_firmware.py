"""The DYNAMIXEL-P's position loop as the emulator's servos would run it
(station/bus/servo_firmware.py): each term worked out by hand, the anti-windup, and the cascade
closed on a shaft that sticks, against a P loop that leaves it where the friction holds it."""

import math

import numpy as np
import pytest

from stewart_drake.base.errors import InvalidConfigError
from stewart_drake.station.bus.servo_firmware import CascadeFirmware, CascadeGains, cascade_gains

COUNT = 2 * math.pi / 4096


def gains(**changes) -> CascadeGains:
    base = dict(
        position_per_s=50.0,
        velocity_A_s_per_rad=0.4,
        velocity_integral_A_per_rad=20.0,
        velocity_filter_s=0.0,
        period_s=1e-3,
        current_limit_A=2.0,
    )
    return CascadeGains(**(base | changes))


def test_the_first_period_is_the_p_terms_and_one_step_of_the_integral():
    """Goal 10 counts ahead, at rest: v_cmd = 50 * 10 counts; i = 0.4 v_cmd, the integral
    then 20 v_cmd 1e-3 (the next period's), both by hand."""
    firmware = CascadeFirmware(gains(), COUNT, np.zeros(2))
    i = firmware.current(np.array([10 * COUNT, -10 * COUNT]), np.zeros(2))
    v_cmd = 50.0 * 10 * COUNT
    np.testing.assert_allclose(i, [0.4 * v_cmd, -0.4 * v_cmd], rtol=1e-12)
    np.testing.assert_allclose(firmware.integral, [0.02 * v_cmd, -0.02 * v_cmd], rtol=1e-12)
    again = firmware.current(np.array([10 * COUNT, -10 * COUNT]), np.zeros(2))
    np.testing.assert_allclose(again, [0.42 * v_cmd, -0.42 * v_cmd], rtol=1e-12)


def test_the_goal_and_the_reading_are_whole_counts_and_the_feed_forward_adds():
    """A goal 0.4 count ahead is no error (the table holds whole counts); the feed-forward's
    velocity goes through K_vp and its current adds as it is."""
    firmware = CascadeFirmware(gains(), COUNT, np.zeros(1))
    assert firmware.current(np.array([0.4 * COUNT]), np.array([0.3 * COUNT]))[0] == 0.0
    i = firmware.current(np.zeros(1), np.zeros(1), velocity_ff=0.5, current_ff=0.25)
    assert i[0] == pytest.approx(0.4 * 0.5 + 0.25, rel=1e-12)


def test_the_velocity_estimate_is_the_filtered_count_rate():
    """A reading that advances a count a period: unfiltered, count / h at once; with a 2 ms
    filter at 1 ms, 1 - e^-0.5 of it after one period, 1 - e^-1 after two."""
    firmware = CascadeFirmware(gains(velocity_filter_s=0.002), COUNT, np.zeros(1))
    rate = COUNT / 1e-3
    firmware.current(np.array([1.0 * COUNT]), np.array([1.0 * COUNT]))
    assert firmware.v_hat[0] == pytest.approx((1 - math.exp(-0.5)) * rate, rel=1e-12)
    firmware.current(np.array([2.0 * COUNT]), np.array([2.0 * COUNT]))
    assert firmware.v_hat[0] == pytest.approx((1 - math.exp(-1.0)) * rate, rel=1e-12)
    raw = CascadeFirmware(gains(), COUNT, np.zeros(1))
    raw.current(np.zeros(1), np.array([3.0 * COUNT]))
    assert raw.v_hat[0] == pytest.approx(3 * rate, rel=1e-12)


def test_the_integral_stops_where_the_current_saturates_and_leaves_at_once():
    """An error far past the limit: the current held at +-2 A and the integral not grown at
    all; the error reversed, the current leaves the limit the same period."""
    firmware = CascadeFirmware(gains(), COUNT, np.zeros(1))
    for _ in range(100):
        i = firmware.current(np.array([2000 * COUNT]), np.zeros(1))
        assert i[0] == 2.0
    assert firmware.integral[0] == 0.0
    i = firmware.current(np.array([-1 * COUNT]), np.zeros(1))
    assert -2.0 < i[0] < 0.0
    down = CascadeFirmware(gains(), COUNT, np.zeros(1))
    for _ in range(100):
        assert down.current(np.array([-2000 * COUNT]), np.zeros(1))[0] == -2.0
    assert down.integral[0] == 0.0


def _shaft(firmware, goal, steps, coulomb_Nm=0.3, k=2.0, J=0.02, load_Nm=0.2):
    """A shaft of inertia J under a constant load and Coulomb friction (sticking below it),
    driven at k N m/A by ``firmware`` towards ``goal``: its final angle, rad."""
    h = firmware.gains.period_s
    q = v = 0.0
    for _ in range(steps):
        tau = k * firmware.current(np.array([goal]), np.array([q]))[0] - load_Nm
        if v == 0.0 and abs(tau) <= coulomb_Nm:
            continue
        a = (tau - math.copysign(coulomb_Nm, v if v != 0.0 else tau)) / J
        v_next = v + h * a
        v = 0.0 if v != 0.0 and v_next * v < 0.0 else v_next
        q += h * v
    return q


def test_the_integral_carries_the_load_past_the_friction_where_a_p_loop_sticks():
    """A shaft that sticks under 0.3 N m of friction and carries 0.2 N m: the cascade with its
    integral settles within two counts of the goal; without it (K_vi 0) the P terms, 2 N m/A x
    0.4 x 50 = 40 N m/rad at rest, let the shaft stick wherever |40 e - 0.2| <= 0.3, an error e
    of -2.5 to 12.5 mrad: it stops short, more than two counts off (4.3 mrad here)."""
    goal = 0.3
    p_only = CascadeFirmware(gains(velocity_integral_A_per_rad=0.0), COUNT, [0.0])
    short = goal - _shaft(p_only, goal, 3000)
    assert 2 * COUNT < short <= 0.0125 + COUNT
    held = _shaft(CascadeFirmware(gains(), COUNT, [0.0]), goal, 3000)
    assert abs(goal - held) <= 2 * COUNT


def test_the_gains_place_the_loops_as_said():
    """K_vp = 2 pi f_v J / k, K_vi a quarter-corner, K_pp = 2 pi f_p, by hand; the velocity
    loop of K_vp on J closes at f_v (k K_vp / J = 2 pi f_v)."""
    g = cascade_gains(0.02, 2.0, 1.5, velocity_hz=40.0, position_hz=5.0)
    assert g.velocity_A_s_per_rad == pytest.approx(2 * math.pi * 40 * 0.02 / 2.0, rel=1e-12)
    assert g.velocity_integral_A_per_rad == pytest.approx(
        g.velocity_A_s_per_rad * 2 * math.pi * 40 / 4, rel=1e-12
    )
    assert g.position_per_s == pytest.approx(2 * math.pi * 5, rel=1e-12)
    assert 2.0 * g.velocity_A_s_per_rad / 0.02 == pytest.approx(2 * math.pi * 40, rel=1e-12)
    assert g.current_limit_A == 1.5 and g.period_s == 1e-3


@pytest.mark.parametrize(
    "call, words",
    [
        (lambda: cascade_gains(0.0, 2.0, 1.0), "inertia_kg_m2"),
        (lambda: cascade_gains(0.02, 2.0, 1.0, velocity_hz=5.0, position_hz=8.0), "velocity_hz"),
        (lambda: cascade_gains(0.02, 2.0, 1.0, velocity_hz=400.0), "velocity_hz"),
        (lambda: gains(position_per_s=-1.0), "position_per_s"),
        (lambda: gains(period_s=0.0), "period_s"),
        (lambda: gains(current_limit_A=math.nan), "current_limit_A"),
    ],
)
def test_wrong_gains_are_refused_naming_the_figure(call, words):
    with pytest.raises(InvalidConfigError, match=words):
        call()
