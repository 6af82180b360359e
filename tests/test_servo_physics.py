"""The servo's physics (stewart_drake/station/bus/servo_physics.py) worked out by hand: the
friction budget of each model class of Duclusaud et al. (ICRA 2025), the stopping torque, the
drive's current with its back-EMF, the firmware's limits, its P term in whole counts, the
current loop's lag; and the bench's pendulum against its closed forms (the small swing's period,
the energy of a free swing, a shaft held by its friction, the P loop's droop under gravity)."""

import math

import numpy as np
import pytest

from stewart_drake.station.bus import servo_physics as sp
from stewart_drake.station.bus.servo_physics import FRICTION, MODEL_CLASSES, friction_vector

BOTH = [sp, sp.reference]  # compiled, and the Python it compiles


def _f(**terms):
    return friction_vector(terms)


@pytest.mark.parametrize("k", BOTH, ids=["compiled", "python"])
def test_the_budget_of_each_model_class_by_hand(k):
    v, tau_m, tau_e = 0.3, 0.5, -0.2
    s = math.exp(-((0.3 / 2.0) ** 1.5))  # Stribeck at v_s 2 rad/s, alpha 1.5
    shape = dict(stribeck_rad_s=2.0, stribeck_alpha=1.5)
    # M1: K_c + K_v |v|
    assert k.friction_budget(_f(coulomb_Nm=0.1, viscous_Nm_s_per_rad=0.2), v, tau_m, tau_e) == (
        pytest.approx(0.1 + 0.06, rel=1e-12)
    )
    # M2: + S K_cs
    f2 = _f(coulomb_Nm=0.1, stribeck_Nm=0.05, **shape)
    assert k.friction_budget(f2, v, tau_m, tau_e) == pytest.approx(0.1 + s * 0.05, rel=1e-12)
    # M4: (K_l + S K_ls) |tau_m - tau_e| = (0.3 + 0.1 s) 0.7
    f4 = _f(load=0.3, load_stribeck=0.1, **shape)
    assert k.friction_budget(f4, v, tau_m, tau_e) == pytest.approx((0.3 + 0.1 * s) * 0.7)
    # M5: |K_le tau_e - K_lm tau_m| + S |K_les tau_e - K_lms tau_m|
    f5 = _f(load_motor=0.2, load_external=0.4, load_motor_stribeck=0.1, load_external_stribeck=0.5)
    f5[FRICTION["stribeck_rad_s"]], f5[FRICTION["stribeck_alpha"]] = 2.0, 1.5
    want = abs(0.4 * -0.2 - 0.2 * 0.5) + s * abs(0.5 * -0.2 - 0.1 * 0.5)
    assert k.friction_budget(f5, v, tau_m, tau_e) == pytest.approx(want, rel=1e-12)
    # M6: the motor drives against the load (|tau_e| < |tau_m|, opposite signs): S K_qe tau_e^2
    f6 = _f(quad_motor_per_Nm=3.0, quad_external_per_Nm=7.0, **shape)
    assert k.friction_budget(f6, v, tau_m, tau_e) == pytest.approx(s * 7.0 * 0.04, rel=1e-12)
    # the load drives the motor back: S K_qm tau_m^2; both of one sign: nothing
    assert k.friction_budget(f6, v, 0.1, -0.4) == pytest.approx(s * 3.0 * 0.01, rel=1e-12)
    assert k.friction_budget(f6, v, 0.1, 0.4) == 0.0


def test_each_class_names_its_own_terms_and_the_larger_ones_contain_the_smaller():
    for name in MODEL_CLASSES["m1"]:
        assert all(name in MODEL_CLASSES[c] for c in MODEL_CLASSES)
    assert set(MODEL_CLASSES["m2"]) < set(MODEL_CLASSES["m4"])
    assert set(MODEL_CLASSES["m3"]) < set(MODEL_CLASSES["m4"])
    assert set(MODEL_CLASSES["m5"]) < set(MODEL_CLASSES["m6"])
    assert "load" not in MODEL_CLASSES["m5"]  # directional, not the sum's
    assert all(name in FRICTION for c in MODEL_CLASSES.values() for name in c)


@pytest.mark.parametrize("k", BOTH, ids=["compiled", "python"])
def test_the_stopping_torque_holds_within_the_budget_and_no_more(k):
    J, h = 0.01, 1e-3
    # at rest, 0.3 N m pushing, a budget of 0.5: it cancels the push exactly
    assert k.stopping_friction(J, h, 0.0, 0.3, 0.5) == pytest.approx(-0.3)
    # a budget of 0.2: it opposes with all of it
    assert k.stopping_friction(J, h, 0.0, 0.3, 0.2) == pytest.approx(-0.2)
    # moving at 1 rad/s with nothing pushing: stopping takes J v / h = 10 N m; 0.2 is what it has
    assert k.stopping_friction(J, h, 1.0, 0.0, 0.2) == pytest.approx(-0.2)
    assert k.stopping_friction(J, h, -1.0, 0.0, 0.2) == pytest.approx(0.2)
    # slow enough to stop within the step: it stops there, not past it
    assert k.stopping_friction(J, h, 0.01, 0.0, 0.2) == pytest.approx(-0.1)


@pytest.mark.parametrize("k", BOTH, ids=["compiled", "python"])
def test_the_drive_by_hand(k):
    # 12 V at half duty, k 2 V s/rad at 1 rad/s, 5 ohm: (6 - 2) / 5 = 0.8 A
    assert k.pwm_current(0.5, 1.0, 12.0, 2.0, 5.0) == pytest.approx(0.8)
    # limited to 0.5 A: the duty at most (k v + R i) / V = (2 + 2.5) / 12
    assert k.limited_duty(0.5, 1.0, 12.0, 2.0, 5.0, 0.5, 1.0) == pytest.approx(4.5 / 12)
    assert k.limited_duty(-0.5, 1.0, 12.0, 2.0, 5.0, 0.5, 1.0) == pytest.approx(-0.5 / 12)
    # at speed the back-EMF asks more than the supply: the PWM Limit wins (the limit not held)
    assert k.limited_duty(0.1, 7.0, 12.0, 2.0, 5.0, 0.5, 0.9) == pytest.approx(0.9)
    # the P term: 0.1 rad is round(65.19) = 65 counts, 400 / 256 PWM units each, of 885
    assert k.position_duty(0.1, 0.0, 400.0, 4096.0, 256.0, 885.0) == pytest.approx(
        400 / 256 * 65 / 885, rel=1e-12
    )
    # the read in whole counts: half a count of error is none
    c = 2 * math.pi / 4096
    assert k.position_duty(0.4 * c, 0.0, 400.0, 4096.0, 256.0, 885.0) == 0.0


@pytest.mark.parametrize("k", BOTH, ids=["compiled", "python"])
def test_the_current_loop_lags_and_is_bounded_by_its_limit_and_the_supply(k):
    # a step of 1 A through a 2 ms lag, over 1 ms: 1 - e^-0.5
    i = k.current_step(0.0, 1.0, 1e-3, 2e-3, 0.0, 12.0, 2.0, 5.0, 3.0)
    assert i == pytest.approx(1 - math.exp(-0.5), rel=1e-12)
    # no lag: at once; the target beyond the limit: the limit (the supply at rest drives 12 / 2)
    assert k.current_step(0.0, 5.0, 1e-3, 0.0, 0.0, 12.0, 2.0, 2.0, 3.0) == pytest.approx(3.0)
    # at rest with 5 ohm the supply drives at most 12 / 5 = 2.4 A, whatever the limit
    assert k.current_step(0.0, 5.0, 1e-3, 0.0, 0.0, 12.0, 2.0, 5.0, 3.0) == pytest.approx(2.4)
    # at 5 rad/s it drives at most (12 - 10) / 2 = 1 A forward, (-12 - 10) / 2 = -11 A back
    assert k.current_step(0.0, 3.0, 1e-3, 0.0, 5.0, 12.0, 2.0, 2.0, 3.0) == pytest.approx(1.0)
    assert k.current_step(0.0, -3.0, 1e-3, 0.0, 5.0, 12.0, 2.0, 2.0, 3.0) == pytest.approx(-3.0)
    assert k.current_step(0.0, -20.0, 1e-3, 0.0, 5.0, 12.0, 2.0, 2.0, 20.0) == pytest.approx(-11)


# -- the bench's pendulum -------------------------------------------------------------------------

MASS, LENGTH, G = 0.49, 0.1, 9.80665
J_PENDULUM = MASS * LENGTH**2
XL330 = np.array([4096.0, 256.0, 885.0, 1.0, 1.75, sp.POSITION_MODE])


def _swing(t, goal, enabled, q0, drive, f, kp=0.0, h=1e-3, k=sp):
    bench = np.array([J_PENDULUM, MASS * G * LENGTH, 7.4, kp])
    q = np.empty(t.size)
    q[0] = q0
    k.pendulum_rollout(t, goal, enabled, bench, XL330, drive, f, h, q)
    return q


def test_a_free_small_swing_has_the_pendulums_period_and_keeps_its_energy():
    """Torque off, no friction, no rotor: 0.05 rad from rest swings with period 2 pi sqrt(J / (m
    g l)) (the small-angle correction, theta0^2 / 16, is 1.6e-4) and keeps its amplitude
    (semi-implicit Euler keeps a pendulum's energy within O(h))."""
    t = np.arange(0.0, 2.0, 1e-3)
    drive = np.array([0.35, 2.8, 1e-12, 0.0, 0.0])
    q = _swing(t, np.zeros(t.size), np.zeros(t.size, bool), 0.05, drive, friction_vector({}))
    period = 2 * math.pi * math.sqrt(J_PENDULUM / (MASS * G * LENGTH))
    down = np.flatnonzero((q[:-1] > 0) & (q[1:] <= 0))  # crossings of zero, going down
    measured = np.diff(t[down]).mean()
    assert measured == pytest.approx(period * (1 + 0.05**2 / 16), rel=2e-3)
    assert np.max(np.abs(q[t > 1.0])) == pytest.approx(0.05, rel=5e-3)


def test_a_shaft_whose_friction_exceeds_gravity_stays_where_it_is():
    """At 0.2 rad the arm's weight pulls with m g l sin 0.2 = 0.0955 N m: a Coulomb budget of
    0.1 N m holds it exactly; 0.09 lets it go."""
    t = np.arange(0.0, 0.5, 1e-3)
    drive = np.array([0.35, 2.8, 1e-12, 0.0, 0.0])
    off = np.zeros(t.size, bool)
    held = _swing(t, np.zeros(t.size), off, 0.2, drive, friction_vector({"coulomb_Nm": 0.1}))
    assert np.all(held == 0.2)
    slid = _swing(t, np.zeros(t.size), off, 0.2, drive, friction_vector({"coulomb_Nm": 0.09}))
    assert slid[-1] < 0.19


def test_the_firmware_loop_droops_under_gravity_as_its_stiffness_says():
    """The servo holding a goal of 0.5 rad at kp 400: the P term gives k V (kp / 256) (4096 /
    2 pi) / (885 R) N m per rad at rest, so the arm settles where that stiffness times the error
    meets m g l sin q, within a count; the rotor's inertia only slows the way there."""
    k, R, V = 0.35, 2.8, 7.4
    t = np.arange(0.0, 8.0, 1e-3)
    goal = np.full(t.size, 0.5)
    drive = np.array([k, R, 0.002, 0.0, 0.0])
    f = friction_vector({"viscous_Nm_s_per_rad": 0.02})
    q = _swing(t, goal, np.ones(t.size, bool), 0.0, drive, f, kp=400.0)
    stiffness = k * V * (400 / 256) * (4096 / (2 * math.pi)) / (885 * R)
    from scipy.optimize import brentq

    q_rest = brentq(lambda x: stiffness * (0.5 - x) - MASS * G * LENGTH * math.sin(x), 0.0, 0.5)
    count = 2 * math.pi / 4096
    assert abs(q[-1] - q_rest) < 1.5 * count, (q[-1], q_rest)
    assert 0.5 - q[-1] > 10 * count  # the droop is there, many counts of it


def test_the_compiled_rollout_is_its_source_to_the_bit():
    rng = np.random.default_rng(3)
    t = np.cumsum(rng.uniform(3e-3, 6e-3, 400))
    goal = np.sin(2 * t)
    enabled = t < 1.5
    drive = np.array([0.35, 2.8, 0.002, 0.01, 0.0])
    f = friction_vector({n: 0.01 for n in MODEL_CLASSES["m6"]})
    a = _swing(t, goal, enabled, 0.0, drive, f, kp=200.0)
    b = _swing(t, goal, enabled, 0.0, drive, f, kp=200.0, k=sp.reference)
    np.testing.assert_array_equal(a, b)
    assert np.ptp(a) > 0.3  # it moved
