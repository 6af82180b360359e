"""A sampled motion's figures, each defined once for every caller.

**The principal direction** of a motion's translations (:func:`principal_direction`; the
Diagram's surrogate signal and its lag matching, the robot session's lag matching and relative
latency, a reproduced pair's report): the first
principal axis of its (n, 3) samples about their mean (the right singular vector of the largest
singular value), signed so that its largest component is positive. A motion along one axis has
that axis; a motion along a diagonal has the diagonal, where the coordinate that moves most
(peak to peak) would see only part of it. The lag of a motion and its relative latency are
measured along it (:func:`principal_displacement`, :func:`~.lag.signal_lag`).

**The parabolic refinement** of a sampled peak (:func:`parabolic_peak`): the vertex of the
parabola through the largest sample and its two neighbours, between samples: a period's
spectrum (:func:`dominant_period`). A lag is refined by the one lag search instead
(:mod:`~.lag`).

**The dominant period** of a sampled motion (:func:`dominant_period`): the period of its
strongest spectral peak, with the share of its power the peak holds; the Kalman predictor's
breathing model and a measured motion's verdict both read it, each with its own threshold.
"""

from __future__ import annotations

import math

import numpy as np

from .errors import InvalidConfigError


def _translations(x) -> np.ndarray:
    p = np.asarray(x, dtype=float)
    if p.ndim != 2 or p.shape[1] not in (3, 6) or len(p) < 2:
        raise InvalidConfigError(
            f"a principal direction needs (n, 6) poses or (n, 3) translations, n >= 2, got "
            f"{p.shape}"
        )
    if not np.all(np.isfinite(p)):
        raise InvalidConfigError("a principal direction needs finite samples")
    return p[:, 3:6] if p.shape[1] == 6 else p


def principal_direction(x) -> np.ndarray:
    """(3,) the unit principal direction of a motion's translations (module docstring).

    Args:
        x: (n, 6) poses [phi, theta, psi rad, X, Y, Z m] or (n, 3) translations, m; n >= 2.
    Returns:
        u (3,), the first principal axis of the translations about their mean, its largest
        component positive; Z (0, 0, 1) for a motion that does not translate.
    Raises:
        InvalidConfigError: another shape, fewer than 2 samples, or a value not finite.
    """
    p = _translations(x)
    c = p - p.mean(axis=0)
    if not np.any(c):
        return np.array([0.0, 0.0, 1.0])
    u = np.linalg.svd(c, full_matrices=False)[2][0]
    return u if u[np.argmax(np.abs(u))] > 0 else -u


def principal_displacement(x) -> tuple[np.ndarray, np.ndarray]:
    """A motion along its principal direction.

    Args:
        x: (n, 6) poses or (n, 3) translations, m (as :func:`principal_direction`).
    Returns:
        (s (n,) m about its mean, u (3,) :func:`principal_direction`).
    Raises:
        InvalidConfigError: as :func:`principal_direction`.
    """
    p = _translations(x)
    u = principal_direction(p)
    return (p - p.mean(axis=0)) @ u, u


def parabolic_peak(a: float, b: float, c: float) -> float:
    """The vertex of the parabola through (-1, ``a``), (0, ``b``), (1, ``c``), in samples
    from the middle one: 0.5 (a - c) / (a - 2 b + c), within (-0.5, 0.5) when ``b`` is the
    largest of the three; 0 where the three make no maximum (a - 2 b + c >= 0: flat or a
    valley) or are not finite."""
    curvature = a - 2.0 * b + c
    if not curvature < 0:  # NaN too
        return 0.0
    shift = 0.5 * (a - c) / curvature
    return float(shift) if np.isfinite(shift) else 0.0


def centred(v) -> np.ndarray:
    """v (n,) less its mean, exactly zero where v does not vary: its first value is taken away
    first, because the mean of n equal floats is not always equal to them, and the rounding left
    would give a signal held still a gain, a correlation and a period."""
    v = np.asarray(v, dtype=float)
    v = v - v[0]
    return v - np.mean(v)


#: A motion is periodic when the strongest peak of its spectrum holds at least this share of its
#: power (:func:`dominant_period`): the measured verdict's period and the Kalman model's.
PERIOD_POWER_SHARE = 0.3


def dominant_period(t, v) -> tuple[float, float]:
    """(period s, share): the period of the strongest spectral peak of v (n,) at the even times
    t (n,) (:func:`centred`; a Hann window; the spectrum zero-padded 8 times and the peak
    refined by :func:`parabolic_peak` through the logarithms of its bins) and the share of the
    motion's power within two bins of it (NaN, 0 for fewer than 8 samples or no motion). The
    motion counts as periodic when the share is at least :data:`PERIOD_POWER_SHARE`; the periods
    looked for are the caller's."""
    n = len(v)
    if n < 8:
        return math.nan, 0.0
    v = centred(v)
    if not np.any(v):
        return math.nan, 0.0
    dt = float(np.median(np.diff(t)))
    pad = 8 * n
    power = np.abs(np.fft.rfft(v * np.hanning(n), pad)) ** 2
    power[0] = 0.0
    k = int(np.argmax(power))
    if k == 0:
        return math.nan, 0.0
    share = float(np.sum(power[max(k - 16, 1) : k + 17]) / np.sum(power))
    peak = float(k)
    if 0 < k < len(power) - 1:
        peak += parabolic_peak(*np.log(power[k - 1 : k + 2] + 1e-300))
    return float(pad * dt / peak), share


def direction_words(u) -> str:
    """``u`` (3,) in words: the axis's name ("X", "Y" or "Z", with "-" for its negative) when
    it is one to 1e-3, else its components, "(0.6, 0, 0.8)"."""
    u = np.asarray(u, dtype=float)
    k = int(np.argmax(np.abs(u)))
    if abs(abs(u[k]) - 1.0) <= 1e-3:
        return ("-" if u[k] < 0 else "") + "XYZ"[k]
    return "(" + ", ".join(f"{v:.3g}" for v in u) + ")"


__all__ = [
    "PERIOD_POWER_SHARE",
    "principal_direction",
    "principal_displacement",
    "parabolic_peak",
    "centred",
    "dominant_period",
    "direction_words",
]
