"""The causes a pair's verdict names (verification/pair_causes.py), each on both sides of its
edge, on motions written here: a breathing shape (cos^4, its own written-out waveform) on one
axis, the measured motion made from it (scaled, reversed, shifted, at another period, noise), and
the figures each message prints computed again here by a brute-force shift search."""

import math
import re
from types import SimpleNamespace

import numpy as np
import pytest

from stewart_drake.verification.pair_causes import (
    PLAYED_RATIO,
    SWAPPED_RATIO,
    _played_words,
    swapped_words,
    why_not_following,
)

#: The camera's clock: 25 Hz over 40 s, from 10 s into the reference (no shift searched reaches
#: its start, where the reference is held).
T = np.arange(10.0, 50.0, 0.04)
Z = 5


class Breathing:
    """``amplitude * cos^4(pi (t - delay_s) / period_s)`` on one axis, at rest on the others
    (Lujan's shape: its reversal is no shift of itself); ``repeat_period_s`` its period. With
    ``swell_s`` its amplitude swells by +-40 % over that period, as breathing does: no shift of a
    period matches it as well as none."""

    def __init__(self, axis=Z, amplitude=5e-3, period_s=4.0, swell_s=None):
        self.axis, self.amplitude, self.repeat_period_s = axis, amplitude, period_s
        self.swell_s, self.end_time = swell_s, 200.0

    def at(self, t):
        t = np.asarray(t, dtype=float)
        v = self.amplitude * np.cos(math.pi * t / self.repeat_period_s) ** 4
        return (
            v if self.swell_s is None else v * (1.0 + 0.4 * np.sin(2 * math.pi * t / self.swell_s))
        )

    def evaluate(self, t):
        x = np.zeros((len(t), 6))
        x[:, self.axis] = self.at(t)
        return x, None, None


def _only(axis=Z):
    measured = np.zeros(6, dtype=bool)
    measured[axis] = True
    return measured


def _poses(v, axis=Z):
    x = np.zeros((len(v), 6))
    x[:, axis] = v
    return x


def _why(reference, v, axis=Z, measured=None):
    x_d = reference.evaluate(T)[0]
    return why_not_following(
        reference, T, _poses(v, axis), x_d, _only(axis) if measured is None else measured
    )


# -- why_not_following ---------------------------------------------------------------------------


def test_a_motion_that_follows_its_reference_has_no_cause():
    reference = Breathing()
    noise = np.random.default_rng(0).normal(0.0, 5e-5, len(T))
    assert _why(reference, reference.at(T) + noise) is None


@pytest.mark.parametrize("scale, at_rest", [(0.09, True), (0.11, False)])
def test_a_motion_under_a_tenth_of_its_references_is_at_rest(scale, at_rest):
    """AT_REST_SHARE 0.1 of the reference's RMS: below it "did not move" with both RMS, above
    it the motion follows (its shape and period are the reference's)."""
    reference = Breathing()
    v = reference.at(T)
    why = _why(reference, scale * v)
    if not at_rest:
        assert why is None
        return
    rms = float(np.std(v))  # the reference's RMS about its mean, over the samples
    assert why == (
        f"did not move (Z {scale * rms * 1e3:.3g} mm RMS against its reference's "
        f"{rms * 1e3:.3g} mm)"
    )
    assert 1.0 < rms * 1e3 < 2.0  # cos^4 of 5 mm: its RMS about its mean is 1.3 mm


def test_a_rotation_at_rest_is_said_in_degrees():
    reference = Breathing(axis=1, amplitude=0.05)
    why = _why(reference, 0.05 * reference.at(T), axis=1)
    rms_deg = math.degrees(0.05 * float(np.std(reference.at(T))))
    assert why == f"did not move (theta {rms_deg:.3g} deg RMS)"


def test_two_axes_at_rest_are_each_said_in_their_unit():
    """A reference on theta and X (the first translation: mm from axis 3 on), the motion at 5 %
    of it on both: each named, in order, rotations in degrees, translations in mm."""
    theta, x = Breathing(axis=1, amplitude=0.05), Breathing(axis=3, amplitude=4e-3, period_s=5.0)
    x_d = theta.evaluate(T)[0] + x.evaluate(T)[0]
    measured = np.zeros(6, dtype=bool)
    measured[[1, 3]] = True
    why = why_not_following(theta, T, 0.05 * x_d, x_d, measured)
    rms_deg, rms_mm = math.degrees(float(np.std(theta.at(T)))), 1e3 * float(np.std(x.at(T)))
    assert why == (
        f"did not move (theta {0.05 * rms_deg:.3g} deg RMS, X {0.05 * rms_mm:.3g} mm RMS "
        f"against its reference's {rms_mm:.3g} mm)"
    )


@pytest.mark.parametrize("amplitude, moves", [(9e-6, False), (11e-6, True)])
def test_an_axis_moves_when_its_reference_moves_more_than_10_um(amplitude, moves):
    reference = Breathing(amplitude=amplitude)
    why = _why(reference, reference.at(T))
    assert why == (None if moves else "moves along no axis measured")


def test_a_reference_moving_on_an_axis_not_measured_has_nothing_to_follow():
    reference = Breathing()
    why = _why(reference, reference.at(T), measured=_only(3))  # X measured, Z moving
    assert why == "moves along no axis measured"


def test_a_motion_against_its_reference_runs_the_wrong_way_with_its_correlation():
    reference = Breathing()
    v = -reference.at(T) + np.random.default_rng(1).normal(0.0, 2e-4, len(T))
    rho = float(np.corrcoef(v, reference.at(T))[0, 1])
    assert rho < -0.9
    assert (
        _why(reference, v) == f"runs the wrong way on Z (correlation {rho:+.2f} with its reference)"
    )


def test_a_reversed_motion_a_quarter_period_late_is_found_reversed_not_a_shifted_one():
    """Reversed and 1 s late (a quarter period): its correlation is near 0, so only its reversal
    matched at another shift tells it; the same motion not reversed is not called reversed (it
    does not follow, by its correlation)."""
    reference = Breathing()
    late = reference.at(T - 1.0)
    noise = np.random.default_rng(2).normal(0.0, 2e-5, len(T))
    reversed_why = _why(reference, -late + noise)
    assert reversed_why is not None and reversed_why.startswith(
        "runs the wrong way on Z (reversed, it matches its reference "
    ), reversed_why
    assert reversed_why.endswith("times better): a sign flipped or the axis reversed")
    times = float(re.search(r"its reference (\d+) times better", reversed_why).group(1))
    # Reversed over as it is, each at its best shift within half a period (2 s).
    v = -late + noise
    expected = _least_msd(v, reference, 2.0) / _least_msd(-v, reference, 2.0)
    assert expected > 1.0 / 0.25  # REVERSED_RATIO
    assert times == pytest.approx(expected, rel=0.02, abs=0.5)
    shifted_why = _why(reference, late + noise)
    rho = float(np.corrcoef(late + noise, reference.at(T))[0, 1])
    assert abs(rho) < 0.5
    assert shifted_why == (
        f"does not follow its reference on Z (correlation {rho:+.2f}): another motion, or noise"
    )


@pytest.mark.parametrize("period_s, named", [(4.4, True), (4.0, False)])
def test_a_motion_at_another_period_is_named_with_both_periods(period_s, named):
    reference = Breathing()
    why = _why(reference, Breathing(period_s=period_s).at(T))
    if not named:
        assert why is None
        return
    found = re.fullmatch(
        r"repeats every ([\d.]+) s on Z where its reference does every ([\d.]+) s", why
    )
    assert found, why
    own, ref = float(found.group(1)), float(found.group(2))
    assert abs(own - 4.4) < 0.1 and abs(ref - 4.0) < 0.05


def test_noise_does_not_follow_its_reference():
    reference = Breathing()
    v = np.random.default_rng(3).normal(0.0, float(np.std(reference.at(T))), len(T))
    rho = float(np.corrcoef(v, reference.at(T))[0, 1])
    assert abs(rho) < 0.2
    assert _why(reference, v) == (
        f"does not follow its reference on Z (correlation {rho:+.2f}): another motion, or noise"
    )


# -- swapped_words -------------------------------------------------------------------------------

INTERNAL = Breathing(period_s=4.0, swell_s=17.0)
SURROGATE = Breathing(amplitude=3e-3, period_s=5.6, swell_s=23.0)


def _measured(v, name):
    return SimpleNamespace(t=T, poses=_poses(v), measured=_only(), path=f"/lab/{name}")


def _least_msd(v, reference, span_s=5.0):
    """The least mean squared distance (each less its mean) between v at T and the reference at
    T + d over d in +-span_s, by brute force: every 10 ms, then every 0.1 ms within 20 ms of the
    best."""

    def scores(shifts):
        r = reference.at(T[None, :] + shifts[:, None])
        r -= np.mean(r, axis=1, keepdims=True)
        return np.mean(((v - np.mean(v))[None, :] - r) ** 2, axis=1)

    coarse = np.arange(-span_s, span_s + 5e-4, 0.01)
    d = coarse[int(np.argmin(scores(coarse)))]
    return float(np.min(scores(np.arange(d - 0.02, d + 0.02, 1e-4))))


def _noise(seed, std=1e-4):
    return np.random.default_rng(seed).normal(0.0, std, len(T))


def _words(internal_v, surrogate_v, relative_latency_s=0.0):
    pair = (_measured(internal_v, "a.csv"), _measured(surrogate_v, "b.csv"))
    return swapped_words((INTERNAL, SURROGATE), pair, 0.0, relative_latency_s)


def test_a_right_pair_has_no_swap_and_no_played_trace():
    assert _words(INTERNAL.at(T) + _noise(4), SURROGATE.at(T) + _noise(5)) is None


def test_two_measurements_swapped_are_named_with_how_much_nearer_each_comes():
    a = SURROGATE.at(T - 0.5) + _noise(6)  # the surrogate's motion, 500 ms late
    b = INTERNAL.at(T - 0.2) + _noise(7)  # the internal platform's, 200 ms late
    words = _words(a, b)
    found = re.fullmatch(
        r"the two measurements swapped: a\.csv comes ([\d.e+]+) times nearer the surrogate's "
        r"reference than the internal's, and b\.csv ([\d.e+]+) times nearer the internal's than "
        r"the surrogate's \(mean squared distances\); exchanged, their relative latency is "
        r"(-?[\d.]+) (ms|s): give each file to its option",
        words or "",
    )
    assert found, words
    expected = (
        _least_msd(a, INTERNAL) / _least_msd(a, SURROGATE),
        _least_msd(b, SURROGATE) / _least_msd(b, INTERNAL),
    )
    for printed, ratio in zip((found.group(1), found.group(2)), expected):
        assert ratio > 1.0 / SWAPPED_RATIO
        assert float(printed) == pytest.approx(ratio, rel=0.01)
    # Exchanged, the internal motion is 300 ms ahead of the surrogate's.
    assert found.group(4) == "ms" and abs(abs(float(found.group(3))) - 300.0) < 5.0


def test_a_platform_that_played_the_others_trace_is_named():
    """The surrogate platform given the internal trace: it comes nearer the internal's
    reference, the internal's measurement nearer its own."""
    a = INTERNAL.at(T) + _noise(8)
    b = INTERNAL.at(T) + _noise(9)
    words = _words(a, b)
    found = re.fullmatch(
        r"the surrogate platform played the internal's trace: b\.csv comes ([\d.e+]+) times "
        r"nearer the internal's reference than the surrogate's, where a\.csv comes ([\d.e+]+) "
        r"times nearer its own \(mean squared distances, each less its mean\): give the "
        r"surrogate platform its own trace",
        words or "",
    )
    assert found, words
    played = _least_msd(b, SURROGATE) / _least_msd(b, INTERNAL)
    own = _least_msd(a, SURROGATE) / _least_msd(a, INTERNAL)
    assert float(found.group(1)) == pytest.approx(played, rel=0.01)
    assert float(found.group(2)) == pytest.approx(own, rel=0.01)
    # And the internal platform given the surrogate's trace, named the other way.
    words = _words(SURROGATE.at(T) + _noise(10), SURROGATE.at(T) + _noise(11))
    assert words.startswith("the internal platform played the surrogate's trace: a.csv comes ")


def test_a_pair_swapped_weakly_is_called_swapped_only_when_exchanging_shortens_its_latency():
    """Each measurement nearer the other's reference but under 4 times (SWAPPED_RATIO 0.25):
    swapped when exchanged the pair's relative latency is smaller than as given (1 s), not when
    it is given as 0 (then neither played the other's trace alone: both came nearer)."""
    a = SURROGATE.at(T) + _noise(12, 2.2e-3)
    b = INTERNAL.at(T) + _noise(13, 2.2e-3)
    ratios = (
        _least_msd(a, INTERNAL) / _least_msd(a, SURROGATE),
        _least_msd(b, SURROGATE) / _least_msd(b, INTERNAL),
    )
    assert all(1.0 / PLAYED_RATIO < r < 1.0 / SWAPPED_RATIO for r in ratios), ratios
    assert _words(a, b, relative_latency_s=1.0).startswith("the two measurements swapped: ")
    assert _words(a, b, relative_latency_s=0.0) is None


@pytest.mark.parametrize(
    "ratios, named",
    [
        ((1.25, 0.5), "internal"),  # at the edge: 1 / PLAYED_RATIO
        ((1.249, 0.5), None),
        ((0.5, 1.25), "surrogate"),
        ((1.3, 0.99), "internal"),  # the other just nearer its own
        ((1.3, 1.0), None),  # the other no nearer its own than the other's
        ((1.3, 1.3), None),  # both nearer the other's: a swap's test, not this one
    ],
)
def test_one_platform_played_the_others_trace_at_its_edges(ratios, named):
    words = _played_words(list(ratios), ("a.csv", "b.csv"))
    if named is None:
        assert words is None
        return
    other = "surrogate" if named == "internal" else "internal"
    k = 0 if named == "internal" else 1
    files = ("a.csv", "b.csv")
    assert words == (
        f"the {named} platform played the {other}'s trace: {files[k]} comes {ratios[k]:.3g} "
        f"times nearer the {other}'s reference than the {named}'s, where {files[1 - k]} comes "
        f"{1.0 / ratios[1 - k]:.3g} times nearer its own (mean squared distances, each less its "
        f"mean): give the {named} platform its own trace"
    )


def test_a_swap_of_references_that_repeat_is_matched_at_the_pairs_clock_not_a_period_away():
    """References that repeat exactly (4 s and 5.6 s) match a period away as well as at the
    pair's clock, within the 10 s searched: the tie goes to the shift nearer the pair's clock
    (around 0 here), so the exchanged latency is the 300 ms apart, not 4.3 s."""
    internal, surrogate = Breathing(period_s=4.0), Breathing(amplitude=3e-3, period_s=5.6)
    pair = (
        _measured(surrogate.at(T) + _noise(6), "a.csv"),
        _measured(internal.at(T - 0.3) + _noise(7), "b.csv"),
    )
    words = swapped_words((internal, surrogate), pair, 0.0, 0.0)
    found = re.search(r"exchanged, their relative latency is (-?[\d.]+) (ms|s):", words or "")
    assert found and found.group(2) == "ms", words
    assert abs(abs(float(found.group(1))) - 300.0) < 5.0
    # Around -3.5 s the copies nearest it are taken: a's match at -5.6 s (a surrogate period
    # back), b's at -4.3 s (an internal period back), 1.3 s apart.
    words = swapped_words((internal, surrogate), pair, -3.5, 0.0)
    found = re.search(r"exchanged, their relative latency is (-?[\d.]+) (ms|s):", words or "")
    assert found and found.group(2) == "s", words
    assert float(found.group(1)) == pytest.approx(-1.3, abs=0.005)
