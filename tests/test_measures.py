"""The measures of a motion's error (base/measures.py) against sums written out here."""

import math

import numpy as np
import pytest

from stewart_drake.base.measures import peak_per_axis, rms_per_axis, rms_translation_rotation


def test_per_axis_rms_and_peak_of_numbers_written_out():
    e = np.array([[3.0, -1.0], [-4.0, 1.0], [0.0, -7.0]])
    assert rms_per_axis(e) == pytest.approx([math.sqrt(25 / 3), math.sqrt(51 / 3)], rel=1e-15)
    assert peak_per_axis(e).tolist() == [4.0, 7.0]
    assert float(rms_per_axis(e[:, 0])) == pytest.approx(math.sqrt(25 / 3), rel=1e-15)


def test_a_float32_log_is_summed_in_float64():
    # 2e6 samples of 1 + 1e-4 in float32: a float32 running sum of their squares drifts; the
    # float64 one is within the squares' own rounding (6e-8).
    e = np.full((2_000_000, 1), 1.0001, dtype=np.float32)
    exact = float(np.float32(1.0001)) ** 2
    assert rms_per_axis(e)[0] ** 2 == pytest.approx(exact, rel=1e-7)
    assert rms_per_axis(e).dtype == np.float64


def test_translation_and_rotation_rms_are_the_3d_sizes():
    e = np.zeros((4, 6))
    e[:, 3:] = [[1e-3, 0, 0], [0, 2e-3, 0], [0, 0, 2e-3], [0, 0, 0]]
    e[:, :3] = [[0, 0, 0], [3e-3, 4e-3, 0], [0, 0, 0], [0, 0, 0]]
    translation, rotation = rms_translation_rotation(e)
    assert translation == pytest.approx(math.sqrt((1 + 4 + 4) * 1e-6 / 4), rel=1e-14)
    assert rotation == pytest.approx(math.sqrt(25e-6 / 4), rel=1e-14)
    assert rms_translation_rotation(e.astype(np.float32)) == pytest.approx(
        (translation, rotation), rel=1e-7
    )
