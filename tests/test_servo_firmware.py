"""A DYNAMIXEL's position loop as the emulator's servos would run it
(station/bus/servo_firmware.py): each term worked out by hand, the profile's interpolation, the
anti-windup, and the loop closed on a shaft that sticks, its integral carrying the load where a
PD loop leaves the shaft where the friction holds it."""

import math

import numpy as np
import pytest

from stewart_drake.base.errors import InvalidConfigError
from stewart_drake.station.bus.servo_firmware import (
    PositionFirmware,
    PositionGains,
    position_gains,
)

COUNT = 2 * math.pi / 4096


def gains(**changes) -> PositionGains:
    base = dict(
        p_V_per_rad=200.0,
        i_V_per_rad_s=1000.0,
        d_V_s_per_rad=2.0,
        ff_V_s_per_rad=0.5,
        supply_V=12.0,
        velocity_filter_s=0.0,
        period_s=1e-3,
    )
    return PositionGains(**(base | changes))


def test_the_first_period_is_the_p_term_and_the_integral_one_step_on():
    """A goal 10 counts either way, no profile (a jump: no velocity fed forward), at rest: u =
    200 V/rad x 10 counts,
    the duty u / 12; the integral then 1000 x e x 1e-3, the next period's duty with it."""
    firmware = PositionFirmware(gains(), COUNT, np.zeros(2))
    firmware.set_goal(np.array([10 * COUNT, -10 * COUNT]))
    e = 10 * COUNT
    np.testing.assert_allclose(firmware.duty(np.zeros(2)), [200 * e / 12, -200 * e / 12])
    np.testing.assert_allclose(firmware.integral, [e, -e], rtol=1e-12)
    np.testing.assert_allclose(firmware.duty(np.zeros(2)), [201 * e / 12, -201 * e / 12])


def test_the_profile_interpolates_the_goal_and_feeds_its_rate_forward():
    """A goal 100 counts on at a profile velocity of 20 counts a period: the trajectory moves
    20 counts a period and stops on the goal; while it moves, its rate v_d = 20 counts / ms goes
    through K_D and K_FF (2.5 V s/rad together), with the P term on the 20 counts it leads."""
    firmware = PositionFirmware(gains(i_V_per_rad_s=0.0, supply_V=100.0), COUNT, np.zeros(1))
    firmware.set_goal(np.array([100 * COUNT]), np.array([20 * COUNT / 1e-3]))
    v_d = 20 * COUNT / 1e-3
    u = firmware.duty(np.zeros(1))[0] * 100
    assert u == pytest.approx(200 * 20 * COUNT + 2.5 * v_d, rel=1e-12)
    reads = []
    for k in range(1, 8):
        firmware.duty(np.array([20 * k * COUNT]))
        reads.append(firmware.trajectory[0])
    assert reads == [40, 60, 80, 100, 100, 100, 100]


def test_the_goal_and_the_reading_are_whole_counts():
    """A goal 0.4 count ahead of a reading 0.3 count on is no error at all."""
    firmware = PositionFirmware(gains(), COUNT, np.zeros(1))
    firmware.set_goal(np.array([0.4 * COUNT]))
    assert firmware.duty(np.array([0.3 * COUNT]))[0] == 0.0


def test_the_velocity_estimate_is_the_filtered_count_rate():
    """A reading that advances a count a period: with a 2 ms filter at 1 ms, 1 - e^-0.5 of
    count / h after one period, 1 - e^-1 after two; unfiltered, at once."""
    firmware = PositionFirmware(gains(velocity_filter_s=0.002), COUNT, np.zeros(1))
    rate = COUNT / 1e-3
    firmware.duty(np.array([1.0 * COUNT]))
    assert firmware.v_hat[0] == pytest.approx((1 - math.exp(-0.5)) * rate, rel=1e-12)
    firmware.duty(np.array([2.0 * COUNT]))
    assert firmware.v_hat[0] == pytest.approx((1 - math.exp(-1.0)) * rate, rel=1e-12)
    raw = PositionFirmware(gains(), COUNT, np.zeros(1))
    raw.duty(np.array([3.0 * COUNT]))
    assert raw.v_hat[0] == pytest.approx(3 * rate, rel=1e-12)


@pytest.mark.parametrize("sign", [1, -1])
def test_the_integral_stops_where_the_duty_saturates_and_leaves_at_once(sign):
    """An error far past the supply: the duty held at +-1 and the integral not grown; the
    error reversed, the duty leaves the limit the same period."""
    firmware = PositionFirmware(gains(d_V_s_per_rad=0.0), COUNT, np.zeros(1))
    firmware.set_goal(np.array([sign * 2000 * COUNT]))
    for _ in range(100):
        assert firmware.duty(np.zeros(1))[0] == sign
    assert firmware.integral[0] == 0.0
    firmware.set_goal(np.array([-sign * COUNT]))
    assert 0.0 < -sign * firmware.duty(np.zeros(1))[0] < 1.0


def _shaft(firmware, goal, steps, coulomb_Nm=0.3, k=2.0, R=5.0, J=0.02, load_Nm=0.7):
    """A shaft of inertia J under a constant load and Coulomb friction (sticking below it),
    driven by a motor of k N m/A and R ohm from ``firmware``'s duty of 12 V: its final angle."""
    h = firmware.gains.period_s
    q = v = 0.0
    firmware.set_goal(np.array([goal]))
    for _ in range(steps):
        u = 12.0 * firmware.duty(np.array([q]))[0]
        tau = k * (u - k * v) / R - load_Nm
        if v == 0.0 and abs(tau) <= coulomb_Nm:
            continue
        a = (tau - math.copysign(coulomb_Nm, v if v != 0.0 else tau)) / J
        v_next = v + h * a
        v = 0.0 if v != 0.0 and v_next * v < 0.0 else v_next
        q += h * v
    return q


def test_the_integral_carries_the_load_past_the_friction_where_a_pd_loop_sticks():
    """A shaft that sticks under 0.3 N m of friction and carries 0.7 N m, its goal a whole
    count: with its integral the loop settles within a count of it; without (K_I 0) the P term,
    2 / 5 x 200 = 80 N m/rad at rest, lets the shaft stick wherever the firmware's error e (in
    whole counts) gives |80 e - 0.7| <= 0.3, 5 to 12.5 mrad: short by that, half a count
    either way."""
    goal = 200 * COUNT
    pd = PositionFirmware(gains(i_V_per_rad_s=0.0), COUNT, [0.0])
    short = goal - _shaft(pd, goal, 3000)
    assert 0.005 - COUNT / 2 <= short <= 0.0125 + COUNT / 2
    held = _shaft(PositionFirmware(gains(), COUNT, [0.0]), goal, 3000)
    assert abs(goal - held) <= COUNT


def test_the_gains_place_the_loop_as_said():
    """By hand, on J 0.02, k 2, R 5 at 10 Hz and damping 0.7: K_P = J w^2 R / k; the back-EMF's
    0.8 N m s/rad short of 2 zeta w J = 1.76, K_D makes up the rest; K_I the quarter corner;
    K_FF the back-EMF constant. The closed loop's poles, J s^2 + (k^2 + k K_D) / R s + k K_P /
    R, are then at 10 Hz with damping 0.7; a damping the back-EMF already gives needs no K_D."""
    g = position_gains(0.02, 2.0, 5.0, 12.0, position_hz=10.0, damping=0.7)
    w = 2 * math.pi * 10
    assert g.p_V_per_rad == pytest.approx(0.02 * w * w * 5 / 2, rel=1e-12)
    assert g.d_V_s_per_rad == pytest.approx((2 * 0.7 * w * 0.02 - 0.8) * 5 / 2, rel=1e-12)
    assert g.i_V_per_rad_s == pytest.approx(g.p_V_per_rad * w / 4, rel=1e-12)
    assert g.ff_V_s_per_rad == 2.0 and g.supply_V == 12.0
    poles = np.roots([0.02, (4 + 2 * g.d_V_s_per_rad) / 5, 2 * g.p_V_per_rad / 5])
    assert abs(poles[0]) == pytest.approx(w, rel=1e-9)
    assert -poles[0].real / abs(poles[0]) == pytest.approx(0.7, rel=1e-9)
    assert position_gains(0.02, 2.0, 5.0, 12.0, position_hz=2.0).d_V_s_per_rad == 0.0


@pytest.mark.parametrize(
    "call, words",
    [
        (lambda: position_gains(0.0, 2.0, 5.0, 12.0, 10.0), "inertia_kg_m2"),
        (lambda: position_gains(0.02, 2.0, 0.0, 12.0, 10.0), "resistance_ohm"),
        (lambda: position_gains(0.02, 2.0, 5.0, 12.0, 50.0), "position_hz"),
        (lambda: position_gains(0.02, 2.0, 5.0, 12.0, 10.0, integral_ratio=0.5), "integral"),
        (lambda: gains(p_V_per_rad=-1.0), "p_V_per_rad"),
        (lambda: gains(period_s=0.0), "period_s"),
        (lambda: gains(supply_V=math.nan), "supply_V"),
    ],
)
def test_wrong_gains_are_refused_naming_the_figure(call, words):
    with pytest.raises(InvalidConfigError, match=words):
        call()
