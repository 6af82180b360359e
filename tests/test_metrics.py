"""Metrics on known signals."""

import numpy as np
import pytest

from stewart_drake.references.trajectories import ChirpTrajectory
from stewart_drake.run.metrics import (
    BANDWIDTH_ABOVE,
    BANDWIDTH_BELOW,
    BANDWIDTH_CROSSING,
    bandwidth_hz,
    frequency_response,
    settling_time,
)


def test_settling_time_and_frequency_response_on_known_signals():
    t = np.arange(0, 2, 1e-3)
    err = np.where(t < 0.5, 0.0, -0.005 * np.exp(-(t - 0.5) / 0.05))
    # |e| = 5 mm exp(-tau/50 ms) leaves the 2 % band at tau = 50 ms ln 50 = 0.1956 s.
    assert settling_time(t, err, 0.005, 0.5) == pytest.approx(0.05 * np.log(50), abs=2e-3)
    assert settling_time(t, np.full_like(t, 1.0), 0.005, 0.5) is None

    chirp = ChirpTrajectory(axis=5, amplitude=1e-3, f0_hz=1, f1_hz=50, duration_s=8)
    t = np.arange(0, 8, 1e-3)
    f_c = 10.0  # a first-order low-pass at 10 Hz
    f_t = chirp.frequency(t)
    g = 1 / np.sqrt(1 + (f_t / f_c) ** 2)
    y = chirp.offset[5] + chirp.amplitude * g * np.sin(chirp.phase(t) - np.arctan(f_t / f_c))
    f, gain, phase = frequency_response(t, y, chirp)
    np.testing.assert_allclose(gain, 1 / np.sqrt(1 + (f / f_c) ** 2), rtol=0.02)
    np.testing.assert_allclose(phase, -np.arctan(f / f_c), atol=np.radians(2))
    assert bandwidth_hz(f, gain).hz == pytest.approx(f_c, rel=0.05)
    assert bandwidth_hz(f, np.ones_like(f)).where == BANDWIDTH_ABOVE


def test_the_sweep_keeps_the_phase_of_a_known_lag():
    # A pure delay of 5 ms: gain 1, phase -2 pi f 5 ms, unwrapped past -180 deg at 100 Hz.
    chirp = ChirpTrajectory(axis=5, amplitude=1e-3, f0_hz=1, f1_hz=50, duration_s=8)
    t = np.arange(0, 8, 1e-3)
    y = chirp.offset[5] + chirp.amplitude * np.sin(chirp.phase(t - 0.005))
    f, gain, phase = frequency_response(t, y, chirp)
    np.testing.assert_allclose(gain, 1.0, rtol=0.02)
    np.testing.assert_allclose(phase, -2 * np.pi * f * 0.005, atol=np.radians(3))
    assert f[0] > 2.0  # the first segment (start transient) is dropped: f starts at 2.4 Hz


def test_bandwidth_never_names_a_frequency_where_the_gain_was_not_above_minus_3_db():
    f = np.array([2.43, 5.0, 10.0, 20.0, 49.0])
    # Below -3 dB from the first point (lqi_0.1_10's Z: never above -3.8 dB): below the sweep.
    low = bandwidth_hz(f, np.full(5, 10 ** (-3.8 / 20)))
    assert (low.hz, low.where) == (None, BANDWIDTH_BELOW)
    assert low.text() == "< 2.43 (below the sweep)"
    high = bandwidth_hz(f, np.full(5, 10 ** (1.4 / 20)))
    assert (high.hz, high.where) == (None, BANDWIDTH_ABOVE)
    assert high.text() == "> 49 (above the sweep)"
    # A crossing between 10 Hz (2 dB above -3.01 dB) and 20 Hz (2 dB below): half way in log f.
    db3 = 20 * np.log10(1 / np.sqrt(2))
    gain_db = np.array([0.0, 0.0, db3 + 2, db3 - 2, -20.0])
    cross = bandwidth_hz(f, 10 ** (gain_db / 20))
    assert cross.where == BANDWIDTH_CROSSING and cross.hz == pytest.approx(np.sqrt(200), rel=1e-3)
    assert cross.text() == "14.1"
    # Every random response: a reported bandwidth lies between a point above -3 dB and the
    # first point below it, and the gain is above -3 dB at every frequency before it.
    rng = np.random.default_rng(0)
    for _ in range(500):
        gain = 10 ** (rng.uniform(-8, 4, 5) / 20)
        bw = bandwidth_hz(f, gain)
        above = gain >= 1 / np.sqrt(2)
        if bw.where == BANDWIDTH_CROSSING:
            k = int(np.searchsorted(f, bw.hz))
            assert above[:k].all() and not above[k] and f[k - 1] <= bw.hz <= f[k]
        else:
            assert bw.hz is None
            assert above.all() if bw.where == BANDWIDTH_ABOVE else not above[0]
