"""The one quintic smoothstep gives, bit for bit, what each of the formulas it replaced gave: the
organ-motion library's (S, S', S'') and its integral, the tuner tasks' tremor fade and the robot
session's homing ramp, at 0, at 1, inside and outside [0, 1]."""

import numpy as np

from stewart_drake.references.smoothstep import smooth_ramp, smoothstep


def inputs() -> np.ndarray:
    """Many x: both ends and their neighbours, -0.0, far outside, and random draws."""
    rng = np.random.default_rng(7)
    ends = np.array([0.0, -0.0, 1.0, 0.5, 1e-300, 1.0 - 2**-53, 1.0 + 2**-52, -1e-300])
    return np.concatenate(
        [
            ends,
            np.nextafter(ends, np.inf),
            np.nextafter(ends, -np.inf),
            rng.random(200_000),
            rng.uniform(-3.0, 4.0, 50_000),
            np.linspace(-1.0, 2.0, 30_001),
            [-1e300, 1e300, -np.inf, np.inf],
        ]
    )


def same_bits(a, b) -> bool:
    a, b = np.asarray(a, dtype=float), np.asarray(b, dtype=float)
    return a.shape == b.shape and a.tobytes() == b.tobytes()


def organ_smoothstep(x):
    """The organ-motion library's formula as it was."""
    x = np.clip(np.asarray(x, dtype=float), 0.0, 1.0)
    return (
        x**3 * (10.0 - 15.0 * x + 6.0 * x * x),
        30.0 * x * x * (1.0 - x) ** 2,
        60.0 * x * (1.0 - x) * (1.0 - 2.0 * x),
    )


def organ_ramp(x):
    """The organ-motion library's integral as it was."""
    x = np.asarray(x, dtype=float)
    c = np.clip(x, 0.0, 1.0)
    S, dS, _ = organ_smoothstep(x)
    return np.where(x > 1.0, x - 0.5, c**4 * (2.5 - 3.0 * c + c * c)), S, dS


def tasks_smoothstep(s, derivative: int = 0):
    """The tuner tasks' formula as it was (called on s clipped to [0, 1])."""
    inside = (s > 0.0) & (s < 1.0)
    if derivative == 0:
        return s**3 * (10 - 15 * s + 6 * s * s)
    if derivative == 1:
        return np.where(inside, 30 * s * s * (1 - s) ** 2, 0.0)
    return np.where(inside, 60 * s * (1 - s) * (1 - 2 * s), 0.0)


def homing_up(s, R):
    """The robot session's rising ramp as it was (s in [0, R])."""
    u = s / R
    return (
        R * u**4 * (2.5 - 3 * u + u * u),
        u**3 * (10 - 15 * u + 6 * u * u),
        (30 * u * u * (1 - u) ** 2 / R),
    )


def test_smoothstep_is_the_organ_motion_formula_bit_for_bit():
    x = inputs()
    for new, old in zip(smoothstep(x), organ_smoothstep(x)):
        assert same_bits(new, old)
    for new, old in zip(smooth_ramp(x), organ_ramp(x)):
        assert same_bits(new, old)
    assert all(np.shape(v) == () for v in smoothstep(0.25))  # a scalar in, scalars out


def test_smoothstep_is_the_tasks_fade_bit_for_bit():
    x = inputs()
    s = np.clip(x, 0.0, 1.0)  # the fade clipped before it called its formula
    S, dS, ddS = smoothstep(x)
    assert same_bits(S, tasks_smoothstep(s, 0))
    assert same_bits(dS, tasks_smoothstep(s, 1))
    # S'' at s = 1 (and at s = -0.0) is -0.0 here and +0.0 there: equal numbers, a zero's
    # sign; every other sample the same bits. The tasks' references (their poses, rates and
    # accelerations, every family) are bit for bit what they were.
    old = tasks_smoothstep(s, 2)
    assert np.array_equal(ddS, old)
    nonzero = old != 0.0
    assert same_bits(ddS[nonzero], old[nonzero]) and np.all(ddS[~nonzero] == 0.0)


def test_smooth_ramp_is_the_homing_ramp_bit_for_bit():
    u = np.clip(inputs(), 0.0, 1.0)  # the homing's ramp runs on [0, R]
    for R in (1.0, 0.37, 2.5, 1e-3):
        s = u * R
        tau, S, dS = smooth_ramp(s / R, scale=R)
        old = homing_up(s, R)
        assert same_bits(tau, old[0]) and same_bits(S, old[1]) and same_bits(dS / R, old[2])


def test_smoothstep_is_c2_and_its_ramp_integrates_it():
    x = np.linspace(-0.5, 1.5, 20_001)
    S, dS, ddS = smoothstep(x)
    assert S[0] == 0.0 and S[-1] == 1.0 and np.all(np.diff(S) >= 0)
    np.testing.assert_allclose(np.gradient(S, x), dS, atol=1e-6)
    np.testing.assert_allclose(np.gradient(dS, x), ddS, atol=2e-3)  # 15 h at the ends
    J = smooth_ramp(x)[0]
    np.testing.assert_allclose(np.gradient(J, x), S, atol=1e-6)
    assert J[-1] == x[-1] - 0.5
