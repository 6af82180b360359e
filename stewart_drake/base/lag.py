"""The lag of a measured signal behind its command by RMSE alignment in continuous shifts: one
search for every lag the package measures.

Its callers: ``verify``'s clock (:mod:`stewart_drake.verification.verify`) and its
reversed-axis test (:mod:`stewart_drake.verification.measured_verdict`), the pair's
relative latency on measurements (``verify --surrogate``,
:mod:`stewart_drake.verification.pair_judgement`) and its swap test
(:mod:`stewart_drake.verification.pair_causes`), a reproduced pair's lags and its external's
lead and the robot's lags from its encoders (:mod:`stewart_drake.base.pair_figures`, the one
relative latency), ``reproduce``'s lag of the
achieved motion (:func:`stewart_drake.organ_motion.fidelity.time_lag`) and a tracker's clock
against the robot computer's (:mod:`stewart_drake.calibration.clock`).

The method is IntERAct's (``RMSEAlignMethod.m``, ``findOptimalShift``; Kaczynska et al. 2026):
the shift of least RMS difference, a constant offset removed, here without their 0.05 s grid.

**The shift** d, s: a measured sample at time t shows the reference at t + d. **The lag** of the
measured behind its command is L = -d: measured(t) ~ commanded(t - L), L > 0 the measured moves
after its command.

**The score** of a shift (:func:`shift_scores`, :func:`shift_score`): the weighted mean squared
distance between the measured columns and the reference's at t + d, each column less its mean
difference when ``offsets`` (a constant offset, as phantom QA protocols and IntERAct remove it).

**The search** (:func:`best_shift`): every shift of the range at once, on a grid of ``step_s``,
by FFT (O((n + K) log(n + K)) for n samples and K shifts, where a loop over the shifts is
O(n K)), the least taken; then to a microsecond by scipy's bounded scalar minimisation of the
score at the samples' own times, within one step of it (:func:`refine_shift`). The least over
every shift of the range is taken, not the nearest one to a start: a periodic motion's other
minima inside the range (its harmonics make them) lose to the true one, and those a period away
are kept out by the range, which the callers hold under half a period (verify: 0.45 of a
repeating reference's). The measured may be sampled unevenly (a camera's frames): only the
coarse step puts it on the uniform grid (linearly interpolated); the refinement compares each
sample at its own time. The reference is a function of time: a trajectory, a recorded trace, or
a command's samples joined by a cubic spline (:func:`signal_lag`). Not linearly: a measured
motion that holds its command a control period at a time (a robot's encoders) has content locked
to the command's sample times, and against a linear interpolant its lag moved with where the
samples fell, by up to 0.47 ms at a 10 ms period (the same log, its times shifted by a fraction
of a period); against the cubic spline it moves by under 0.1 us.

**A turned frame** (:func:`rigid_shift`): where the measured positions are in a frame turned from
the reference's (a tracker not yet registered), the score of a shift is taken after the best
rotation at that shift (Kabsch), every shift at once by FFT: a registration motion's first clock
(:mod:`stewart_drake.verification.registration_motion`) and a FAIL's test for turned axes
(:mod:`stewart_drake.verification.causes`).
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np

from .columns import uniform_columns
from .errors import InvalidConfigError

#: Most samples the fine search evaluates the reference at (evenly picked): the score's minimum
#: is found to a fraction of a sample with far fewer.
REFINE_SAMPLES = 20000
#: A rotation's weight against a translation when a pose's six axes are scored together (a
#: clock searched on poses), m per rad: a point 0.15 m from the axis.
ROTATION_WEIGHT_M = 0.15
#: Fewest samples :func:`signal_lag` compares, unless told.
MIN_SAMPLES = 20


def shift_scores(
    t, y, weights, seen, shifts: tuple[float, float], step_s: float, offsets: bool
) -> tuple[np.ndarray, np.ndarray]:
    """(d (K,) s, score (K,)): every shift d in [shifts] on a grid of ``step_s`` and the
    weighted mean squared distance between the measured y and the reference's at t + d, each
    column less its mean difference when ``offsets``, every shift at once by FFT.

    Args:
        t: (n,) s, increasing. y: (n, k) the measured columns (NaN in a column of weight 0 is
            never read). weights: (k,) each column's factor (0 skips it).
        seen: t (m,) -> (m, k) the reference at those times.
        shifts: (lo, hi) s. step_s: s. offsets: remove each column's mean difference.
    Returns:
        the shifts and their scores, in y's unit squared times the weights'.
    """
    from scipy.signal import correlate

    weighted = np.flatnonzero(weights)
    grid, y_grid = uniform_columns(t, np.asarray(y)[:, weighted], step_s)  # only those read
    m = len(grid)
    # The last shift too where rounding leaves (hi - lo) / step a hair under a whole number.
    count = int(np.floor((shifts[1] - shifts[0]) / step_s + 1e-9)) + 1
    d = shifts[0] + step_s * np.arange(count)
    r_all = seen(grid[0] + shifts[0] + step_s * np.arange(m + count - 1))
    ones = np.ones(m)
    score = np.zeros(count)
    for j, k in enumerate(weighted):
        ym = y_grid[:, j]
        r = r_all[:, k]
        centre = float(np.mean(r))  # both less one constant: the differences keep their digits
        ym, r = ym - centre, r - centre
        s_r = correlate(r, ones, "valid")
        part = np.sum(ym * ym) + correlate(r * r, ones, "valid") - 2 * correlate(r, ym, "valid")
        if offsets:
            part -= (np.sum(ym) - s_r) ** 2 / m
        score += weights[k] ** 2 * part / m
    return d, score


def coarse_shift(
    t, y, weights, seen, shifts: tuple[float, float], step_s: float, offsets: bool
) -> float:
    """The shift d in [shifts] (measured time + d = the reference's time) of least
    :func:`shift_scores`, to ``step_s``, s."""
    d, score = shift_scores(t, y, weights, seen, shifts, step_s, offsets)
    return float(d[int(np.argmin(score))])


def shift_score(t, y, weights, seen, d: float, offsets: bool) -> float:
    """The weighted mean squared distance of :func:`shift_scores` at one shift d, from the
    reference evaluated at t + d (no grid)."""
    r = seen(t + d)
    score = 0.0
    for k in np.flatnonzero(weights):
        e = y[:, k] - r[:, k]
        if offsets:
            e = e - np.mean(e)
        score += weights[k] ** 2 * float(np.mean(e * e))
    return score


def refine_shift(t, y, weights, seen, d0: float, step_s: float, offsets: bool) -> float:
    """The shift of least :func:`shift_score` within ``step_s`` of the coarse d0 (scipy's
    bounded scalar minimisation, to a microsecond), on at most :data:`REFINE_SAMPLES` samples,
    s."""
    from scipy.optimize import minimize_scalar

    # As many as allowed, spread evenly from the first sample to the last.
    pick = np.round(np.linspace(0, len(t) - 1, min(len(t), REFINE_SAMPLES))).astype(int)
    t, y = t[pick], y[pick]
    # Minimised over the shift's departure from d0: the method's tolerance is relative to its
    # variable as well as absolute, and a shift of 1.7e9 s (a clock counting from 1970) would
    # leave it 25 s, more than the step, where the departure keeps its microsecond.
    sol = minimize_scalar(
        lambda u: shift_score(t, y, weights, seen, d0 + u, offsets),
        bounds=(-step_s, step_s),
        method="bounded",
        options={"xatol": 1e-6},
    )
    return float(d0 + sol.x)


def best_shift(
    t,
    y,
    weights,
    seen,
    shifts: tuple[float, float],
    step_s: float,
    offsets: bool,
) -> float:
    """The shift d in [shifts] (measured time + d = the reference's time) of least score, s: the
    one search (module docstring): :func:`coarse_shift` over every shift, then
    :func:`refine_shift` within a step of it and inside [shifts].

    Args:
        t, y, weights, seen, step_s, offsets: as :func:`shift_scores`'s.
        shifts: (lo, hi) s, lo <= hi.
    Raises:
        InvalidConfigError: shifts not finite or lo > hi; a step not > 0; fewer than 2 samples.
    """
    lo, hi = float(shifts[0]), float(shifts[1])
    if not (math.isfinite(lo) and math.isfinite(hi) and lo <= hi):
        raise InvalidConfigError(f"the shifts searched must be finite, lo <= hi, got {shifts}")
    if not 0 < step_s < math.inf:
        raise InvalidConfigError(f"the search's step must be > 0 s, got {step_s}")
    if len(t) < 2:
        raise InvalidConfigError(f"a shift is searched over 2 samples or more, got {len(t)}")
    d0 = coarse_shift(t, y, weights, seen, (lo, hi), step_s, offsets)
    # Within a step of d0 and inside the range: the interval's centre and half-width.
    a, b = max(d0 - step_s, lo), min(d0 + step_s, hi)
    if b - a <= 0.0:
        return a
    return refine_shift(t, y, weights, seen, 0.5 * (a + b), 0.5 * (b - a), offsets)


def inner_mask(t, max_lag_s: float) -> np.ndarray:
    """(n,) bool: the samples at the increasing times ``t`` (s) more than ``max_lag_s`` from
    either end (at exactly ``max_lag_s`` included), the ones :func:`signal_lag` compares: every
    shift within +-``max_lag_s`` compares the same samples and never reads the command past its
    span."""
    t = np.asarray(t, dtype=float)
    first, last = (t[0], t[-1]) if t.size else (0.0, 0.0)
    return (t >= first + max_lag_s) & (t <= last - max_lag_s)


def _checked_samples(t, measured, commanded, max_lag_s: float):
    """(t (n,), y (n, k), c (n, k)) as floats, or the error of :func:`signal_lag`."""
    t = np.asarray(t, dtype=float)
    y = np.asarray(measured, dtype=float)
    c = np.asarray(commanded, dtype=float)
    if t.ndim != 1 or y.shape != c.shape or y.shape[:1] != t.shape or y.ndim not in (1, 2):
        raise InvalidConfigError(
            f"the times, measured and commanded samples must be (n,) alike (or the two signals "
            f"(n, k) alike), got {t.shape}, {y.shape}, {c.shape}"
        )
    if not (np.all(np.isfinite(t)) and np.all(np.isfinite(y)) and np.all(np.isfinite(c))):
        raise InvalidConfigError("a time, measured or commanded sample is not finite")
    if not 0 < max_lag_s < math.inf:
        raise InvalidConfigError(f"max_lag_s must be > 0 s, got {max_lag_s}")
    if np.any(np.diff(t) <= 0):
        raise InvalidConfigError("the sample times must increase")
    return t, (y if y.ndim == 2 else y[:, None]), (c if c.ndim == 2 else c[:, None])


def signal_lag(
    t,
    measured,
    commanded,
    max_lag_s: float,
    *,
    offsets: bool = False,
    still_below: float = 0.0,
    min_samples: int = MIN_SAMPLES,
) -> tuple[float, float]:
    """The lag L of a measured signal behind its command sampled at the same times, s, within
    +-``max_lag_s``, and the RMS residual at it: the L minimising RMS(measured(t_k) -
    commanded(t_k - L)) (module docstring; the command joined between its samples by scipy's
    not-a-knot cubic spline), by :func:`best_shift`. The samples compared are the inner ones
    (more than ``max_lag_s`` from either end), so that every shift compares the same samples
    and the command is never read past its span. Columns count alike.

    Args:
        t: (n,) sample times, s, increasing (evenly or not). measured, commanded: (n,) or (n, k)
            at them (one unit).
        max_lag_s: the search's half-width, s (> 0; under half a period of a periodic motion,
            or a cycle earlier or later may match).
        offsets: remove each column's mean difference (a constant offset) before the RMS.
        still_below: a command no column of which moves more than this peak to peak over the
            inner samples has no lag (NaN).
        min_samples: the fewest inner samples taken.
    Returns:
        (L s, > 0: the measured after its command; the RMS residual at L, the signals' unit: the
        root of the sum over the columns of each one's mean square), (NaN, NaN) for a still
        command.
    Raises:
        InvalidConfigError: shapes that differ, times not increasing, a value not finite,
            ``max_lag_s`` not > 0, fewer than ``min_samples`` inner samples.
    Source: IntERAct's RMSEAlignMethod.m / findOptimalShift (Kaczynska et al. 2026), in
        continuous shifts.
    """
    t, y, c = _checked_samples(t, measured, commanded, max_lag_s)
    inner = inner_mask(t, max_lag_s)
    n_in = int(np.count_nonzero(inner))
    if n_in < max(min_samples, 2):
        raise InvalidConfigError(
            f"{n_in} samples lie inside the search's margins of {max_lag_s:g} s: the window is "
            f"too short to measure a lag (at least {max(min_samples, 2)})"
        )
    if np.all(np.ptp(c[inner], axis=0) <= still_below):
        return math.nan, math.nan
    t_in, y_in = t[inner], y[inner]
    from scipy.interpolate import CubicSpline

    weights = np.ones(c.shape[1])
    seen = CubicSpline(t, c, axis=0)

    step = float(np.median(np.diff(t)))
    d = best_shift(t_in, y_in, weights, seen, (-max_lag_s, max_lag_s), step, offsets)
    return -d, math.sqrt(max(shift_score(t_in, y_in, weights, seen, d, offsets), 0.0))


def _kabsch(H: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(R (..., 3, 3), score (...,)): the rotations maximising tr(R^T H) of cross-covariances H
    (..., 3, 3) (a sum of r y^T: R maps y onto r) and that maximum (Kabsch)."""
    U, S, Vt = np.linalg.svd(H)
    sign = np.sign(np.linalg.det(U @ Vt))
    sign = np.where(sign == 0, 1.0, sign)
    D = np.ones(S.shape)
    D[..., 2] = sign
    return (U * D[..., None, :]) @ Vt, np.sum(S * D, axis=-1)


def rigid_shift(
    t, y, positions: Callable, shifts: tuple[float, float], step_s: float
) -> tuple[float, np.ndarray]:
    """(d s, R (3, 3)): the shift in [shifts] (to ``step_s``) at which the measured positions
    y (n, 3) at the times t (n,), s, turned by the best rotation at each shift and put on the
    reference's centroid, come nearest the reference's positions (``positions(times)`` -> (m,
    3)): the rotation-aware score of a shift, for a measured frame turned from the reference's
    (a tracker's); every shift at once by FFT, the best rotation at each by Kabsch; and the
    rotation at that shift (it maps y onto the reference's positions)."""
    from scipy.signal import correlate

    grid, ym = uniform_columns(t, y, step_s)
    m = len(grid)
    # The last shift too where rounding leaves (hi - lo) / step a hair under a whole number.
    count = int(np.floor((shifts[1] - shifts[0]) / step_s + 1e-9)) + 1
    r = np.asarray(positions(grid[0] + shifts[0] + step_s * np.arange(m + count - 1)), float)
    r = r - r.mean(axis=0)
    ones = np.ones(m)
    S_r = np.column_stack([correlate(r[:, b], ones, "valid") for b in range(3)])  # (K, 3)
    S_rr = correlate(np.sum(r * r, axis=1), ones, "valid")
    C = np.empty((count, 3, 3))  # C[k, b, a] = sum_i r[i + k, b] y[i, a]
    for b in range(3):
        for a in range(3):
            C[:, b, a] = correlate(r[:, b], ym[:, a], "valid")
    y0 = ym - ym.mean(axis=0)
    R, score = _kabsch(C - S_r[:, :, None] * ym.mean(axis=0)[None, None, :])
    ms = (np.sum(y0 * y0) + S_rr - np.sum(S_r * S_r, axis=1) / m - 2 * score) / m
    k = int(np.argmin(ms))
    return float(shifts[0] + k * step_s), np.array(R[k])


__all__ = [
    "ROTATION_WEIGHT_M",
    "REFINE_SAMPLES",
    "MIN_SAMPLES",
    "shift_scores",
    "coarse_shift",
    "shift_score",
    "refine_shift",
    "best_shift",
    "rigid_shift",
    "signal_lag",
    "inner_mask",
]
