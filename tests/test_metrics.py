"""Metrics on known signals."""

import numpy as np
import pytest

from stewart_drake.simulation.trajectories import ChirpTrajectory
from stewart_drake.studies.metrics import bandwidth_hz, frequency_response, settling_time


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
    assert bandwidth_hz(f, gain) == pytest.approx(f_c, rel=0.05)
    assert bandwidth_hz(f, np.ones_like(f)) is None
