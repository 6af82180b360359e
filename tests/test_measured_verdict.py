"""The verdict of ``stewart-drake verify`` (:mod:`~stewart_drake.verification.measured_verdict`)
held to numbers found here another way: each axis's figures against numpy's own (standard
deviation, least-squares slope, correlation), a dominant period against the known one, each
cause's numbers read back from its words against the same, the sensitivity against its closed
form for sines over whole cycles, and the verdict's line word by word. Unit tests of a fraction
of a second each: tools/mutation.py runs them to mutate the module."""

import math
import re
import warnings
from types import SimpleNamespace

import numpy as np
import pytest
from harmonic_motion import Harmonics, along
from scipy.spatial.transform import Rotation

from stewart_drake.base.signals import dominant_period
from stewart_drake.verification import causes as vc
from stewart_drake.verification.alignment import Frames
from stewart_drake.verification.causes import axis_figures, causes_of, reversed_match
from stewart_drake.verification.measured_motion import MeasuredMotion
from stewart_drake.verification.measured_verdict import (
    Judgement,
    compared_words,
    judge,
    seconds,
)
from stewart_drake.verification.verdict_sensitivity import (
    axis_amount,
    axis_tolerances,
    sensitivity,
    sensitivity_words,
)
from stewart_drake.verification.verify import MeasuredRun

TOLERANCE = (1e-4, math.radians(0.1))
#: A breath along X, 5 mm and a second harmonic (so that it is not its own reversal shifted),
#: every 4 s, about a pose 0.3 m up; sampled at 20 Hz over 8 whole cycles.
MOTION = Harmonics(along("X", 5e-3, 1.5e-3), phase=(0.0, 0.8), centre=(0, 0, 0, 0.01, -0.02, 0.3))
T = 4.0 + 0.05 * np.arange(640)
X_D = MOTION.evaluate(T)[0]
CENTRE = X_D.mean(axis=0)
XYZ = np.array([False] * 3 + [True] * 3)
ALONG_X = np.array([False] * 3 + [True, False, False])

_UNITS = {"mm": 1e-3, "um": 1e-6, "deg": math.pi / 180, "urad": 1e-6, "ms": 1e-3, "s": 1.0}
_AMOUNT = re.compile(r"([-+]?\d+(?:\.\d+)?(?:e[-+]?\d+)?) (mm|um|deg|urad|ms|s)\b")


def amounts(text: str) -> list:
    """The amounts a text gives, in SI (m, rad, s), in order."""
    return [float(v) * _UNITS[u] for v, u in _AMOUNT.findall(text)]


def noisy(x, sigma, seed=0):
    return x + np.random.default_rng(seed).normal(0.0, sigma, x.shape)


def causes(x, moving=ALONG_X, removes_offsets=True, reference=MOTION, measured=XYZ, **kw):
    return causes_of(T, x, X_D, measured, moving, TOLERANCE, removes_offsets, reference, **kw)


# -- small pieces ----------------------------------------------------------------------------------


def test_the_tolerance_of_each_axis_and_amounts_in_words():
    np.testing.assert_array_equal(axis_tolerances((1e-4, 2e-3)), [2e-3] * 3 + [1e-4] * 3)
    assert axis_amount(3, -0.0012) == "1.2 mm" and axis_amount(5, 3e-5) == "30 um"
    assert axis_amount(0, -math.radians(0.5)) == "0.5 deg" and axis_amount(2, 2e-4) == "200 urad"
    assert vc._signed(4, 3e-4) == "+0.3 mm" and vc._signed(3, -1.25e-3) == "-1.25 mm"
    assert vc._signed(1, -math.radians(0.2)) == "-0.2 deg"


@pytest.mark.parametrize(
    "value, text",
    [
        (0.06, "60 ms"),
        (-0.94, "-940 ms"),
        (0.9999, "999.9 ms"),
        (1.0, "1 s"),
        (-1.5, "-1.5 s"),
        (1232.4, "1232 s"),
    ],
)
def test_seconds_in_words(value, text):
    assert seconds(value) == text


def test_the_judgement_as_json_values():
    j = Judgement(False, "FAIL: ...", "m.csv", ["a"], {"X": {"rms": 1.0}}, True, {"s": 1})
    assert j.as_dict() == {
        "verdict": "FAIL",
        "cannot_judge": "",
        "passed": False,
        "line": "FAIL: ...",
        "compared": "m.csv",
        "causes": ["a"],
        "axes": {"X": {"rms": 1.0}},
        "latency_judged": True,
        "sensitivity": {"s": 1},
        "action_level": None,
        "action": {},
    }
    assert Judgement(True, "", "").causes == [] and Judgement(True, "", "").axes == {}
    # The verdict's word: passed with an axis beyond the action level is ACTION, whose JSON
    # gives the level and the axis; not passed it stays FAIL or CANNOT JUDGE.
    action = Judgement(True, "ACTION: ...", "m.csv", action_level=(7e-5, 1e-3), action={"X": 8e-5})
    assert action.verdict == "ACTION" and action.as_dict()["action"] == {"X": 8e-5}
    assert action.as_dict()["action_level"] == [7e-5, 1e-3]
    assert Judgement(True, "", "", action_level=(7e-5, 1e-3)).verdict == "PASS"
    assert Judgement(False, "", "", action={"X": 8e-5}).verdict == "FAIL"
    assert Judgement(False, "", "", cannot_judge="x", action={"X": 8e-5}).verdict == "CANNOT JUDGE"


# -- the figures -----------------------------------------------------------------------------------


def test_the_dominant_period_is_the_sines_between_two_bins():
    t = 0.05 * np.arange(
        700
    )  # 8.33 cycles: the strongest bin is 4.179 s, its neighbours 4.12, 4.24
    v = 0.3 + 2e-3 * np.sin(2 * np.pi * t / 4.2 + 0.4)
    period, share = dominant_period(t, v)
    assert period == pytest.approx(4.2, rel=2e-5)
    assert share == pytest.approx(1.0, abs=0.005)
    # With white noise of half the sine's power, two thirds of the power is the sine's.
    w = v + np.random.default_rng(0).normal(0.0, 1e-3, len(t))
    period, share = dominant_period(t, w)
    assert period == pytest.approx(4.2, rel=2e-3)
    assert share == pytest.approx(2 / 3, abs=0.04)


@pytest.mark.parametrize("size", [1e-6, 5.0])
def test_the_dominant_period_does_not_depend_on_the_motions_size(size):
    t = 0.05 * np.arange(700)
    period, share = dominant_period(t, 0.3 + size * np.sin(2 * np.pi * t / 4.2 + 0.4))
    assert period == pytest.approx(4.2, rel=2e-5) and share == pytest.approx(1.0, abs=0.005)


def test_no_period_without_motion_or_samples():
    t = 0.05 * np.arange(100)
    for v in (np.full(100, 0.3), np.zeros(100)):
        period, share = dominant_period(t, v)
        assert math.isnan(period) and share == 0.0
    # Two samples at the ends, which the window does not see.
    edges = np.zeros(100)
    edges[0], edges[-1] = 1.0, -1.0
    period, share = dominant_period(t, edges)
    assert math.isnan(period) and share == 0.0
    period, share = dominant_period(t[:7], np.sin(t[:7]))
    assert math.isnan(period) and share == 0.0
    assert dominant_period(t[:8], np.sin(2 * np.pi * t[:8] / 0.2))[1] > 0.5


def test_the_figures_of_each_measured_axis_are_numpys():
    x = X_D.copy()
    x[:, 3] = noisy(CENTRE[3] + 1.3 * (X_D[:, 3] - CENTRE[3]) + 2e-4, 3e-4)
    x[:, 5] = noisy(X_D[:, 5], 2e-3, seed=1)  # noise where the reference holds still
    seen = np.array([False, False, False, True, False, True])
    f = axis_figures(T, x, X_D, seen)
    assert list(f) == ["X", "Z"]
    fx = f["X"]
    q, r = x[:, 3], X_D[:, 3]
    assert fx["rms"] == pytest.approx(np.sqrt(np.mean((q - r) ** 2)), rel=1e-12)
    assert fx["motion_rms"] == pytest.approx(np.std(q), rel=1e-12)
    assert fx["reference_rms"] == pytest.approx(np.std(r), rel=1e-12)
    assert fx["gain"] == pytest.approx(np.polyfit(r, q, 1)[0], rel=1e-9)
    assert fx["gain"] == pytest.approx(1.3, abs=0.01)
    assert fx["correlation"] == pytest.approx(np.corrcoef(q, r)[0, 1], rel=1e-12)
    assert fx["mean_error"] == pytest.approx(np.mean(q - r), rel=1e-9)
    assert fx["mean_error"] == pytest.approx(2e-4, abs=3e-5)
    assert fx["period_s"] == pytest.approx(4.0, rel=1e-3)
    assert fx["reference_period_s"] == pytest.approx(4.0, rel=1e-3)
    fz = f["Z"]  # a reference that does not move: no gain, no correlation, no period
    assert math.isnan(fz["gain"]) and math.isnan(fz["correlation"])
    assert math.isnan(fz["period_s"]) and math.isnan(fz["reference_period_s"])
    assert fz["reference_rms"] == 0.0
    assert fz["motion_rms"] == pytest.approx(np.std(x[:, 5]), rel=1e-12)
    # A measured axis at rest: a gain of 0, no correlation.
    still = axis_figures(T, np.tile(X_D[0], (len(T), 1)), X_D, ALONG_X)["X"]
    assert still["gain"] == 0.0 and math.isnan(still["correlation"])


def test_no_dominant_period_where_no_peak_holds_its_share():
    # Five harmonics of equal power: the strongest holds a fifth of it, under the 0.3 named.
    x_d = X_D.copy()
    x_d[:, 3] = CENTRE[3] + 1e-3 * sum(np.sin(2 * np.pi * j * T / 4.0 + j) for j in range(1, 6))
    f = axis_figures(T, x_d, x_d, ALONG_X)["X"]
    assert math.isnan(f["period_s"]) and math.isnan(f["reference_period_s"])
    assert dominant_period(T, x_d[:, 3])[1] == pytest.approx(0.2, abs=0.01)


def test_the_correlation_is_numpys_and_0_for_a_constant():
    a, b = X_D[:, 3], noisy(X_D[:, 3], 2e-3)
    assert vc._correlation(a, b) == pytest.approx(np.corrcoef(a, b)[0, 1], rel=1e-12)
    assert vc._correlation(a, -b) == pytest.approx(-np.corrcoef(a, b)[0, 1], rel=1e-12)
    assert vc._correlation(a, np.full_like(a, 0.3)) == 0.0


# -- the causes ------------------------------------------------------------------------------------


def test_a_phantom_at_rest():
    x = noisy(np.tile(X_D[0], (len(T), 1)), 1e-6)
    (cause,), follows = causes(x)
    assert not follows
    assert re.fullmatch(
        r"the phantom did not move \(X \S+ um RMS against the reference's \S+ mm\)", cause
    )
    moved, ref = amounts(cause)
    assert moved == pytest.approx(np.std(x[:, 3]), rel=0.01)
    assert ref == pytest.approx(np.std(X_D[:, 3]), rel=0.01)
    # Moving a tenth of the reference's motion is not at rest; moving less is, though beyond
    # the tolerance.
    assert causes(CENTRE + 0.08 * (X_D - CENTRE))[0][0].startswith("the phantom did not move")
    assert causes(CENTRE + 0.12 * (X_D - CENTRE)) == (
        ["X moves 0.12x the reference's amplitude"],
        True,
    )
    # An axis the reference holds still moving beyond the tolerance: not at rest.
    x[:, 4] = noisy(x[:, 4], 3e-4, seed=3)
    found, follows = causes(x)
    assert not follows
    assert found[0].startswith("X did not move (") and "where the reference moves" in found[0]
    assert found[1].startswith("Y moves ") and "where the reference holds still" in found[1]


def test_a_phantom_at_rest_names_every_axis_the_reference_moves():
    motion = Harmonics(np.array(along("X", 5e-3)) + along("Z", 2e-3), centre=MOTION.centre)
    x_d = motion.evaluate(T)[0]
    x = np.tile(x_d[0], (len(T), 1))
    moving = np.array([False] * 3 + [True, False, True])
    (cause,), follows = causes_of(T, x, x_d, XYZ, moving, TOLERANCE, True, motion)
    assert follows is False
    assert re.fullmatch(
        r"the phantom did not move \(X 0 um RMS against the reference's \S+ mm, Z 0 um RMS "
        r"against the reference's \S+ mm\)",
        cause,
    )
    assert amounts(cause)[1::2] == pytest.approx([5e-3 / np.sqrt(2), 2e-3 / np.sqrt(2)], rel=0.01)


def test_an_axis_that_did_not_move_where_another_did():
    motion = Harmonics(np.array(along("X", 5e-3)) + along("Y", 2e-3), centre=MOTION.centre)
    x_d = motion.evaluate(T)[0]
    x = x_d.copy()
    x[:, 4] = noisy(np.full(len(T), x_d[0, 4]), 1e-5)
    moving = np.array([False] * 3 + [True, True, False])
    found, follows = causes_of(T, x, x_d, XYZ, moving, TOLERANCE, False, motion)
    assert follows is False
    (cause,) = found
    assert re.fullmatch(r"Y did not move \(\S+ um RMS where the reference moves \S+ mm\)", cause)
    assert amounts(cause) == pytest.approx([np.std(x[:, 4]), 2e-3 / np.sqrt(2)], rel=0.01)


def test_a_reversed_axis():
    x = noisy(2 * CENTRE - X_D, 2e-5)
    for reference in (MOTION, None):
        (cause,), follows = causes(x, reference=reference)
        assert not follows
        assert cause == (
            "X runs the wrong way (correlation -1.00 with the reference, gain -1.00): a sign "
            "flipped or the axis reversed"
        )


def direct_min_score(t, v, r, shifts):
    """The least over ``shifts`` of the mean squared distance between v and the reference's
    axis r(t + d) (a function), each less its mean."""
    scores = []
    for d in shifts:
        e = v - r(t + d)
        scores.append(np.mean((e - e.mean()) ** 2))
    k = int(np.argmin(scores))
    return scores[k], shifts[k]


def test_a_reversed_axis_that_the_clock_shifted_is_found_reversed():
    # Reversed and a second late: the clock's shift made it correlate little with the
    # reference, but reversed it matches it far better, a second on.
    x = noisy(2 * CENTRE - MOTION.evaluate(T + 1.0)[0], 2e-5)
    rho = np.corrcoef(x[:, 3], X_D[:, 3])[0, 1]
    assert -0.5 < rho < 0.5
    shifts = np.arange(-2.0, 2.0 + 1e-9, 0.05)

    def r(times):
        return MOTION.evaluate(times)[0][:, 3]

    as_is, _ = direct_min_score(T, x[:, 3], r, shifts)
    flipped, delta = direct_min_score(T, -x[:, 3], r, shifts)
    ratio, found = reversed_match(T, x[:, 3], 3, MOTION, 2.0)
    assert ratio == pytest.approx(flipped / as_is, rel=1e-3)
    assert found == pytest.approx(delta, abs=1e-9) and delta == pytest.approx(1.0, abs=1e-9)
    (cause,), follows = causes(x, latency_s=0.06)
    assert follows is False
    m = re.fullmatch(
        r"X runs the wrong way \(reversed, it matches the reference (\d+) times better, at a "
        r"latency of -940 ms\): a sign flipped or the axis reversed",
        cause,
    )
    assert m and int(m.group(1)) == pytest.approx(as_is / flipped, rel=1e-3)


@pytest.mark.parametrize("late_s, latency", [(1.0, "-940 ms"), (1.25, "-1.19 s")])
def test_an_exactly_reversed_axis_is_said_so(late_s, latency):
    # Without noise the reversed axis matches to the rounding of the FFT's sums, which left
    # the least mean square a little below zero, or zero: "-5e13 times better", or a division
    # by zero.
    x = 2 * CENTRE - MOTION.evaluate(T + late_s)[0]
    ratio, delta = reversed_match(T, x[:, 3], 3, MOTION, 2.0)
    assert 0.0 <= ratio < 1e-9 and delta == pytest.approx(late_s, abs=1e-9)
    (cause,), follows = causes(x, latency_s=0.06)
    assert not follows
    assert re.fullmatch(
        r"X runs the wrong way \(reversed, it matches the reference (exactly|\d+ times better), "
        rf"at a latency of {latency}\): a sign flipped or the axis reversed",
        cause,
    )


def test_the_latency_of_a_reversed_axis_is_the_one_found_less_its_further_shift():
    x = noisy(2 * CENTRE - MOTION.evaluate(T + 1.0)[0], 2e-5)
    (cause,), _ = causes(x)  # the latency found not given: 0
    assert "at a latency of -1 s)" in cause


@pytest.mark.parametrize(
    "period, late_s, latency",
    [
        (3.0, 1.4, "-1.34 s"),  # within half a period: not 1.6 s the other way
        (3.0, -1.4, "1.46 s"),
        (6.0, 1.9, "-1.84 s"),
    ],
)
def test_a_reversed_axis_is_sought_within_half_a_period_and_2_s(period, late_s, latency):
    motion = Harmonics(MOTION.amplitude, period_s=period, phase=MOTION.phase, centre=MOTION.centre)
    x_d = motion.evaluate(T)[0]
    x = noisy(2 * CENTRE - motion.evaluate(T + late_s)[0], 2e-5)
    found, follows = causes_of(T, x, x_d, XYZ, ALONG_X, TOLERANCE, True, motion, latency_s=0.06)
    assert follows is False
    assert "(reversed, it matches the reference " in found[0]
    assert found[0].endswith(f"at a latency of {latency}): a sign flipped or the axis reversed")


def test_a_motion_matched_as_well_either_way_is_not_reversed():
    ratio, _ = reversed_match(T, X_D[:, 3], 3, MOTION, 2.0)
    assert ratio > 1e6
    x = noisy(np.zeros(len(T)), 1e-3)
    ratio, _ = reversed_match(T, x, 3, MOTION, 2.0)
    assert ratio == pytest.approx(1.0, abs=0.05)


def test_each_axis_the_reference_moves_is_judged():
    motion = Harmonics(
        np.array(along("X", 5e-3, 1.5e-3, 0)) + along("Y", 0, 0, 2e-3),
        phase=(0.0, 0.8, 0.3),
        centre=MOTION.centre,
    )
    x_d = motion.evaluate(T)[0]
    moving = np.array([False] * 3 + [True, True, False])
    c = x_d.mean(axis=0)
    reversed_late = 2 * c[3] - motion.evaluate(T + 1.0)[0][:, 3]
    for first, x_axis in (
        ("still", c[3]),
        ("reversed", 2 * c[3] - x_d[:, 3]),
        ("reversed late", reversed_late),
    ):
        x = x_d.copy()
        x[:, 3] = x_axis
        x[:, 4] = c[4] + 1.3 * (x_d[:, 4] - c[4])
        found, follows = causes_of(T, x, x_d, XYZ, moving, TOLERANCE, True, motion)
        assert follows is False
        assert found[0].startswith("X did not move" if first == "still" else "X runs the wrong way")
        assert ("(reversed, it matches" in found[0]) == (first == "reversed late")
        assert found[1:] == ["Y moves 1.3x the reference's amplitude"]


def test_another_period():
    other = Harmonics(along("X", 5e-3), period_s=5.0, centre=MOTION.centre)
    x = noisy(other.evaluate(T)[0], 2e-5)
    for reference in (MOTION, None):
        (cause,), follows = causes(x, reference=reference)
        assert not follows
        m = re.fullmatch(
            r"X repeats every (\S+) s where the reference does every (\S+) s: another period", cause
        )
        assert m and float(m.group(1)) == pytest.approx(5.0, abs=0.01)
        assert float(m.group(2)) == pytest.approx(4.0, abs=0.01)
    # 4 % off is the same period.
    near = Harmonics(along("X", 5e-3), period_s=4.16, centre=MOTION.centre)
    found, _ = causes(noisy(near.evaluate(T)[0], 2e-5), reference=None)
    assert not any("another period" in c for c in found)


def test_noise_does_not_follow_the_reference():
    x = np.tile(CENTRE, (len(T), 1))
    x[:, 3] = noisy(x[:, 3], 2e-3)
    (cause,), follows = causes(x)
    assert not follows
    m = re.fullmatch(
        r"X does not follow the reference \(correlation ([-+]\d\.\d\d)\): another motion, or noise",
        cause,
    )
    assert m and float(m.group(1)) == pytest.approx(
        np.corrcoef(x[:, 3], X_D[:, 3])[0, 1], abs=0.006
    )


@pytest.mark.parametrize(
    "share, named", [(0.45, False), (0.55, True), (-0.55, True), (-0.45, False)]
)
def test_a_scale_is_named_when_it_alone_takes_half_the_tolerance(share, named):
    # The gain's error alone takes |gain - 1| RMS(X) of the error, named beyond half the
    # tolerance.
    gain = 1.0 + share * TOLERANCE[0] / np.std(X_D[:, 3])
    found, follows = causes(CENTRE + gain * (X_D - CENTRE))
    assert follows
    assert found == ([f"X moves {gain:.3g}x the reference's amplitude"] if named else [])


def test_a_distorted_motion_departs_from_the_shape():
    x = X_D.copy()
    x[:, 3] += 5e-4 * np.sin(2 * np.pi * 3 * T / 4.0)
    (cause,), follows = causes(x)
    assert follows is False
    m = re.fullmatch(
        r"X departs from the reference's shape \((\S+ mm) RMS of it that no scale of the "
        r"reference explains; correlation (0\.\d{3})\): another motion, or the motion distorted",
        cause,
    )
    rho = np.corrcoef(x[:, 3], X_D[:, 3])[0, 1]
    assert m and float(m.group(2)) == pytest.approx(rho, abs=6e-4)
    assert amounts(m.group(1))[0] == pytest.approx(np.std(x[:, 3]) * np.sqrt(1 - rho**2), rel=6e-3)
    # A distortion within the tolerance is not named.
    x[:, 3] = X_D[:, 3] + 1e-4 * np.sin(2 * np.pi * 3 * T / 4.0)
    assert causes(x) == ([], True)


@pytest.mark.parametrize("removes_offsets", [True, False])
def test_an_axis_that_follows_another_of_the_references(removes_offsets):
    x = X_D.copy()
    x[:, 4] = CENTRE[4] + X_D[:, 3] - CENTRE[3]  # Y moves as X does
    (cause,), follows = causes(x, removes_offsets=removes_offsets)
    assert follows
    frame = ", or the tracker's frame turned from the base's" if removes_offsets else ""
    assert re.fullmatch(
        r"Y moves (\S+ mm) RMS where the reference holds still \(it follows the reference's X: "
        rf"axes swapped or mislabelled{frame}\?\)",
        cause,
    )
    assert amounts(cause)[0] == pytest.approx(np.std(X_D[:, 3]), rel=0.01)
    # Following it at less than half its motion is not named as swapped (with the offsets
    # removed, it is a turn of the motion).
    x[:, 4] = CENTRE[4] + 0.4 * (X_D[:, 3] - CENTRE[3])
    (cause,), _ = causes(x, removes_offsets=False)
    assert cause.endswith("RMS where the reference holds still")


def test_an_axis_that_follows_the_references_y():
    motion = Harmonics(np.array(along("Y", 5e-3)) + along("phi", 0.0), centre=MOTION.centre)
    x_d = motion.evaluate(T)[0]
    x = x_d.copy()
    x[:, 3] = x_d[:, 4] - x_d[0, 4] + x_d[0, 3]
    moving = np.array([False] * 4 + [True, False])
    (cause,), _ = causes_of(T, x, x_d, XYZ, moving, TOLERANCE, False, None)
    assert cause.endswith(
        "where the reference holds still (it follows the reference's Y: axes "
        "swapped or mislabelled?)"
    )


def test_a_rotation_where_the_reference_turns_about_no_axis():
    x = X_D.copy()
    x[:, 0] = noisy(x[:, 0], math.radians(0.5))
    (cause,), _ = causes(x, measured=np.ones(6, bool), removes_offsets=False)
    assert re.fullmatch(r"phi moves \S+ deg RMS where the reference holds still", cause)
    assert amounts(cause)[0] == pytest.approx(np.std(x[:, 0]), rel=0.01)


def test_a_rotation_follows_only_the_references_rotations():
    motion = Harmonics(np.array(along("X", 5e-3)) + along("phi", 0.02), centre=MOTION.centre)
    x_d = motion.evaluate(T)[0]
    x = x_d.copy()
    x[:, 1] = x_d[:, 0]  # theta moves as phi does; Y as X does
    x[:, 4] = x_d[:, 3] - x_d[0, 3]
    moving = np.array([True, False, False, True, False, False])
    found, _ = causes_of(T, x, x_d, np.ones(6, bool), moving, TOLERANCE, False, None)
    assert [c.split(" (it follows ")[1] for c in found[:2]] == [
        "the reference's phi: axes swapped or mislabelled?)",
        "the reference's X: axes swapped or mislabelled?)",
    ]


def test_a_marker_off_the_platform_shows_a_platform_that_does_not_turn_as_motion():
    motion = Harmonics(np.array(along("X", 5e-3)) + along("phi", 0.02), centre=MOTION.centre)
    x_d = motion.evaluate(T)[0]
    x = x_d.copy()
    x[:, 5] = noisy(x_d[:, 5], 3e-4, seed=4)
    moving = np.array([True, False, False, True, False, False])
    (cause,), _ = causes_of(T, x, x_d, XYZ, moving, TOLERANCE, False, None, lever_m=0.05)
    assert cause.endswith(
        "RMS where the reference holds still (the marker, 50 mm from the platform's origin, is "
        "taken off along the reference's rotation: a platform that does not turn as asked "
        "shows that lever arm as motion)"
    )
    # Without a lever, or a reference that does not turn, the motion is named alone.
    (cause,), _ = causes_of(T, x, x_d, XYZ, moving, TOLERANCE, False, None)
    assert cause.endswith("mm RMS where the reference holds still")
    (cause,), _ = causes(
        noisy(X_D, 3e-4, seed=4) * [1, 1, 1, 0, 0, 1] + X_D * [0, 0, 0, 1, 1, 0],
        removes_offsets=False,
        lever_m=0.05,
    )
    assert cause.endswith("mm RMS where the reference holds still")


def test_a_constant_offset_is_named_where_the_frames_keep_it():
    x = X_D.copy()
    x[:, 4] += 3e-4
    x[:, 3] -= 6e-5
    x[:, 5] += 4e-5  # under half the tolerance: not named
    assert causes(x, removes_offsets=False) == (
        [
            "a constant offset of X -0.06 mm, Y +0.3 mm (the phantom set down off its place or "
            "tilted, or a registration out of date)"
        ],
        True,
    )
    assert causes(x, removes_offsets=True) == ([], True)
    rotated = np.ones(6, bool)
    x[:, 1] += math.radians(0.2)
    found, _ = causes_of(T, x, X_D, rotated, ALONG_X, TOLERANCE, False, None)
    assert found[-1].startswith("a constant offset of theta +0.2 deg, X -0.06 mm, Y +0.3 mm")


def turned(x, angle_deg, axis):
    """The translations of the poses x (n, 6) turned by angle_deg about axis, about the origin."""
    out = x.copy()
    out[:, 3:] = Rotation.from_rotvec(math.radians(angle_deg) * np.asarray(axis)).apply(x[:, 3:])
    return out


def test_a_turned_motion_is_named_with_its_turn():
    motion = Harmonics(
        np.array(along("X", 5e-3, 0.0, 0.0)) + along("Y", 0.0, 3e-3, 0.0) + along("Z", 0, 0, 2e-3),
        phase=(0.0, 0.5, 1.0),
        centre=MOTION.centre,
    )
    x_d = motion.evaluate(T)[0]
    moving = np.array([False] * 3 + [True] * 3)
    x = turned(x_d, 12.3, (0.2, -0.3, 0.9) / np.linalg.norm((0.2, -0.3, 0.9)))
    (cause,), follows = causes_of(T, x, x_d, XYZ, moving, TOLERANCE, True, motion)
    assert follows
    m = re.fullmatch(
        r"the measured motion is turned (\S+) deg from the reference's \(turned back, it comes "
        r"within (\S+ \S+) RMS of it, against (\S+ mm)\): the tracker's axes are not the base "
        r"frame's, or the whole phantom is set down tilted; register the tracker "
        r"\(--registration REG.yaml, from fiducials or calibrate --register\) to tell them apart",
        cause,
    )
    assert m and float(m.group(1)) == pytest.approx(12.3, abs=0.05)
    q = x[:, 3:] - x[:, 3:].mean(axis=0)
    r = x_d[:, 3:] - x_d[:, 3:].mean(axis=0)
    before = np.sqrt(np.mean(np.sum((q - r) ** 2, axis=1)))
    assert amounts(m.group(3))[0] == pytest.approx(before, rel=6e-3)
    assert amounts(m.group(2))[0] < 0.01 * before  # turned back, it is the reference
    # The frames that keep offsets do not look for it.
    found, _ = causes_of(T, x, x_d, XYZ, moving, TOLERANCE, False, motion)
    assert not any("turned" in c for c in found)


@pytest.mark.parametrize("angle, named", [(135.0, True), (180.0, False)])
def test_a_motion_along_one_line_turned_beyond_60_deg_is_named_beside_its_axes(angle, named):
    """The motion along X (MOTION) turned about Z: at 135 deg X runs the wrong way and Y moves
    where the reference holds still; each axis's words name neither the whole, so the turn is
    named beside them. At 180 deg X reversed is the whole story (nothing else moves): the turn
    is not repeated. Was: the 135 deg turn went unnamed (X's reversal taken for all of it)."""
    x = turned(X_D, angle, (0.0, 0.0, 1.0))
    moving = np.array([False] * 3 + [True, False, False])
    causes, _ = causes_of(T, x, X_D, XYZ, moving, TOLERANCE, True, MOTION)
    assert any(c.startswith("X runs the wrong way") for c in causes), causes
    assert any(c.startswith("Y moves") for c in causes) == named
    turn = [c for c in causes if c.startswith("the measured motion is turned ")]
    assert bool(turn) == named, causes
    if named:
        assert float(turn[0].split("turned ")[1].split(" deg")[0]) == pytest.approx(135, abs=0.5)


@pytest.mark.parametrize(
    "angle, named",
    [
        (0.8, False),
        (1.5, True),
        (55.0, True),
        (65.0, True),
        (90.0, True),
        (135.0, True),
        (170.0, True),
    ],
)
def test_a_turn_is_named_from_1_deg_at_any_angle(angle, named):
    x = turned(X_D, angle, (0.0, 0.0, 1.0))
    # Beyond 60 deg a turn is named only when, turned back, the motion is within the tolerance
    # (here 20 um, a least-squares turn's own error on a motion along one line is a few um).
    found, _ = vc._turned_axes(x, X_D, XYZ, (2e-5, 1.0))
    assert (found is not None) == named
    if named:
        assert float(found.split("turned ")[1].split(" deg")[0]) == pytest.approx(angle, rel=2e-3)
        # Beyond 60 deg a quarter or half turn is also an axis swapped or reversed: said so.
        assert ("a quarter or half turn" in found) == (angle > 60.0)


def test_a_turn_is_named_only_when_turning_back_explains_the_motion():
    # Turned 5 deg and noisy: turned back, the motion is not within a quarter of its distance,
    # but it is within the tolerance of each axis, or not.
    x = noisy(turned(X_D, 5.0, (0.0, 0.0, 1.0)), 2e-4, seed=2)
    assert vc._turned_axes(x, X_D, XYZ, (3e-4, 1.0))[0] is not None
    assert vc._turned_axes(x, X_D, XYZ, (1.5e-4, 1.0))[0] is None
    assert vc._turned_axes(x, X_D, ALONG_X, (3e-4, 1.0))[0] is None  # one translation measured
    # Within the tolerance on every axis, not on their mean: X beyond it, Y and Z well within.
    x = turned(X_D, 5.0, (0.0, 0.0, 1.0))
    x[:, 3] = noisy(x[:, 3], 3e-4, seed=5)
    assert vc._turned_axes(x, X_D, XYZ, (2.5e-4, 1.0))[0] is None
    assert vc._turned_axes(x, X_D, XYZ, (3.5e-4, 1.0))[0] is not None
    two = np.array([False] * 3 + [True, True, False])
    assert vc._turned_axes(x, X_D, two, (3e-4, 1.0))[0] is not None


# -- the sensitivity -------------------------------------------------------------------------------

#: A sine on X, Z and phi about a pose 0.3 m up; over whole cycles its standard deviation is its
#: amplitude over sqrt(2) and its mean the centre.
A = np.array([0.01, 0.0, 0.0, 4e-3, 0.0, 1.5e-3])
C = np.array([0.0, 0.0, 0.0, 0.02, -0.01, 0.3])
T_S = 0.05 * np.arange(400)
SINE = C + A * np.sin(2 * np.pi * T_S / 4.0)[:, None]


def tilt_closed_form(measured, removes_offsets):
    """(tilt, about, axis) from the closed form: a tilt a about u moves p by a u x p (its
    constant part u x C, its sine u x A), and turns the platform by a u."""
    tol = np.array([TOLERANCE[1]] * 3 + [TOLERANCE[0]] * 3)
    best = (math.inf, "", "")
    for name, u in zip("XYZ", np.eye(3)):
        const, sine = np.cross(u, C[3:]), np.cross(u, A[3:])
        for k in np.flatnonzero(measured):
            if k >= 3:
                rms = abs(sine[k - 3]) / math.sqrt(2)
                if not removes_offsets:
                    rms = math.hypot(const[k - 3], rms)
            else:
                rms = 0.0 if removes_offsets else abs(u[k])
            if rms > 0 and tol[k] / rms < best[0]:
                best = (tol[k] / rms, name, "phi theta psi X Y Z".split()[k])
    return best


@pytest.mark.parametrize("removes_offsets", [True, False])
@pytest.mark.parametrize(
    "measured",
    [np.ones(6, bool), XYZ, np.array([True, False, False, False, False, True]), ALONG_X],
    ids=["6-DoF", "XYZ", "phi and Z", "X"],
)
def test_the_sensitivity_is_its_closed_form(measured, removes_offsets):
    s = sensitivity(T_S, SINE, measured, TOLERANCE, removes_offsets)
    tol = np.array([TOLERANCE[1]] * 3 + [TOLERANCE[0]] * 3)
    ratios = {k: tol[k] / (A[k] / math.sqrt(2)) for k in np.flatnonzero(measured) if A[k]}
    k = min(ratios, key=ratios.get)
    assert s["amplitude_fraction"] == pytest.approx(ratios[k], rel=1e-9)
    assert s["amplitude_axis"] == "phi theta psi X Y Z".split()[k]
    tilt, about, axis = tilt_closed_form(measured, removes_offsets)
    assert s["tilt_rad"] == pytest.approx(tilt, rel=1e-9)
    assert (s["tilt_about"], s["tilt_axis"]) == (about, axis)


def test_the_sensitivity_of_axes_that_do_not_move():
    still = np.tile(C, (len(T_S), 1))
    still[:, 4] += 5e-6 * np.sin(2 * np.pi * T_S / 4.0)  # under the 10 um that moves
    s = sensitivity(T_S, still, XYZ, TOLERANCE, True)
    assert math.isnan(s["amplitude_fraction"]) and s["amplitude_axis"] == ""
    # A tilt moves the still pose only by a constant, which the offsets take away.
    assert math.isnan(s["tilt_rad"])
    s = sensitivity(T_S, np.zeros((len(T_S), 6)), np.ones(6, bool), TOLERANCE, True)
    assert math.isnan(s["tilt_rad"]) and s["tilt_about"] == "" and s["tilt_axis"] == ""
    with warnings.catch_warnings():  # an axis that does not move divides nothing by zero
        warnings.simplefilter("error")
        sensitivity(T_S, np.zeros((len(T_S), 6)), XYZ, TOLERANCE, False)
    # Kept, the constant shows: 0.3 m up, a tilt about X moves Y by 0.3 m per rad.
    s = sensitivity(T_S, still, XYZ, TOLERANCE, False)
    assert s["tilt_rad"] == pytest.approx(1e-4 / 0.3, rel=1e-9)
    assert s["tilt_about"] == "X" and s["tilt_axis"] == "Y"


def test_a_tilt_beyond_60_deg_is_not_one_the_check_sees():
    s = sensitivity(T_S, SINE, XYZ, (0.01, 1.0), True)
    assert math.isnan(s["tilt_rad"])
    s = sensitivity(T_S, SINE, XYZ, (3e-3, 1.0), True)  # 3 mm over 2.83 mm: 1.06 rad, 61 deg
    assert math.isnan(s["tilt_rad"])
    s = sensitivity(T_S, SINE, XYZ, (2.8e-3, 1.0), True)  # 56.7 deg
    assert s["tilt_rad"] == pytest.approx(2.8e-3 / (4e-3 / math.sqrt(2)), rel=1e-9)


def test_the_sensitivity_in_words():
    s = {
        "amplitude_fraction": 0.02834,
        "amplitude_axis": "X",
        "tilt_rad": math.radians(0.5),
        "tilt_about": "Y",
        "tilt_axis": "Z",
    }
    assert sensitivity_words(s) == (
        "this check fails a scale of the whole motion off by 2.83 % or more (on X) and a tilt of "
        "the whole phantom of 0.5 deg or more about the base's Y (on Z); smaller ones pass"
    )
    assert sensitivity_words({**s, "tilt_rad": math.nan}) == (
        "this check fails a scale of the whole motion off by 2.83 % or more (on X); smaller ones "
        "pass"
    )
    assert sensitivity_words({**s, "amplitude_fraction": math.nan}) == (
        "this check fails a tilt of the whole phantom of 0.5 deg or more about the base's Y (on "
        "Z); smaller ones pass"
    )
    none = {"amplitude_fraction": math.nan, "amplitude_axis": ""}
    assert sensitivity_words(none) == (
        "this check sees no scale or tilt error: the reference moves along no axis measured"
    )


# -- the verdict -----------------------------------------------------------------------------------


def verification(
    x,
    rms,
    how="axes",
    clock="given (--clock-offset)",
    latency_s=0.06,
    shift_s=-0.06,
    searched_s=(-1.5, 1.5),
    measured=XYZ,
    moving=("X",),
    window=(6.0, 34.0),
):
    """What :func:`judge` reads of a verification: the measured x (n, 6) at T over X_D, the
    figures' RMS per axis (6,) and window, the clocks and the frames."""
    frame = Frames(how) if how != "registration" else Frames(how, p_EM=np.array([0.0, 0.03, 0.04]))
    return SimpleNamespace(
        name="harmonics",
        reference=MOTION,
        measured=MeasuredMotion("/data/m.csv", "tracker", T, x, measured),
        result=MeasuredRun(T, x, X_D),
        fidelity={"rms": list(rms), "window_s": window, "moving": list(moving)},
        clock=clock,
        latency_s=latency_s,
        shift_s=shift_s,
        searched_s=searched_s,
        max_latency_s=0.5,
        frame=frame,
    )


def test_a_pass_names_what_it_compared_and_its_figures_over_the_window():
    x = noisy(X_D, 5e-5) * np.r_[np.nan, np.nan, np.nan, 1, 1, 1]
    x[T > 34.0 + 1e-6, 3] += 0.1  # outside the window: not judged
    ver = verification(x, [math.nan] * 3 + [5e-5, 7e-5, 6e-5])
    j = judge(ver, TOLERANCE)
    assert j.passed and j.causes == [] and j.latency_judged
    assert j.compared == "m.csv (X, Y, Z; each axis's offset removed) against harmonics"
    assert j.line == (
        "PASS: m.csv (X, Y, Z; each axis's offset removed) against harmonics: RMS error per axis "
        "within 0.1 mm | 0.1 deg over t = 6-34 s (largest: Y 70 um, rotation not measured); "
        "latency 60 ms within 500 ms"
    )
    inside = (T >= 6.0) & (T <= 34.0)
    assert T[inside][0] == pytest.approx(6.0) and T[inside][-1] == pytest.approx(34.0)
    assert list(j.axes) == ["X", "Y", "Z"]
    q = x[inside, 3]
    assert j.axes["X"]["rms"] == pytest.approx(np.sqrt(np.mean((q - X_D[inside, 3]) ** 2)))
    assert j.axes["X"]["motion_rms"] == pytest.approx(np.std(q), rel=1e-12)
    assert j.sensitivity["amplitude_fraction"] == pytest.approx(
        1e-4 / np.std(X_D[inside, 3]), rel=1e-12
    )
    # Its offsets removed, a tilt about Y or Z shows as the breath's motion across it.
    assert j.sensitivity["tilt_rad"] == pytest.approx(1e-4 / np.std(X_D[inside, 3]), rel=1e-9)
    assert j.as_dict()["passed"] is True


def test_a_pass_beyond_the_action_level_is_action_on_its_line():
    """The same PASS (X 50, Y 70, Z 60 um) with an action level of 65 um: Y alone is beyond
    it, so the verdict is ACTION, its line saying which axis and by how much; at 70 um exactly
    it stays PASS; a FAIL stays FAIL whatever the action level."""
    x = noisy(X_D, 5e-5) * np.r_[np.nan, np.nan, np.nan, 1, 1, 1]
    ver = verification(x, [math.nan] * 3 + [5e-5, 7e-5, 6e-5])
    j = judge(ver, TOLERANCE, (6.5e-5, math.radians(0.05)))
    assert j.passed and j.verdict == "ACTION" and j.action == {"Y": 7e-5}
    assert j.action_level == (6.5e-5, math.radians(0.05))
    assert j.line == (
        "ACTION: m.csv (X, Y, Z; each axis's offset removed) against harmonics: RMS error per "
        "axis within 0.1 mm | 0.1 deg over t = 6-34 s (largest: Y 70 um, rotation not "
        "measured); latency 60 ms within 500 ms; beyond the action level 65 um | 873 urad: Y 70 "
        "um (within the tolerance: to be looked at before it fails)"
    )
    at = judge(ver, TOLERANCE, (7e-5, math.radians(0.05)))
    assert at.verdict == "PASS" and at.action == {} and at.line.startswith("PASS: ")
    failing = verification(x, [math.nan] * 3 + [5e-5, 1.1e-4, 6e-5])
    f = judge(failing, TOLERANCE, (6.5e-5, math.radians(0.05)))
    assert f.verdict == "FAIL" and f.action == {} and "action level" not in f.line


def test_an_axis_beyond_the_tolerance_fails_with_its_causes():
    x = CENTRE + 1.3 * (X_D - CENTRE)
    x[:, :3] = np.nan
    rms = [math.nan] * 3 + [1.2e-3, 0.0, 0.0]
    j = judge(verification(x, rms), TOLERANCE)
    assert not j.passed
    assert j.causes == ["X moves 1.3x the reference's amplitude"]
    assert j.line == (
        "FAIL: m.csv (X, Y, Z; each axis's offset removed) against harmonics: RMS error per axis "
        "beyond 0.1 mm | 0.1 deg over t = 6-34 s (largest: X 1.2 mm, rotation not measured); "
        "latency 60 ms within 500 ms; cause: X moves 1.3x the reference's amplitude"
    )
    # At the tolerance it passes.
    assert judge(verification(x, [math.nan] * 3 + [1e-4, 0, 0]), TOLERANCE).passed


def test_a_failure_no_cause_explains_is_the_motions_shape():
    rms = [math.nan] * 3 + [2e-4, 0.0, 0.0]
    j = judge(verification(X_D.copy(), rms), TOLERANCE)
    assert not j.passed
    assert j.causes == [
        "no offset, scale, sign, axis, period or latency explains it: the motion departs from "
        "the reference in its shape"
    ]


def test_a_failure_of_the_figures_and_the_latency_says_both():
    rms = [math.nan] * 3 + [2e-4, 0.0, 0.0]
    j = judge(verification(X_D.copy(), rms, latency_s=0.7, shift_s=-0.7), TOLERANCE)
    shape = (
        "no offset, scale, sign, axis, period or latency explains it: the motion departs from "
        "the reference in its shape"
    )
    latency = "latency 700 ms beyond --max-latency 500 ms"
    assert j.causes == [shape, latency]
    assert j.line.endswith(f"; cause: {shape}; {latency}")


def test_the_verdict_looks_for_a_turn_a_reversal_and_a_lever_as_its_frames_say():
    # A turned tracker, in the base's axes: named as a turn.
    x = X_D.copy()
    q = X_D[:, 3] - CENTRE[3]
    x[:, 3], x[:, 4] = CENTRE[3] + q * math.cos(0.2), CENTRE[4] + q * math.sin(0.2)
    rms = [math.nan] * 3 + [2e-4, 5e-4, 0.0]
    (cause,) = judge(verification(x, rms), TOLERANCE).causes
    turn = re.match(r"the measured motion is turned (\S+) deg from the reference's", cause)
    assert turn and float(turn.group(1)) == pytest.approx(math.degrees(0.2), abs=0.1)
    # Reversed a second late: found reversed, at the latency found less that second.
    x = noisy(2 * CENTRE - MOTION.evaluate(T + 1.0)[0], 2e-5)
    (cause,) = judge(verification(x, [math.nan] * 3 + [5e-3, 0, 0]), TOLERANCE).causes
    assert cause.startswith("X runs the wrong way (reversed, it matches the reference ")
    assert "at a latency of -940 ms)" in cause
    # A registered marker 50 mm off the platform whose reference turns.
    x = X_D.copy()
    x[:, 5] = noisy(x[:, 5], 3e-4, seed=4)
    rms = [math.nan] * 3 + [0.0, 0.0, 3e-4]
    ver = verification(x, rms, how="registration", moving=("theta", "X"))
    (cause,) = judge(ver, TOLERANCE).causes
    assert "(the marker, 50 mm from the platform's origin, is taken off along" in cause


def test_the_latency_beyond_its_bound_fails_alone_and_at_the_edge_says_at_least():
    rms = [math.nan] * 3 + [5e-5, 5e-5, 5e-5]
    j = judge(verification(X_D, rms, latency_s=0.7, shift_s=-0.7), TOLERANCE)
    assert not j.passed and j.latency_judged
    assert j.causes == ["latency 700 ms beyond --max-latency 500 ms"]
    assert j.line.endswith(
        "(largest: X 50 um, rotation not measured); latency 700 ms beyond 500 ms; cause: latency "
        "700 ms beyond --max-latency 500 ms"
    )
    j = judge(verification(X_D, rms, latency_s=1.47, shift_s=-1.47), TOLERANCE)
    assert j.causes == [
        "latency at least 1.47 s beyond --max-latency 500 ms (at the edge of the shifts searched)"
    ]
    j = judge(verification(X_D, rms, latency_s=-1.46, shift_s=1.46), TOLERANCE)
    assert j.causes[0].startswith("latency at least -1.46 s beyond")
    j = judge(verification(X_D, rms, latency_s=-1.44, shift_s=1.44), TOLERANCE)
    assert j.causes == ["latency -1.44 s beyond --max-latency 500 ms"]
    # Within the bound, either way.
    assert judge(verification(X_D, rms, latency_s=-0.5, shift_s=0.5), TOLERANCE).passed


def test_the_latency_of_a_motion_that_does_not_follow_means_nothing():
    x = noisy(np.tile(X_D[0], (len(T), 1)), 1e-6)
    rms = [math.nan] * 3 + [3.7e-3, 1e-6, 1e-6]
    j = judge(verification(x, rms, latency_s=0.9, shift_s=-0.9), TOLERANCE)
    assert j.causes[1] == (
        "latency 900 ms beyond --max-latency 500 ms, of no meaning while the above holds"
    )
    assert "; latency 900 ms of no meaning (the motion does not follow); cause: " in j.line
    j = judge(verification(x, rms), TOLERANCE)
    assert len(j.causes) == 1 and "latency 60 ms of no meaning" in j.line


def test_without_the_clocks_relation_the_latency_is_not_judged():
    rms = [math.nan] * 3 + [5e-5, 5e-5, 5e-5]
    j = judge(verification(X_D, rms, clock="not known", latency_s=121.0), TOLERANCE)
    assert j.passed and not j.latency_judged
    assert j.line.endswith("; latency not judged (the clocks' relation not given)")


def test_the_largest_error_of_each_kind_and_the_rotations_tolerance():
    rms = [2e-3, 1e-3, 1.5e-3, 5e-5, 8e-5, 2e-5]
    x = X_D.copy()
    j = judge(verification(x, rms, how="encoders", measured=np.ones(6, bool)), TOLERANCE)
    assert not j.passed  # phi's 0.115 deg is beyond 0.1 deg
    assert "(largest: Y 80 um, phi 0.115 deg);" in j.line
    assert j.line.startswith("FAIL: m.csv (phi, theta, psi, X, Y, Z; the encoders' pose) against")
    rms[0] = 1.7e-3
    assert judge(verification(x, rms, how="encoders", measured=np.ones(6, bool)), TOLERANCE).passed
    only_phi = np.array([True] + [False] * 5)
    line = judge(verification(x, rms, how="base", measured=only_phi), TOLERANCE).line
    assert "(largest: translation not measured, phi 0.0974 deg);" in line


def test_the_axes_not_measured_are_judged_against_themselves():
    # NaN on Y and Z: their figures compare the reference with itself.
    x = X_D.copy()
    x[:, 4:] = np.nan
    j = judge(verification(x, [math.nan] * 3 + [0.0, 0.0, 0.0]), TOLERANCE)
    assert j.passed and j.axes["Y"]["rms"] == 0.0 and j.axes["Z"]["motion_rms"] == 0.0


@pytest.mark.parametrize(
    "how, words",
    [
        ("axes", "each axis's offset removed"),
        ("base", "in the base frame as given"),
        ("registration", "registered to the base frame"),
        ("encoders", "the encoders' pose"),
    ],
)
def test_what_was_compared_in_words(how, words):
    ver = verification(X_D, [0.0] * 6, how=how, measured=np.array([0, 1, 0, 1, 0, 1], bool))
    assert compared_words(ver) == f"m.csv (theta, X, Z; {words}) against harmonics"


def test_the_frames_that_keep_offsets_judge_them_and_a_lever_is_named():
    x = X_D.copy()
    x[:, 4] += 3e-4
    rms = [math.nan] * 3 + [0.0, 3e-4, 0.0]
    j = judge(verification(x, rms, how="base"), TOLERANCE)
    assert j.causes == [
        "a constant offset of Y +0.3 mm (the phantom set down off its place or tilted, or a "
        "registration out of date)"
    ]
    assert math.isnan(j.sensitivity["tilt_rad"]) is False
    assert j.sensitivity["tilt_rad"] == pytest.approx(1e-4 / np.sqrt(0.3**2 + 0.01**2), rel=1e-3)


def _unseen_motion(phi_rms, x_rms, y_rms):
    """(400, 6) a reference moving phi, X and Y by these RMS about its mean (whole sine cycles)
    and Z by 5 mm, which the checks below do not measure."""
    t = np.linspace(0.0, 1.0, 400, endpoint=False)
    s, c = np.sqrt(2) * np.sin(2 * np.pi * t), np.sqrt(2) * np.cos(2 * np.pi * t)
    x = np.zeros((400, 6))
    x[:, 0], x[:, 3], x[:, 4] = phi_rms * s, x_rms * s, y_rms * c
    x[:, 5] = 0.3 + 5e-3 * s
    return x


def test_a_motion_within_the_tolerance_on_every_axis_measured_cannot_be_judged():
    """The phantom at rest errs by the reference's RMS about its mean: within the tolerance
    on every measured axis (phi 0.5 mrad of 1, X 50 um and Y 80 um of 0.1 mm; Z's 5 mm not
    measured), the line says so, naming each axis's RMS and the axis nearest its tolerance (Y,
    0.8 of it; phi when it is 0.95 of its own)."""
    from stewart_drake.verification.verdict_sensitivity import motion_unseen

    measured = [True, False, False, True, True, False]
    words = motion_unseen(_unseen_motion(5e-4, 5e-5, 8e-5), measured, (1e-4, 1e-3))
    assert words == (
        "cannot judge: the phantom at rest would pass too (the reference moves phi 500 urad, "
        "X 50 um, Y 80 um RMS on the axes measured, each within the tolerance): judge at a "
        "tolerance below Y's 80 um, or on a larger motion"
    )
    words = motion_unseen(_unseen_motion(9.5e-4, 5e-5, 8e-5), measured, (1e-4, 1e-3))
    assert words.endswith("judge at a tolerance below phi's 950 urad, or on a larger motion")
    # One measured axis beyond its tolerance: the check can tell the motion from none.
    assert motion_unseen(_unseen_motion(5e-4, 1.1e-4, 8e-5), measured, (1e-4, 1e-3)) == ""
    assert motion_unseen(_unseen_motion(1.1e-3, 5e-5, 8e-5), measured, (1e-4, 1e-3)) == ""
    # Z measured too (5 mm): it can; no axis measured: nothing to say.
    assert motion_unseen(_unseen_motion(5e-4, 5e-5, 8e-5), [True] * 6, (1e-4, 1e-3)) == ""
    assert motion_unseen(_unseen_motion(5e-4, 5e-5, 8e-5), [False] * 6, (1e-4, 1e-3)) == ""


def test_a_motion_exactly_at_the_tolerance_cannot_be_judged():
    """At rest the phantom errs by exactly the tolerance (X alternating +-2^-13 m about 0, its
    RMS 2^-13 m to the bit, the tolerance the same): within it, so it would pass."""
    from stewart_drake.verification.verdict_sensitivity import motion_unseen

    x = np.zeros((400, 6))
    x[:, 3] = 2.0**-13 * np.tile([1.0, -1.0], 200)
    assert np.std(x[:, 3]) == 2.0**-13
    words = motion_unseen(x, [False, False, False, True, False, False], (2.0**-13, 1e-3))
    assert words.startswith("cannot judge") and "below X's 0.122 mm" in words


def test_the_sensitivity_counts_an_axis_by_its_own_thresholds():
    """Which axis the scale is shown on and whether a tilt is seen, at each threshold's edge:
    of two axes moving alike the first is named (a tie keeps it); an axis whose span is exactly
    its moving threshold (MOVING_P2P) does not move; X counts a tilt by the translations' least
    effect (1 um per rad), not the rotations': a tilt about Z moves X by -Y, whose RMS is set
    either side of it (0.9 and 1.1 um), and with a tolerance of 0.1 um the tilt is then seen
    from 0.1 / 1.1 rad."""
    from stewart_drake.organ_motion.fidelity import MOVING_P2P
    from stewart_drake.verification.verdict_sensitivity import sensitivity

    t = np.linspace(0.0, 1.0, 400, endpoint=False)
    x = np.zeros((400, 6))
    x[:, 3] = x[:, 4] = 1e-3 * np.sin(2 * np.pi * t)
    x[:, 5] = 0.3
    both = [False, False, False, True, True, False]
    assert sensitivity(t, x, both, (1e-4, 1e-3), True)["amplitude_axis"] == "X"
    edge = x.copy()
    edge[:, 3] = MOVING_P2P[3] / 2 * np.tile([1.0, -1.0], 200)
    assert np.ptp(edge[:, 3]) == MOVING_P2P[3]
    s = sensitivity(t, edge, [False, False, False, True, False, False], (1e-4, 1e-3), True)
    assert s["amplitude_axis"] == "" and math.isnan(s["amplitude_fraction"])
    only_x = [False, False, False, True, False, False]
    for y_rms, seen in ((0.9e-6, False), (1.1e-6, True)):
        tilted = np.zeros((400, 6))
        tilted[:, 4] = y_rms * np.sqrt(2) * np.sin(2 * np.pi * t)
        tilted[:, 5] = 0.3
        s = sensitivity(t, tilted, only_x, (1e-7, 1e-3), True)
        if seen:
            assert s["tilt_rad"] == pytest.approx(1e-7 / 1.1e-6, rel=1e-9)
            assert (s["tilt_about"], s["tilt_axis"]) == ("Z", "X")
        else:
            assert math.isnan(s["tilt_rad"]) and s["tilt_axis"] == ""


def test_each_axis_is_graded_at_the_edges_of_its_tolerance_and_action_level():
    """An axis's RMS error at the tolerance exactly PASSes, a hair beyond FAILs; at the action
    level exactly it PASSes, a hair beyond is ACTION; rotations against the angle, translations
    against the length; an axis not measured is not graded."""
    from stewart_drake.verification.verdict_levels import axis_levels

    tol, act = (1e-4, 2e-3), (7e-5, 1e-3)
    measured = np.array([False, True, True, True, True, False])
    rms = np.array([9.0, 1e-3, 2e-3, 7e-5, 1e-4, 9.0])
    assert axis_levels(rms, measured, tol, act) == {
        "theta": "PASS",
        "psi": "ACTION",
        "X": "PASS",
        "Y": "ACTION",
    }
    hair = rms * (1 + 1e-9)
    assert axis_levels(hair, measured, tol, act) == {
        "theta": "ACTION",
        "psi": "FAIL",
        "X": "ACTION",
        "Y": "FAIL",
    }
    assert axis_levels(hair, measured, tol) == dict.fromkeys(["theta", "X"], "PASS") | {
        "psi": "FAIL",
        "Y": "FAIL",
    }
    assert axis_levels(np.full(6, np.nan), measured, tol, act)["X"] == "FAIL"  # NaN never passes


def test_the_exit_status_is_the_worst_verdicts():
    """0 for PASS alone; ACTION 4; CANNOT JUDGE 3 over ACTION; FAIL 2 over everything."""
    from stewart_drake.verification.command import exit_status

    assert exit_status(["PASS", "PASS"]) == 0
    assert exit_status(["PASS", "ACTION"]) == 4
    assert exit_status(["ACTION", "CANNOT JUDGE", "PASS"]) == 3
    assert exit_status(["ACTION", "CANNOT JUDGE", "FAIL"]) == 2


def test_the_action_level_is_checked_against_the_tolerance_at_its_edges():
    """Equal to the tolerance is allowed on both kinds of axis; zero, negative, NaN or beyond
    it is refused, naming the option, the kind of axis, the bound and the value."""
    from stewart_drake.base.errors import InvalidConfigError
    from stewart_drake.verification.verdict_levels import check_action_level

    tol = (1e-4, math.radians(0.1))
    check_action_level(tol, tol)
    check_action_level((1e-9, 1e-9), tol)
    cases = [
        ((0.0, 1e-3), "its length must be above 0 and at most the --tolerance's 0.1 mm, got 0 um"),
        ((1.0001e-4, 1e-3), "its length must be above 0 and at most the --tolerance's 0.1 mm"),
        ((-1e-5, 1e-3), "its length must be above 0"),
        ((math.nan, 1e-3), "its length must be above 0"),
        ((5e-5, 0.0), "its angle must be above 0 and at most the --tolerance's 0.1 deg, got 0 "),
        ((5e-5, math.radians(0.1001)), "its angle must be above 0 and at most the --tolerance's"),
    ]
    for action, words in cases:
        with pytest.raises(InvalidConfigError, match="^--action-level: ") as err:
            check_action_level(action, tol)
        assert words in str(err.value), (action, str(err.value))


def test_the_action_words_name_each_axis_beyond_the_level():
    """None beyond: nothing said. Beyond: the level in both units, then each axis with its RMS
    error in its own unit, in the order given, and what ACTION means."""
    from stewart_drake.verification.verdict_levels import action_words

    level = (7e-5, math.radians(0.07))
    assert action_words({}, level) == ""
    assert action_words({"X": 7.05e-5}, level) == (
        "; beyond the action level 70 um | 0.07 deg: X 70.5 um (within the tolerance: to be "
        "looked at before it fails)"
    )
    both = action_words({"theta": math.radians(0.08), "Z": 9e-5}, level)
    assert both.startswith("; beyond the action level 70 um | 0.07 deg: theta 0.08 deg, Z 90 um (")
