"""Fidelity metrics against signals whose errors are known (a known delay, a known gain, a
brute-force gamma, an error built sample by sample, gamma's textbook cases, cosines of known
phase, delays at the edges of the lag's search). `stewart-drake reproduce`, which reports them,
is tests/test_reproduce.py's: these are the fidelity module's fast unit tests, the ones
tools/mutation.py runs."""

import json
import math

import numpy as np
import pytest

from stewart_drake.base.errors import InvalidConfigError
from stewart_drake.organ_motion import fidelity as fd
from stewart_drake.references.organ.library import make_motion
from stewart_drake.robot.geometry import X_HOME


@pytest.mark.parametrize("delay_s", [0.00037, -0.0021, 0.0125])
def test_the_lag_is_found_between_samples(delay_s):
    t = np.arange(0.0, 8.0, 1e-3)
    motion = make_motion("breathing_heartbeat", {"period": "4s"})
    ref = motion.evaluate(t)[0]
    late = motion.evaluate(t - delay_s)[0]
    assert fd.time_lag(t, late[:, 3], ref[:, 3]) == pytest.approx(delay_s, abs=2e-5)
    assert fd.time_lag(t, late[:, 3:5], ref[:, 3:5]) == pytest.approx(delay_s, abs=2e-5)
    assert math.isnan(fd.time_lag(t, ref[:, 0], ref[:, 0]))  # an axis that does not move


def test_harmonic_phasors_are_the_fft_bins_over_whole_periods():
    t = np.arange(0.0, 20.0, 1e-3)  # 5 breaths, 24 beats
    y = (
        1.0
        + 3.0 * np.cos(2 * np.pi * 0.25 * t + 0.4)
        + 0.5 * np.cos(2 * np.pi * 0.5 * t - 1)
        + 0.2 * np.cos(2 * np.pi * 1.2 * t + 2.0)
    )
    p = fd.harmonic_phasors(t, y[:, None], [0.25, 0.5, 1.2])[:, 0]
    spectrum = np.fft.rfft(y) * 2 / len(y)
    bins = [round(f * 20.0) for f in (0.25, 0.5, 1.2)]
    assert np.allclose(p, spectrum[bins], atol=1e-9)
    assert np.allclose(np.abs(p), [3.0, 0.5, 0.2]) and np.allclose(np.angle(p), [0.4, -1, 2])
    # a window of other lengths keeps them apart (no leakage), where one FFT would not
    w = t < 13.3
    q = fd.harmonic_phasors(t[w], y[w, None], [0.25, 0.5, 1.2])[:, 0]
    assert np.allclose(q, p, atol=1e-9)


def test_fidelity_of_a_late_and_small_copy():
    motion = make_motion("breathing_heartbeat", {"period": "5s"})
    t = np.arange(0.0, 10.0, 1e-3)
    x_d = motion.evaluate(t)[0]
    delay, gain = 0.004, 0.97
    x = X_HOME + gain * (motion.evaluate(t - delay)[0] - X_HOME)
    fid = fd.fidelity(t, x, x_d, (5.0, 10.0 - 1e-9), motion.frequencies_hz(), [0, 5, 10])
    assert fid["moving"] == ["X", "Y"]
    assert fid["lag_s"]["X"] == pytest.approx(delay, abs=3e-5)
    assert fid["lag_all_s"] == pytest.approx(delay, abs=3e-5)
    for h in fid["harmonics"]:
        assert h["amplitude_error"] == pytest.approx(gain - 1, abs=1e-6)
        assert h["phase_error_rad"] == pytest.approx(-2 * np.pi * h["f_hz"] * delay, abs=1e-6)
    sources = {(h["source"], h["k"], h["axis"]) for h in fid["harmonics"]}
    assert ("breathing", 1, "X") in sources and ("cardiac", 2, "Y") in sources
    assert ("cardiac", 1, "X") not in sources  # not in the reference
    e = x - x_d
    w = (t >= 5.0) & (t < 10.0)
    assert fid["rms"][3] == pytest.approx(np.sqrt(np.mean(e[w, 3] ** 2)), rel=1e-3)
    assert fid["rms_fraction"][3] == pytest.approx(fid["rms"][3] / 0.015, rel=1e-3)
    assert fid["rms_translation_m"] == pytest.approx(
        np.sqrt(np.mean(np.sum(e[w, 3:] ** 2, axis=1))), rel=1e-3
    )
    assert math.isnan(fid["rms_fraction"][5]) and fid["rms_rotation_rad"] == 0.0
    assert len(fid["cycles"]["starts"]) == 2


def test_the_tolerance_and_the_verdict():
    assert fd.parse_tolerance("0.1mm,0.1deg") == pytest.approx((1e-4, math.radians(0.1)))
    assert fd.parse_tolerance("50urad, 2 um") == pytest.approx((2e-6, 5e-5))
    for bad in ("0.1mm", "0.1mm,0.2mm", "1deg,-1mm", "fast", "0mm,1deg"):
        with pytest.raises(InvalidConfigError, match="one length and one angle"):
            fd.parse_tolerance(bad)
    fid = {"rms": [1e-5, 2e-5, 1e-5, 3e-6, 9e-6, 1e-6], "window_s": [5.0, 10.0]}
    ok, line = fd.verdict(fid, (1e-5, 3e-5))
    assert ok and line.startswith("PASS") and "Y 9 um" in line and "theta 20 urad" in line
    ok, line = fd.verdict(fid, (5e-6, 3e-5))
    assert not ok and line.startswith("FAIL")


def test_the_tables_of_docs_organ_motion_are_generated_from_its_figures():
    """docs/organ_motion.md's tables are what fidelity_study.tables makes of the figures kept
    beside them (python tools/organ_motion_tables.py writes both; never edit them by hand)."""
    from pathlib import Path

    from stewart_drake.studies.fidelity_study import CASES, TABLE_MARKERS, tables

    docs = Path(__file__).resolve().parent.parent / "docs"
    figures = json.loads((docs / "organ_motion.json").read_text())
    assert set(figures) == {c.job_id for c in CASES}
    doc = (docs / "organ_motion.md").read_text()
    start, end = doc.index(TABLE_MARKERS[0]), doc.index(TABLE_MARKERS[1])
    assert tables(figures) == doc[start : end + len(TABLE_MARKERS[1])]


def test_mismatched_or_non_finite_inputs_are_typed_errors():
    from stewart_drake.base.errors import InvalidConfigError
    from stewart_drake.references.organ.combinators import common_period

    t = np.arange(100) * 0.01
    with pytest.raises(InvalidConfigError, match="time_lag needs two signals of the same shape"):
        fd.time_lag(t, np.zeros((100, 6)), np.zeros((99, 6)))
    with pytest.raises(InvalidConfigError, match="finite times and frequencies"):
        fd.harmonic_phasors(t, np.zeros(100), [math.nan])
    with pytest.raises(InvalidConfigError, match="periods must be finite positive numbers"):
        common_period([4.0, math.nan])
    assert common_period([4.0, 60 / 72]) == pytest.approx(20.0)  # 5 breaths, 24 heartbeats


def test_the_gamma_pass_rate_is_the_distance_to_agreement_of_every_sample():
    """Against a brute-force gamma over every pair of samples, on a noisy, delayed trace; and
    on a pure delay: a reference 50 ms late passes a 100 ms criterion everywhere it can be
    shifted (not at the end of the record) and fails a 10 ms one where it moves."""
    rng = np.random.default_rng(5)
    t = np.arange(0.0, 4.0, 0.004)
    p_d = np.column_stack([np.sin(t), 0.5 * np.cos(2 * t), 0 * t]) * 1e-3
    p = np.roll(p_d, 5, axis=0) + rng.normal(scale=1e-4, size=p_d.shape)
    for distance, time_s in ((0.3e-3, 0.05), (0.1e-3, 0.02)):
        brute = [
            min(
                math.hypot(np.linalg.norm(p[i] - p_d[j]) / distance, (t[i] - t[j]) / time_s)
                for j in range(len(t))
                if abs(t[i] - t[j]) <= time_s + 1e-12
            )
            <= 1.0
            for i in range(len(t))
        ]
        assert fd.gamma_pass_rate(t, p, p_d, distance, time_s) == pytest.approx(np.mean(brute))
    t2 = np.arange(0.0, 8.0, 0.001)
    p_d2 = np.column_stack([np.sin(np.pi * t2) * 2e-3, 0 * t2, 0 * t2])
    p2 = np.column_stack([np.sin(np.pi * (t2 - 0.05)) * 2e-3, 0 * t2, 0 * t2])  # 50 ms late
    assert fd.gamma_pass_rate(t2, p2, p_d2, 1e-9, 0.1) > 0.99
    # 50 ms late at up to 6.3 mm/s is up to 0.31 mm off: a 10 ms, 0.1 mm criterion fails
    # wherever the motion is faster than 0.1 mm / 50 ms
    assert fd.gamma_pass_rate(t2, p2, p_d2, 0.1e-3, 0.01) < 0.5
    with pytest.raises(InvalidConfigError, match="gamma criteria must be > 0"):
        fd.gamma_pass_rate(t2, p2, p_d2, 0.0, 0.1)


# -- every figure of fidelity() and its measures against numbers computed apart from them ------


def _known_run():
    """100 Hz for 10 s: a reference moving phi (20 mrad) and X (4 mm) at 0.5 Hz, Y stepping by
    exactly MOVING_P2P (10 um: not moving), and a pose whose error is known sample by sample:
    constants on X, Y, phi, spikes at the window's ends (2 s, 9 s), and beyond it (0 s, 9.5 s,
    the last sample)."""
    t = np.arange(1001) * 0.01
    x_d = np.tile(X_HOME, (t.size, 1))
    x_d[:, 0] = 0.02 * np.sin(np.pi * t)
    x_d[:, 3] = 0.004 * np.sin(np.pi * t)
    x_d[:, 4] = np.where(t > 5.0, 1e-5, 0.0)
    e = np.zeros_like(x_d)
    e[:, 3], e[:, 4], e[:, 0] = 2e-6, 3e-6, 1e-5
    e[200, 1] = 7e-5  # theta at the window's first sample, t = 2 s
    e[900, 3] += 5e-5  # X and Z at its last, t = 9 s
    e[900, 5] = -4e-5
    e[900, 2] = 6e-5  # psi
    e[950, 3] = 1e-3  # beyond the window (9.5 s), and at the run's two ends
    e[0, 2] = 3e-4
    e[-1, 5] = 2e-4
    return t, x_d + e, x_d, e


def test_fidelity_gives_every_figure_of_a_known_error():
    """Over the window [2, 9] s (samples 200 to 900, both ends in): each axis's RMS and peak,
    the reference's peak to peak (8 mm and 40 mrad over whole periods, 10 um on Y: not moving),
    their fractions, the 3-D RMS and peaks, the gamma rows; errors outside the window do not
    count. Computed here by index, from the error as built."""
    t, x, x_d, e = _known_run()
    fid = fd.fidelity(t, x, x_d, (2.0, 9.0))
    w = e[200:901]
    assert fid["window_s"] == pytest.approx([2.0, 9.0], abs=1e-12)
    assert fid["moving"] == ["phi", "X"]
    np.testing.assert_allclose(fid["rms"], np.sqrt(np.mean(w**2, axis=0)), rtol=1e-3, atol=1e-12)
    np.testing.assert_allclose(fid["peak"], np.abs(w).max(axis=0), rtol=1e-3)
    assert fid["peak"][1] == pytest.approx(7e-5, rel=1e-3)  # the window's first sample counts
    assert fid["peak"][3] == pytest.approx(5.2e-5, rel=1e-3)  # its last; not 9.5 s's 1 mm
    np.testing.assert_allclose(fid["p2p"], [0.04, 0, 0, 0.008, 1e-5, 0], rtol=1e-9, atol=0)
    for key, value in (("rms_fraction", fid["rms"]), ("peak_fraction", fid["peak"])):
        assert fid[key][0] == pytest.approx(value[0] / 0.04, rel=1e-6)
        assert fid[key][3] == pytest.approx(value[3] / 0.008, rel=1e-6)
        assert all(math.isnan(fid[key][k]) for k in (1, 2, 4, 5)), key
    assert fid["rms_translation_m"] == pytest.approx(
        math.sqrt(np.mean(np.sum(w[:, 3:] ** 2, axis=1))), rel=1e-3
    )
    assert fid["rms_rotation_rad"] == pytest.approx(
        math.sqrt(np.mean(np.sum(w[:, :3] ** 2, axis=1))), rel=1e-3
    )
    assert fid["peak_translation_m"] == pytest.approx(math.hypot(5.2e-5, 3e-6, 4e-5), rel=1e-3)
    assert fid["peak_rotation_rad"] == pytest.approx(math.hypot(1e-5, 7e-5), rel=1e-3)
    assert set(fid["lag_s"]) == {"phi", "X"} and abs(fid["lag_all_s"]) < 1e-3
    # gamma: every sample within 0.5 mm; at 5 um / 10 ms all but t = 9 s (65 um off, and a
    # sample's shift costs the whole 10 ms)
    assert [(g["distance_m"], g["time_s"]) for g in fid["gamma"]] == list(fd.GAMMA_CRITERIA)
    assert [g["pass_rate"] for g in fid["gamma"]] == pytest.approx([1.0, 700 / 701])
    assert fid["harmonics"] == [] and fid["cycles"]["starts"] == []
    # The whole run by default: its first and last samples count, 9.5 s's millimetre too.
    whole = fd.fidelity(t, x, x_d)
    assert whole["window_s"] == pytest.approx([0.0, 10.0], abs=1e-12)
    np.testing.assert_allclose(whole["peak"], np.abs(e).max(axis=0), rtol=1e-3)
    assert whole["peak"][2] == pytest.approx(3e-4, rel=1e-3)
    assert whole["peak"][5] == pytest.approx(2e-4, rel=1e-3)


def test_fidelity_reads_the_poses_before_the_rates_and_refuses_what_does_not_match():
    """Logs that carry rates after the pose (12 columns) give the figures of the pose alone;
    shapes that differ, a pose of one column, fewer than 10 samples (in all or in the window)
    are refused in words."""
    t, x, x_d, _ = _known_run()
    rates = np.full_like(x, 0.5)
    wide = fd.fidelity(t, np.hstack([x, rates]), np.hstack([x_d, -rates]), (2.0, 9.0))
    narrow = fd.fidelity(t, x, x_d, (2.0, 9.0))
    assert len(wide["rms"]) == 6
    for key in ("rms", "peak", "p2p", "rms_translation_m", "rms_rotation_rad", "gamma"):
        assert wide[key] == narrow[key], key
    with pytest.raises(InvalidConfigError, match=r"must match"):
        fd.fidelity(t, x, x_d[:, 3])
    with pytest.raises(InvalidConfigError, match=r"must match"):
        fd.fidelity(t, x[:, 3], x_d[:, 3])
    with pytest.raises(InvalidConfigError, match=r"must match"):
        fd.fidelity(t[:-1], x, x_d)
    with pytest.raises(
        InvalidConfigError, match=r"^t \(1001,\), x \(1001, 6\) and x_d \(1001, 5\) must match$"
    ):
        fd.fidelity(t, x, x_d[:, :5])
    ten = fd.fidelity(t[:10], x[:10], x_d[:10])
    assert ten["window_s"] == pytest.approx([0.0, 0.09])
    with pytest.raises(
        InvalidConfigError, match=r"^fewer than 10 samples \(9\): nothing to measure$"
    ):
        fd.fidelity(t[:9], x[:9], x_d[:9])
    # a window shorter than the gamma's 100 ms (10 samples): every shift within it is tried
    short = fd.fidelity(t, x, x_d, (9.91, 10.0))
    assert short["window_s"] == pytest.approx([9.91, 10.0])
    assert [g["pass_rate"] for g in short["gamma"]] == [1.0, 0.9]  # 10.0 s: 200 um off
    with pytest.raises(
        InvalidConfigError, match=r"^fewer than 10 samples in the window \[9\.92, 10\] s$"
    ):
        fd.fidelity(t, x, x_d, (9.92, 10.0))


def test_the_cycles_are_the_samples_from_each_start_up_to_the_next():
    """A cycle's samples are those from its start up to, not including, the next start; a
    cycle starting before the data, ending more than two samples after it, or of fewer than ten
    samples is left out (and the cycles after it still counted). Each sample's error differs,
    so a sample in the wrong cycle changes its figures."""
    t = np.arange(351) * 0.01  # 0 to 3.5 s
    x_d = np.tile(X_HOME, (t.size, 1))
    e = np.zeros_like(x_d)
    e[:, 3] = 1e-6 * (1 + np.arange(t.size))  # X: 1, 2, 3, ... um
    e[:, 4] = 2e-6
    e[:, 0] = 1e-6 * np.arange(t.size) % 7e-6  # phi
    starts = [-0.5, 0.5, 1.5, 2.5, 2.6, 3.0, 3.515, 4.0]
    cycles = fd.fidelity(t, x_d + e, x_d, cycle_starts=starts)["cycles"]
    # [-0.5, 0.5): before the data; [2.5, 2.6): ten samples, kept; [3.0, 3.515): ends 1.5
    # samples after the last, kept; [3.515, 4.0): beyond it
    kept = {0.5: (50, 150), 1.5: (150, 250), 2.5: (250, 260), 2.6: (260, 300), 3.0: (300, 351)}
    assert cycles["starts"] == list(kept)
    for n, (i, j) in enumerate(kept.values()):
        ec = e[i:j]
        assert cycles["rms_translation_m"][n] == pytest.approx(
            math.sqrt(np.mean(ec[:, 3] ** 2 + ec[:, 4] ** 2)), rel=1e-6
        )
        assert cycles["rms_rotation_rad"][n] == pytest.approx(
            math.sqrt(np.mean(ec[:, 0] ** 2)), rel=1e-6
        )
        assert cycles["peak_translation_m"][n] == pytest.approx(
            math.hypot(1e-6 * j, 2e-6), rel=1e-6
        )
    per_axis = cycles.pop("rms")
    for n, (i, j) in enumerate(kept.values()):  # and each axis's own, X here
        assert per_axis[n][3] == pytest.approx(math.sqrt(np.mean(e[i:j, 3] ** 2)), rel=1e-6)
    assert all(type(v) is float for values in cycles.values() for v in values)
    assert all(type(v) is float for row in per_axis for v in row)
    short = fd.fidelity(t, x_d + e, x_d, cycle_starts=[3.0, 3.525])["cycles"]
    assert short["starts"] == []  # 2.5 samples after the last


def test_the_harmonics_are_those_of_the_reference_up_to_the_fifth_and_a_quarter_of_the_rate():
    """A reference of 0.25 Hz with its harmonics 1 to 6 (amplitudes 1, 0.5, ... 1/6 mm) about a
    2 mm centre, sampled at 50 Hz over whole periods, followed exactly: each harmonic 1 to 5
    reported with its amplitude and no error; not the sixth (harmonics=5 by default), none at
    0 Hz. Sampled at 3.2 Hz, only those below 0.8 Hz (a quarter of the rate). None without
    frequencies or when nothing moves."""
    t = np.arange(1000) * 0.02  # 20 s: 5 periods
    x_d = np.tile(X_HOME, (t.size, 1))
    x_d[:, 3] = 2e-3  # a centre off 0: no harmonic at 0 Hz
    for k in range(1, 7):
        x_d[:, 3] += 1e-3 / k * np.cos(2 * np.pi * 0.25 * k * t + 0.3 * k)
    fid = fd.fidelity(t, x_d, x_d, frequencies={"breathing": 0.25})
    assert [(h["source"], h["k"], h["axis"]) for h in fid["harmonics"]] == [
        ("breathing", k, "X") for k in range(1, 6)
    ]
    for h in fid["harmonics"]:
        assert h["f_hz"] == pytest.approx(0.25 * h["k"])
        assert h["reference"] == pytest.approx(1e-3 / h["k"], rel=1e-9)
        assert h["amplitude_error"] == pytest.approx(0.0, abs=1e-9)
        assert h["phase_error_rad"] == pytest.approx(0.0, abs=1e-9)
    slow = np.arange(64) * 0.3125  # 3.2 Hz for 20 s
    x_slow = np.tile(X_HOME, (slow.size, 1))
    for k in range(1, 7):
        x_slow[:, 3] += 1e-3 / k * np.cos(2 * np.pi * 0.25 * k * slow)
    got = fd.fidelity(slow, x_slow, x_slow, frequencies={"breathing": 0.25}, harmonics=6)
    assert [h["k"] for h in got["harmonics"]] == [1, 2, 3]  # 0.75 Hz < 0.8 Hz <= 1 Hz
    assert fd.fidelity(t, x_d, x_d)["harmonics"] == []
    still = np.tile(X_HOME, (t.size, 1))
    quiet = fd.fidelity(t, still, still, frequencies={"breathing": 0.25})
    assert quiet["moving"] == [] and quiet["harmonics"] == [] and math.isnan(quiet["lag_all_s"])


def test_the_lag_of_all_axes_weighs_each_by_its_motion():
    """phi (100 mrad) 2 ms late and X (1 mm) 10 ms late on the same 0.5 Hz sine: weighed by
    their peak to peak, each counts alike and the lag of both is the mean, 6 ms (two equal
    cosines' sum peaks halfway); unweighed, phi's 2 ms would win."""
    t = np.arange(4000) * 1e-3
    x_d = np.tile(X_HOME, (t.size, 1))
    x = x_d.copy()
    for axis, amplitude, delay in ((0, 0.1, 0.002), (3, 1e-3, 0.010)):
        x_d[:, axis] += amplitude * np.sin(np.pi * t)
        x[:, axis] += amplitude * np.sin(np.pi * (t - delay))
    fid = fd.fidelity(t, x, x_d)
    assert fid["lag_s"]["phi"] == pytest.approx(0.002, abs=2e-5)
    assert fid["lag_s"]["X"] == pytest.approx(0.010, abs=2e-5)
    assert fid["lag_all_s"] == pytest.approx(0.006, abs=5e-5)
    both = fd.time_lag(t, x[:, [0, 3]], x_d[:, [0, 3]], weights=[1 / 0.2, 1 / 2e-3])
    assert both == pytest.approx(0.006, abs=5e-5)
    assert fd.time_lag(t, x[:, [0, 3]], x_d[:, [0, 3]]) == pytest.approx(0.002, abs=1e-4)


def test_the_lag_at_the_edges_of_its_search():
    """max_lag_s = 10 ms at 1 kHz: 9.3 ms late or early is found between samples next to the
    search's ends; a delay beyond them is reported at the end, 10 ms. A window of exactly three
    times max_lag_s is measured, a shorter one gives NaN."""
    motion = make_motion("breathing_heartbeat", {"period": "4s"})
    t = np.arange(0.0, 8.0, 1e-3)
    ref = motion.evaluate(t)[0][:, 3]
    for delay, found in ((0.0093, 0.0093), (-0.0093, -0.0093), (0.015, 0.01), (-0.015, -0.01)):
        late = motion.evaluate(t - delay)[0][:, 3]
        assert fd.time_lag(t, late, ref, max_lag_s=0.01) == pytest.approx(found, abs=2e-5), delay
    # a search of one sample: 1.5 ms late is reported at its end, 1 ms (to the search's
    # microsecond: base.lag)
    late = motion.evaluate(t - 0.0015)[0][:, 3]
    assert fd.time_lag(t, late, ref, max_lag_s=0.001) == pytest.approx(0.001, abs=1e-6)
    # 30 samples of a 20 Hz sine 4 ms late
    ref, late = np.sin(40 * np.pi * t[:30]), np.sin(40 * np.pi * (t[:30] - 0.004))
    assert fd.time_lag(t[:30], late, ref, max_lag_s=0.01) == pytest.approx(0.004, abs=1e-4)
    for n in (29, 25, 15):
        assert math.isnan(fd.time_lag(t[:n], late[:n], ref[:n], max_lag_s=0.01)), n


def test_the_lag_is_found_past_a_constant_offset():
    """10 mm of offset on a 4.2 ms lag over 7.3 s (not whole cycles): each axis less its mean
    difference, the lag is the delay to 2 us; compared as it is, the offset pulls the search to
    12 ms (base.lag without offsets)."""
    motion = make_motion("breathing_heartbeat", {"period": "4s"})
    t = np.arange(0.0, 7.3, 1e-3)
    ref = motion.evaluate(t)[0][:, 3]
    late = motion.evaluate(t - 0.0042)[0][:, 3] + 0.01
    assert fd.time_lag(t, late, ref) == pytest.approx(0.0042, abs=2e-6)


def test_the_lag_of_the_fewest_samples_it_measures():
    """Four samples 10 ms apart and a search of 9.9 ms: two lie inside its margins, a lag is
    measured (inside the search); three samples hold one: NaN, not an error."""
    t = np.arange(4) * 0.01
    lag = fd.time_lag(t, np.sin(30 * t - 0.1), np.sin(30 * t), max_lag_s=0.0099)
    assert 0.0 < lag <= 0.0099
    assert math.isnan(fd.time_lag(t[:3], np.sin(30 * t[:3] - 0.1), np.sin(30 * t[:3]), 0.0099))
    assert math.isnan(fd.time_lag(t[:2], t[:2], t[:2], 1e-4))
    assert math.isnan(fd.time_lag(t[:0], t[:0], t[:0]))


@pytest.mark.parametrize(
    "t0, t1, text",
    [
        (4.0, 19.98, "4-19.98"),  # 16 s: two decimals, trailing zeros left out
        (259200.0, 259230.5, "259200-259230.5"),  # far from zero: every digit before the point
        (0.0, 1234.5678, "0-1235"),  # 1235 s: no decimal
        (0.0, 0.123456, "0-0.1235"),  # 0.12 s: four decimals
        (5.12345, 5.12345, "5.123-5.123"),  # no length: three decimals
        (-0.2, 1.5, "-0.2 to 1.5"),  # an end negative: "to", not a dash
        (1.0, -0.5, "1 to -0.5"),
        (-0.00001, 2.0, "0-2"),  # a negative zero is zero
    ],
)
def test_a_window_is_written_with_the_digits_that_tell_its_ends_apart(t0, t1, text):
    assert fd.format_window(t0, t1) == text


def test_the_gamma_index_of_textbook_cases():
    """A trace on its reference passes everywhere; a still reference missed by exactly the
    distance criterion gives gamma = 1, which passes, and by twice it fails; a motion 4 samples
    early within a 5-sample time criterion (gamma 0.8) passes wherever the reference goes on
    for 4 samples more; two samples are enough; time_s = 0 and shapes that differ are refused."""
    t = np.arange(200) * 0.01
    ramp = np.column_stack([0.1 * t, 0 * t, 0 * t])  # 1 mm per sample
    assert fd.gamma_pass_rate(t, ramp, ramp, 1e-6, 0.05) == 1.0
    still = np.zeros((200, 3))
    off = still.copy()
    off[:, 2] = 5e-4
    assert fd.gamma_pass_rate(t, off, still, 5e-4, 0.05) == 1.0
    assert fd.gamma_pass_rate(t, 2 * off, still, 5e-4, 0.05) == 0.0
    early = np.column_stack([0.1 * (t + 0.04), 0 * t, 0 * t])
    assert fd.gamma_pass_rate(t, early, ramp, 1e-6, 0.05) == pytest.approx(196 / 200)
    # a record shorter than the time criterion: two samples, 10 ms apart, within 50 ms
    assert fd.gamma_pass_rate(t[:2], ramp[:2], ramp[:2], 1e-6, 0.05) == 1.0
    assert fd.gamma_pass_rate(t[:2], ramp[1:3], ramp[:2], 1e-6, 0.05) == 0.5  # 1 sample early
    # so fidelity over 50 ms of 1 kHz logs, shorter than the 100 ms criterion (it raised)
    fast = np.tile(X_HOME, (50, 1))
    fast[:, 3] += 1e-3 * np.sin(2 * np.pi * 5 * np.arange(50) * 1e-3)
    gamma = fd.fidelity(np.arange(50) * 1e-3, fast, fast)["gamma"]
    assert [g["pass_rate"] for g in gamma] == [1.0, 1.0]
    for bad in ((1e-3, 0.0), (0.0, 0.1), (-1e-3, 0.1)):
        with pytest.raises(InvalidConfigError, match=r"^gamma criteria must be > 0"):
            fd.gamma_pass_rate(t, ramp, ramp, *bad)
    for args in ((t, ramp, ramp[:, :2]), (t[:-1], ramp, ramp), (t[:1], ramp[:1], ramp[:1])):
        with pytest.raises(InvalidConfigError, match=r"^t \(\d+,\), p .* must match$"):
            fd.gamma_pass_rate(*args, 1e-3, 0.1)


def test_harmonic_phasors_keep_the_time_of_a_window_that_starts_late():
    """cos(2 pi f t + phase) sampled from t = 3.7 s is amplitude e^(i phase), as from t = 0: the
    phase is that of the absolute time. One frequency may be given as a number."""
    t = 3.7 + np.arange(0.0, 8.0, 1e-3)
    y = 2.0 * np.cos(2 * np.pi * 0.5 * t + 0.4) + 0.3 * np.cos(2 * np.pi * 1.5 * t - 1.0)
    p = fd.harmonic_phasors(t, y, [0.5, 1.5])[:, 0]
    np.testing.assert_allclose(p, [2.0 * np.exp(0.4j), 0.3 * np.exp(-1.0j)], atol=1e-9)
    one = fd.harmonic_phasors(t, y, 0.5)
    assert one.shape == (1, 1) and one[0, 0] == pytest.approx(2.0 * np.exp(0.4j), abs=1e-9)


def test_the_rms_of_translation_and_rotation():
    """3-4-5 in each: 3 and 4 um on X and Z give 5 um at every sample, 3 and 4 urad on theta
    and psi 5 urad; the RMS of a constant is the constant, however many samples."""
    e = np.zeros((50, 6))
    e[:, 3], e[:, 5], e[:, 1], e[:, 2] = 3e-6, 4e-6, 3e-6, 4e-6
    assert fd.rms_translation_rotation(e) == pytest.approx((5e-6, 5e-6), rel=1e-12)
    e[::2, [1, 2]] = 0.0  # half the samples without rotation: sqrt(25 / 2)
    assert fd.rms_translation_rotation(e)[1] == pytest.approx(5e-6 / math.sqrt(2), rel=1e-12)


def test_the_tolerance_s_units_and_the_verdict_line():
    """Units as written or all in capitals, exponents with E; an unknown unit, a unit in mixed
    case (0.05Mm is no millimetre), an infinite number or a tolerance past 1 m or 180 deg
    refused, each naming the option. The
    verdict compares translations with the length and rotations with the angle, an RMS equal to
    the tolerance within it, and says so in one line with the largest of each kind."""
    assert fd.parse_tolerance("0.1MM,1E-3RAD") == pytest.approx((1e-4, 1e-3))
    assert fd.parse_tolerance(" 2 um , 5e+1 URAD ") == pytest.approx((2e-6, 5e-5))
    for bad in ("1mm,1furlong", "1e999mm,1deg", "1mm,1deg,1mm", "0.05Mm,1deg", "1mm,1Deg"):
        with pytest.raises(InvalidConfigError, match="^--tolerance: one length and one angle"):
            fd.parse_tolerance(bad)
    with pytest.raises(InvalidConfigError, match="the unit 'Mm' is not one of m, cm, mm, um, rad"):
        fd.parse_tolerance("0.05Mm,1deg")
    assert fd.parse_tolerance("1m,180deg") == pytest.approx((1.0, math.pi))  # the largest
    for bad in ("1e300m,1e300deg", "1.01m,1deg", "1mm,181deg"):
        with pytest.raises(InvalidConfigError, match="^--action-level: at most 1 m and 180 deg"):
            fd.parse_tolerance(bad, "--action-level")
    fid = {"rms": [1e-5, 2e-5, 1e-5, 3e-4, 9e-6, 1e-6], "window_s": [5.0, 10.0]}
    ok, line = fd.verdict(fid, (3e-4, 2e-5))  # X's 0.3 mm and theta's 20 urad exactly
    assert ok and line == (
        "PASS: the pose against its reference, RMS error per axis within 0.3 mm | 20 urad over "
        "t = 5-10 s (largest: X 0.3 mm, theta 20 urad)"
    )
    ok, line = fd.verdict(fid, (2.9e-4, 0.1), compared="the robot's true pose against A")
    assert not ok and line.startswith(
        "FAIL: the robot's true pose against A, RMS error per axis beyond 0.29 mm | 5.73 deg over"
    )
    ok, line = fd.verdict(fid, (1e-3, 1.9e-5))  # theta beyond
    assert not ok and "RMS error per axis beyond 1 mm | 19 urad over" in line
    # The text alone, for a figure beside a verdict: the same judgement, no PASS or FAIL.
    within, text = fd.tolerance_line(fid, (1e-3, 1.9e-5))
    assert not within and line.endswith(text) and "PASS" not in text and "FAIL" not in text
    fid["rms"][3] = 5e-5  # X below the length, above the angle's number: a length still
    assert fd.verdict(fid, (1e-4, 3e-5))[0]


def test_lengths_and_angles_as_text():
    assert fd.format_length(1.234e-4) == "0.123 mm"
    assert fd.format_length(1e-4) == "0.1 mm"
    assert fd.format_length(9.87e-5) == "98.7 um"
    assert fd.format_length(9.994999e-5) == "99.9 um"  # 99.994999 um: not yet 100
    assert fd.format_angle(9.994999e-4) == "999 urad"
    assert fd.format_length(0.25) == "250 mm"
    assert fd.format_angle(math.radians(0.1)) == "0.1 deg"
    assert fd.format_angle(1e-3) == "0.0573 deg"
    assert fd.format_angle(9.99e-4) == "999 urad"
    assert fd.format_angle(2e-6) == "2 urad"


def test_a_long_float32_log_s_rms_is_summed_in_float64():
    """Logs are float32 (RunResult): over 100 000 samples of a constant 3 um error the RMS per
    axis is 3 um to float32's precision; summed in float32 it drifted by 4e-4."""
    n = 100_000
    x_d = np.tile(X_HOME.astype(np.float32), (n, 1))
    x = x_d.copy()
    x[:, 3] += np.float32(3e-6)
    error = float(x[0, 3]) - float(x_d[0, 3])  # 3 um as float32 holds it near 0
    fid = fd.fidelity(np.arange(n) * 0.05, x, x_d)
    assert fid["rms"][3] == pytest.approx(error, rel=1e-6)
    assert fid["rms_translation_m"] == pytest.approx(error, rel=1e-6)


def test_the_start_up_figures_of_an_error_built_sample_by_sample():
    """startup_figures over the samples before ``end`` (poses with their rates, (n, 12)): the
    RMS of translation and rotation are the root mean square of the error vectors' norms, the
    peaks their largest norms; a sample at ``end`` is not before it; a motion with no sample
    before ``end`` gives zeros; a rotation not measured (NaN) gives NaN."""
    t = np.arange(6) * 0.1  # 0.0 ... 0.5 s
    x_d = np.full((6, 12), 0.25)  # poses and rates; the rates are not read
    x = x_d.copy()
    x[:, 6:] = 7.0
    x[0, 3:6] += [3e-3, 4e-3, 0.0]  # |e| = 5 mm
    x[1, 3:6] += [0.0, 0.0, 1e-3]  # 1 mm
    x[2, :3] += [0.0, 2e-3, 0.0]  # 2 mrad
    x[1, :3] += [1e-3, 0.0, 0.0]  # 1 mrad
    x[3, 3:6] += 1.0  # at the end: not counted
    end = float(t[3])  # the sample at the end is not before it
    figures = fd.startup_figures(t, x, x_d, end=end)  # samples 0, 1, 2
    assert figures["window_s"] == (0.0, end)
    assert figures["rms_translation_m"] == pytest.approx(math.sqrt((25e-6 + 1e-6) / 3))
    assert figures["rms_rotation_rad"] == pytest.approx(math.sqrt((4e-6 + 1e-6) / 3))
    assert figures["peak_translation_m"] == pytest.approx(5e-3)
    assert figures["peak_rotation_rad"] == pytest.approx(2e-3)
    late = fd.startup_figures(t + 1.0, x, x_d, end=0.3)
    assert late["window_s"] == (1.0, 0.3)
    assert [late[k] for k in late if k != "window_s"] == [0.0, 0.0, 0.0, 0.0]
    empty = fd.startup_figures(t[:0], x[:0], x_d[:0], end=0.3)
    assert empty["window_s"] == (0.0, 0.3) and empty["peak_translation_m"] == 0.0
    positions_only = x.copy()
    positions_only[:, :3] = np.nan
    blind = fd.startup_figures(t, positions_only, x_d, end=end)
    assert math.isnan(blind["rms_rotation_rad"])
    assert blind["rms_translation_m"] == figures["rms_translation_m"]


def test_the_verdict_judges_only_the_rotations_that_were_measured():
    """A marker that gives positions only (every rotation NaN) is judged on its translations,
    the line naming the largest and saying the rotation was not measured; one rotation measured
    among NaNs is judged and named."""
    fid = {"rms": [math.nan] * 3 + [1e-5, 3e-5, 2e-5], "window_s": (0.0, 10.0)}
    ok, line = fd.verdict(fid, (1e-4, 1e-3))
    assert ok and "(largest: Y 30 um, rotation not measured)" in line
    assert not fd.verdict(fid, (2e-5, 1e-3))[0]
    fid["rms"] = [math.nan, 5e-4, math.nan, 1e-5, 3e-5, 2e-5]
    ok, line = fd.verdict(fid, (1e-4, 1e-3))
    assert ok and "(largest: Y 30 um, theta 500 urad)" in line
    assert not fd.verdict(fid, (1e-4, 4e-4))[0]


def test_the_gamma_index_of_each_sample_is_its_distance_over_the_criterion():
    """A still reference missed by 0.25 mm at a 0.5 mm criterion: gamma 0.5 at every sample
    (no time shift brings a still reference nearer); by 0.6 mm, 1.2. A ramp 4 samples early
    within a 5-sample time criterion: gamma 0.8 wherever the reference goes on 4 samples more,
    the gamma pass rate the share at most 1 (:func:`gamma_pass_rate` agrees)."""
    t = np.arange(100) * 0.01
    still = np.zeros((100, 3))
    for miss, gamma in ((2.5e-4, 0.5), (6e-4, 1.2)):
        off = still.copy()
        off[:, 0] = miss
        np.testing.assert_allclose(fd.gamma_index(t, off, still, 5e-4, 0.1), gamma, rtol=1e-12)
    ramp = np.column_stack([0.1 * t, 0 * t, 0 * t])  # 1 mm a sample
    early = np.column_stack([0.1 * (t + 0.04), 0 * t, 0 * t])
    g = fd.gamma_index(t, early, ramp, 1e-6, 0.05)
    np.testing.assert_allclose(g[:96], 0.8, rtol=1e-9)
    assert np.all(g[96:] > 1.0)
    assert fd.gamma_pass_rate(t, early, ramp, 1e-6, 0.05) == np.mean(g <= 1.0) == 0.96


def test_the_rms_error_of_each_cycle_per_axis():
    """An error of a sin(2 pi t / 4 s) on X and a constant c on theta, cycles of 4 s: per cycle
    per axis the RMS is a / sqrt(2) on X, c on theta and 0 elsewhere, whatever the cycle."""
    t = np.arange(0.0, 16.0, 0.01)
    x_d = np.tile(X_HOME, (t.size, 1))
    x = x_d.copy()
    a, c = 3e-4, 2e-4
    x[:, 3] += a * np.sin(2 * np.pi * t / 4.0)
    x[:, 1] += c
    cyc = fd.fidelity(t, x, x_d, cycle_starts=[0.0, 4.0, 8.0, 12.0])["cycles"]
    assert cyc["starts"] == [0.0, 4.0, 8.0]
    rms = np.array(cyc["rms"])
    assert rms.shape == (3, 6)
    np.testing.assert_allclose(rms[:, 3], a / math.sqrt(2), rtol=1e-9)
    np.testing.assert_allclose(rms[:, 1], c, rtol=1e-9)
    np.testing.assert_allclose(rms[:, [0, 2, 4, 5]], 0.0, atol=1e-15)
