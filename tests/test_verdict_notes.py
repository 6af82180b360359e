"""The verdict line's notes on what a verdict did not judge (verification/verdict_notes.py),
held to words and figures written here by hand: the samples left uncompared and when a
searched clock leaving them cannot judge (either side of 10 %), the pauses judged across, the
constants removed beyond the tolerance (either side of it, each sign, each unit), and the
outliers (frames placed by hand, their count, their largest distance and the rest's RMS)."""

from types import SimpleNamespace

import numpy as np
import pytest

from stewart_drake.verification.verdict_notes import (
    MAX_UNCOMPARED_SHARE,
    OUTLIER_SIGMAS,
    OUTLIER_TOLERANCES,
    outlier_words,
    outliers,
    pause_words,
    removed_offset_words,
    seconds,
    uncompared_words,
)

TOL = (1e-4, np.radians(0.1))  # 0.1 mm | 0.1 deg
ALL = np.ones(6, dtype=bool)
TRANSLATIONS = np.array([False] * 3 + [True] * 3)


def test_the_rules_constants_are_the_documented_ones():
    assert (MAX_UNCOMPARED_SHARE, OUTLIER_SIGMAS, OUTLIER_TOLERANCES) == (0.1, 6.0, 5.0)


@pytest.mark.parametrize(
    "value, words",
    [(0.0601, "60.1 ms"), (-0.5, "-500 ms"), (0.999, "999 ms"), (1.0, "1 s"), (1232.4, "1232 s")],
)
def test_seconds_are_ms_below_one_second(value, words):
    assert seconds(value) == words


def _uncompared(**kw):
    base = {"samples": 1000, "before": 0, "after": 0, "before_s": 0.0, "after_s": 0.0}
    return base | {"whole": False, "span_s": 100.0, "longer_s": 0.0} | kw


def test_nothing_uncompared_says_nothing():
    assert uncompared_words(_uncompared()) == ("", "")
    assert uncompared_words({}) == ("", "")
    assert uncompared_words(_uncompared(samples=0, before=5)) == ("", "")


def test_samples_on_both_sides_are_counted_and_placed():
    words, cannot = uncompared_words(
        _uncompared(before=30, after=20, before_s=3.0, after_s=0.2, whole=True)
    )
    assert words == (
        "50 of 1000 measured samples not compared (5%: its first 3 s, before the reference's "
        "start; its last 200 ms, after the reference's end)"
    )
    assert cannot == ""


def test_one_side_alone_is_named_alone():
    words, _ = uncompared_words(_uncompared(after=7, after_s=0.07, whole=True))
    assert words == (
        "7 of 1000 measured samples not compared (1%: its last 70 ms, after the reference's end)"
    )


@pytest.mark.parametrize("left, judged", [(100, True), (101, False), (150, False)])
def test_a_searched_clock_leaving_over_a_tenth_cannot_judge(left, judged):
    """100 of 1000 is 10 %: judged; 101 is beyond: CANNOT JUDGE, naming --clock-offset."""
    words, cannot = uncompared_words(_uncompared(before=left, before_s=left / 10))
    assert words.startswith(f"{left} of 1000 measured samples not compared")
    if judged:
        assert cannot == ""
    else:
        assert cannot.startswith(f"the clock found leaves {left} of 1000 measured samples")
        assert "over 10% of the recording" in cannot and "--clock-offset" in cannot


def test_as_many_samples_before_as_after_are_counted():
    words, _ = uncompared_words(_uncompared(before=5, after=5, before_s=0.05, after_s=0.05))
    assert words.startswith("10 of 1000 measured samples not compared (1%")


def test_a_recording_half_a_second_longer_is_said_and_a_clock_not_said_searched_is_known():
    words, _ = uncompared_words(_uncompared(after=10, after_s=0.5, longer_s=0.5, whole=True))
    assert words.endswith("; the recording 500 ms longer than the reference)")
    unsaid = _uncompared(before=500, before_s=50.0)
    del unsaid["whole"]
    assert uncompared_words(unsaid)[1] == ""


def test_a_known_clock_judges_whatever_it_leaves():
    assert uncompared_words(_uncompared(before=600, before_s=60.0, whole=True))[1] == ""


def test_what_the_recording_outlasts_the_reference_by_is_not_the_clocks_choice():
    """300 of 1000 left out of a 100 s recording 25 s longer than the reference: 25 % no clock
    could compare, 5 % chosen: judged; 10 s longer, 20 % chosen: CANNOT JUDGE."""
    words, cannot = uncompared_words(
        _uncompared(before=100, after=200, before_s=10, after_s=20, longer_s=25.0)
    )
    assert words.endswith("; the recording 25 s longer than the reference)") and cannot == ""
    _, cannot = uncompared_words(
        _uncompared(before=100, after=200, before_s=10, after_s=20, longer_s=10.0)
    )
    assert cannot != ""
    # Without a span, nothing is taken off: 30 % chosen.
    _, cannot = uncompared_words(
        _uncompared(before=100, after=200, before_s=10, after_s=20, longer_s=25.0, span_s=0.0)
    )
    assert cannot != ""


def test_pauses_are_listed_up_to_three_then_counted():
    assert pause_words(()) == ""
    assert pause_words([(12.5, 50.81)]) == (
        "; judged in 2 segments across a pause (50.81 s after t = 12.5 s of the file): each "
        "sample at its own time, nothing bridged"
    )
    four = [(10.0, 2.0), (20.0, 0.5), (30.0, 3.0), (40.0, 4.0)]
    assert pause_words(four) == (
        "; judged in 5 segments across 4 pauses (2 s after t = 10 s, 500 ms after t = 20 s, "
        "3 s after t = 30 s and 1 more of the file): each sample at its own time, nothing "
        "bridged"
    )
    assert "more" not in pause_words(four[:3]) and "3 pauses" in pause_words(four[:3])


def _frame(removes: bool, offsets, measured=ALL):
    return SimpleNamespace(
        frame=SimpleNamespace(removes_offsets=removes),
        offsets=np.asarray(offsets, dtype=float),
        measured=SimpleNamespace(measured=np.asarray(measured)),
    )


def test_a_removed_offset_is_said_only_beyond_its_axis_tolerance():
    tilt = np.radians(0.2)
    ver = _frame(True, [0.0, -tilt, np.radians(0.05), 4.4e-3, -5.5e-3, 0.99e-4])
    words = removed_offset_words(ver, TOL)
    assert words.startswith(
        "; a constant removed and not judged, larger than the tolerance: "
        "theta -0.2 deg, X +4.4 mm, Y -5.5 mm (each measured axis's mean error"
    )
    assert "psi" not in words and "Z" not in words and "--frame base" in words
    # The edge: exactly at the tolerance is not beyond it; just over is.
    assert removed_offset_words(_frame(True, [0, 0, 0, 1e-4, 0, 0]), TOL) == ""
    assert "X +0.1001 mm" in removed_offset_words(_frame(True, [0, 0, 0, 1.001e-4, 0, 0]), TOL)
    assert "phi +0.3 deg" in removed_offset_words(
        _frame(True, [np.radians(0.3), 0, 0, 0, 0, 0]), TOL
    )


def test_no_offset_is_said_where_none_is_removed_or_measured():
    big = [0.1, 0.1, 0.1, 0.01, 0.01, 0.01]
    assert removed_offset_words(_frame(False, big), TOL) == ""
    assert removed_offset_words(_frame(True, big, [False] * 6), TOL) == ""
    assert removed_offset_words(_frame(True, big, TRANSLATIONS), TOL).count("deg") == 0


def _glitched(n=400, spikes=(50, 51, 300), size=0.02):
    """A motion 10 um of noise off its reference on X, Y, Z (seeded), with ``spikes`` frames
    ``size`` m off on Y."""
    rng = np.random.default_rng(4)
    x_d = np.zeros((n, 6))
    x_d[:, 3] = 0.005 * np.sin(np.linspace(0, 6 * np.pi, n))
    x = x_d.copy()
    x[:, 3:] += 1e-5 * rng.standard_normal((n, 3))
    x[list(spikes), 4] += size
    return x, x_d


def test_outliers_are_the_frames_placed_far_off():
    x, x_d = _glitched()
    found = outliers(x, x_d, TRANSLATIONS, TOL)
    assert found["frames"] == 3 and found["samples"] == 400
    assert np.flatnonzero(found["mask"]).tolist() == [50, 51, 300]
    # The largest distance from the median error, on Y alone: the spike, within the noise.
    e = x - x_d
    assert found["largest"][4] == pytest.approx(
        np.max(np.abs(e[[50, 51, 300], 4] - np.median(e[:, 4])))
    )
    assert 0.0199 < found["largest"][4] < 0.0201
    # Only Y is beyond its bound: X and Z, whose noise those frames also carry, are not named.
    assert found["largest"][[0, 1, 2, 3, 5]].tolist() == [0, 0, 0, 0, 0]
    # The rest's RMS: the noise alone (10 um), computed here from the frames left.
    keep = np.ones(400, bool)
    keep[[50, 51, 300]] = False
    rest = np.sqrt(np.mean(e[keep, 3:] ** 2, axis=0))
    assert np.allclose(found["rest_rms"][3:], rest, rtol=1e-12)
    assert np.all(np.isnan(found["rest_rms"][:3]))
    assert 0.7e-5 < rest.max() < 1.3e-5


def test_a_frame_within_five_tolerances_is_never_an_outlier():
    """0.45 mm off: 4.5 tolerances, beyond 6 robust SD of a 10 um noise, still the motion's own
    error; 0.55 mm is an outlier."""
    x, x_d = _glitched(spikes=(10,), size=4.5e-4)
    assert outliers(x, x_d, TRANSLATIONS, TOL)["frames"] == 0
    x, x_d = _glitched(spikes=(10,), size=5.5e-4)
    assert outliers(x, x_d, TRANSLATIONS, TOL)["frames"] == 1


def test_an_axis_not_measured_flags_nothing():
    x, x_d = _glitched()
    only_x = np.array([False] * 3 + [True, False, False])
    found = outliers(x, x_d, only_x, TOL)
    assert found["frames"] == 0 and np.isnan(found["rest_rms"][4])


def test_the_rest_is_about_its_own_mean_when_the_frames_remove_it():
    x, x_d = _glitched()
    x[:, 5] += 1e-3  # a constant 1 mm on Z
    kept = outliers(x, x_d, TRANSLATIONS, TOL)["rest_rms"][5]
    removed = outliers(x, x_d, TRANSLATIONS, TOL, removes_offsets=True)["rest_rms"][5]
    assert 0.99e-3 < kept < 1.01e-3 and removed < 2e-5


def test_the_outliers_words_give_count_distance_and_the_rest():
    x, x_d = _glitched()
    words = outlier_words(outliers(x, x_d, TRANSLATIONS, TOL), TRANSLATIONS, TOL)
    assert words.startswith(
        "; 3 of 400 frames compared are outliers (beyond 6 robust SD and 5x the tolerance "
        "from the median error on some axis; up to Y 20 mm off it: a marker mis-detected?)"
    )
    assert "the other 397 frames, on the clock found with the outliers: RMS X " in words
    assert "within the tolerance; --exclude-outliers judges without them" in words
    assert "phi" not in words


def test_the_rest_beyond_the_tolerance_is_said_beyond():
    found = {
        "frames": 2,
        "samples": 10,
        "largest": np.array([0, 0, 0, 0, 0.02, 0.0]),
        "rest_rms": np.array([np.nan] * 3 + [1e-4, 1.5e-4, 1e-12]),
    }
    words = outlier_words(found, TRANSLATIONS, TOL)
    assert "up to Y 20 mm off it" in words and "X 0.1 mm, Y 0.15 mm, Z 0 um, beyond" in words
    found["rest_rms"][4] = 1e-4  # at the tolerance: within
    assert "X 0.1 mm, Y 0.1 mm, Z 0 um, within" in outlier_words(found, TRANSLATIONS, TOL)


def test_excluded_frames_are_counted_and_none_says_nothing():
    assert outlier_words({}, ALL, TOL) == ""
    assert outlier_words({"frames": 0, "samples": 9}, ALL, TOL) == ""
    assert outlier_words({}, ALL, TOL, excluded=5).startswith(
        "; 5 frames excluded as outliers (--exclude-outliers: beyond 6 robust SD and 5x the "
        "tolerance from the median error on some axis); the rest judged"
    )


def test_on_a_noisy_axis_the_robust_spread_sets_the_bound():
    """X with 100 um of noise (seeded): 6 robust SD is about 0.6 mm, beyond 5 tolerances
    (0.5 mm), so a frame 0.55 mm off is the noise's and one 1 mm off an outlier; Y, quiet,
    keeps its own bound (its spread is not pooled with X's)."""
    rng = np.random.default_rng(7)
    n = 2000
    x_d = np.zeros((n, 6))
    x = x_d.copy()
    x[:, 3] = 1e-4 * rng.standard_normal(n)
    x[:, 4] = 1e-6 * rng.standard_normal(n)
    e = x[:, 3]
    sigma = 1.4826 * np.median(np.abs(e - np.median(e)))
    assert 0.9e-4 < sigma < 1.1e-4
    x[10, 3] = np.median(e) + 5.5e-4  # within 6 sigma (~0.6 mm)
    x[20, 3] = np.median(e) + 1.0e-3  # beyond
    x[30, 4] = 6e-4  # Y: beyond 5 tolerances, its own spread tiny
    found = outliers(x, x_d, TRANSLATIONS, TOL)
    assert np.flatnonzero(found["mask"]).tolist() == [20, 30]
