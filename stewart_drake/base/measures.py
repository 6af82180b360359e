"""The measures of a sampled signal, once for every caller: the per-axis RMS and peak (of a
motion's error, the motors' torques, a basis's columns), and the translation's and rotation's
RMS of pose errors.

A pose error is (n, 6), the rotation first (roll, pitch, yaw, rad), then the translation (X, Y,
Z, m), as the package writes poses. The arrays may be float32 (a long run's logs) or float64;
the sums are in float64 either way, so that a float32 log's figures lose nothing to their
accumulation (its squares are float32, 6e-8 relative).
"""

from __future__ import annotations

import numpy as np


def rms_per_axis(e) -> np.ndarray:
    """(k,) float64 RMS of each column of ``e`` (n, k), over its rows; a (n,) array gives a
    0-d array, its RMS."""
    return np.sqrt(np.mean(np.square(np.asarray(e)), axis=0, dtype=float))


def peak_per_axis(e) -> np.ndarray:
    """(k,) float64 largest magnitude of each column of ``e`` (n, k), over its rows."""
    return np.abs(np.asarray(e)).max(axis=0).astype(float)


def rms_translation_rotation(e) -> tuple[float, float]:
    """(sqrt(mean |e_XYZ|^2) m, sqrt(mean |e_rpy|^2) rad) of pose errors ``e`` (n, 6): the
    RMS of the 3-D translation error and of the rotation vector's size (small angles)."""
    e = np.asarray(e)
    return (
        float(np.sqrt(np.mean(np.sum(np.square(e[:, 3:]), axis=1, dtype=float)))),
        float(np.sqrt(np.mean(np.sum(np.square(e[:, :3]), axis=1, dtype=float)))),
    )


__all__ = ["peak_per_axis", "rms_per_axis", "rms_translation_rotation"]
