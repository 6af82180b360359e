"""Fidelity metrics against signals whose errors are known (a known delay, a known gain, a
brute-force gamma). `stewart-drake reproduce`, which reports them, is tests/test_reproduce.py's:
these are the fidelity module's fast unit tests, the ones tools/mutation.py runs."""

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

    from stewart_drake.organ_motion.fidelity_study import CASES, TABLE_MARKERS, tables

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
